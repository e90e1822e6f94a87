"""What a study concludes: each case's peaks, exponents fitted against the parameter beside Hertz's scaling laws,
the paper's conclusions (2)-(5) checked one by one, and the written report (peaks.csv / peaks.md, study.md,
study.json, figures through :mod:`millimpact.studies.study_figures`).
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..commandkit.store import write_atomic
from .sweep import CaseRun, Study, describe_reuse

LITTLE = 0.10
#: a monotone trend must change by more than this over the range to count as a rise or a fall
TREND = 0.01

# --- analysis -------------------------------------------------------------------------------------
#: the peaks of a case: key -> (column header with unit, markdown header, scale to the shown unit)
PEAK_COLUMNS = {
    "F_max": ("peak_contact_force_N", "F_max [kN]", 1e-3),
    "F_max_hertz": ("hertz_peak_contact_force_N", "Hertz F_max [kN]", 1e-3),
    "t_c": ("contact_duration_s", "t_c [us]", 1e6),
    "t_c_hertz": ("hertz_contact_duration_s", "Hertz t_c [us]", 1e6),
    "displacement": ("peak_contact_point_displacement_m", "disp. [um]", 1e6),
    "velocity": ("peak_contact_point_velocity_m_s", "vel. [m/s]", 1.0),
    "acceleration": ("peak_contact_point_acceleration_in_contact_m_s2", "acc. in contact [km/s^2]", 1e-3),
    "acceleration_raw": ("peak_contact_point_acceleration_m_s2", "acc. peak [km/s^2]", 1e-3),
    "t_acceleration": ("time_of_peak_acceleration_in_contact_s", "t(acc.) [us]", 1e6),
    "displacement_after": ("peak_contact_point_displacement_after_contact_m", "disp. after [um]", 1e6),
    "acceleration_after": ("peak_contact_point_acceleration_after_contact_m_s2", "acc. after [km/s^2]", 1e-3),
    "stress": ("peak_contact_point_stress_Pa", "|sigma_n| [GPa]", 1e-9),
    "stress_hertz": ("hertz_p0_Pa", "Hertz p0 [GPa]", 1e-9),
    "von_mises": ("peak_contact_point_von_mises_Pa", "von Mises [GPa]", 1e-9),
    "restitution": ("restitution", "e", 1.0),
    "vibration_share": ("vibration_energy_share_end", "vib. share [%]", 100.0),
    "wall": ("wall_time_s", "wall [s]", 1.0),
}

#: quantities fitted against the parameter: key, name, Hertz key (or None), Hertz law
FITTED = [
    ("F_max", "peak contact force", "F_max_hertz", "F ~ v^(6/5) R^2 E*^(2/5)"),
    ("t_c", "contact duration", "t_c_hertz", "t_c ~ v^(-1/5) R E*^(-2/5)"),
    ("stress", "peak normal stress at the contact point", "stress_hertz", "p0 ~ v^(2/5) R^0 E*^(4/5)"),
    ("displacement", "peak contact-point displacement", "displacement_hertz", "w ~ v^(4/5) R (block's share)"),
    ("velocity", "peak contact-point velocity", "velocity_hertz", "w' ~ v R^0 (block's share at first contact)"),
    ("acceleration", "peak contact-point acceleration in contact", "acceleration_hertz", "w'' ~ v^(6/5) R^-1"),
]


def case_peaks(run: CaseRun) -> dict[str, float]:
    """Peaks of one case (SI) and the Hertz values of its scene for the same quantities.

    The contact-point acceleration jumps at first contact and at release (the point takes the
    block's share of the ball's speed within one step: its peak is ~ share * v / dt, a resolution
    value, and infinite in the quasi-static Hertz limit), and in contact it carries step-to-step
    noise; the acceleration "in contact" is the velocity's slope over windows of t_c / 8 between
    10 % and 90 % of the pulse, the smooth part (~ share * F / m at the peak in Hertz's model).
    """
    from ..results.timeseries import contact_metrics
    from ..scene.plan import scene_hertz

    ts, s, scene = run.series, run.summary, run.case.scene
    assert s is not None, "a finished case has its summary"
    m = contact_metrics(ts)
    t = ts.time
    t0 = m.get("contact_start_s", float(t[0]))
    tc = m["contact_duration_s"]

    def col(name: str) -> np.ndarray:
        return ts[name] if name in ts else np.full_like(t, np.nan)

    def peak(x: np.ndarray) -> float:
        return float(np.max(x)) if np.all(np.isfinite(x)) and len(x) else math.nan

    acc = np.abs(col("contact_point_acceleration_m_s2"))
    # in contact: the mean slope of the velocity over windows of t_c / 8 (the pulse's band; a half-sine
    # peak loses 0.6 % to it), centred between 10 % and 90 % of the pulse so no window holds the
    # velocity jumps at first contact and release
    w = tc / 8.0
    tt = np.linspace(t0 + 0.1 * tc, t0 + 0.9 * tc, 81)
    vel = col("contact_point_velocity_m_s")
    if tc > 0 and np.all(np.isfinite(vel)):
        acc_in = np.abs(np.interp(tt + w / 2, t, vel) - np.interp(tt - w / 2, t, vel)) / w
        i_in = int(np.argmax(acc_in))
        acc_contact, t_acc = float(acc_in[i_in]), float(tt[i_in] - t0)
    else:
        acc_contact = t_acc = math.nan
    # after the contact: the amplitude of the block's ringing at the contact point (the free vibration)
    after = t > t0 + 1.2 * tc
    disp_after = peak(np.abs(col("contact_point_displacement_m"))[after]) if np.any(after) else math.nan
    acc_after = peak(acc[after]) if np.any(after) else math.nan
    h = scene_hertz(scene)
    blk = scene.block.material
    share = (1 - blk.poisson**2) / blk.youngs_modulus * h.e_star  # the block's share of the approach
    p = {
        "F_max": m["peak_contact_force_N"],
        "t_c": tc,
        "displacement": peak(col("contact_point_displacement_m")),
        "velocity": peak(np.abs(col("contact_point_velocity_m_s"))),
        "acceleration": acc_contact,
        "acceleration_raw": peak(acc),
        "t_acceleration": t_acc,
        "displacement_after": disp_after,
        "acceleration_after": acc_after,
        "stress": peak(-col("contact_point_stress_Pa")),
        "von_mises": peak(col("contact_point_von_mises_Pa")),
        "restitution": s.get("restitution") if s.get("restitution") is not None else math.nan,
        "vibration_share": s.get("vibration_energy_share_end", math.nan),
        "wall": run.wall_time_s,
        "F_max_hertz": h.force_max,
        "t_c_hertz": h.contact_time,
        "stress_hertz": h.p0,
        "displacement_hertz": share * h.delta_max,
        "velocity_hertz": share * h.speed,
        "acceleration_hertz": share * h.force_max / h.mass,
        "e_star": h.e_star,
    }
    return {k: (float(v) if v is not None else math.nan) for k, v in p.items()}


def fit_exponent(x: Sequence[float] | np.ndarray, y: Sequence[float] | np.ndarray) -> float:
    """Least-squares slope of log|y| against log x (the k of y ~ x^k); nan if undefined."""
    xs, ys = np.asarray(x, float), np.abs(np.asarray(y, float))
    ok = np.isfinite(xs) & np.isfinite(ys) & (xs > 0) & (ys > 0)
    if ok.sum() < 2 or np.ptp(np.log(xs[ok])) == 0:
        return math.nan
    return float(np.polyfit(np.log(xs[ok]), np.log(ys[ok]), 1)[0])


def local_exponents(x: Sequence[float] | np.ndarray, y: Sequence[float] | np.ndarray) -> list[float]:
    """Slopes of log|y| against log x between neighbouring cases."""
    return [fit_exponent(x[i : i + 2], y[i : i + 2]) for i in range(len(x) - 1)]


@dataclass
class StudyAnalysis:
    """Peaks per case, fitted exponents and the comparison with the paper."""

    x: np.ndarray
    peaks: list[dict[str, float]]
    fits: list[dict[str, Any]] = field(default_factory=list)
    paper_checks: list[dict[str, str]] = field(default_factory=list)

    def values(self, key: str) -> np.ndarray:
        return np.array([p[key] for p in self.peaks])


def analyse(study: Study, runs: Sequence[CaseRun]) -> StudyAnalysis:
    """Peaks, fitted exponents (simulation and Hertz over the same scenes) and paper checks."""
    ok = [r for r in runs if r.series is not None]
    x = np.array([r.case.x for r in ok])
    a = StudyAnalysis(x, [case_peaks(r) for r in ok])
    if len(ok) >= 2 and np.all(np.isfinite(x)):
        for key, name, hkey, law in FITTED:
            sim, hz = a.values(key), a.values(hkey)
            k, kh = fit_exponent(x, sim), fit_exponent(x, hz)
            a.fits.append(
                {
                    "quantity": key,
                    "name": name,
                    "k": k,
                    "k_hertz": kh,
                    "law": law,
                    "local_k": local_exponents(x, sim),
                    "change": float(sim[-1] / sim[0] - 1.0) if sim[0] else math.nan,
                    "change_hertz": float(hz[-1] / hz[0] - 1.0) if hz[0] else math.nan,
                }
            )
    if study.paper is not None and len(ok) == len(study.cases) == len(study.paper.values):
        a.paper_checks = paper_checks(study, a)
    return a


#: the paper's conclusions (2)-(5) as checkable statements: (quantity, expectation, the paper's words)
PAPER_CLAIMS = {
    "poisson": [
        ("displacement", "little", "little effect on the displacement"),
        ("velocity", "little", "little effect on the velocity"),
        ("acceleration", "little", "little effect on the acceleration"),
        ("stress", "rises", "the stress changes greatly (its amplitude increases)"),
        ("stress", "slower", "above u = 1.0 the increase of the stress becomes smaller"),
    ],
    "velocity": [
        ("displacement", "rises", "the displacement increases"),
        ("velocity", "rises", "the velocity increases"),
        ("acceleration", "rises", "the acceleration increases"),
        ("stress", "rises", "the stress increases"),
        ("displacement", "slower", "above 3 m/s the increase of the displacement is smaller"),
        ("stress", "slower", "above 3 m/s the increase of the stress is smaller"),
        ("acceleration", "slower", "above 3 m/s the increase of the acceleration is smaller"),
    ],
    "radius": [
        ("displacement", "rises", "the displacement increases"),
        ("velocity", "rises", "the velocity increases"),
        ("stress", "rises", "the stress amplitude increases"),
        ("acceleration", "little", "the acceleration amplitude changes little"),
        ("stress", "faster", "above 20 mm the stress changes greatly"),
        ("t_acceleration", "falls", "the maximum acceleration occurs earlier"),
    ],
    "thickness": [
        ("displacement", "rises", "the displacement increases"),
        ("acceleration", "rises", "the acceleration increases"),
        ("stress", "falls", "the stress amplitude decreases"),
        ("velocity", "little", "the velocity does not increase significantly"),
        ("t_acceleration", "settles", "above 40 mm the time of the maximum acceleration hardly changes"),
    ],
}

QUANTITY_NAMES = {
    "displacement": "peak contact-point displacement",
    "velocity": "peak contact-point velocity",
    "acceleration": "peak contact-point acceleration (in contact)",
    "stress": "peak normal stress at the contact point",
    "t_acceleration": "time of the peak acceleration after first contact",
    "F_max": "peak contact force",
    "t_c": "contact duration",
}


def _fmt_values(key: str, v: np.ndarray) -> str:
    _, _, scale = PEAK_COLUMNS[key]
    unit = PEAK_COLUMNS[key][1].split("[")[-1].rstrip("]") if "[" in PEAK_COLUMNS[key][1] else ""
    return ", ".join(f"{x * scale:.4g}" for x in v) + (f" {unit}" if unit else "")


def _trend_word(v: np.ndarray) -> str:
    d, rel = np.diff(v), v[-1] / v[0] - 1.0
    if abs(rel) <= TREND and np.all(np.abs(d) <= TREND * abs(v[0])):
        return "stays within 1 %"
    if np.all(d > 0):
        return "rises"
    if np.all(d < 0):
        return "falls"
    return "is not monotonic"


def paper_checks(study: Study, a: StudyAnalysis) -> list[dict[str, str]]:
    """Each of the paper's statements of this study against our numbers: agrees / disagrees."""
    assert study.paper is not None, "checked for a study of the paper's"
    out = []
    for key, expect, words in PAPER_CLAIMS.get(study.paper.name, []):
        v = a.values(key)
        d = np.diff(v)
        rel = float(v[-1] / v[0] - 1.0) if v[0] else math.nan
        ours = f"{QUANTITY_NAMES[key]}: {_fmt_values(key, v)}"
        ok: bool | str  # "relative": agrees in relative terms only
        if expect in ("rises", "falls"):
            ok = bool(np.all(d > 0) and rel > TREND) if expect == "rises" else bool(np.all(d < 0) and rel < -TREND)
            found = f"{_trend_word(v)} ({100 * rel:+.1f} % over the range)"
        elif expect == "little":
            ok = bool(abs(rel) < LITTLE)
            found = (
                f"changes by {100 * rel:+.1f} % over the range "
                f"({'little' if ok else 'not little'}: threshold {100 * LITTLE:.0f} %)"
            )
        elif expect in ("slower", "faster"):
            inc1, inc2 = v[1] - v[0], v[2] - v[1]
            r1, r2 = v[1] / v[0] - 1.0, v[2] / v[1] - 1.0
            smaller = abs(inc2) < abs(inc1)
            # "changes greatly": the larger second step must also be a large one (>= LITTLE)
            ok = smaller if expect == "slower" else (not smaller and abs(r2) >= LITTLE)
            if expect == "slower" and not smaller and abs(r2) < abs(r1):
                ok = "relative"
            found = (
                f"change {_fmt_values(key, np.array([inc1]))} then {_fmt_values(key, np.array([inc2]))} "
                f"(relative {100 * r1:+.1f} % then {100 * r2:+.1f} %): the second step is "
                f"{'smaller' if smaller else 'larger'} in absolute terms"
                + (
                    ""
                    if (abs(r2) < abs(r1)) == smaller
                    else f", {'smaller' if abs(r2) < abs(r1) else 'larger'} in relative terms"
                )
            )
        elif expect == "settles":
            s1, s2 = abs(v[1] - v[0]), abs(v[2] - v[1])
            ok = bool(s2 < 0.5 * s1 or s2 < 0.05 * abs(v[1]))
            found = f"changes by {_fmt_values(key, np.array([v[1] - v[0]]))} then {_fmt_values(key, np.array([v[2] - v[1]]))}"
        else:  # pragma: no cover
            raise ValueError(expect)
        verdict = "agrees in relative terms only" if ok == "relative" else ("agrees" if ok else "disagrees")
        out.append({"claim": words, "ours": ours, "found": found, "verdict": verdict})
    return out


# --- reports ----------------------------------------------------------------------------------------
def peaks_table(study: Study, runs: Sequence[CaseRun], a: StudyAnalysis) -> tuple[str, str]:
    """(CSV text in SI units, markdown table in the shown units) of the peaks and timings."""
    ok = [r for r in runs if r.series is not None]
    keys = list(PEAK_COLUMNS)
    csv_lines = [",".join(["case", study.param, "status"] + [PEAK_COLUMNS[k][0] for k in keys])]
    md_keys = [
        "F_max",
        "F_max_hertz",
        "t_c",
        "t_c_hertz",
        "displacement",
        "velocity",
        "acceleration",
        "acceleration_raw",
        "t_acceleration",
        "stress",
        "stress_hertz",
        "von_mises",
        "displacement_after",
        "acceleration_after",
        "restitution",
        "vibration_share",
        "wall",
    ]
    md = [
        "| case | " + " | ".join(PEAK_COLUMNS[k][1] for k in md_keys) + " | status |",
        "|---|" + "---|" * (len(md_keys) + 1),
    ]
    for r, p in zip(ok, a.peaks):
        val = r.case.value
        vtext = json.dumps(val) if isinstance(val, (list, str)) else f"{val:g}"
        csv_lines.append(
            ",".join([r.case.folder, f'"{vtext}"' if "," in vtext else vtext, r.status] + [f"{p[k]:.8g}" for k in keys])
        )
        cells = []
        for k in md_keys:
            v = p[k] * PEAK_COLUMNS[k][2]
            cells.append("-" if not math.isfinite(v) else (f"{v:.3f}" if k == "restitution" else f"{v:.4g}"))
        md.append(f"| {r.case.label} | " + " | ".join(cells) + f" | {r.status} |")
    for r in runs:
        if r.status == "failed":
            md.append(f"| {r.case.label} | failed: {r.error} |")
    return "\n".join(csv_lines) + "\n", "\n".join(md) + "\n"


#: simulated peak -> its Hertz counterpart
PAIRS = {key: hkey for key, _, hkey, _ in FITTED}


def _explain(study: Study, a: StudyAnalysis) -> list[str]:
    """Why our numbers go as they do (Hertz's laws and the rig's structure), per built-in study."""
    # the paper-specific reading needs the paper's three cases (not a reduced subset)
    paper = study.paper
    full = paper is not None and len(a.peaks) == len(paper.values)
    name = paper.name if paper is not None and full else None
    fit = {f["quantity"]: f for f in a.fits}
    lines = []

    def vals(key: str, fmt: str = "{:.4g}", scale: float = 1.0) -> str:
        return ", ".join(fmt.format(v * scale) for v in a.values(key))

    def pct(key: str) -> str:
        sim, hz = a.values(key), a.values(PAIRS[key])
        return ", ".join(f"{100 * (x / y - 1):+.1f} %" for x, y in zip(sim, hz))

    def chg(key: str, hertz: bool = False) -> str:
        f = fit.get(key)
        return "n/a" if f is None else f"{100 * f['change_hertz' if hertz else 'change']:+.1f} %"

    if name == "poisson":
        es = a.values("e_star")
        p0 = a.values("stress_hertz")
        lines.append(
            f"The paper keeps G fixed, so raising nu_ball raises E_ball = 2G(1+nu) and lowers (1-nu^2)/E: the contact "
            f"modulus E* goes {', '.join(f'{e / 1e9:.4g}' for e in es)} GPa ({100 * (es[-1] / es[0] - 1):+.1f} %). "
            f"Hertz then changes p0 ~ E*^(4/5) by {chg('stress', True)}, F ~ E*^(2/5) by {chg('F_max', True)}, "
            f"but also the liner's contact-point displacement by {chg('displacement', True)}, its velocity at first "
            f"contact by {chg('velocity', True)} and its acceleration by {chg('acceleration', True)}: the liner's share "
            "of the approach, (1-nu2^2) E* / E2, grows with E*. Elastic contact theory therefore does not support "
            "'little effect on the displacement, velocity and acceleration'; we find "
            f"{chg('displacement')}, {chg('velocity')} and {chg('acceleration')} for them and {chg('stress')} for the "
            "stress (Hertz p0: " + ", ".join(f"{v / 1e9:.4g}" for v in p0) + " GPa). "
            "Since 1/E* = (1 - nu_ball)/(2G) + const, E* grows faster than linearly in nu_ball, so in Hertz's model "
            f"each step of u adds more stress than the one before ({(p0[1] - p0[0]) / 1e9:+.3g} then "
            f"{(p0[2] - p0[1]) / 1e9:+.3g} GPa): the paper's 'smaller increase above u = 1' is not what elastic contact "
            "predicts."
        )
    elif name == "velocity":
        lines.append(
            "Hertz: F ~ v^(6/5), t_c ~ v^(-1/5), p0 ~ v^(2/5), contact-point displacement ~ v^(4/5), velocity ~ v, "
            "acceleration ~ v^(6/5). Every peak grows with v, as conclusion (3) says. For equally spaced values "
            "(1, 3, 5 m/s) the relative growth per step falls for any power law, but the absolute increase from 3 to "
            "5 m/s is smaller than from 1 to 3 m/s only for exponents below 1 (displacement, stress), not for the "
            "force or the acceleration (6/5). So the paper's 'smaller increase above 3 m/s' holds in relative terms "
            "for all quantities and in absolute terms only for the displacement and the stress; our sampled stress "
            "carries several percent of mesh noise (below), enough to flip that absolute comparison. "
            f"F_max against Hertz: {pct('F_max')} (the block is finite, clamped at its base and bends)."
        )
    elif name == "radius":
        lines.append(
            "Hertz: F ~ R^2, t_c ~ R, contact radius a ~ R, so the mean pressure F / (pi a^2) and p0 do not depend on R "
            "at all; the contact-point displacement grows ~ R, its velocity at first contact does not change, and the "
            "acceleration ~ F/m ~ R^-1 falls. An elastic model therefore finds the stress nearly independent of r "
            f"(ours: {chg('stress')}), while the paper reports that it grows, strongly above 20 mm; and the peak "
            "acceleration comes later for a larger ball (t_c ~ R), not earlier (ours: t(acc.) "
            f"{vals('t_acceleration', '{:.3g}', 1e6)} us). We cannot reproduce those statements; the paper does not "
            "say how its contact-point stress is sampled."
        )
        if "F_max" in fit:
            lines.append(
                f"Our F_max exponent {fit['F_max']['k']:.2f} lies below Hertz's 2 because the rig's block is no "
                "half-space: clamped at its base and struck on its side it bends, and a heavier ball (m ~ r^3, a "
                "longer pulse nearer the block's low modes) drives it harder: the share of the impact energy left in "
                f"vibration goes {vals('vibration_share', '{:.0f}', 100)} % and F_max against Hertz "
                f"{pct('F_max')}."
            )
    elif name == "thickness":
        lines.append(
            "Hertz has no b: the local contact (F, t_c, p0) is that of a half-space. b enters only through the rig's "
            "structure: the block is clamped at its base and struck on its side, so it bends like a short cantilever "
            "whose bending stiffness grows ~ b^3. A thinner block is more compliant: its struck face gives way more "
            f"(contact-point displacement {vals('displacement', '{:.3g}', 1e6)} um), it keeps more of the impact "
            f"energy as vibration ({vals('vibration_share', '{:.0f}', 100)} %; restitution "
            f"{vals('restitution', '{:.3f}')}) and the contact force falls below Hertz ({pct('F_max')}). So we find "
            "the displacement falling with b, where the paper finds it rising; the stress at the contact point is "
            "local (Hertz: independent of b) and changes within its sampling noise "
            f"({vals('stress', '{:.3g}', 1e-9)} GPa), where the paper finds it falling. After the contact the "
            f"contact point rings with amplitudes {vals('displacement_after', '{:.3g}', 1e6)} um and "
            f"{vals('acceleration_after', '{:.3g}', 1e-3)} km/s^2 (the block's free vibration; the paper's curves "
            "over 40 ms may show these rather than the contact peaks)."
        )
    if fit.get("acceleration") is not None:
        lines.append(
            "Acceleration: the table also gives the raw peak of the contact-point acceleration; it occurs at first "
            "contact or at release, where the point takes the block's share of the ball's speed within about one "
            "step, so it scales as ~ share * v / dt (a resolution value; infinite in the quasi-static limit). The "
            "trends use the acceleration in contact: the velocity's slope over windows of t_c / 8 between 10 % and "
            "90 % of the pulse."
        )
        lines.append(
            "Stress: the normal stress is sampled just below the contact point in a P1 mesh, where it is constant per "
            "element and comes from the few ball nodes nearest the centre (h_contact = a_max / 4 by default), so it "
            "is off Hertz's p0 by up to ~10 %, differently for each case (see the Hertz p0 column); trends in it "
            "smaller than that are not resolved (docs: foundations, section 3: the pressure peak needs ~16 elements across a_max)."
        )
    return lines


def study_markdown(
    study: Study, runs: Sequence[CaseRun], a: StudyAnalysis, method: str, method_note: str, md_table: str, wall: float
) -> str:
    """``study.md``: setup, the peaks table, fitted trends beside Hertz, the paper's conclusions."""
    n_comp = sum(r.status == "computed" for r in runs)
    n_cache = sum(r.status == "cached" for r in runs)
    values = ", ".join(r.case.label.split("= ", 1)[-1] for r in runs)
    lines = [
        f"# Study `{study.name}`: {study.symbol} = {values}",
        "",
        f"Base scene `{study.base}`, parameter `{study.param}`; method `{method}` ({method_note}). "
        f"{len(runs)} cases: {n_comp} computed, {n_cache} from the cache; study wall time {wall:.1f} s "
        f"(sum of case wall times {sum(p['wall'] for p in a.peaks if math.isfinite(p['wall'])):.1f} s).",
        f"Simulated time {runs[0].case.scene.time.end * 1e3:g} ms per case. Figures: `contact_point.png` "
        "(the paper's four panels around the impact), `contact_point_run.png` (impact and ringing, first 2 ms), `contact_force.png` "
        "(with Hertz), `trends.png`.",
        "",
        "## Peaks",
        "",
        md_table,
        "disp., vel., acc.: the liner's contact point along the impact direction; |sigma_n|: compressive normal "
        "stress just below it; t(acc.): time of the in-contact acceleration peak after first contact; "
        "disp./acc. after: amplitude of the contact point's ringing after the contact (the block's free "
        "vibration, undamped in this elastic model); e: restitution; vib. share: share of the impact energy left "
        "in the bodies' vibration at the end.",
        "",
    ]
    if a.fits:
        words = []
        for f in a.fits[:3]:
            words.append(
                f"the {f['name']} {_trend_word(a.values(f['quantity']))}, {100 * f['change']:+.1f} % over "
                f"the range (fit ~ {study.symbol}^{f['k']:.2f}; Hertz ~ {study.symbol}^{round(f['k_hertz'], 2) + 0.0:.2f})"
            )
        lines += ["## Summary", "", "Over the cases " + "; ".join(words) + ".", ""]
        lines += [
            "## Trends (power laws y ~ x^k fitted over the cases)",
            "",
            f"x = {study.xlabel}. 'Hertz k' is the same fit of Hertz's values for the same scenes "
            "(quasi-static, half-space).",
            "",
            "| quantity | k (ours) | k (Hertz) | local k | change over the range | Hertz law |",
            "|---|---|---|---|---|---|",
        ]
        for f in a.fits:
            loc = ", ".join(f"{k:.3f}" for k in f["local_k"])
            lines.append(
                f"| {f['name']} | {f['k']:.3f} | {round(f['k_hertz'], 3) + 0.0:.3f} | {loc} | {100 * f['change']:+.1f} % "
                f"| {f['law']} |"
            )
        lines.append("")
    if a.paper_checks:
        assert study.paper is not None, "only a study of the paper's is checked against it"
        lines += ["## Against the paper's conclusion", "", f"> {study.paper.paper_conclusion}", ""]
        for c in a.paper_checks:
            lines.append(f"- Paper: {c['claim']}. Ours: {c['found']} -- **{c['verdict']}**. ({c['ours']})")
        lines.append("")
    expl = _explain(study, a)
    if expl:
        lines += ["## Why", ""] + [f"{t}\n" for t in expl]
    failed = [r for r in runs if r.status == "failed"]
    if failed:
        lines += ["## Failed cases", ""] + [f"- {r.case.label}: {r.error}" for r in failed] + [""]
    return "\n".join(lines)


def thornton_curve(scene) -> tuple[float, str] | None:
    """(V_y, label) of Thornton's curve for a scene whose materials yield: the yield-onset speed of
    the softer plastic material (theory/thornton.py); None when both are elastic."""
    from ..theory.hertz import effective_modulus
    from ..theory.thornton import yield_onset_velocity

    ys = [m.initial_yield_stress for m in (scene.ball.material, scene.target_material) if m.plastic]
    if not ys:
        return None
    y = min(ys)
    vy = yield_onset_velocity(
        y, effective_modulus(scene.ball.material, scene.target_material), scene.ball.effective_density
    )
    return vy, f"Thornton 1997 (Y = {y / 1e9:.3g} GPa, V_y = {vy:.3g} m/s; a lower bound of FE)"


def write_study(
    study: Study, runs: Sequence[CaseRun], out: Path, method: str, method_note: str, wall: float
) -> StudyAnalysis:
    """The study's figures, tables, text and ``study.json`` (last) in ``out`` (rank 0)."""
    from ..results.timeseries import contact_metrics, jsonable
    from ..scene.plan import scene_hertz
    from ..theory.hertz import hertz_history
    from . import study_figures as study_plots

    a = analyse(study, runs)
    ok = [r for r in runs if r.series is not None]
    title = f"study {study.name} ({study.base}, {method})"
    if ok:
        cp = []
        for r in ok:
            m = contact_metrics(r.series)
            cp.append((r.case.label, r.series, m.get("contact_start_s", 0.0), m["contact_duration_s"]))
        study_plots.plot_study_contact_point(
            cp, out / "contact_point.png", f"{title}: liner contact point around the impact"
        )
        study_plots.plot_study_contact_point(
            cp,
            out / "contact_point_run.png",
            f"{title}: liner contact point, impact and ringing "
            f"(first {min(study_plots.RUN_WINDOW, study.cases[0].scene.time.end) * 1e3:g} ms)",
            whole_run=True,
        )
        study_plots.plot_study_force(
            [(lab, ts, t0, hertz_history(scene_hertz(r.case.scene))) for (lab, ts, t0, _), r in zip(cp, ok)],
            out / "contact_force.png",
            f"{title}: contact force",
        )
        if len(ok) >= 2 and np.all(np.isfinite(a.x)):
            quantities = [(name, a.values(key), a.values(hkey)) for key, name, hkey, _ in FITTED]
            study_plots.plot_study_trends(
                a.x, study.xlabel, quantities, out / "trends.png", f"{title}: peaks against {study.symbol}"
            )
        e = a.values("restitution")
        if study.param == "impact.velocity" and len(ok) >= 2 and np.sum(np.isfinite(e)) >= 2:
            speeds = np.array([r.case.scene.normal_speed for r in ok])
            study_plots.plot_study_restitution(
                speeds, e, out / "restitution.png", f"{title}: restitution", thornton_curve(study.cases[0].scene)
            )
    csv_text, md_table = peaks_table(study, runs, a)
    write_atomic(out / "peaks.csv", csv_text)
    write_atomic(out / "peaks.md", md_table)
    write_atomic(out / "study.md", study_markdown(study, runs, a, method, method_note, md_table, wall))
    data = {
        "study": study.name,
        "param": study.param,
        "base": study.base,
        "method": method,
        "method_note": method_note,
        "wall_time_s": wall,
        "cases": [
            {
                "folder": r.case.folder,
                "label": r.case.label,
                "value": r.case.value,
                "x": r.case.x,
                "status": r.status,
                "error": r.error,
                "peaks": a.peaks[[q.case.index for q in ok].index(r.case.index)] if r.series is not None else None,
            }
            for r in runs
        ],
        "reuse": describe_reuse(runs)[0],
        "fits": a.fits,
        "paper_checks": a.paper_checks,
        "paper_conclusion": study.paper.paper_conclusion if study.paper else None,
    }
    write_atomic(out / "study.json", json.dumps(jsonable(data), indent=2) + "\n")
    return a
