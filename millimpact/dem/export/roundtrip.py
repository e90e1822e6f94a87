"""``millimpact export --check``: the exported law run in Yade, one ball per table point.

Yade (:func:`millimpact.dem.yade.run_yade`) runs ``yade_scripts/roundtrip.py``: a ball of the
table's radius and density strikes a wall at each table speed and angle, with the exported law
file (``law`` mode) or a naive constant input (``naive`` mode: ``Ip2(en = mean table e_n)``, the
materials' Young's modulus and Yade's default NewtonIntegrator, the plain set-up). The
time step is t_c / 2000 of the point's Hertz-dashpot contact (dimensionless duration ~3.2
delta_0 / v_n): halving it changes e_n by < 1e-5 (yade_drop at 1e-8 and 2.5e-9 s).
``roundtrip.csv`` puts millimpact's and Yade's e_n, e_t and F_max side by side; ``roundtrip.png``
plots them.
"""

from __future__ import annotations

import csv
import json
import math
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from ..yade import run_yade
from .files import JSON_NAMES, ExportedLaw, law_data
from .table_input import ContactTable

SCRIPT = Path(__file__).with_name("yade_scripts") / "roundtrip.py"
#: time steps per contact duration
STEPS_PER_CONTACT = 2000
#: the columns of roundtrip.csv (docs/dem.md)
COLUMNS = (
    "impact_speed_m_s",
    "impact_angle_deg",
    "restitution_normal_table",
    "restitution_normal_dem",
    "restitution_tangential_table",
    "restitution_tangential_dem",
    "peak_normal_force_N_table",
    "peak_normal_force_N_dem",
)


def _cases(t: ContactTable, e_star: np.ndarray) -> list[dict]:
    out = []
    for i, s in enumerate(t.speeds):
        for j, a in enumerate(t.angles):
            k_no = 4.0 / 3.0 * float(e_star[i, j]) * math.sqrt(t.radius)
            vn = float(t.normal_speed[i, j])
            t_c = 3.2 * (t.ball_mass * vn**2 / k_no) ** 0.4 / vn
            out.append(
                {
                    "speed_m_s": float(s),
                    "angle_deg": float(a),
                    "dt_s": t_c / STEPS_PER_CONTACT,
                    "max_steps": 6 * STEPS_PER_CONTACT,
                }
            )
    return out


def constant_law_file(law: ExportedLaw, path: Path) -> Path:
    """A Yade law file with the constant law (what LIGGGHTS and LAMMPS get) on a 1 x 1 grid."""
    from .files import RUNTIME

    data = law_data(law)
    data.update(speeds_m_s=[1.0], angles_deg=[0.0], zeta=[[law.zeta_const]], e_star_Pa=[[law.e_star_const]])
    path.write_text(JSON_NAMES + "MILLIMPACT_LAW = " + json.dumps(data) + "\n\n" + RUNTIME.read_text())
    return path


def run_roundtrip(
    law: ExportedLaw,
    workdir: Path,
    mode: str = "law",
    law_file: Path | None = None,
    timeout: float = 1800,
    on_progress: Callable[[str], None] | None = None,
) -> list[dict]:
    """Yade's e_n, e_t, F_max at every table point (``mode``: law | naive); rows in grid order."""
    t = law.table
    workdir.mkdir(parents=True, exist_ok=True)
    results_file = workdir / f"yade_{mode}.json"
    inp = {
        "mode": mode,
        "radius_m": t.radius,
        "density_kg_m3": t.ball_density,
        "results_file": str(results_file),
        "law_file": str(law_file) if law_file else None,
        "naive": {
            "en": float(np.mean(np.minimum(t.e_n, 0.999))),
            "young_Pa": t.youngs_modulus,
            "poisson": t.poisson,
            "friction": t.friction,
        },
        "cases": _cases(t, law.e_star if mode == "law" else np.full(t.e_n.shape, t.e_star_materials)),
    }
    path = workdir / f"yade_{mode}_input.json"
    path.write_text(json.dumps(inp, indent=1))
    run_yade(SCRIPT, workdir, [path.name], timeout=timeout, on_progress=on_progress)
    return json.loads(results_file.read_text())["results"]


def roundtrip_rows(t: ContactTable, results: Sequence[dict]) -> list[dict]:
    """The rows of roundtrip.csv (COLUMNS), table against Yade."""
    rows = []
    k = 0
    for i, s in enumerate(t.speeds):
        for j, a in enumerate(t.angles):
            r = results[k]
            k += 1
            rows.append(
                dict(
                    zip(
                        COLUMNS,
                        (
                            float(s),
                            float(a),
                            float(t.e_n[i, j]),
                            r["restitution_normal"],
                            float(t.e_t[i, j]),
                            r["restitution_tangential"],
                            float(t.peak_force[i, j]),
                            r["peak_normal_force_N"],
                        ),
                    )
                )
            )
    return rows


def write_roundtrip(
    folder: Path, t: ContactTable, rows: Sequence[dict], code: str, runner: str = "Yade", stem: str = "roundtrip"
) -> None:
    """STEM.csv (a # header naming the table, the law and the code that ran it) and STEM.png."""
    with open(folder / f"{stem}.csv", "w", newline="") as fh:
        fh.write(
            f"# millimpact export --check: the {code} law exported from {t.folder.resolve()} (scene "
            f"{t.scene_name}, method {t.method}) run in {runner}, one ball on a wall per table point\n"
        )
        fh.write(f"# _table: millimpact's contact table; _dem: {runner}. e_t NaN at normal incidence. SI units\n")
        w = csv.writer(fh)
        w.writerow(COLUMNS)
        for r in rows:
            w.writerow([repr(float(r[c])) for c in COLUMNS])
    plot_roundtrip(folder / f"{stem}.png", t, rows, code, runner)


def plot_roundtrip(path: Path, t: ContactTable, rows: Sequence[dict], code: str, runner: str = "Yade") -> None:
    from ...results.plots import pyplot

    plt = pyplot()
    fig, axes = plt.subplots(1, 3, figsize=(13, 4.2), constrained_layout=True)
    for j, a in enumerate(t.angles):
        rr = [r for r in rows if r["impact_angle_deg"] == a]
        v = [r["impact_speed_m_s"] for r in rr]
        c = f"C{j % 10}"
        for ax, key, scale in (
            (axes[0], "restitution_normal", 1.0),
            (axes[1], "restitution_tangential", 1.0),
            (axes[2], "peak_normal_force_N", 1e-3),
        ):
            tab = [
                r[f"{key}_table" if key != "peak_normal_force_N" else "peak_normal_force_N_table"] * scale for r in rr
            ]
            dem = [r[f"{key}_dem" if key != "peak_normal_force_N" else "peak_normal_force_N_dem"] * scale for r in rr]
            ax.plot(v, tab, "o-", color=c, label=f"millimpact, {a:g} deg")
            ax.plot(v, dem, "x--", color=c, ms=9, label=f"{runner}, {a:g} deg")
    for ax, lab in zip(axes, ("normal restitution e_n", "tangential restitution e_t", "peak normal force (kN)")):
        ax.set_xlabel("impact speed (m/s)")
        ax.set_ylabel(lab)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=7)
    fig.suptitle(f"{code} law from the table of {t.scene_name} ({t.method}): millimpact (o) against {runner} (x)")
    fig.savefig(path, dpi=130)
    plt.close(fig)
