"""A contact table's rows, files, figures and fitted laws (``millimpact table``, :mod:`.table`).

Row of one impact (:func:`case_row`), from the run's time series and summary (SI units; the
columns and their definitions are :data:`COLUMNS`). The ball's spin is not a model output: it
follows from the tangential impulse J_t on a rigid sphere without initial spin,
omega = -5 J_t / (2 m R) (positive: rolling forward), and the contact point's tangential velocity
is u_t = v_t - R omega, so u_t,out = v_t,in + 7 J_t / (2 m) (Maw, Barber & Fawcett, Wear 38 (1976)
101-114); ``restitution_tangential`` = u_t,out / u_t,in (1 without friction; NaN for a normal
impact).

Files (rank 0): ``contact_table.csv`` (a ``#`` header: scene, method, version, then one line per
column with its unit and definition; then the rows), ``contact_table.json`` (columns, units,
definitions, the resolved base scene, a hash per case, the rows), ``contact_table.h5`` (a dataset
per column with ``unit`` / ``definition`` attributes), ``contact_laws.json`` (fitted laws with their
errors), figures ``e_n_speed.png``, ``e_t_angle.png``, ``force_speed.png``.

Fits (:func:`fit_laws`): e_n(v_n) as a power law e = A v^-k over the normal impacts, Thornton's
e(V; V_y) with V_y fitted (plastic tables), and a Hertz stiffness: the contact modulus E* that makes
F_max = (4/3) E* R^(1/2) delta_max^(3/2) of a Hertz impact match the peak forces (least squares in
log F), k_n = (4/3) E* R^(1/2); each with its RMS relative error over the cases.
"""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from .. import __version__
from ..results.timeseries import contact_metrics, jsonable
from ..scene.schema import Scene
from ..scene.toml_io import dump_scene
from ..theory.hertz import hertz_impact
from ..theory.thornton import restitution_thornton

#: (name, unit, definition) of the table's columns, in order
COLUMNS = [
    ("impact_speed_m_s", "m/s", "impact speed |v|"),
    ("impact_angle_deg", "deg", "angle of v from the face normal"),
    ("ball_radius_m", "m", "ball radius"),
    ("normal_velocity_in_m_s", "m/s", "normal approach speed -v.n"),
    ("tangential_velocity_in_m_s", "m/s", "tangential speed |v - (v.n) n|"),
    ("restitution_normal", "-", "normal rebound speed of the ball's centre over the approach speed"),
    (
        "restitution_tangential",
        "-",
        "contact point's tangential velocity out over in (Maw-Barber-Fawcett; rigid-ball spin)",
    ),
    ("rebound_spin_rad_s", "rad/s", "ball spin after the impact, -5 J_t / (2 m R) (positive: rolling forward)"),
    ("peak_normal_force_N", "N", "largest normal contact force"),
    ("peak_tangential_force_N", "N", "largest tangential contact force magnitude"),
    ("contact_duration_s", "s", "time the contact force is positive"),
    ("normal_impulse_N_s", "N s", "time integral of the normal contact force"),
    (
        "tangential_impulse_N_s",
        "N s",
        "time integral of the tangential force on the ball along the tangential direction",
    ),
    ("max_approach_m", "m", "largest approach of the ball's centre after first contact"),
    (
        "energy_to_liner_J",
        "J",
        "impact energy not returned to the ball's translation and spin nor dissipated: the "
        "bodies' vibration after the impact (mostly the struck body's)",
    ),
    ("friction_dissipation_J", "J", "work of friction"),
    ("plastic_dissipation_J", "J", "plastic work (0 for elastic materials)"),
    ("residual_dent_depth_m", "m", "depth of the residual dent (0 for elastic materials)"),
    ("status", "", "ok, ok (contact not ended) or failed: why"),
    ("wall_time_s", "s", "wall time of the case"),
]


