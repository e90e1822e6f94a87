"""Benchmark: the reduced methods against the full FE model, side by side in one run.

Part A (``--part a``): the default scene ``paper-rig`` over ``--t-end`` (default 40 ms), on one
mesh (the reduced methods' default contact zone, 2.5 a_max; ``model.zone_radius`` set to it for the
full runs, so gmsh meshes the same model: same cache key): ``improved``, ``traditional``, ``full``
P1 and ``full`` P2, each timed in this process (wall and CPU). Each reduced method is compared with
the full model it reduces: improved (an NMM zone in a P2 mesh) with full P2 (its Galerkin parent:
the same answer is the target), traditional with full P1; improved against full P1 is listed too
(P1 is cheaper but 2-3 % stiffer). ``--p2 first-contact`` runs full P2 over the first contact only
(its 40 ms take ~20 min on 2 cores).

Part B (``--part b``): error against DOFs of ``traditional`` / ``improved`` / ``modal-p2`` at
``--resolutions`` (h_contact = a_max / n), the first contact only (gap / v + 1.6 t_c). The
reference is ``full`` P2 at the finest resolution on its own mesh (P2 at a_max/4 is within ~0.1 %
of Hertz on the half-space scene: README, "Measured"); each method's error is |F_max / F_ref - 1|
and |t_c / t_ref - 1| against the reduced coordinates it integrates.

Writes ``benchmarks/out/reduced_vs_full.json`` (+ ``.md`` table) and ``reduced_vs_full.png``.

    .venv/bin/python benchmarks/reduced_vs_full.py                    # A and B (~30-60 min, 2 cores)
    .venv/bin/python benchmarks/reduced_vs_full.py --part a --p2 first-contact
    .venv/bin/python benchmarks/reduced_vs_full.py --part b --resolutions 2,3,4
"""
from __future__ import annotations

import argparse
import json
import platform
import time
from pathlib import Path

import millimpact  # noqa: F401  (before numpy: it chooses OpenBLAS's kernels, millimpact/__init__.py)
import numpy as np
from mpi4py import MPI

from millimpact.scene.plan import make_plan
from millimpact.methods.reduced import REDUCED_ZONE_FACTOR
from millimpact.results.timeseries import contact_metrics
from millimpact.methods.run import compute
from millimpact.scene.builtin import builtin_scene

HERE = Path(__file__).resolve().parent
GAUGE_WINDOW = 1e-3   # s shown of the gauge signal (40 ms of ringing is a solid band)


def _run(scene, method: str, options: dict, label: str, comm) -> dict:
    """One run, timed (wall and this process's CPU); its contact metrics, gauge peaks, sizes and
    the time series needed for the figure."""
    comm.Barrier()
    t0, c0 = time.perf_counter(), time.process_time()
    out, plan = compute(scene, method, dict(options), progress=False)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    m = contact_metrics(out.series)
    ts = out.series
    row = {
        "label": label, "method": method, "options": options, "wall_s": wall, "cpu_s": cpu,
        "F_max_N": m["peak_contact_force_N"], "t_c_s": m["contact_duration_s"],
        "gauge_peaks_Pa": out.results.get("peak_gauge_stress_Pa"),
        "restitution": out.results.get("restitution"),
        "energy_drift_max_rel": out.results.get("energy_drift_max_rel"),
        "dofs": out.model.get("dofs"), "reduced_dofs": out.model.get("reduced_dofs", out.model.get("dofs")),
        "timings_s": out.results.get("timings_s"), "notes": out.notes,
        "F_hertz_N": plan.hertz.force_max, "t_c_hertz_s": plan.hertz.contact_time,
    }
    row["series"] = {k: np.asarray(ts[k]).tolist() for k in ("time_s", "contact_force_N")}
    g = [k for k in ts.columns if k.startswith("gauge_")]
    if g:
        row["series"]["gauge"] = np.asarray(ts[g[0]]).tolist()
        row["series"]["gauge_name"] = g[0]
    if comm.rank == 0:
        print(f"[{label}] {method}: wall {wall:.1f} s (cpu {cpu:.1f} s), F_max {row['F_max_N'] / 1e3:.4f} kN, "
              f"t_c {row['t_c_s'] * 1e6:.3f} us, dofs {row['dofs']} -> {row['reduced_dofs']}", flush=True)
    return row


#: part A's runs: key -> (method, options, label); each reduced method's like-for-like full model
#: is the one it reduces (improved and modal-p2: P2; traditional: P1) on the same mesh
A_RUNS = {"improved": ("improved", {}, "improved"), "traditional": ("traditional", {}, "traditional"),
          "full_p1": ("full", {"degree": 1}, "full P1"), "full_p2": ("full", {"degree": 2}, "full P2")}
#: (reduced run, full run) pairs whose wall/CPU ratio and F_max / t_c differences part A reports
A_PAIRS = (("improved", "full_p2"), ("improved", "full_p1"), ("traditional", "full_p1"))


