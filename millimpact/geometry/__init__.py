"""Geometry and meshes: gmsh (OpenCASCADE) models of the ball and the struck body, meshed with
tetrahedra, converted to DOLFINx once and cached.

Takes a scene and its plan (sizes), gives :class:`.mesh.MeshData` (mesh, cell tags, facet tags,
info). The physical groups it writes are the mesh contract (meshes/README.md). Imports the scene
stage and below.
"""
