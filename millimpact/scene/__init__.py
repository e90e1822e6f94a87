"""The scene and its plan: what the user describes, and what that scene needs.

- :mod:`.schema`: the scene as frozen dataclasses (ball, block or liner, materials, impact, gauges,
  time span, model options, outputs), validated on construction with one-line errors that name
  the field; TOML in and out; the built-in scenes and studies.
- :mod:`.liner_shape`: the pure geometry of a liner segment (lifter face point and normal).
- :mod:`.plan`: sizes derived from the Hertz estimate (symmetry, zone radius, element sizes, time
  steps, modal cutoff), each reported with its reason.

Imports only :mod:`millimpact.theory` and :mod:`millimpact.errors`; knows nothing of gmsh,
DOLFINx or PETSc.
"""
