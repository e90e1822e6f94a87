"""Time integration: the schemes, the PETSc solver set-ups they use, and the contact/friction
problems of each step.

Takes a linear dynamic system (M, K, contact rows B and gaps, fixed dofs) and a time schedule;
gives the states of each step to an observer and the statistics of the run. Solver choices are
PETSc options with a prefix per solver (``impact_...``). Imports only :mod:`millimpact.errors`:
it knows nothing of meshes or scenes, so the 1D bar (:mod:`.bar`) and the 3D models use it alike.
"""
