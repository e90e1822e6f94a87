"""Restitution of an elastic-perfectly-plastic steel sphere on a very stiff flat against V / V_y,
with Thornton's 1997 analytical curve (theory/thornton.py) and the elastic line: the issue-15
benchmark chart.

Configuration (Thornton 1997; Wu, Li & Thornton 2005): the ball (r 15 mm, steel, Y = 1 GPa,
perfectly plastic) strikes the hertz-halfspace block made 10x stiffer (G x 10: nearly rigid); full FE,
P1, h_c = a_max / 2 of each speed (the plan's sizes otherwise), to 2.5 Hertz contact times. Writes
benchmarks/out/plastic_restitution/{restitution.csv, restitution.png}.

    .venv/bin/python benchmarks/plastic_restitution.py [--ratios 1.5,3,10,30,100] [--hc 2]
"""
from __future__ import annotations

import argparse
import csv
import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from millimpact.scene.builtin import builtin_scene  # noqa: E402
from millimpact.scene.plan import make_plan  # noqa: E402
from millimpact.theory.hertz import effective_modulus  # noqa: E402
from millimpact.theory.thornton import restitution_thornton, yield_onset_velocity  # noqa: E402

Y = 1e9
STIFF = 10.0


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--ratios", default="1.5,3,10,30,100")
    ap.add_argument("--hc", type=float, default=2.0, help="h_contact = a_max / HC")
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "out" / "plastic_restitution"))
    a = ap.parse_args()
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    base = builtin_scene("hertz-halfspace")
    G = base.block.material.shear_modulus
    stiff = base.with_value("block.material.shear_modulus", STIFF * G)
    e_star = effective_modulus(stiff.ball.material, stiff.block.material)
    vy = yield_onset_velocity(Y, e_star, stiff.ball.material.density)
    rows = []
    for ratio in [float(x) for x in a.ratios.split(",")]:
        v = ratio * vy
        scene = stiff.with_value("impact.velocity", [0.0, -v, 0.0])
        plan = make_plan(scene)
        sets = {"impact.velocity": f"[0.0,{-v!r},0.0]", "block.material.shear_modulus": repr(STIFF * G),
                "ball.material.yield_stress": repr(Y), "model.h_contact": repr(plan.hertz.a_max / a.hc),
                "time.end": repr(plan.gap / v + 2.5 * plan.hertz.contact_time)}
        case = out / f"v_over_vy_{ratio:g}"
        cmd = [sys.executable, "-m", "millimpact.cli", "run", "hertz-halfspace", "--method", "full", "-q",
               "--out", str(case), "--force"] + [x for k, val in sets.items() for x in ("--set", f"{k}={val}")]
        t0 = time.perf_counter()
        r = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
        wall = time.perf_counter() - t0
        if r.returncode != 0:
            print(f"V/V_y {ratio:g}: failed: {r.stderr.strip().splitlines()[-1]}")
            continue
        s = json.loads((case / "summary.json").read_text())
        row = {"v_over_vy": ratio, "speed_m_s": v, "restitution": s["restitution"],
               "restitution_thornton": restitution_thornton(v, vy), "plastic_share": s["plastic_dissipation_share"],
               "energy_drift": s["energy_drift_max_rel"], "dofs": s["model"]["dofs"], "wall_s": wall}
        rows.append(row)
        print(", ".join(f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}" for k, v in row.items()), flush=True)
    with open(out / "restitution.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(7, 4.5), constrained_layout=True)
    x = np.logspace(0, 2.2, 200)
    ax.semilogx(x, restitution_thornton(x * vy, vy), "k--", label="Thornton 1997 (analytical, over-dissipates)")
    ax.axhline(1.0, color="0.6", lw=1, label="elastic")
    ax.semilogx([r["v_over_vy"] for r in rows], [r["restitution"] for r in rows], "o-", label="millimpact full FE")
    ax.set_xlabel("V / V_y")
    ax.set_ylabel("coefficient of restitution e")
    ax.set_ylim(0, 1.05)
    ax.grid(alpha=0.3, which="both")
    ax.set_title(f"Elastic-perfectly-plastic sphere (Y 1 GPa, V_y {vy:.3g} m/s) on a stiff flat")
    ax.legend()
    fig.savefig(out / "restitution.png", dpi=130)
    print(f"-> {out}/restitution.csv, restitution.png (V_y = {vy:.4g} m/s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
