"""Repeated impacts at one spot: each impact starts from the previous one's residual state (plastic
strain, hardening, residual stress, the dent; foundations.md section 10). :mod:`millimpact.repeat.sequence` takes
a scene and a list of ``ImpactSpec`` and gives one ``ImpactOutcome`` per impact (one mesh and
reduction for the whole sequence); :mod:`millimpact.repeat.verdict` says shakedown or ratcheting;
:mod:`millimpact.repeat.report` writes impacts.csv and the figures; :mod:`millimpact.repeat.command`
is ``millimpact repeat``. Imports methods and below.
"""
