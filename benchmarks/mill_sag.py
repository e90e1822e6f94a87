"""A SAG charge in ``liner-panel``'s 11 m mill against Morrell's and Austin's models, its spectrum
against a balls-only charge of the same ball fill, and its cost at 1 and 2 Yade threads.

Cases (each a ``millimpact mill`` command, one warm-up revolution and ``--revolutions`` logged):

- ``sag-J{J}-S{S}``: ``--charge sag --fill J --speed-fraction S`` (balls 0.12, rock 0.2-0.1 m) at
  S 0.75 and 0.80 and J 0.28 and 0.35: the shell's power within 15 % of Morrell's and of Austin's
  models put at the shell (Morrell's k P_C, the motor's draw above the empty mill's; Austin's
  pinion figure less Morrell's no-load P_0: millimpact.dem.mill.power), toe and shoulder within
  10 degrees of Morrell's correlations;
- ``sag-J28-S0.75-slurry``: one change, the bed's voids full of a 1790 kg/m^3 slurry carried as
  mass (``--slurry-density``): Austin's constants assume a wet charge;
- ``balls-J12-S0.75``: balls alone at the SAG charge's ball fill (``--fill 0.12``): the balls'
  cumulative impact spectrum on the liner beside the SAG charge's (spectra.png), and the share
  of the balls' contacts that land on rock;
- ``threads``: a short SAG run (0.1 revolution after 0.1 of warm-up, from the same start) at
  ``MILLIMPACT_YADE_THREADS`` 1 and 2, one after the other.

    .venv/bin/python benchmarks/mill_sag.py [--jobs 2] [--revolutions 1] [--only sag-J28-S0.75 ...]

A case whose folder holds a summary.json is not run again; the tables are rewritten after each
case (mill_sag.csv / .md, threads.csv / .md), so an interrupted run keeps what it finished.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _report import write_report  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
SAG_CASES = [(j, s) for j in (0.28, 0.35) for s in (0.75, 0.80)]
#: a SAG mill's discharge slurry, 70 % solids by mass (ore 2700 kg/m^3): 1 / (0.7 / 2700 + 0.3 / 1000)
SLURRY_DENSITY = 1790.0


def _command(args: list[str], folder: Path, threads: int = 1) -> float:
    cmd = [sys.executable, "-m", "millimpact.cli", "mill", "liner-panel", *args, "--force", "--out", str(folder)]
    env = {**os.environ, "MILLIMPACT_YADE_THREADS": str(threads)}
    t0 = time.perf_counter()
    with open(folder.parent / f"{folder.name}.log", "w") as log:
        subprocess.run(cmd, cwd=ROOT, env=env, check=True, stdout=log, stderr=subprocess.STDOUT)
    return time.perf_counter() - t0


def cases(revolutions: float) -> dict[str, list[str]]:
    rev = ["--revolutions", str(revolutions), "--warmup", "1"]
    out = {
        f"sag-J{round(100 * j)}-S{s:.2f}": ["--charge", "sag", "--fill", str(j), "--speed-fraction", str(s), *rev]
        for j, s in SAG_CASES
    }
    out["balls-J12-S0.75"] = ["--fill", "0.12", "--speed-fraction", "0.75", *rev]
    # one change: the voids' slurry carried as mass (70 % solids of 2700 kg/m^3: 1790 kg/m^3)
    out["sag-J28-S0.75-slurry"] = [*out["sag-J28-S0.75"], "--slurry-density", str(SLURRY_DENSITY)]
    return out


def row_of(name: str, folder: Path) -> dict:
    s = json.loads((folder / "summary.json").read_text())
    p, c = s["power"], s["charge_shape"]
    m = p["model_inputs"]
    shell = _shell_figures(p)
    return {
        "case": name,
        "fill": m["fill"],
        "ball_fill": m["ball_fill"],
        "speed_fraction": m["speed_fraction"],
        "balls": s["charge"]["balls"],
        "rocks": s["charge"].get("rocks", 0),
        "net_kW_m": p["measured"]["net_per_metre_W_m"] / 1e3,
        "morrell_kW_m": p["morrell_net_per_metre_W_m"] / 1e3,
        "morrell_diff": p["morrell_relative_difference"],
        "austin_kW_m": p["austin_per_metre_W_m"] / 1e3,
        "austin_diff": p["austin_relative_difference"],
        **shell,
        "slurry_kg_m3": m.get("slurry_density_kg_m3", 0.0),
        "toe_deg": c["toe_deg"],
        "morrell_toe_deg": c["morrell_toe_deg"],
        "shoulder_deg": c["shoulder_deg"],
        "morrell_shoulder_deg": c["morrell_shoulder_deg"],
        "ball_impacts_per_rev": s["impacts_per_revolution"]["all"],
        "ball_energy_J_per_rev": s["energy_per_revolution_J"]["all"],
        "rock_impacts_per_rev": s.get("rock_impacts", {}).get("impacts_per_revolution", {}).get("all", 0.0),
        "ball_contacts_on_rock_share": s["charge"].get("ball_contacts_on_rock_share"),
        "energy_balance_error": s["energy_balance"]["relative_error"],
        "liner_friction_J_per_rev": s["abrasion"]["friction_work_J_per_revolution"],
        "yade_wall_s": s["yade"]["wall_s"],
        "steps": s["yade"]["steps"],
    }


def _shell_figures(p: dict) -> dict:
    """Morrell's k P_C and Austin's pinion power less the empty mill's P_0 (kW/m), and the run's
    differences to them: summary.json's, or computed as millimpact.dem.mill.power does for a
    summary written before it gave them."""
    if "morrell_shell_per_metre_W_m" not in p:
        from millimpact.dem.mill.power import shell_power

        d, phi = p["model_inputs"]["diameter_m"], p["model_inputs"]["speed_fraction"]
        morrell, austin, _ = shell_power(d, phi, p["morrell_net_per_metre_W_m"], p["austin_per_metre_W_m"], 0.5 * d)
        p = {**p, "morrell_shell_per_metre_W_m": morrell, "austin_shell_per_metre_W_m": austin}
        x = p["measured"]["net_per_metre_W_m"]
        p["morrell_shell_relative_difference"] = x / p["morrell_shell_per_metre_W_m"] - 1.0
        p["austin_shell_relative_difference"] = x / p["austin_shell_per_metre_W_m"] - 1.0
    return {
        "morrell_shell_kW_m": p["morrell_shell_per_metre_W_m"] / 1e3,
        "morrell_shell_diff": p["morrell_shell_relative_difference"],
        "austin_shell_kW_m": p["austin_shell_per_metre_W_m"] / 1e3,
        "austin_shell_diff": p["austin_shell_relative_difference"],
    }


def _pct(x) -> str:
    return "n/a" if x is None else f"{100 * x:+.0f} %"


def _deg(x) -> str:
    return "n/a" if x is None else f"{x:.0f}"


def report(out: Path, rows: list[dict]) -> None:
    write_report(
        out,
        "mill_sag",
        rows,
        1,
        [
            "case",
            "J",
            "J_B",
            "speed",
            "balls + rocks",
            "slurry (kg/m^3)",
            "net (kW/m)",
            "Morrell k P_C (kW/m)",
            "Austin - P_0 (kW/m)",
            "Morrell P_C (kW/m)",
            "Austin, pinion (kW/m)",
            "toe, Morrell (deg)",
            "shoulder, Morrell (deg)",
            "ball impacts/rev",
            "balance",
            "Yade wall (s)",
        ],
        lambda r: [
            r["case"],
            f"{r['fill']:.3f}",
            f"{r['ball_fill']:.3f}",
            f"{r['speed_fraction']:.2f}",
            f"{r['balls']} + {r['rocks']}",
            f"{r['slurry_kg_m3']:.0f}",
            f"{r['net_kW_m']:.1f}",
            f"{r['morrell_shell_kW_m']:.1f} ({_pct(r['morrell_shell_diff'])})",
            f"{r['austin_shell_kW_m']:.1f} ({_pct(r['austin_shell_diff'])})",
            f"{r['morrell_kW_m']:.1f} ({_pct(r['morrell_diff'])})",
            f"{r['austin_kW_m']:.1f} ({_pct(r['austin_diff'])})",
            f"{_deg(r['toe_deg'])}, {_deg(r['morrell_toe_deg'])}",
            f"{_deg(r['shoulder_deg'])}, {_deg(r['morrell_shoulder_deg'])}",
            f"{r['ball_impacts_per_rev']:.0f}",
            _pct(r["energy_balance_error"]),
            f"{r['yade_wall_s']:.0f}",
        ],
        note=f"; load average when written {os.getloadavg()[0]:.1f}",
    )


def spectra_figure(out: Path) -> None:
    """spectra.png: the balls' cumulative impact spectrum on the liner, SAG against balls alone."""
    import numpy as np

    from millimpact.results.plots import pyplot

    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6.4, 4.6))
    for name, style in (("balls-J12-S0.75", "k-"), ("sag-J28-S0.75", "C0-"), ("sag-J28-S0.80", "C1--")):
        folder = out / name
        if not (folder / "summary.json").exists():
            continue
        s = json.loads((folder / "summary.json").read_text())
        rev = s["clock"]["revolutions"]
        with open(folder / "impacts.csv") as fh:
            head = fh.readline().strip().split(",")
            rows = [line.strip().split(",") for line in fh]
        k_e, k_kind = head.index("impact_energy_J"), head.index("kind")
        for kind, alpha in (("ball", 1.0), ("rock", 0.5)):
            e = np.sort([float(r[k_e]) for r in rows if r[k_kind] == kind])[::-1]
            if e.size and e[0] > 0:
                label = f"{name}: {kind} impacts"
                ax.loglog(np.arange(1, e.size + 1) / rev, e, style, alpha=alpha, label=label)
    ax.set_xlabel("cumulative number of impacts on the liner per revolution (-)")
    ax.set_ylabel("impact energy (J)")
    ax.set_title("liner-panel's mill: a SAG charge against balls alone at J_B 0.12", fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out / "spectra.png", dpi=120)
    plt.close(fig)


