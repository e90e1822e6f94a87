"""Benchmark: the stability maps of the three time integrators (``millimpact stability``).

Runs the full sweep (the 1D bar, 12 step sizes x 5 velocities, and the default scene's sphere
impact on a coarse mesh, 5 step sizes x 3 velocities) into ``benchmarks/out/stability/`` and
prints a Markdown summary per integrator and problem, and the explicit critical step against
theory, for benchmarks/README.md.

    .venv/bin/python benchmarks/stability.py                 # ~5-10 min on 2 cores
    .venv/bin/python benchmarks/stability.py --table-only
"""
from __future__ import annotations

import argparse
import json
import sys
from collections import defaultdict
from pathlib import Path

from millimpact.cli import main as cli_main
from millimpact.studies.stability import read_csv

OUT = Path(__file__).resolve().parent / "out" / "stability"


def table(folder: Path) -> str:
    rows = read_csv(folder / "stability.csv")
    crit = json.loads((folder / "critical_step.json").read_text())
    groups = defaultdict(list)
    for r in rows:
        groups[(r["integrator"], r["problem"])].append(r)
    lines = ["| integrator | problem | runs | pass | degraded | failed | pass: max energy drift | "
             "failed at (step axis: velocities) | typical reason |", "|---|---|---|---|---|---|---|---|---|"]
    for (integ, prob), rs in groups.items():
        n = {s: sum(r["status"] == s for r in rs) for s in ("pass", "degraded", "failed")}
        drift = max((float(r["energy_drift_rel"]) for r in rs if r["status"] == "pass"), default=float("nan"))
        fails = sorted({float(r["dt_rel"]) for r in rs if r["status"] == "failed"})
        reasons = [r["reason"].split(";")[0].split(" (")[0] for r in rs if r["status"] != "pass"]
        common = max(set(reasons), key=reasons.count) if reasons else ""
        lines.append(f"| {integ} | {prob} | {len(rs)} | {n['pass']} | {n['degraded']} | {n['failed']} | "
                     f"{100 * drift:.2g} % | {', '.join(f'{x:g}' for x in fails) or '-'} ({rs[0]['dt_axis']}) | "
                     f"{common} |")
    lines.append("")
    th, m = crit.get("bar_theory_courant", {}), crit.get("bar_measured_courant", {})
    if m:
        lines.append(f"Explicit critical step on the bar (Courant dt c / h): theory {th['free']:.3f} free, "
                     f"{th['contact']:.3f} in contact (penalty k_p = E/h); measured stable up to "
                     f"{m['largest_stable']:g}, failed from {m['smallest_failed']:g}.")
    for v, s in crit.get("sphere", {}).items():
        lines.append(f"Sphere {v} m/s: linear estimate dt_crit {s['dt_crit_estimate_s'] * 1e9:.3g} ns; stable up "
                     f"to {s['largest_stable_rel']:g} x, failed from {s['smallest_failed_rel']:g} x.")
    return "\n".join(lines)


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--table-only", action="store_true")
    p.add_argument("--out", default=str(OUT))
    a = p.parse_args()
    if not a.table_only:
        rc = cli_main(["stability", "--out", a.out])
        if rc:
            return rc
    print(table(Path(a.out)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
