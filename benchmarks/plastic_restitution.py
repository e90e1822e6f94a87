"""Restitution of an elastic-perfectly-plastic steel sphere on a very stiff flat against V / V_y,
to V / V_y = 1000, each point at two meshes (h and h / 1.5), with Thornton's 1997 analytical
curve (theory/thornton.py), the fitted slope of log e against log(V / V_y) and the small-strain
check.

Configuration (Thornton 1997; Wu, Li & Thornton 2005): the ball (r 15 mm, steel, Y = 1 GPa,
perfectly plastic) strikes the hertz-halfspace block made 10x stiffer (G x 10: nearly rigid);
full FE, P1, quarter model.

Mesh: h = a_c / HC (HC = 3 by default), a_c the larger of the Hertz contact radius a_max and the
plastic one, Thornton's a_p = (R delta_max)^(1/2) (theory/thornton.py; above ~30 V_y the plastic
contact is the larger, 1.7x Hertz's at 1000 V_y). Johnson's fully plastic estimate (mean pressure
p_m = 3 Y over a^2 = 2 R delta, the work p_m x the dent volume pi a^4 / (4 R) = m V^2 / 2: Johnson,
Contact Mechanics, 1985, section 11.4, after Tabor; theory/thornton.py) gives a_fp, within 2 %
of a_p here: printed beside it. The plan's zone holds 1.75 Johnson cavity radii up to its cap
(0.45 R: scene/plan.py), and the size is h over the whole zone (model.fine_radius = the zone
radius), so the plastic region, 2-3x wider than the contact, is meshed at h as well. HC = 2 (two
elements across the contact radius) is too coarse: at 183 V_y e = 0.5225 at a_c / 2, 0.4945 at
a_c / 3 and 0.4959 at a_c / 4.5 (the plan's fine radius 1.5 Hertz a_max instead, `--plan-fine`:
0.5285 and 0.4969 at a_c / 2 and a_c / 3).

Time: the plastic contact lasts longer than Hertz's: the run covers the flight (gap / V) and 2.5
x max(t_Hertz, t_load + t_Hertz / 2), t_load = (pi / 2) (m / (pi p_y R))^(1/2) the quarter period of
Thornton's linear loading law (an upper bound of the loading time); a run whose contact force is
not zero at its end is flagged (`contact_ended`).

Writes benchmarks/out/plastic_restitution/{restitution.csv, restitution.md, restitution.png};
each case's folder keeps its run and is reused when its settings are unchanged (``--rerun``
forces the runs):

    nice -n 5 .venv/bin/python benchmarks/plastic_restitution.py [--ratios 1.5,3,10,30,100,183,300,1000]
        [--refine 1,1.5] [--third 3,30,100,183,1000] [--hc 3] [--fit-from 30] [--method full|improved]
        [--out DIR]
"""
from __future__ import annotations

import argparse
import csv
import json
import math
import subprocess
import sys
import time
from pathlib import Path

import millimpact  # noqa: F401  (before numpy: it chooses OpenBLAS's kernels, millimpact/__init__.py)
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from millimpact.scene.builtin import builtin_scene  # noqa: E402
from millimpact.scene.plan import make_plan  # noqa: E402
from millimpact.scene.plan import SIZE_GROWTH_ZONE_RADII  # noqa: E402
from millimpact.theory.hertz import effective_modulus  # noqa: E402
from millimpact.theory.thornton import (FIRST_YIELD_PRESSURE_FACTOR, FULLY_PLASTIC_PRESSURE_FACTOR,  # noqa: E402
                                        fully_plastic_contact_radius, plastic_zone_radius,
                                        restitution_thornton, yield_onset_velocity)

Y = 1e9
STIFF = 10.0
#: e converged: the two meshes' restitutions within this (the bound of the validation)
CONVERGED = 0.01
#: the small-strain J2 model's limit on the equivalent plastic strain (millimpact/results/dent.py)
SMALL_STRAIN = 0.1
#: Thornton's asymptote e -> 1.185 (V / V_y)^(-1/4) (eq. 26 as r = V_y / V -> 0:
#: (6 sqrt(3) / 5)^(1/2) / (2 (6/5)^(1/2))^(1/4) = 1.185)
THORNTON_ASYMPTOTE = (math.sqrt(6.0 * math.sqrt(3.0) / 5.0) / (2.0 * math.sqrt(1.2)) ** 0.25, -0.25)
#: the Wu, Li & Thornton (2005) high-speed law in the form it is often quoted, e = 0.62 (V/V_y)^(-1/2)
#: (Int. J. Impact Eng. 32, 593-604). NOT verified against the paper here (not reachable from this
#: machine): plotted as it is quoted, its slope compared with ours
WLT_LAW = (0.62, -0.5)


