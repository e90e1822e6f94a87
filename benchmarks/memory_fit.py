"""Peak memory of liner-panel runs against their DOFs: the data of millimpact.methods.memory's model.

Runs ``millimpact run liner-panel`` under ``/usr/bin/time -v`` (one rank) at a few mesh sizes per
method (short simulated time: the peak comes from assembly, factorization and the reduction, not
from the time loop), reads the peak RSS and ``summary.json``'s ``model.dofs``, fits
peak = a + c DOFs^(4/3) per method by least squares (the fill of a sparse direct factorization of a
3D mesh with nested-dissection-like orderings grows as N^(4/3): Lipton, Rose and Tarjan, SIAM J.
Numer. Anal. 16 (1979) 346-358) and writes ``benchmarks/out/memory_fit.json`` and a
Markdown table (docs/scenes.md, "Memory"). Usage, from the repository:

    python benchmarks/memory_fit.py [full|improved ...]
"""
from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import millimpact  # noqa: F401  (before numpy: it chooses OpenBLAS's kernels, millimpact/__init__.py)
import numpy as np

REPO = Path(__file__).resolve().parents[1]
OUT = REPO / "benchmarks" / "out"
#: (method, h_far m, h_contact m): zone radius 24 mm everywhere
CASES = {
    "full": [(0.05, 0.005), (0.035, 0.0035), (0.025, 0.0025), (0.018, 0.0018)],
    "improved": [(0.05, 0.005), (0.035, 0.0035), (0.025, 0.0025)],
}


def run_case(method: str, h_far: float, h_contact: float) -> dict:
    out = Path("/tmp/memory_fit") / f"{method}-{h_far:g}"
    cmd = ["/usr/bin/time", "-v", sys.executable, "-m", "millimpact.cli", "run", "liner-panel", "--method", method,
           "--set", f"model.h_far={h_far}", "--set", f"model.h_contact={h_contact}", "--set", "model.zone_radius=0.024",
           "--set", "time.end=1e-4", "--set", "outputs.figures=false", "--set", "outputs.xdmf=false",
           "--out", str(out), "--force", "--quiet"]
    env = {**os.environ, "MILLIMPACT_MEMORY_CHECK": "off"}
    p = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True, env=env)
    if p.returncode != 0:
        raise SystemExit(p.stderr[-2000:])
    rss_kb = int(re.search(r"Maximum resident set size \(kbytes\): (\d+)", p.stderr).group(1))
    wall = re.search(r"Elapsed \(wall clock\) time \(h:mm:ss or m:ss\): (\S+)", p.stderr).group(1)
    summary = json.loads((out / "summary.json").read_text())
    return {"method": method, "h_far": h_far, "h_contact": h_contact, "dofs": summary["model"]["dofs"],
            "degree": summary["model"].get("degree", 2), "peak_rss_bytes": rss_kb * 1024, "wall": wall}


#: the exponent of the DOFs in the peak-memory model (module docstring)
EXPONENT = 4.0 / 3.0


def fit(rows: list[dict]) -> tuple[float, float, float]:
    """Least-squares a + c dofs^EXPONENT; returns (a bytes, c bytes, largest relative error)."""
    x = np.array([r["dofs"] for r in rows], float) ** EXPONENT
    y = np.array([r["peak_rss_bytes"] for r in rows], float)
    c, a = np.polyfit(x, y, 1)
    return float(a), float(c), float(np.max(np.abs((a + c * x) / y - 1.0)))


def main() -> None:
    OUT.mkdir(parents=True, exist_ok=True)
    path = OUT / "memory_fit.json"
    data = json.loads(path.read_text()) if path.exists() else {"rows": []}
    for method in sys.argv[1:] or list(CASES):
        for h_far, h_c in CASES[method]:
            row = run_case(method, h_far, h_c)
            data["rows"] = [r for r in data["rows"] if (r["method"], r["h_far"]) != (method, h_far)] + [row]
            path.write_text(json.dumps(data, indent=1))
            print(json.dumps(row), flush=True)
    data["fits"] = {}
    for method in sorted({r["method"] for r in data["rows"]}):
        rows = [r for r in data["rows"] if r["method"] == method]
        if len(rows) >= 2:
            a, c, err = fit(rows)
            data["fits"][method] = {"base_bytes": a, "coefficient": c, "exponent": EXPONENT, "max_rel_error": err,
                                    "n": len(rows)}
    path.write_text(json.dumps(data, indent=1))
    print("| method | h_far (mm) | h_contact (mm) | DOFs | peak RSS (MB) | wall |\n|---|---|---|---|---|---|")
    for r in sorted(data["rows"], key=lambda r: (r["method"], r["dofs"])):
        print(f"| {r['method']} | {r['h_far'] * 1e3:g} | {r['h_contact'] * 1e3:g} | {r['dofs']} | "
              f"{r['peak_rss_bytes'] / 1e6:.0f} | {r['wall']} |")
    for m, f in data["fits"].items():
        print(f"{m}: peak = {f['base_bytes'] / 1e6:.0f} MB + {f['coefficient']:.4g} B x DOFs^(4/3), "
              f"largest error {100 * f['max_rel_error']:.1f} % ({f['n']} runs)")


if __name__ == "__main__":
    main()
