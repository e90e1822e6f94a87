"""One mill run: the plan's input to Yade, Yade's files read, the outputs written and the summary.

:func:`run_mill` writes ``yade/`` (the script ``yade_scripts/mill_slice.py``, its input and raw
output), ``impacts.csv``, ``spectrum.csv``, ``impacts_per_revolution.csv`` (per kind and place),
``abrasion.csv`` (:mod:`~millimpact.dem.mill.abrasion`) and the figures into a staged folder and
returns ``summary.json``'s content; ``millimpact mill`` (:mod:`~millimpact.dem.mill.command`) and
``millimpact life`` (its re-runs on a worn profile) call it.
"""

from __future__ import annotations

import dataclasses
import json
import shutil
import sys
from pathlib import Path

#: the Yade script (millimpact/dem/mill/yade_scripts/)
SCRIPT = Path(__file__).resolve().parent / "yade_scripts" / "mill_slice.py"


class _Progress:
    """Prints the Yade run's PROGRESS lines, one every 5 % (every 1 % on a terminal, in place)."""

    def __init__(self) -> None:
        self.tty = sys.stderr.isatty()
        self.shown = -1

    def __call__(self, line: str) -> None:
        words = line.split()
        try:
            frac = float(words[0])
        except (IndexError, ValueError):
            return
        step = 1 if self.tty else 5
        pct = int(100 * frac)
        if pct // step == self.shown // step and pct < 100:
            return
        self.shown = pct
        text = f"  DEM {pct:3d} % " + " ".join(words[1:])
        if self.tty:
            print("\r" + text, end="\n" if pct >= 100 else "", file=sys.stderr, flush=True)
        else:
            print(text, file=sys.stderr, flush=True)


def _contact_summary(setup) -> dict:
    if setup.law is None:
        return {
            "law": "Yade Hertz-Mindlin (Law2_ScGeom_MindlinPhys_Mindlin)",
            "restitution": setup.restitution,
            "restitution_source": setup.restitution_source,
            "friction": setup.friction,
            "stiffness_scale": setup.stiffness_scale,
        }
    lo, hi = setup.law.restitution_range
    return {
        "law": f"exported by millimpact export (Hertz-dashpot, betan per contact): {setup.law.folder}",
        "source_table": setup.law.data.get("source_table"),
        "restitution_normal_range": [lo, hi],
        "restitution_source": setup.restitution_source,
        "friction": setup.friction,
        "stiffness_scale": setup.stiffness_scale,
        "law_update_every_steps": setup.law_every,
    }


def run_mill(
    scene, opts, stage: Path, plots: bool = True, setup=None, timeout=None, quiet: bool = False, threads=None
) -> dict:
    """Plan, run and report one mill run into the folder ``stage``; returns the summary."""
    from ..yade import run_yade
    from .log import read_mill_run
    from .power import charge_shape_report, power_report
    from .report import charge_angles, charge_figure, energy_balance, plot_spectrum
    from .setup import plan_mill

    if setup is None:
        setup = plan_mill(scene, opts)
    work = stage / "yade"
    work.mkdir()
    shutil.copy(SCRIPT, work / SCRIPT.name)
    if setup.law is not None:
        shutil.copy(setup.law.script, work / setup.law.script.name)
    (work / "input.json").write_text(json.dumps(setup.yade_input()) + "\n")
    progress = None if quiet else _Progress()
    run_yade(work / SCRIPT.name, work, ["input.json"], timeout=timeout, on_progress=progress, threads=threads)
    run = read_mill_run(work, setup)
    revs = setup.revolutions
    tables = _write_tables(stage, run, setup)
    angles = charge_angles(run.snapshots, setup)
    # a scene naming its mill's length (liner.mill_length, m) gets the whole mill's power; the
    # built-in liners give the mill's radius only, and the power is reported per metre
    power = power_report(setup, run.energy, mill_length=getattr(scene.liner, "mill_length", None))
    if plots:
        particles = f"{setup.n_balls} balls" + (f", {setup.n_rocks} rocks" if setup.n_rocks else "")
        title = f"{setup.scene_name}: {particles}, {100 * setup.speed_fraction:.0f} % of n_c, {revs:g} revolutions"
        plot_spectrum(stage / "spectrum.png", run.impacts, revs, title)
        charge_figure(stage / "charge.png", run.snapshots, setup, angles)
    balls = tables["ball"]
    summary = {
        "scene": setup.scene_name,
        "options": dataclasses.asdict(opts),
        "mill": _mill_summary(setup),
        "charge": _charge_summary(setup, run.info),
        "contact": _contact_summary(setup),
        "clock": {
            "dt_s": setup.dt,
            "contact_time_s": setup.contact_time_s,
            "v_max_m_s": setup.v_max,
            "check_every_steps": setup.check_every,
            "warmup_revolutions": setup.warmup_s / setup.period_s,
            "revolutions": revs,
            "period_s": setup.period_s,
        },
        "impacts_per_revolution": {row["place"]: row["impacts_per_revolution"] for row in balls},
        "energy_per_revolution_J": {row["place"]: row["energy_per_revolution_J"] for row in balls},
        "impacts_are": "the balls' impacts on the liner (rock impacts: rock_impacts)",
        "shoulder_deg": angles["shoulder_deg"],
        "toe_deg": angles["toe_deg"],
        "angles_measured": "from the vertical below the axis, positive in the direction of rotation",
        "centrifuged_fraction": angles["centrifuged_fraction"],
        "energy_balance": energy_balance(run.energy),
        "power": power,
        "charge_shape": charge_shape_report(setup, angles),
        "abrasion": tables["abrasion"],
        "yade": run.info,
        "impacts_time_origin": "the end of the warm-up",
    }
    if setup.n_rocks:
        summary["rock_impacts"] = {
            "impacts_per_revolution": {row["place"]: row["impacts_per_revolution"] for row in tables["rock"]},
            "energy_per_revolution_J": {row["place"]: row["energy_per_revolution_J"] for row in tables["rock"]},
        }
    return summary