def checks_figure(out: Path, rows: list[dict]) -> None:
    """checks.png: each run's power against the two models put at the shell (left, a parity plot
    with the +-15 % band), and its toe and shoulder against Morrell's correlations (right, +-10 deg)."""
    from millimpact.results.plots import pyplot

    plt = pyplot()
    fig, (ax, bx) = plt.subplots(1, 2, figsize=(10.5, 4.6))
    top = 1.15 * max(max(r["net_kW_m"], r["morrell_shell_kW_m"], r["austin_shell_kW_m"]) for r in rows)
    ax.fill_between([0, top], [0, 0.85 * top], [0, 1.15 * top], color="0.9", label="+-15 %")
    ax.plot([0, top], [0, top], "k-", lw=0.8)
    for k, r in enumerate(rows):
        c = f"C{k}"
        ax.plot(r["morrell_shell_kW_m"], r["net_kW_m"], "o", color=c, label=f"{r['case']}: Morrell k P_C")
        ax.plot(r["austin_shell_kW_m"], r["net_kW_m"], "s", mfc="none", color=c, label="  Austin - P_0")
        for name, marker in (("toe", "v"), ("shoulder", "^")):
            bx.plot(r[f"morrell_{name}_deg"], r[f"{name}_deg"], marker, color=c, label=f"{r['case']}: {name}")
    ax.set(xlim=(0, top), ylim=(0, top), xlabel="model, at the shell (kW/m)", ylabel="the run's net power (kW/m)")
    ax.set_title("power draw: the run against the models", fontsize=9)
    ax.legend(fontsize=6)
    lo, hi = -60.0, 160.0
    bx.fill_between([lo, hi], [lo - 10, hi - 10], [lo + 10, hi + 10], color="0.9", label="+-10 deg")
    bx.plot([lo, hi], [lo, hi], "k-", lw=0.8)
    bx.set(xlim=(lo, hi), ylim=(lo, hi), xlabel="Morrell's correlation (deg from the bottom)", ylabel="the run (deg)")
    bx.set_title("charge shape: toe and shoulder", fontsize=9)
    bx.legend(fontsize=6)
    fig.tight_layout()
    fig.savefig(out / "checks.png", dpi=120)
    plt.close(fig)