def loglog_slope(x, y) -> float:
    """Least-squares slope of log y against log x."""
    return float(np.polyfit(np.log(np.asarray(x, float)), np.log(np.asarray(y, float)), 1)[0])


def case_settings(stiff, ratio: float, vy: float, hc: float, refine: float, whole_zone: bool = True,
                  strain: str = "auto") -> tuple[dict, dict]:
    """The run's --set values and the sizes behind them (SI, mm in the info); ``whole_zone``: the
    size is h over the whole contact zone (model.fine_radius = zone radius), else the plan's 1.5 a_max;
    ``strain``: model.strain (auto: the plan's choice)."""
    v = ratio * vy
    scene = stiff.with_value("impact.velocity", [0.0, -v, 0.0]).with_value("ball.material.yield_stress", Y)
    plan = make_plan(scene)
    hz = plan.hertz
    a_p, c = plastic_zone_radius(hz.radius, hz.mass, v, hz.e_star, Y)
    a_c = max(hz.a_max, a_p)
    h = a_c / hc / refine
    p_y = FIRST_YIELD_PRESSURE_FACTOR * Y
    t_load = 0.5 * math.pi * math.sqrt(hz.mass / (math.pi * p_y * hz.radius))
    t_run = plan.gap / v + 2.5 * max(hz.contact_time, t_load + 0.5 * hz.contact_time)
    fine = plan.zone_radius if whole_zone else plan.fine_radius
    grow = (plan.h_far - h) / (SIZE_GROWTH_ZONE_RADII * plan.zone_radius)
    sets = {"impact.velocity": f"[0.0,{-v!r},0.0]", "block.material.shear_modulus": repr(stiff.block.material.shear_modulus),
            "ball.material.yield_stress": repr(Y), "model.h_contact": repr(h), "time.end": repr(t_run)}
    if whole_zone:
        sets["model.fine_radius"] = repr(fine)
    if strain != "auto":
        sets["model.strain"] = strain
    info = {"a_hertz_mm": hz.a_max * 1e3, "a_plastic_mm": a_p * 1e3,
            "a_fully_plastic_mm": fully_plastic_contact_radius(hz.radius, hz.mass, v, FULLY_PLASTIC_PRESSURE_FACTOR * Y) * 1e3,
            "cavity_radius_mm": c * 1e3, "zone_radius_mm": plan.zone_radius * 1e3, "fine_radius_mm": fine * 1e3,
            "h_contact_mm": h * 1e3, "h_at_a_p_mm": (h + max(0.0, a_p - fine) * max(grow, 0.0)) * 1e3,
            "t_hertz_us": hz.contact_time * 1e6, "t_load_us": t_load * 1e6, "time_end_us": t_run * 1e6}
    return sets, info


def run_case(case: Path, sets: dict, rerun: bool, method: str = "full") -> tuple[dict, float]:
    """Run (or reuse) one case; its summary and wall time (s, NaN when reused)."""
    stamp = case / "benchmark_settings.json"
    if not rerun and (case / "summary.json").exists() and stamp.exists() and json.loads(stamp.read_text()) == sets:
        s = json.loads((case / "summary.json").read_text())
        return s, float(json.loads(stamp.with_name("benchmark_wall.json").read_text())["wall_s"])
    cmd = [sys.executable, "-m", "millimpact.cli", "run", "hertz-halfspace", "--method", method, "-q",
           "--out", str(case), "--force"] + [x for k, val in sets.items() for x in ("--set", f"{k}={val}")]
    t0 = time.perf_counter()
    r = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if r.returncode != 0:
        raise RuntimeError((r.stderr.strip().splitlines() or ["no message"])[-1])
    stamp.write_text(json.dumps(sets))
    stamp.with_name("benchmark_wall.json").write_text(json.dumps({"wall_s": wall}))
    return json.loads((case / "summary.json").read_text()), wall


