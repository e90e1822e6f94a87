"""Repeated impacts at one spot: each impact starts from the previous one's residual state
(plastic strain, hardening, residual stress, the dent; DESIGN.md 10). :mod:`.sequence` takes a scene
and a list of ``ImpactSpec`` and gives one ``ImpactOutcome`` per impact (one mesh and reduction
for the whole sequence); :mod:`.verdict` says shakedown or ratcheting; :mod:`.report` writes
impacts.csv and the figures; :mod:`.command` is ``millimpact repeat``. Imports methods and below.
"""
