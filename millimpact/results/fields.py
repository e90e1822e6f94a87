"""ParaView fields: the displacement at chosen times as XDMF with the mesh's cell tags."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..fem.model import FEModel


def write_fields(model: FEModel, fields: list[tuple[float, np.ndarray]], path: Path) -> None:
    """XDMF of the displacement (m) at the recorded times, with cell tags (collective)."""
    from dolfinx.io import XDMFFile

    mesh = model.V.mesh
    u = model.function("displacement_m")
    # XDMF in DOLFINx 0.5 writes P1 geometry: interpolate P2 fields to P1
    from dolfinx import fem

    out_fn = u
    if model.degree != 1:
        V1 = fem.VectorFunctionSpace(mesh, ("Lagrange", 1))
        out_fn = fem.Function(V1)
        out_fn.name = "displacement_m"
    with XDMFFile(mesh.comm, str(path), "w") as xdmf:
        xdmf.write_mesh(mesh)
        xdmf.write_meshtags(model.meshdata.cell_tags)
        for t, arr in fields:
            u.vector.array[:] = arr
            u.x.scatter_forward()
            if out_fn is not u:
                out_fn.interpolate(u)
            xdmf.write_function(out_fn, t)
