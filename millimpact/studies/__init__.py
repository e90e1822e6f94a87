"""Studies built from many runs: parameter sweeps (:mod:`.study`), the speed/accuracy chart
(:mod:`.bench`), stability maps of the integrators (:mod:`.stability`) and scoring another code's
histories against a reference (:mod:`.compare`). Each command module has ``HELP``,
``add_arguments(parser)`` and ``main(args)``. Imports methods and below.
"""