def part_a(t_end: float, p2: str, comm) -> dict:
    """``p2``: "full" (full P2 over t_end: the like-for-like run of improved; ~20 min on 2
    cores), "first-contact" (full P2 over the first contact only: accuracy, no ratio) or "none"."""
    base = builtin_scene("paper-rig")
    zone = REDUCED_ZONE_FACTOR * make_plan(base).hertz.a_max
    scene = base.with_value("model.zone_radius", zone).with_value("time.end", t_end)
    res = {"t_end_s": t_end, "zone_radius_m": zone, "runs": {}, "pairs": []}
    for key, (method, options, label) in A_RUNS.items():
        if key == "full_p2" and p2 == "none":
            continue
        sc = scene
        if key == "full_p2" and p2 == "first-contact":
            plan = make_plan(scene)
            sc = scene.with_value("time.end", plan.gap / scene.impact.speed + 1.6 * plan.hertz.contact_time)
            label += " (first contact)"
        res["runs"][key] = _run(sc, method, options, label, comm)
        res["runs"][key]["t_end_s"] = sc.time.end
    for red, full in A_PAIRS:
        R, F = res["runs"].get(red), res["runs"].get(full)
        if R is None or F is None:
            continue
        same_span = abs(R["t_end_s"] - F["t_end_s"]) < 1e-12
        res["pairs"].append({
            "reduced": red, "full": full,
            "ratio_wall": F["wall_s"] / R["wall_s"] if same_span else None,
            "ratio_cpu": F["cpu_s"] / R["cpu_s"] if same_span else None,
            "dF_max": R["F_max_N"] / F["F_max_N"] - 1, "dt_c": R["t_c_s"] / F["t_c_s"] - 1})
    return res


def part_b(resolutions: list[float], comm, extra_traditional: tuple[float, ...] = ()) -> dict:
    base = builtin_scene("paper-rig")
    a = make_plan(base).hertz.a_max
    zone = REDUCED_ZONE_FACTOR * a
    rows = []
    ref = None
    # finest first: the reference; then traditional alone on finer meshes (P1 zones are small, so
    # its DOF range reaches the P2-based methods' only there)
    cases = [(n, ("traditional", "improved", "modal-p2")) for n in sorted(resolutions, reverse=True)]
    cases += [(n, ("traditional",)) for n in extra_traditional]
    for n, methods in cases:
        scene = base.with_value("model.zone_radius", zone).with_value("model.h_contact", a / n)
        plan = make_plan(scene)
        scene = scene.with_value("time.end", plan.gap / scene.impact.speed + 1.6 * plan.hertz.contact_time)
        if ref is None:
            ref = _run(scene, "full", {"degree": 2}, f"B a_max/{n:g} reference", comm)
        for method in methods:
            r = _run(scene, method, {}, f"B a_max/{n:g}", comm)
            r["n"] = n
            r["err_F_max"] = abs(r["F_max_N"] / ref["F_max_N"] - 1)
            r["err_t_c"] = abs(r["t_c_s"] / ref["t_c_s"] - 1)
            rows.append(r)
    return {"reference": ref, "rows": rows, "zone_radius_m": zone}


