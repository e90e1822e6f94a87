"""The finite-element model: DOLFINx spaces, materials, mass and stiffness, supports and symmetry,
node-to-surface contact rows, and point probes.

Takes a mesh (:mod:`millimpact.geometry`) and the plan (the scene's derived numbers, never the
scene itself); gives :class:`.model.FEModel` (PETSc M, K, the dof sets, the materials),
:class:`.contact.ContactSet` (the gap rows B, g0, tangents) and :class:`.probes.PointProbe`. UFL
forms live in :mod:`.forms`. Imports geometry and below.
"""
