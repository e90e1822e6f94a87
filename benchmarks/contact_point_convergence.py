"""Benchmark: convergence of the contact point's kinematics under the time step and the mesh.

The contact point's velocity and acceleration are those of the centre of mass of the half-ball of
radius a_max under the impact point (``millimpact.fem.probes.patch_momentum_row``: its momentum
over its mass, with the integrator's mass matrix), band-limited to 4 / t_c
(``millimpact.results.band_limit``). The surface node's own values jumped at first contact (0 ->
1.45 m/s in one step on the rig) and spiked at onset and release (1,100 and 1,550 km/s^2, issue
18). This runs the scene (default paper-rig, ``improved``, cut to 3 t_c) at the plan's dt_contact
and h_contact, then at dt/2, dt/4 and at h/1.4, h/2, and reports per run: the peak velocity into
the block, the peak acceleration of each sign (in contact), the largest one-step velocity change
over the peak velocity (a jump is ~1, a resolved signal ~1/steps) and the largest |acceleration|
just outside the contact over the largest inside (the zero-phase band limit spreads the onset
over ~2 sigma = 8 us, so ~1 is expected; a spike at onset or release would be >> 1). Writes
benchmarks/out/contact_point_convergence/contact_point_convergence.{csv,md}.

    .venv/bin/python benchmarks/contact_point_convergence.py [--scene paper-rig] [--method improved]
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

import millimpact  # noqa: F401  (before numpy: it chooses OpenBLAS's kernels, millimpact/__init__.py)
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
sys.path.insert(0, str(ROOT))

from _report import write_report  # noqa: E402


def run(scene: str, method: str, folder: Path, sets: list[str]) -> tuple[dict, dict, float]:
    cmd = [sys.executable, "-m", "millimpact.cli", "run", scene, "--method", method, "-q", "--force",
           "--out", str(folder), *[x for s in sets for x in ("--set", s)]]
    t0 = time.perf_counter()
    subprocess.run(cmd, check=True, cwd=ROOT)
    wall = time.perf_counter() - t0
    from millimpact.results.timeseries import TimeSeries

    ts = TimeSeries.read_csv(folder / "timeseries.csv")
    return json.loads((folder / "summary.json").read_text()), ts, wall


def measures(ts) -> dict:
    t = ts.time
    f = ts["contact_force_N"]
    v = ts["contact_point_velocity_m_s"]
    a = ts["contact_point_acceleration_m_s2"]
    on = f > 1e-6 * f.max()
    first, last = np.argmax(on), len(on) - 1 - np.argmax(on[::-1])
    inside = slice(first, last + 1)
    near = slice(max(first - 3, 0), min(last + 4, len(t)))   # a few steps either side: onset and release
    out = np.ones(len(t), dtype=bool)
    out[inside] = False
    win = np.zeros(len(t), dtype=bool)
    win[near] = True
    a_out = np.abs(a[out & win]).max() if np.any(out & win) else 0.0
    return {"v_peak_m_s": float(v[inside].max()), "a_max_m_s2": float(a[inside].max()),
            "a_min_m_s2": float(a[inside].min()),
            "max_step_dv_over_v_peak": float(np.abs(np.diff(v[near])).max() / v[inside].max()),
            "a_outside_over_inside": float(a_out / np.abs(a[inside]).max())}


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--scene", default="paper-rig")
    ap.add_argument("--method", default="improved")
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "out" / "contact_point_convergence"))
    a = ap.parse_args()
    from millimpact.scene.builtin import resolve_scene
    from millimpact.scene.plan import make_plan

    plan = make_plan(resolve_scene(a.scene))
    dt, h = plan.dt_contact, plan.h_contact
    end = plan.gap / np.linalg.norm(plan.velocity) + 3.0 * plan.hertz.contact_time
    variants = [("plan", 1.0, 1.0), ("dt/2", 0.5, 1.0), ("dt/4", 0.25, 1.0), ("h/1.4", 1.0, 1 / 1.4), ("h/2", 1.0, 0.5)]
    rows = []
    for name, fdt, fh in variants:
        sets = [f"time.end={end!r}", f"time.dt_contact={dt * fdt!r}", f"model.h_contact={h * fh!r}"]
        s, ts, wall = run(a.scene, a.method, Path(a.out) / name.replace("/", "_"), sets)
        rows.append({"variant": name, "dt_contact_s": dt * fdt, "h_contact_m": h * fh, "dofs": s["model"]["dofs"],
                     **measures(ts), "peak_contact_force_N": s["peak_contact_force_N"], "wall_time_s": wall})
    ref = rows[0]

    def cells(r: dict) -> list[str]:
        rel = lambda k: f"{(r[k] / ref[k] - 1) * 100:+.1f} %"   # noqa: E731
        return [r["variant"], f"{r['dt_contact_s'] * 1e6:.3g}", f"{r['h_contact_m'] * 1e3:.3g}", f"{r['dofs']}",
                f"{r['v_peak_m_s']:.4g} ({rel('v_peak_m_s')})", f"{r['a_min_m_s2'] / 1e3:.4g} ({rel('a_min_m_s2')})",
                f"{r['a_max_m_s2'] / 1e3:.4g} ({rel('a_max_m_s2')})", f"{r['max_step_dv_over_v_peak']:.3f}",
                f"{r['a_outside_over_inside']:.3f}", f"{r['wall_time_s']:.0f}"]

    write_report(a.out, "contact_point_convergence", rows, 1,
                 ["variant", "dt us", "h_contact mm", "DOFs", "v peak m/s", "a min km/s^2", "a max km/s^2",
                  "max step dv / v peak", "max |a| out / in", "wall s"], cells,
                 note=f"; scene {a.scene}, method {a.method}, end {end * 1e6:.0f} us; contact point = centre of mass "
                      f"of the half-ball of radius a_max = {plan.hertz.a_max * 1e3:.3g} mm")
    return 0


if __name__ == "__main__":
    sys.exit(main())