def _write_tables(stage: Path, run, setup) -> dict:
    """impacts.csv, spectrum.csv, impacts_per_revolution.csv (per kind and place) and abrasion.csv;
    returns the per-kind place tables and the abrasion summary."""
    from ..impacts import write_impacts
    from .abrasion import abrasion_rows, abrasion_summary, write_abrasion
    from .report import place_table, write_spectrum_csv

    revs = setup.revolutions
    write_impacts(stage / "impacts.csv", run.impacts)
    write_spectrum_csv(stage / "spectrum.csv", run.impacts, revs)
    kinds = ("ball", "rock") if setup.n_rocks else ("ball",)
    tables: dict = {kind: place_table(run.impacts, revs, kind) for kind in kinds}
    with open(stage / "impacts_per_revolution.csv", "w") as fh:
        cols = list(tables["ball"][0])
        fh.write(",".join(["kind", *cols]) + "\n")
        for kind in kinds:
            for row in tables[kind]:
                fh.write(",".join([kind, *(row[c] if c == "place" else repr(float(row[c])) for c in cols)]) + "\n")
    rows = abrasion_rows(run.abrasion, setup)
    write_abrasion(stage / "abrasion.csv", rows)
    tables["abrasion"] = abrasion_summary(rows)
    return tables


def _mill_summary(setup) -> dict:
    p = setup.profile
    return {
        "unit_surfaces_m": p.unit_surfaces(),
        "unit_is": "a lifter's unit along the profile: trailing face, top, leading face, plate (m from its trailing foot)",
        "diameter_m": p.diameter,
        "lifters": p.n_lifters,
        "lifter_height_m": p.lifter_height,
        "slice_thickness_m": setup.thickness,
        "critical_speed_rpm": setup.critical_rpm,
        "speed_fraction": setup.speed_fraction,
        "speed_rpm": setup.speed_fraction * setup.critical_rpm,
    }


def _charge_summary(setup, info: dict) -> dict:
    """summary.json's "charge": the particles, the fills, the rock and, for a SAG charge, the share
    of the balls' new contacts that land on rock."""
    out: dict = {
        "balls": setup.n_balls,
        "ball_radius_m": setup.ball_radius,
        "fill": setup.fill,
        "charge_is": "balls alone (no rock, no slurry)",
    }
    if not setup.n_rocks:
        return out
    n = {k: v["at_1_m_s_or_more"] for k, v in info.get("particle_contacts_after_warmup", {}).items()}
    bb, br = n.get("ball-ball", 0), n.get("ball-rock", 0)
    mine = 2 * bb + br  # a ball-ball contact is a contact of two balls
    rev = setup.revolutions
    out.update(
        charge_is="balls and rock (SAG), no slurry",
        rocks=setup.n_rocks,
        ball_fill=setup.ball_fill,
        rock=setup.rock.summary(),
        rock_radius_range_m=[min(setup.rock_radii), max(setup.rock_radii)],
        particle_contacts_per_revolution={k: v / rev for k, v in n.items()},
        particle_contacts_are="new contacts after the warm-up approaching at 1 m/s or more along their normal",
        ball_contacts_on_rock_share=br / mine if mine else None,
    )
    return out
