"""millimpact: reference-quality 3D impact dynamics of a grinding ball on a SAG mill liner.

The flow of one run (see README): scene -> plan -> geometry -> model -> reduction -> contact ->
integrator -> solvers -> results -> plots.
"""
__version__ = "0.1.0"