def threads_check(out: Path) -> None:
    rows = []
    for threads in (1, 2):
        folder = out / f"threads-j{threads}"
        args = ["--charge", "sag", "--revolutions", "0.1", "--warmup", "0.1", "--no-plots", "--threads", str(threads)]
        wall = _command(args, folder, threads)
        y = json.loads((folder / "summary.json").read_text())["yade"]
        rows.append(
            {
                "threads": threads,
                "steps": y["steps"],
                "wall_s": wall,
                "yade_wall_s": y["wall_s"],
                "yade_cpu_s": y["cpu_s"],
                "load_1min": os.getloadavg()[0],
            }
        )
    rows.append(
        {
            **rows[0],
            "threads": "1/2",
            "wall_s": rows[0]["wall_s"] / rows[1]["wall_s"],
            "yade_wall_s": rows[0]["yade_wall_s"] / rows[1]["yade_wall_s"],
            "yade_cpu_s": rows[0]["yade_cpu_s"] / rows[1]["yade_cpu_s"],
        }
    )
    write_report(
        out,
        "threads",
        rows,
        1,
        ["Yade threads", "steps", "wall (s)", "Yade wall (s)", "Yade CPU (s)"],
        lambda r: [
            str(r["threads"]),
            str(r["steps"]),
            f"{r['wall_s']:.3g}",
            f"{r['yade_wall_s']:.3g}",
            f"{r['yade_cpu_s']:.3g}",
        ],
        note="; the last row is the ratio 1 thread / 2 threads",
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--revolutions", type=float, default=1.0)
    ap.add_argument("--jobs", type=int, default=2, help="cases run at once, one Yade thread each (default 2)")
    ap.add_argument("--only", nargs="+", help="these cases only (names as in the module docstring)")
    ap.add_argument("--no-threads", action="store_true", help="skip the 1 vs 2 threads check")
    ap.add_argument("--report-only", action="store_true", help="run nothing: tabulate the finished cases")
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "out" / "mill_sag"))
    a = ap.parse_args()
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    todo = {k: v for k, v in cases(a.revolutions).items() if not a.only or k in a.only}

    if a.report_only:
        done = [k for k in todo if (out / k / "summary.json").exists()]
        rows = [row_of(k, out / k) for k in done]
        report(out, rows)
        spectra_figure(out)
        checks_figure(out, rows)
        return

    def run(item):
        name, args = item
        if not (out / name / "summary.json").exists():
            _command(args, out / name)
        return name

    rows = []
    with ThreadPoolExecutor(max_workers=a.jobs) as pool:
        for name in pool.map(run, todo.items()):
            rows.append(row_of(name, out / name))
            report(out, rows)
    spectra_figure(out)
    checks_figure(out, rows)
    if not a.no_threads:
        threads_check(out)


if __name__ == "__main__":
    main()