def case_row(case, plan, out, wall: float) -> dict[str, Any]:
    """The table row of one case's run (``out``: a :class:`millimpact.results.output.RunOutput`)."""
    ts, res = out.series, out.results
    metrics = contact_metrics(ts)
    t = ts.time
    fn = ts["contact_force_N"]
    ft = ts["tangential_force_N"] if "tangential_force_N" in ts else np.zeros_like(t)
    m, R = plan.ball.mass, plan.ball.radius
    n = np.asarray(plan.contact_normal, float)
    v = np.asarray(plan.velocity, float)
    v_n = float(-(v @ n))
    v_t = float(np.linalg.norm(v - (v @ n) * n))
    j_n, j_t = float(np.trapz(fn, t)), float(np.trapz(ft, t))
    omega = -5.0 * j_t / (2.0 * m * R)
    e_n = float(res.get("restitution", math.nan))
    u_out = v_t + 3.5 * j_t / m
    e_t = u_out / v_t if v_t > 1e-9 * max(v_n, 1e-300) else math.nan
    v_t_out = v_t + j_t / m
    w_f = float(ts["friction_dissipation_J"][-1]) if "friction_dissipation_J" in ts else 0.0
    w_p = float(ts["plastic_dissipation_J"][-1]) if "plastic_dissipation_J" in ts else 0.0
    e_in = 0.5 * m * (v_n**2 + v_t**2)
    e_ball = 0.5 * m * ((e_n * v_n) ** 2 + v_t_out**2) + 0.5 * (0.4 * m * R * R) * omega**2
    status = "ok" if fn[-1] <= 1e-6 * max(float(fn.max()), 1e-300) else "ok (contact not ended)"
    return {
        "case": case.index,
        "key": case.key,
        "impact_speed_m_s": case.speed,
        "impact_angle_deg": case.angle,
        "ball_radius_m": case.radius,
        "normal_velocity_in_m_s": v_n,
        "tangential_velocity_in_m_s": v_t,
        "restitution_normal": e_n,
        "restitution_tangential": e_t,
        "rebound_spin_rad_s": omega,
        "peak_normal_force_N": float(fn.max()),
        "peak_tangential_force_N": float(np.abs(ft).max()),
        "contact_duration_s": float(metrics["contact_duration_s"]),
        "normal_impulse_N_s": j_n,
        "tangential_impulse_N_s": j_t,
        "max_approach_m": float(metrics.get("max_approach_m", math.nan)),
        "energy_to_liner_J": e_in - e_ball - w_f - w_p,
        "friction_dissipation_J": w_f,
        "plastic_dissipation_J": w_p,
        "residual_dent_depth_m": float(res.get("residual_dent_depth_m", 0.0)),
        "status": status,
        "wall_time_s": wall,
        "band": case.band,
        "hertz_peak_force_N": plan.hertz.force_max,
    }


# --- fits ---------------------------------------------------------------------------------------------
def fit_laws(rows: Sequence[dict], base: Scene) -> dict[str, Any]:
    """Fitted laws of the ok rows (module docstring), each with its RMS relative error."""
    ok = [r for r in rows if str(r.get("status", "")).startswith("ok")]
    laws: dict[str, Any] = {}
    if not ok:
        return laws
    vn = np.array([r["normal_velocity_in_m_s"] for r in ok])
    e = np.array([r["restitution_normal"] for r in ok])
    good = np.isfinite(e) & (e > 0)
    if good.sum() >= 2 and np.ptp(np.log(vn[good])) > 0:
        k, lnA = np.polyfit(np.log(vn[good]), np.log(e[good]), 1)
        pred = np.exp(lnA) * vn[good] ** k
        laws["restitution_power_law"] = {
            "form": "e_n = A v_n^k",
            "A": float(np.exp(lnA)),
            "k": float(k),
            "rms_rel_error": float(np.sqrt(np.mean((pred / e[good] - 1) ** 2))),
            "cases": int(good.sum()),
        }
        plastic = base.ball.material.plastic or base.target_material.plastic
        if plastic:
            grid = np.geomspace(1e-3, max(vn.max(), 1e-2), 400)
            errs = [np.sqrt(np.mean((restitution_thornton(vn[good], vy) / e[good] - 1) ** 2)) for vy in grid]
            i = int(np.argmin(errs))
            laws["restitution_thornton"] = {
                "form": "Thornton 1997 e(V; V_y)",
                "V_y_m_s": float(grid[i]),
                "rms_rel_error": float(errs[i]),
                "cases": int(good.sum()),
            }
    f = np.array([r["peak_normal_force_N"] for r in ok])
    rad = np.array([r["ball_radius_m"] for r in ok])
    fine = f > 0
    if fine.any():
        m_of = lambda R: base.ball.material.density * 4.0 / 3.0 * math.pi * R**3  # noqa: E731
        # F_max ~ E*^(2/5): log F = 0.4 log E* + log F(E* = 1)
        unit = np.array([hertz_impact(R, m_of(R), v, 1.0).force_max for R, v in zip(rad[fine], vn[fine])])
        ln_e = float(np.mean(np.log(f[fine] / unit))) / 0.4
        e_star = math.exp(ln_e)
        pred = unit * e_star**0.4
        laws["hertz_stiffness"] = {
            "form": "F = (4/3) E* R^(1/2) delta^(3/2)",
            "E_star_Pa": e_star,
            "k_n_N_m1_5": {f"R={R:g}": 4.0 / 3.0 * e_star * math.sqrt(R) for R in sorted(set(rad))},
            "rms_rel_error": float(np.sqrt(np.mean((pred / f[fine] - 1) ** 2))),
            "cases": int(fine.sum()),
        }
    return laws


