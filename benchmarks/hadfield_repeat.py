"""Hadfield steel under repeated impacts: 50 impacts of a 125 mm ball at 6 m/s at one spot on the
manganese liner steel as a Voce law, its surface hardness per impact against the work-hardened
surface the field measures.

Scene ``mill-hadfield`` (a 125 mm forged 60 HRC ball on a 75 mm plate clamped at its back) with
``block.material = hadfield-mn-liner-voce`` (Y 380 MPa, Q 1.42 GPa, b 2.5: saturating at 1.8 GPa,
scene/materials.toml) at 6 m/s, method ``improved``, the plan's mesh; the block's zone at 33 mm
(``--zone``), the most a 75 mm plate allows (0.45 x its thickness), the ball's its own 27.6 mm.
Reported per impact: the hardness 3 sigma_y (HB; Tabor) at the impact point just under the face and
at the largest plastic strain (the law at the sequence's max eps_p), the dent's
depth and diameter (its lateral spread), e_n and the plastic work. Field reference: Hadfield
liners work-harden from ~200 HB to 500-550 HB at the surface in service (the saturation the Voce
law is built on).

    .venv/bin/python benchmarks/hadfield_repeat.py [--impacts 50] [--speed 6] [--zone 0.033]

Writes benchmarks/out/hadfield_repeat/{hadfield.csv, hadfield.md, hardening.png} (and the
sequence's own folder ``sequence/``, which a rerun continues).
"""
from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

from _report import timed_run, write_report  # noqa: E402

from millimpact.fem.hardening import voce_stress  # noqa: E402
from millimpact.repeat.report import read_impacts_csv  # noqa: E402
from millimpact.scene.materials import named_material  # noqa: E402
from millimpact.repeat.sequence import HB_PER_PA  # noqa: E402

#: hadfield-mn-liner-voce's law (Y, Q, b, from scene/materials.toml), its saturation (Y + Q = 1.8 GPa) as
#: a hardness, and the field's work-hardened surface
_STEEL = named_material("hadfield-mn-liner-voce", "block.material")
VOCE = (float(_STEEL["yield_stress"]), *(float(x) for x in _STEEL["voce"]))
SATURATION_HB = (VOCE[0] + VOCE[1]) * HB_PER_PA
FIELD_HB = (500.0, 550.0)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--impacts", type=int, default=50)
    ap.add_argument("--speed", type=float, default=6.0)
    ap.add_argument("--zone", type=float, default=0.033, help="the block's contact-zone radius, m")
    ap.add_argument("--set", action="append", default=[], metavar="FIELD=VALUE")
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "out" / "hadfield_repeat"))
    ap.add_argument("--report-only", action="store_true", help="rewrite the report from the finished sequence")
    a = ap.parse_args()
    out = Path(a.out)
    seq = out / "sequence"
    sets = ["--set", "block.material=hadfield-mn-liner-voce", "--set", f"model.zone_radius={a.zone!r}"]
    for s in a.set:
        sets += ["--set", s]
    cmd = [sys.executable, "-m", "millimpact.cli", "repeat", "mill-hadfield", "--impacts", str(a.impacts),
           "--velocities", repr(a.speed), *sets, "--out", str(seq), "--force"]
    code, wall, rss = (0, math.nan, math.nan) if a.report_only else timed_run(cmd, 1, ROOT)
    if code != 0:
        raise SystemExit(f"millimpact repeat failed (exit {code}): {' '.join(cmd)}")
    outcomes = read_impacts_csv(seq / "impacts.csv")
    summary = json.loads((seq / "summary.json").read_text())
    rows = [{"impact": o.impact, "surface_hardness_HB": o.surface_flow_stress_Pa * HB_PER_PA,
             "peak_hardness_HB": voce_stress(o.max_equivalent_plastic_strain, *VOCE) * HB_PER_PA,
             "surface_flow_stress_Pa": o.surface_flow_stress_Pa, "dent_depth_m": o.residual_dent_depth_m,
             "dent_diameter_m": 2.0 * o.residual_dent_radius_m, "restitution": o.restitution_normal,
             "plastic_work_J": o.plastic_dissipation_J, "max_equivalent_plastic_strain": o.max_equivalent_plastic_strain}
            for o in outcomes]
    boundary = [k for k, d in enumerate(summary["details"], 1) if d.get("zone_boundary_elastic") is False]
    write_report(out, "hadfield", rows, 1,
                 ["impact", "surface HB", "HB at max eps_p", "dent depth (um)", "dent diameter (mm)", "e_n", "plastic work (J)", "max eps_p"],
                 lambda r: [str(r["impact"]), f"{r['surface_hardness_HB']:.0f}", f"{r['peak_hardness_HB']:.0f}",
                            f"{r['dent_depth_m'] * 1e6:.0f}",
                            f"{r['dent_diameter_m'] * 1e3:.2f}", f"{r['restitution']:.3f}",
                            f"{r['plastic_work_J']:.2f}", f"{r['max_equivalent_plastic_strain']:.3f}"],
                 note=f"; mill-hadfield, Voce law, {a.speed:g} m/s, zone {a.zone * 1e3:g} mm; "
                      + ("" if a.report_only else f"{wall:.0f} s, peak RSS {rss:.2f} GB; ")
                      + f"verdict {summary['verdict']['kind']}; zone boundary reached in "
                      f"{len(boundary)} of {len(rows)} impacts")
    plot(rows, out, a.speed)
    return 0


def plot(rows: list[dict], out: Path, speed: float) -> None:
    """Surface hardness and dent diameter against the impact number, with the law's saturation and
    the field's band."""
    from millimpact.results.plots import pyplot

    plt = pyplot()
    k = [r["impact"] for r in rows]
    fig, ax = plt.subplots(figsize=(7, 4.5), constrained_layout=True)
    ax.plot(k, [r["surface_hardness_HB"] for r in rows], "o-", ms=3, color="C2",
            label="3 sigma_y at the impact point (just under the face)")
    ax.plot(k, [r["peak_hardness_HB"] for r in rows], "^-", ms=3, color="C1",
            label="3 sigma_y at the largest plastic strain")
    ax.axhline(SATURATION_HB, color="C2", ls=":", label=f"the Voce law's saturation ({SATURATION_HB:.0f} HB)")
    ax.axhspan(*FIELD_HB, color="0.85", label="work-hardened liners in service (500-550 HB)")
    ax.set_xlabel("impact number")
    ax.set_ylabel("hardness 3 sigma_y (HB)")
    ax.set_ylim(0, 600)
    ax2 = ax.twinx()
    ax2.plot(k, [r["dent_diameter_m"] * 1e3 for r in rows], "s--", ms=3, color="C0", label="dent diameter")
    ax2.set_ylabel("residual dent diameter (mm)", color="C0")
    ax2.set_ylim(bottom=0)
    ax.set_title(f"Hadfield steel (Voce), 125 mm ball at {speed:g} m/s, one spot")
    h1, l1 = ax.get_legend_handles_labels()
    h2, l2 = ax2.get_legend_handles_labels()
    ax.legend(h1 + h2, l1 + l2, fontsize=8, loc="center right")
    ax.grid(alpha=0.3)
    fig.savefig(out / "hardening.png", dpi=130)
    print(f"-> {out}/hadfield.csv, hadfield.md, hardening.png")


if __name__ == "__main__":
    sys.exit(main())
