"""Benchmark: speed against accuracy of every method on the default scene (``millimpact bench``).

Runs ``millimpact bench paper-rig`` at full size (every method at three resolutions against a
cached full-P2 reference, see ``millimpact bench --help``), writes its outputs to
``benchmarks/out/bench-paper-rig/`` and prints the Pareto table (Markdown) and the wall-time ratio
of ``improved`` to ``full`` at equal error, for benchmarks/README.md.

    .venv/bin/python benchmarks/bench_default.py              # full size (~15-30 min, 2 cores)
    .venv/bin/python benchmarks/bench_default.py --table-only # re-print the table of the last run
    .venv/bin/python benchmarks/bench_default.py --quick      # tiny sizes
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from millimpact.studies.bench import read_csv
from millimpact.cli import main as cli_main

OUT = Path(__file__).resolve().parent / "out" / "bench-paper-rig"


def table(folder: Path) -> str:
    """The bench's rows as a Markdown table, then the equal-error wall-time ratios."""
    rows = read_csv(folder / "bench.csv")
    meta = json.loads((folder / "bench.json").read_text())
    pct = lambda x: "n/a" if x in ("", "nan") else f"{100 * float(x):+.2f} %"  # noqa: E731
    l2 = lambda x: "n/a" if x in ("", "nan") else f"{100 * float(x):.2f} %"  # noqa: E731
    lines = ["| method | resolution | status | wall (s) | peak RSS (MB) | DOFs (solved) | F_max | t_c | impulse "
             "| force L2 | gauge A L2 |", "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        wall = "-" if r["wall_s"] in ("", "nan") else f"{float(r['wall_s']):.3g}"
        rss = "-" if r["peak_rss_MB"] in ("", "nan") else f"{float(r['peak_rss_MB']):.0f}"
        dofs = r["dofs"] if r["dofs"] == r["solved_dofs"] else f"{r['dofs']} ({r['solved_dofs']})"
        lines.append(f"| {r['method']} | {r['resolution']} | {r['status']} | {wall} | {rss} | {dofs} | "
                     f"{pct(r['err_F_max'])} | {pct(r['err_t_c'])} | {pct(r['err_impulse'])} | "
                     f"{l2(r['err_force_L2'])} | {l2(r['err_gauge_L2'])} |")
    ref = meta["reference"]["finest"]
    lines.append("")
    lines.append(f"Reference: full {ref['resolution']}, {ref['dofs']} DOFs, {ref['wall_s']:.0f} s; "
                 f"F_max {ref['F_max_N'] / 1e3:.4g} kN, t_c {ref['t_c_s'] * 1e6:.4g} us; simulated "
                 f"{meta['end_s'] * 1e6:.4g} us.")
    for k, r in meta["equal_error_wall_ratio"].items():
        if r.get("ratio") is not None:
            lines.append(f"Wall-time ratio {k} at equal contact-force L2 error ({r['at_errors'][0]:.2g} to "
                         f"{r['at_errors'][1]:.2g}): {r['ratio']:.3g}")
        else:
            lines.append(f"Wall-time ratio {k}: no common error range ({k.split('/')[0]} "
                         f"{r['a_error_range']}, {k.split('/')[1]} {r['b_error_range']})")
    return "\n".join(lines)


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--table-only", action="store_true")
    p.add_argument("--quick", action="store_true")
    p.add_argument("--out", default=str(OUT))
    a = p.parse_args()
    out = Path(a.out)
    if not a.table_only:
        rc = cli_main(["bench", "paper-rig", "--out", str(out)] + (["--quick"] if a.quick else []))
        if rc:
            return rc
    print(table(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