def contact_ended(case: Path) -> bool:
    """Whether the contact force is zero over the run's last rows (the ball has left)."""
    path = case / "timeseries.csv"
    if not path.exists():
        return True
    with open(path) as fh:
        rows = list(csv.DictReader(fh))
    return all(float(r["contact_force_N"]) <= 0.0 for r in rows[-3:])


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--ratios", default="1.5,3,10,30,100,183,300,1000")
    ap.add_argument("--refine", default="1,1.5", help="mesh refinements: h_contact = a_c / (HC x each)")
    ap.add_argument("--hc", type=float, default=3.0, help="h_contact = a_c / HC, a_c = max(Hertz a_max, Thornton a_p)")
    ap.add_argument("--third", default="", help="V/V_y values that also run at h/2.25 (comma-separated)")
    ap.add_argument("--fit-from", type=float, default=30.0, help="the slope is fitted over V/V_y >= this")
    ap.add_argument("--plan-fine", action="store_true",
                    help="keep the plan's fine radius (1.5 Hertz a_max) instead of meshing the whole zone at h")
    ap.add_argument("--method", default="full", choices=("full", "improved"),
                    help="full FE P1 (the default) or improved (P2, reduced: the cross-check of P1's contact)")
    ap.add_argument("--strain", default="auto", choices=("auto", "small", "finite"),
                    help="the plastic zone's kinematics (auto: the plan's choice, finite above 0.15 R contact radius)")
    ap.add_argument("--rerun", action="store_true", help="run every case even if its folder holds it")
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "out" / "plastic_restitution"))
    a = ap.parse_args()
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    base = builtin_scene("hertz-halfspace")
    stiff = base.with_value("block.material.shear_modulus", STIFF * base.block.material.shear_modulus)
    e_star = effective_modulus(stiff.ball.material, stiff.block.material)
    vy = yield_onset_velocity(Y, e_star, stiff.ball.material.density)
    ratios = [float(x) for x in a.ratios.split(",")]
    refines = [float(x) for x in a.refine.split(",")]
    rows = []
    t_all = time.perf_counter()
    third = [float(x) for x in a.third.split(",")] if a.third else []
    for ratio in ratios:
        for refine in refines + ([refines[-1] * 1.5] if ratio in third else []):
            sets, info = case_settings(stiff, ratio, vy, a.hc, refine, not a.plan_fine, a.strain)
            case = out / (f"v_over_vy_{ratio:g}_h_ac_over_{a.hc * refine:.4g}{'_planfine' if a.plan_fine else ''}"
                          f"{'' if a.method == 'full' else '_' + a.method}{'' if a.strain == 'auto' else '_' + a.strain}")
            try:
                s, wall = run_case(case, sets, a.rerun, a.method)
            except RuntimeError as err:
                print(f"V/V_y {ratio:g}, h/{refine:g}: failed: {err}", flush=True)
                continue
            pz = s.get("plastic_zone_radius_m", {})
            row = {"v_over_vy": ratio, "refine": refine, "speed_m_s": ratio * vy, **info, "dofs": s["model"]["dofs"],
                   "strain": s.get("strain", "small"), "plastic_whole": "+".join(s.get("plastic_whole", [])) or "-",
                   "restitution": s["restitution"], "restitution_thornton": restitution_thornton(ratio * vy, vy),
                   "plastic_share": s["plastic_dissipation_share"], "energy_drift": s["energy_drift_max_rel"],
                   "max_equivalent_plastic_strain": s["max_equivalent_plastic_strain"],
                   "max_residual_rotation_rad": s.get("max_residual_rotation_rad", float("nan")),
                   "plastic_radius_ball_mm": pz.get("ball", float("nan")) * 1e3,
                   "zone_boundary_elastic": bool(s.get("zone_boundary_elastic", True)),
                   "zone_boundary_plastic_strain": s.get("zone_boundary_max_equivalent_plastic_strain", 0.0),
                   "contact_ended": contact_ended(case), "wall_s": wall}
            rows.append(row)
            print(", ".join(f"{k} {v:.4g}" if isinstance(v, float) else f"{k} {v}" for k, v in row.items()), flush=True)
    if not rows:
        return 1
    with open(out / "restitution.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    table, _ = summarise(rows, refines, a.fit_from)
    (out / "restitution.md").write_text(table)
    print(table)
    plot(out, rows, sorted({r["refine"] for r in rows}), vy, a.hc,
         "full FE P1" if a.method == "full" else "improved (P2, reduced)")
    print(f"-> {out}/restitution.csv, restitution.md, restitution.png (V_y = {vy:.4g} m/s; "
          f"{time.perf_counter() - t_all:.0f} s in all)")
    return 0


def summarise(rows: list[dict], refines: list[float], fit_from: float) -> tuple[str, dict]:
    """The markdown tables (one line per V/V_y: e and its convergence; the validity checks) and
    the fitted slopes. The convergence column compares h with h/1.5; where a third mesh h/2.25
    was run (``--third``), the pair h/1.5, h/2.25 decides when the first does not."""
    by = {}
    for r in rows:
        by.setdefault(r["v_over_vy"], {})[r["refine"]] = r
    coarse, fine = refines[0], refines[1] if len(refines) > 1 else refines[0]
    third = fine * 1.5
    conv, valid, finest = {}, {}, {}
    e_lines = ["| V/V_y | V (m/s) | h (mm) | DOFs at h, h/1.5 | e at h | e at h/1.5 | abs diff | converged to 0.01 | "
               "e at h/2.25 (abs diff to h/1.5) | Thornton 1997 |", "|" + "---|" * 10]
    v_lines = ["| V/V_y | plastic work share | max eq. plastic strain | max residual rotation (rad) | "
               "plastic radius in the ball / zone (mm) | plastic strain at the zone boundary | contact ended | "
               "wall (s), each mesh |", "|" + "---|" * 8]
    for ratio in sorted(by):
        d = by[ratio]
        rc, rf, r3 = d.get(coarse), d.get(fine), d.get(third)
        ref = r3 or rf or rc
        finest[ratio] = ref
        diff = abs(rc["restitution"] - rf["restitution"]) if (rc and rf and coarse != fine) else float("nan")
        diff3 = abs(rf["restitution"] - r3["restitution"]) if (rf and r3) else float("nan")
        ok = diff <= CONVERGED if math.isfinite(diff) else None
        ok3 = diff3 <= CONVERGED if math.isfinite(diff3) else None
        conv[ratio] = bool(ok) or bool(ok3)
        valid[ratio] = all(x["zone_boundary_elastic"] and x["contact_ended"] for x in d.values())
        verdict = ("yes" if ok else ("no" if ok is not None else "-")) + (
            "" if ok or ok3 is None else (", yes at h/1.5 vs h/2.25" if ok3 else ", nor at h/1.5 vs h/2.25"))
        e = lambda x: f"{x['restitution']:.3f}" if x else "-"  # noqa: E731
        e_lines.append(
            f"| {ratio:g} | {ref['speed_m_s']:.3g} | {rc['h_contact_mm'] if rc else float('nan'):.3g} | "
            f"{rc['dofs'] if rc else '-'}, {rf['dofs'] if rf else '-'} | {e(rc)} | {e(rf)} | {diff:.3f} | {verdict} | "
            f"{e(r3) + f' ({diff3:.3f})' if r3 else '-'} | {ref['restitution_thornton']:.3f} |")
        walls = " + ".join(f"{d[k]['wall_s']:.0f}" for k in sorted(d))
        v_lines.append(
            f"| {ratio:g} | {100 * ref['plastic_share']:.1f} % | "
            f"{max(x['max_equivalent_plastic_strain'] for x in d.values()):.3g} | "
            f"{max(x['max_residual_rotation_rad'] for x in d.values()):.3g} | "
            f"{ref['plastic_radius_ball_mm']:.3g} / {ref['zone_radius_mm']:.3g} | "
            f"{max(x['zone_boundary_plastic_strain'] for x in d.values()):.2g} | "
            f"{'yes' if all(x['contact_ended'] for x in d.values()) else 'NO'} | {walls} |")
    fits = {}
    high = [k for k in sorted(by) if k >= fit_from]
    sets_ = {f"all points >= {fit_from:g} (finest mesh)": high,
             f"points >= {fit_from:g} whose zone boundary stayed elastic (finest mesh)": [k for k in high if valid[k]],
             f"points >= {fit_from:g} converged to 0.01 and valid (finest mesh)": [k for k in high if valid[k] and conv[k]]}
    for label, ks in sets_.items():
        if len(ks) >= 2:
            fits[label] = (loglog_slope(ks, [finest[k]["restitution"] for k in ks]), ks)
    for k0, k1 in zip(high, high[1:]):
        fits[f"local, {k0:g} to {k1:g} (finest mesh; Thornton 1997 there: "
             f"{loglog_slope([k0, k1], [finest[k0]['restitution_thornton'], finest[k1]['restitution_thornton']]):.3f})"] = (
            loglog_slope([k0, k1], [finest[k0]["restitution"], finest[k1]["restitution"]]), [k0, k1])
    if len(high) >= 2:
        fits["Thornton 1997 at the same V/V_y"] = (loglog_slope(high, [finest[k]["restitution_thornton"] for k in high]), high)
    text = "\n".join(e_lines) + "\n\n" + "\n".join(v_lines)
    text += "\n\nFitted slope of log e against log(V/V_y):\n\n| fit | V/V_y | slope |\n|---|---|---|\n"
    text += "".join(f"| {k} | {', '.join(f'{x:g}' for x in v[1])} | {v[0]:.3f} |\n" for k, v in fits.items())
    text += (f"| Thornton 1997 asymptote | V/V_y -> inf | {THORNTON_ASYMPTOTE[1]:.3f} |\n"
             f"| Wu, Li & Thornton 2005 (form as quoted, unverified) | high | {WLT_LAW[1]:.3f} |\n")
    text += ("\nNot converged to 0.01 on the meshes run: " + (", ".join(f"{k:g}" for k in sorted(by) if not conv[k]) or "none")
             + "\nNot valid (plastic strain at the contact zone's boundary, or the contact not ended): "
             + (", ".join(f"{k:g}" for k in sorted(by) if not valid[k]) or "none") + "\n")
    return text, fits


def plot(out: Path, rows: list[dict], refines: list[float], vy: float, hc: float, method: str = "full FE P1") -> None:
    from millimpact.results.plots import pyplot
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7.5, 4.8), constrained_layout=True)
    x = np.logspace(0, 3.1, 300)
    ax.loglog(x, restitution_thornton(x * vy, vy), "k--", label="Thornton 1997 (analytical, over-dissipates)")
    finest = {}
    for r in sorted(rows, key=lambda r: r["refine"]):
        finest[r["v_over_vy"]] = r["restitution"]
    if 30.0 in finest:      # reference slopes through the finest 30 V_y point
        xh = x[x >= 30]
        for (c, k), style, label in ((THORNTON_ASYMPTOTE, ":", "slope -1/4 (Thornton 1997 asymptote)"),
                                     (WLT_LAW, "-.", "slope -1/2 (Wu-Li-Thornton 2005 as quoted, unverified)")):
            ax.loglog(xh, finest[30.0] * (xh / 30.0) ** k, style, color="0.4" if k == -0.25 else "tab:red", lw=1,
                      label=label + ", through the 30 V_y point")
    for refine, mk in zip(refines, ("o-", "s--", "^")):
        pts = sorted((r["v_over_vy"], r["restitution"], r["max_equivalent_plastic_strain"] > SMALL_STRAIN
                      or not r["zone_boundary_elastic"]) for r in rows if r["refine"] == refine)
        if not pts:
            continue
        ax.loglog([p[0] for p in pts], [p[1] for p in pts], mk, label=f"millimpact {method}, h = a_c / {hc * refine:.3g}")
        bad = [p for p in pts if p[2]]
        if bad:
            ax.loglog([p[0] for p in bad], [p[1] for p in bad], "x", color="k", ms=10)
    ax.plot([], [], "x", color="k", label="plastic strain > 0.1 or plastic zone boundary")
    ax.set_xlabel("V / V_y")
    ax.set_ylabel("coefficient of restitution e")
    ax.set_ylim(0.15, 1.1)
    ax.grid(alpha=0.3, which="both")
    ax.set_title(f"Elastic-perfectly-plastic sphere (Y 1 GPa, V_y {vy:.3g} m/s) on a stiff flat", fontsize=10)
    ax.legend(fontsize=7)
    fig.savefig(out / "restitution.png", dpi=130)


if __name__ == "__main__":
    sys.exit(main())