# --- files and figures --------------------------------------------------------------------------------
#: the column an adaptive table adds (:mod:`.table_adaptive`)
ROLE_COLUMN = (
    "role",
    "",
    "grid: a case the law (bilinear in ln speed and angle) is built on; check: a case that measures its "
    "error; spare: a cell's centre computed ahead that a later split made no check",
)


def write_table(
    out: Path, base: Scene, cases, rows: Sequence[dict], method: str, options: dict, adaptive: dict | None = None
) -> None:
    """contact_table.csv / .json / .h5, contact_laws.json and the figures (rank 0). ``adaptive``:
    an adaptive table's summary (:func:`millimpact.studies.table_adaptive.adaptive_summary`), said
    in the files' headers and kept in contact_table.json; its rows carry the ``role`` column."""
    from ..results.output_folder import hdf5_file

    out.mkdir(parents=True, exist_ok=True)
    columns = COLUMNS + [ROLE_COLUMN] if adaptive is not None else COLUMNS
    names = [c[0] for c in columns]
    head = [
        f"# millimpact {__version__} contact table: scene {base.name}, method {method}, options {json.dumps(options)}",
        f"# {len(rows)} impacts; the angle is measured from the face normal; SI units (in the column names)",
    ]
    if adaptive is not None:
        head.append(f"# adaptive table (grid and check cases, checks.csv): {summary_line(adaptive)}")
    head += [f"# {n} [{u}]: {d}" for n, u, d in columns]
    tmp = out / ".contact_table.csv.tmp"
    with open(tmp, "w", newline="") as fh:
        fh.write("\n".join(head) + "\n")
        w = csv.writer(fh)
        w.writerow(names)
        for r in rows:
            w.writerow([r.get(n, "") if not isinstance(r.get(n), float) else repr(r[n]) for n in names])
    tmp.replace(out / "contact_table.csv")
    laws = fit_laws(rows, base)
    doc = {
        "millimpact_version": __version__,
        "scene": base.name,
        "method": method,
        "options": options,
        "columns": [{"name": n, "unit": u, "definition": d} for n, u, d in columns],
        "scene_resolved": dump_scene(base),
        "case_keys": {str(c.index): c.key for c in cases},
        "rows": list(rows),
        "laws": laws,
        **({"adaptive": adaptive} if adaptive is not None else {}),
    }
    (out / "contact_table.json").write_text(json.dumps(jsonable(doc), indent=1) + "\n")
    (out / "contact_laws.json").write_text(json.dumps(jsonable(laws), indent=1) + "\n")
    with hdf5_file(out / "contact_table.h5") as h5:  # in memory, one write: a full disk is one line
        h5.attrs["millimpact_version"] = __version__
        h5.attrs["scene"] = base.name
        h5.attrs["method"] = method
        for n, u, d in columns:
            vals = [r.get(n, "") for r in rows]
            text = n in ("status", "role")
            data = np.array([str(x) for x in vals], dtype="S") if text else np.array(vals, dtype=float)
            ds = h5.create_dataset(n, data=data)
            ds.attrs["unit"], ds.attrs["definition"] = u, d
    plot_table(out, base, rows, laws)


