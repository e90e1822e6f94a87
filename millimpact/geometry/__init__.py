"""Geometry and meshes: gmsh (OpenCASCADE) models of the ball and the struck body, meshed with
tetrahedra, converted to DOLFINx once and cached.

Takes a scene and its plan (sizes), gives :class:`.mesh.MeshData` (mesh, cell tags, facet tags,
info). The physical groups it writes are the mesh contract (meshes/README.md). Imports the scene
stage and below.
"""

import signal as _signal
import threading as _threading

import gmsh as _gmsh

# gmsh's Python module (4.8) sets SIGINT to SIG_DFL when it is imported and restores it only in
# gmsh.finalize(): from the first import on, Ctrl-C would kill the process outright (no
# KeyboardInterrupt: a study could not stop its workers or say what it kept). Put Python's handler
# back; gmsh.finalize() restores the same one.
if _threading.current_thread() is _threading.main_thread() and getattr(_gmsh, "oldsig", None) is not None:
    _signal.signal(_signal.SIGINT, _gmsh.oldsig)
