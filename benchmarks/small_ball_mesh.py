"""A small ball on a large block stays a small model: the gmsh mesh of a ball of
radius R on hertz-halfspace cubes of growing side L, its vertices, P1 DOFs, meshing time and peak
memory, beside the plan's estimate. Each case runs in its own process (peak RSS per case).

    .venv/bin/python benchmarks/small_ball_mesh.py [--radius 0.0025] [--sides 0.025,0.1,0.4]

``--old`` sizes the far mesh as before the small-ball plan (h_far = R / 4 everywhere, through
``model.h_far``) and only estimates it for sides above 30 mm (the 100 mm cube passed 9 GB).
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def one_case(radius: float, side: float, old: bool, mesh: bool) -> dict:
    from millimpact.scene.builtin import builtin_scene
    from millimpact.scene.plan import make_plan
    from millimpact.scene.sizing import estimate_mesh

    base = dataclasses.replace(builtin_scene("hertz-halfspace"), gauges=())
    scene = base.with_values([("ball.radius", radius), ("block.length", side), ("block.thickness", side),
                              ("block.height", side)] + ([("model.h_far", radius / 4.0)] if old else []))
    plan = make_plan(scene)
    row = {"ball_radius_m": radius, "block_side_m": side, "plan": "old (h_far = R/4)" if old else "small ball",
           "h_contact_m": plan.h_contact, "h_far_m": plan.h_far, "h_ball_m": plan.h_ball,
           "estimated_p1_dofs": estimate_mesh(scene, plan).dofs(1)}
    if mesh:
        from mpi4py import MPI

        from millimpact.geometry.mesh import create_mesh

        t0 = time.perf_counter()
        md = create_mesh(scene, plan, MPI.COMM_WORLD, cache_dir=tempfile.mkdtemp())
        n = md.mesh.geometry.index_map().size_global
        row.update(vertices=n, p1_dofs=3 * n, mesh_s=time.perf_counter() - t0,
                   peak_rss_MB=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)
    return row


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--radius", type=float, default=2.5e-3)
    ap.add_argument("--sides", default="0.025,0.1,0.4")
    ap.add_argument("--old", action="store_true", help="also the plan before (h_far = R / 4), meshed up to 30 mm")
    ap.add_argument("--case", help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.case:
        r, L, old, mesh = json.loads(a.case)
        print(json.dumps(one_case(r, L, old, mesh)))
        return 0
    rows = []
    for old in ([False, True] if a.old else [False]):
        for side in (float(x) for x in a.sides.split(",")):
            mesh = not old or side <= 0.03
            out = subprocess.run([sys.executable, __file__, "--case", json.dumps([a.radius, side, old, mesh])],
                                 capture_output=True, text=True, cwd=ROOT, check=True).stdout
            row = json.loads(out.strip().splitlines()[-1])
            rows.append(row)
            print(", ".join(f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}" for k, v in row.items()), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