def write(res: dict, out: Path, comm) -> None:
    if comm.rank != 0:
        return
    from millimpact.results.plots import pyplot
    plt = pyplot()

    out.mkdir(parents=True, exist_ok=True)
    lines = [f"machine: {platform.node()}, {comm.size} rank(s); wall times are noisy on a shared machine "
             "(cpu = this process's CPU time)", ""]
    panels = []
    if "a" in res:
        A = res["a"]
        lines += [f"## A: paper-rig, {A['t_end_s'] * 1e3:g} ms, same mesh (zone radius {A['zone_radius_m'] * 1e3:.4g} mm)", "",
                  "| run | simulated ms | dofs | integrated | wall s | cpu s | F_max kN | t_c us | gauge peaks MPa (A, B, C) |",
                  "|---|---|---|---|---|---|---|---|---|"]
        for key, r in A["runs"].items():
            gp = ", ".join(f"{v / 1e6:.2f}" for v in (r["gauge_peaks_Pa"] or {}).values())
            lines.append(f"| {r['label']} | {r['t_end_s'] * 1e3:.4g} | {r['dofs']} | {r['reduced_dofs']} | {r['wall_s']:.1f} | "
                         f"{r['cpu_s']:.1f} | {r['F_max_N'] / 1e3:.4f} | {r['t_c_s'] * 1e6:.3f} | {gp} |")
        lines += ["", "| reduced | full (same mesh) | wall ratio | cpu ratio | F_max diff | t_c diff |",
                  "|---|---|---|---|---|---|"]
        for pr in A["pairs"]:
            ratio = lambda x: "-" if x is None else f"{x:.1f}"     # noqa: E731
            lines.append(f"| {pr['reduced']} | {A['runs'][pr['full']]['label']} | {ratio(pr['ratio_wall'])} | "
                         f"{ratio(pr['ratio_cpu'])} | {100 * pr['dF_max']:+.2f} % | {100 * pr['dt_c']:+.2f} % |")
        lines.append("")
        panels += ["force", "gauge"]
    if "b" in res:
        B = res["b"]
        ref = B["reference"]
        lines += [f"## B: error against DOFs (first contact); reference full P2 at the finest mesh: "
                  f"F_max {ref['F_max_N'] / 1e3:.4f} kN, t_c {ref['t_c_s'] * 1e6:.3f} us, {ref['dofs']} dofs", "",
                  "| h_c | method | model dofs | reduced coords | F_max err % | t_c err % | wall s |", "|---|---|---|---|---|---|---|"]
        for r in B["rows"]:
            lines.append(f"| a_max/{r['n']:g} | {r['method']} | {r['dofs']} | {r['reduced_dofs']} | "
                         f"{100 * r['err_F_max']:.3f} | {100 * r['err_t_c']:.3f} | {r['wall_s']:.1f} |")
        lines.append("")
        panels += ["err"]
    (out / "reduced_vs_full.md").write_text("\n".join(lines) + "\n")
    slim = json.loads(json.dumps(res, default=float))
    (out / "reduced_vs_full.json").write_text(json.dumps(slim, indent=1))
    print("\n".join(lines))

    fig, axes = plt.subplots(1, len(panels), figsize=(5.2 * len(panels), 4.2), squeeze=False)
    for ax, kind in zip(axes[0], panels):
        if kind == "force":
            A = res["a"]
            for key, style in (("full_p1", "-"), ("full_p2", "-"), ("improved", "--"), ("traditional", ":")):
                if key in A["runs"]:
                    r = A["runs"][key]
                    t = np.asarray(r["series"]["time_s"])
                    sel = t < 1.3 * r["t_c_hertz_s"]
                    ax.plot(t[sel] * 1e6, np.asarray(r["series"]["contact_force_N"])[sel] / 1e3, style,
                            label=f"{r['label']} ({r['reduced_dofs']} coords, {r['wall_s']:.0f} s)")
            ax.set_xlabel("time (us)")
            ax.set_ylabel("contact force (kN)")
            ax.set_title("paper-rig: contact force")
        elif kind == "gauge":
            A = res["a"]
            for key, style in (("full_p2", "-"), ("improved", "--")):
                s = A["runs"].get(key, {}).get("series", {})
                if "gauge" in s:
                    t = np.asarray(s["time_s"])
                    sel = t <= GAUGE_WINDOW
                    ax.plot(t[sel] * 1e3, np.asarray(s["gauge"])[sel] / 1e6, style, lw=0.9,
                            label=f"{A['runs'][key]['label']}: {s['gauge_name'].replace('_stress_Pa', '')}")
            ax.set_xlabel("time (ms)")
            ax.set_ylabel("gauge stress (MPa)")
            ax.set_title(f"gauge, first {GAUGE_WINDOW * 1e3:g} ms of {A['t_end_s'] * 1e3:g} ms")
        else:
            B = res["b"]
            for method, mk in (("traditional", "o-"), ("improved", "s-"), ("modal-p2", "^-")):
                rr = sorted((r for r in B["rows"] if r["method"] == method), key=lambda r: r["reduced_dofs"])
                ax.loglog([r["reduced_dofs"] for r in rr], [max(100 * r["err_F_max"], 1e-3) for r in rr], mk,
                          label=f"{method}: F_max")
                ax.loglog([r["reduced_dofs"] for r in rr], [max(100 * r["err_t_c"], 1e-3) for r in rr], mk,
                          alpha=0.4, label=f"{method}: t_c")
            ax.set_xlabel("reduced coordinates (time loop size)")
            ax.set_ylabel("error vs full P2 reference (%)")
            ax.set_title("error per DOF (first contact)")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(out / "reduced_vs_full.png", dpi=130)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--part", choices=["a", "b", "ab"], default="ab")
    p.add_argument("--t-end", type=float, default=0.04, help="simulated time of part A, s")
    p.add_argument("--p2", choices=["full", "first-contact", "none"], default="full",
                   help="part A: full P2 over --t-end (the like-for-like run of improved, ~20 min), over "
                        "the first contact only, or not at all")
    p.add_argument("--resolutions", default="2,3,4", help="part B: n of h_contact = a_max / n")
    p.add_argument("--extra-traditional", default="6,8", help="part B: finer n for traditional alone")
    p.add_argument("--out", default=str(HERE / "out"))
    p.add_argument("--from-json", nargs="+", metavar="JSON",
                   help="no runs: merge the parts of earlier reduced_vs_full.json files and rewrite table and figure")
    args = p.parse_args()
    comm = MPI.COMM_WORLD
    res = {}
    if args.from_json:
        for f in args.from_json:
            res.update(json.loads(Path(f).read_text()))
        write(res, Path(args.out), comm)
        return
    if "a" in args.part:
        res["a"] = part_a(args.t_end, args.p2, comm)
    if "b" in args.part:
        extra = tuple(float(x) for x in args.extra_traditional.split(",") if x)
        res["b"] = part_b([float(x) for x in args.resolutions.split(",")], comm, extra)
    write(res, Path(args.out), comm)


if __name__ == "__main__":
    main()
