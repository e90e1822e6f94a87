"""ParaView fields: the displacement at chosen times as XDMF with the mesh's cell tags."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..fem.model import FEModel


def write_fields(
    model: FEModel,
    fields: list[tuple[float, np.ndarray]],
    path: Path,
    plastic_fields: list[tuple[np.ndarray, np.ndarray, np.ndarray]] | None = None,
) -> None:
    """XDMF of the displacement (m) at the recorded times, with cell tags (collective); for a
    plastic run also the cellwise (DG0) largest equivalent plastic strain and von Mises stress (Pa)
    of the contact zones' quadrature points (``plastic_fields``: one (cells, alpha, von Mises) per
    time, from :meth:`millimpact.fem.plastic_zone.PlasticZone.cell_fields`)."""
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
        cellwise = []
        if plastic_fields:
            Q0 = fem.FunctionSpace(mesh, ("DG", 0))
            for name in ("equivalent_plastic_strain", "von_mises_Pa"):
                f = fem.Function(Q0)
                f.name = name
                cellwise.append(f)
        for i, (t, arr) in enumerate(fields):
            u.vector.array[:] = arr
            u.x.scatter_forward()
            if out_fn is not u:
                out_fn.interpolate(u)
            xdmf.write_function(out_fn, t)
            if plastic_fields and i < len(plastic_fields):  # cellwise holds their two functions
                cells, alpha, vm = plastic_fields[i]
                for f, values in zip(cellwise, (alpha, vm)):
                    f.x.array[:] = 0.0
                    f.x.array[cells] = values  # DG0: one dof per cell, dof index = cell index
                    f.x.scatter_forward()
                    xdmf.write_function(f, t)
