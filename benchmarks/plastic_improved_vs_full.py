"""Benchmark: the improved method against full FE of the same mesh on a plastic scene.

Runs ``paper-rig-plastic`` (both steels yield, 3 m/s, 40 ms; ``--set time.end=2e-3`` for the impact) with ``improved``, then ``full`` P2 on
the same mesh, zone and contact candidates (the radii the improved run's notes print), one after
the other on this machine, and reports F_max, restitution, residual dent depth, plastic work and
the wall times with their ratio. The bounds: F_max within 1 %, restitution within 0.01,
dent within 2 %, improved at least 20x faster over the scene's run time.

A third run bounds what a faster plastic step can give: ``improved`` on the same mesh, zone and
candidates with the yield stresses raised to YIELD_NEVER, so nothing yields (the plastic machinery
runs, each step takes one solve and one return map; its answer is the elastic one). Its wall time
is the improved plastic run's floor, reached only by a plastic step that costs nothing over an
elastic one: full P2's wall time over it is the largest speed-up any plastic step gives here (the
ceiling, in the report's first line). Writes benchmarks/out/plastic_improved_vs_full/{plastic_improved_vs_full.csv,.md}.

    .venv/bin/python benchmarks/plastic_improved_vs_full.py [--scene paper-rig-plastic] [--set time.end=...]
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

from _report import write_report  # noqa: E402

KEYS = ("peak_contact_force_N", "restitution", "residual_dent_depth_m", "plastic_dissipation_J")
#: the yield stress (Pa) of the twin in which nothing yields: ~1e5 x any steel's
YIELD_NEVER = 1e15


def run(scene: str, folder: Path, *args: str) -> tuple[dict, float]:
    cmd = [sys.executable, "-m", "millimpact.cli", "run", scene, "-q", "--force", "--out", str(folder), *args]
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, cwd=ROOT)
    wall = time.perf_counter() - t0
    return json.loads((folder / "summary.json").read_text()), wall


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--scene", default="paper-rig-plastic")
    ap.add_argument("--set", action="append", default=[], help="FIELD=VALUE for both runs")
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "out" / "plastic_improved_vs_full"))
    a = ap.parse_args()
    out = Path(a.out)
    sets = [x for s in a.set for x in ("--set", s)]
    imp, t_imp = run(a.scene, out / "improved", "--method", "improved", *sets)
    zone, cand = imp["model"]["zone_radius_m"], imp["model"]["candidate_radius_m"]
    full, t_full = run(a.scene, out / "full-p2", "--method", "full", "--degree", "2", *sets,
                       "--set", f"model.zone_radius={zone!r}", "-candidate_radius", repr(cand))
    lines = (out / "improved" / "scene.toml").read_text().splitlines()
    struck = "liner" if "[liner]" in (line.strip() for line in lines) else "block"
    twin, t_twin = run(a.scene, out / "improved-nothing-yields", "--method", "improved", *sets,
                       "--set", f"ball.material.yield_stress={YIELD_NEVER!r}",
                       "--set", f"{struck}.material.yield_stress={YIELD_NEVER!r}",
                       "--set", f"model.zone_radius={zone!r}", "-candidate_radius", repr(cand))
    rows = []
    for name, s, wall in (("improved", imp, t_imp), ("full P2", full, t_full),
                          ("improved, nothing yields", twin, t_twin)):
        rows.append({"method": name, "dofs": s["model"]["dofs"], "reduced_dofs": s["model"].get("reduced_dofs", ""),
                     **{k: s[k] for k in KEYS}, "wall_time_s": wall,
                     "tangent_factorizations": s["integration"]["n_tangent_factorizations"],
                     "yielding_steps": s["integration"]["n_plastic_steps"]})
    ref = rows[1]

    def cells(r: dict) -> list[str]:
        return [r["method"], f"{r['dofs']}" + (f" -> {r['reduced_dofs']}" if r["reduced_dofs"] != "" else ""),
                f"{r['peak_contact_force_N'] / 1e3:.4g} ({(r['peak_contact_force_N'] / ref['peak_contact_force_N'] - 1) * 100:+.2f} %)",
                f"{r['restitution']:.4f} ({r['restitution'] - ref['restitution']:+.4f})",
                f"{r['residual_dent_depth_m'] * 1e6:.4g} ({(r['residual_dent_depth_m'] / ref['residual_dent_depth_m'] - 1) * 100:+.2f} %)",
                f"{r['plastic_dissipation_J']:.4g}", f"{r['yielding_steps']}", f"{r['tangent_factorizations']}",
                f"{r['wall_time_s']:.0f} ({ref['wall_time_s'] / r['wall_time_s']:.1f}x)"]

    write_report(out, "plastic_improved_vs_full", rows, 1,
                 ["method", "dofs", "F_max kN", "restitution", "dent um", "plastic work J", "yielding steps", "tangents",
                  "wall s (speed-up)"],
                 cells, note=f"; scene {a.scene} {' '.join(a.set)}; full P2 and the twin in which nothing yields on the "
                             f"improved run's mesh, zone and candidates; the ceiling of any plastic step: "
                             f"{t_full / t_twin:.1f}x (full P2's wall time over the twin's)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
