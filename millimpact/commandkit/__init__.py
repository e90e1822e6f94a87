"""What every command shares, below the commands and above the computing stages: the
``--set FIELD=VALUE`` and ``--option KEY=VALUE`` arguments read and validated once
(:mod:`millimpact.commandkit.settings`: all ``--set`` assignments together, so their order never
matters), the keyed store of finished pieces a command keeps as it goes and a rerun resumes from
(:mod:`millimpact.commandkit.store`: the key, the atomic save, the load, the note an interruption
prints), and a command's wall time per stage (:mod:`millimpact.commandkit.timing`). Printing on
rank 0 is :func:`millimpact.console.sayer`; figures select their backend with
:func:`millimpact.results.plots.pyplot`. Imports methods and below.
"""