def plot_table(out: Path, base: Scene, rows: Sequence[dict], laws: dict) -> None:
    from ..results.plots import pyplot

    plt = pyplot()
    ok = [r for r in rows if str(r.get("status", "")).startswith("ok")]
    if not ok:
        return
    angles = sorted({r["impact_angle_deg"] for r in ok})
    fig, ax = plt.subplots(figsize=(7, 4.5), constrained_layout=True)
    for i, a in enumerate(angles):
        rr = sorted([r for r in ok if r["impact_angle_deg"] == a], key=lambda r: r["normal_velocity_in_m_s"])
        ax.plot(
            [r["normal_velocity_in_m_s"] for r in rr],
            [r["restitution_normal"] for r in rr],
            "o-",
            color=f"C{i % 10}",
            label=f"{a:g} deg",
        )
    if "restitution_thornton" in laws:
        vy = laws["restitution_thornton"]["V_y_m_s"]
        v = np.geomspace(
            min(r["normal_velocity_in_m_s"] for r in ok) / 1.3, max(r["normal_velocity_in_m_s"] for r in ok) * 1.3, 100
        )
        ax.plot(v, restitution_thornton(v, vy), "k--", lw=1, label=f"Thornton 1997, fitted V_y = {vy:.3g} m/s")
    ax.axhline(1.0, color="0.6", ls=":", lw=1, label="elastic, quasi-static")
    ax.set_xscale("log")
    ax.set_xlabel("normal impact speed [m/s]")
    ax.set_ylabel("normal restitution e_n")
    ax.set_title(f"contact table {base.name}: normal restitution")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=7, ncol=2)
    fig.savefig(out / "e_n_speed.png", dpi=130)
    plt.close(fig)

    mu = base.contact.friction
    fig, ax = plt.subplots(figsize=(7, 4.5), constrained_layout=True)
    obl = [r for r in ok if r["tangential_velocity_in_m_s"] > 0]
    if obl:
        x = np.array([r["tangential_velocity_in_m_s"] / r["normal_velocity_in_m_s"] for r in obl])
        x = x / mu if mu > 0 else x
        ax.plot(x, [r["restitution_tangential"] for r in obl], "o", label="millimpact")
        if mu > 0:
            # Maw-Barber-Fawcett rigid-body bounds: gross sliding e_t = 1 - 3.5 mu (1 + e_n) / tan(a)
            xs = np.linspace(max(x.min(), 1e-3), x.max(), 100)
            en = float(np.nanmean([r["restitution_normal"] for r in obl]))
            ax.plot(xs, 1.0 - 3.5 * (1.0 + en) / xs, "k--", lw=1, label="gross sliding, rigid (MBF)")
    ax.set_xlabel("tan(angle) / mu" if mu > 0 else "tan(angle) (frictionless)")
    ax.set_ylabel("tangential restitution e_t")
    ax.set_title(f"contact table {base.name}: tangential restitution (mu = {mu:g})")
    ax.grid(alpha=0.3)
    if obl:
        ax.legend(fontsize=8)
    else:
        ax.text(0.5, 0.5, "no oblique impacts in this table", transform=ax.transAxes, ha="center")
    fig.savefig(out / "e_t_angle.png", dpi=130)
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(7, 4.5), constrained_layout=True)
    vn = np.array([r["normal_velocity_in_m_s"] for r in ok])
    ax.plot(vn, [r["peak_normal_force_N"] / 1e3 for r in ok], "o", label="millimpact")
    order = np.argsort(vn)
    ax.plot(
        vn[order], np.array([r["hertz_peak_force_N"] for r in ok])[order] / 1e3, "k--", lw=1, label="Hertz, F ~ v^(6/5)"
    )
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("normal impact speed [m/s]")
    ax.set_ylabel("peak normal force [kN]")
    ax.set_title(f"contact table {base.name}: peak force")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    fig.savefig(out / "force_speed.png", dpi=130)
    plt.close(fig)


def percent(x: float) -> str:
    """A relative error as a percentage, 3 digits."""
    return f"{100.0 * x:.3g} %"


def largest_errors_text(summary: dict[str, Any]) -> str:
    """The largest checked errors, e.g. ``e_n 0.0041, e_t 0.0012, F_max 1.3 %``."""
    w = summary["largest_checked_error"]
    return (
        f"e_n {w['restitution_normal']:.3g}, e_t {w['restitution_tangential']:.3g}, "
        f"F_max {percent(w['peak_normal_force_rel'])}"
    )


def summary_line(summary: dict[str, Any]) -> str:
    """One line: the grid, the checks and the largest checked errors against the tolerance."""
    return (
        f"{len(summary['speeds_m_s'])} speeds x {len(summary['angles_deg'])} angles + {summary['checks']} checks = "
        f"{summary['cases']} cases; largest checked error {largest_errors_text(summary)} (tolerance "
        f"{summary['tolerance']:g}, F_max {percent(summary['tolerance_peak_force_rel'])}): "
        + ("reached" if summary["reached"] else f"NOT reached within {summary['max_cases']} cases")
    )
