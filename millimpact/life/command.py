"""``millimpact life SCENE --mill DIR``: wear and metal flow per place, the worn profile through time.

Reads a mill run of the scene's liner (``millimpact mill``: its abrasion.csv and impacts.csv),
gives per surface of a lifter's unit the steel lost per 1000 h by abrasion and by impact
(:mod:`~millimpact.life.wear`) with constants from a calibration (:mod:`~millimpact.life.calibration`),
the metal flow of a damage map beside it (never added to the wear), and moves the profile through
``--cycles`` steps of ``--hours / --cycles`` (:mod:`~millimpact.life.loop`), the mill run again on
each worn profile, until the relining criterion.
"""

from __future__ import annotations

import argparse
import json
import math
import shutil
from pathlib import Path

from ..errors import InputError
from ..results.output_folder import FORCE_HELP, OUT_HELP

HELP = "liner life: wear (mm and kg per 1000 h) and metal flow per place, the worn profile through time"

DESCRIPTION = """\
Wear of SCENE's liner from a mill run of it (--mill DIR, a millimpact mill folder): per surface of
a lifter (trailing face, top, leading face, plate) and along it, the depth (mm) and mass (kg) of
steel lost per 1000 h of operation by abrasion (Archard: k_a int F_n ds / H) and by impact
(k_i E_abs / H), each share reported; the metal flow (dent growth, mm per 1000 h, moved not removed)
from a damage map (--damage DIR) beside it. The constants: --calibration FILE, or calibrate them
here on one measured figure (--calibrate-height H0:H1:HOURS, --calibrate-mass G_PER_KWH; written
to calibration.json). --cycles N moves the profile N times over --hours, running the mill again
on each worn profile, until the lifters' height or the plate's thickness reaches its relining
limit.

Writes DIR/wear.csv, profiles.csv, summary.json, calibration.json, wear.png, profiles.png,
height_angle.png and, for each re-run, mills/cycle-K/, kept as soon as it is complete: an
interrupted life run, run again, continues from its finished re-runs.

  millimpact life liner-panel --mill out/sag --calibrate-height 152:58:4000
  millimpact life liner-panel --mill out/sag --calibration out/life/calibration.json --cycles 4 --hours 4000
"""


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("scene", help="the liner scene the mill run was made of (liner-panel, or a TOML file)")
    p.add_argument("--mill", required=True, metavar="DIR", help="a millimpact mill output folder of this scene")
    p.add_argument("--damage", metavar="DIR", help="a millimpact damage folder: its dent growth as metal flow")
    p.add_argument("--calibration", metavar="FILE", help="the wear constants (a calibration.json)")
    p.add_argument(
        "--calibrate-height", metavar="H0:H1:HOURS", help="calibrate on lifters worn from H0 to H1 mm in HOURS"
    )
    p.add_argument(
        "--calibrate-life",
        metavar="H0:H1:HOURS",
        help="calibrate on lifters worn from H0 to H1 mm in HOURS along this life's own steps (runs to HOURS)",
    )
    p.add_argument("--calibrate-mass", type=float, metavar="G_PER_KWH", help="calibrate on a liner mass rate (g/kWh)")
    p.add_argument(
        "--impact-ratio", type=float, default=1.0, metavar="R", help="k_i / k_a held by a calibration (default 1)"
    )
    p.add_argument(
        "--spread", type=float, metavar="S", help="relative spread of the constants (default the file's, 0.3)"
    )
    p.add_argument(
        "--hours", type=float, metavar="H", help="hours of operation (default 1000; --calibrate-life: its HOURS)"
    )
    p.add_argument("--cycles", type=int, default=1, metavar="N", help="profile steps over --hours (default 1)")
    p.add_argument(
        "--max-step-depth",
        type=float,
        metavar="F",
        help="shorten a step so no bin loses more than F of the lifter's height (0 < F <= 1; default: equal steps; "
        "not with --calibrate-life)",
    )
    p.add_argument(
        "--revolutions", type=float, metavar="R", help="revolutions of each re-run mill (default: the given run's)"
    )
    p.add_argument(
        "--reline-height", type=float, default=50.0, metavar="MM", help="reline at this lifter height (default 50 mm)"
    )
    p.add_argument(
        "--reline-plate", type=float, default=25.0, metavar="MM", help="reline at this plate thickness (default 25 mm)"
    )
    p.add_argument("--set", action="append", metavar="FIELD=VALUE", help="override a scene field")
    p.add_argument("--out", help=OUT_HELP.format(default="out/life-SCENE"))
    p.add_argument("--force", action="store_true", help=FORCE_HELP)
    p.add_argument("--no-plots", action="store_true", help="skip the figures")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress output")


def check_args(args: argparse.Namespace) -> None:
    """One line per bad option (InputError), before anything is read or made; sets ``args.hours``
    when it was not given."""
    from .calibration import parse_height_figure

    life = getattr(args, "calibrate_life", None)
    figure_hours = parse_height_figure(life, "--calibrate-life")[2] if life is not None else None
    if args.hours is None:
        args.hours = 1000.0 if figure_hours is None else figure_hours
    elif figure_hours is not None and args.hours != figure_hours:
        raise InputError(
            f"--hours {args.hours:g}: --calibrate-life runs the life to its figure's {figure_hours:g} h; "
            "for other hours pass its calibration.json with --calibration"
        )
    for name, x, lo, hi in (
        ("--hours", args.hours, 0.0, 1e6),
        ("--impact-ratio", args.impact_ratio, 0.0, 1e6),
        ("--reline-height", args.reline_height, 0.0, 1e4),
        ("--reline-plate", args.reline_plate, 0.0, 1e4),
    ):
        if not (isinstance(x, (int, float)) and math.isfinite(x) and lo <= x <= hi) or (name == "--hours" and x == 0):
            raise InputError(f"{name} {x!r}: must lie in {'(' if name == '--hours' else '['}{lo:g}, {hi:g}]")
    if not 1 <= args.cycles <= 100:
        raise InputError(f"--cycles {args.cycles}: must be an integer in [1, 100]")
    if args.max_step_depth is not None and not (
        math.isfinite(args.max_step_depth) and 0.0 < args.max_step_depth <= 1.0
    ):
        raise InputError(f"--max-step-depth {args.max_step_depth!r}: must lie in (0, 1]")
    if args.max_step_depth is not None and life is not None:
        raise InputError(
            f"--max-step-depth {args.max_step_depth:g}: not with --calibrate-life, whose steps are --cycles equal "
            "falls of the lifters' height"
        )
    if args.spread is not None and not (math.isfinite(args.spread) and 0.0 <= args.spread < 1.0):
        raise InputError(f"--spread {args.spread!r}: must lie in [0, 1)")
    given = [
        o
        for o, v in (
            ("--calibration", args.calibration),
            ("--calibrate-height", args.calibrate_height),
            ("--calibrate-life", life),
            ("--calibrate-mass", args.calibrate_mass),
        )
        if v is not None
    ]
    if len(given) > 1:
        raise InputError(f"{' and '.join(given)}: give one of them (a calibration file, or one figure to calibrate on)")
    if args.calibrate_height is not None:
        parse_height_figure(args.calibrate_height)
    if args.calibrate_mass is not None and not (math.isfinite(args.calibrate_mass) and args.calibrate_mass > 0):
        raise InputError(f"--calibrate-mass {args.calibrate_mass!r}: must be a number > 0 (g/kWh)")
    if args.revolutions is not None and not (math.isfinite(args.revolutions) and 0 < args.revolutions <= 1000):
        raise InputError(f"--revolutions {args.revolutions!r}: must lie in (0, 1000]")


def calibrate(args, rec, steel: dict):
    """The calibration the command uses: the file (refused when made on another steel than the
    scene's liner ``steel``, :func:`~millimpact.life.calibration.liner_steel`), the default, or one
    fitted on a figure."""
    from .calibration import DEFAULT_LAW, DEFAULT_SPREAD, Calibration, initial_height_rate, parse_height_figure, scaled
    from .wear import depth_rates, place_rates

    if args.calibration is not None:
        from .calibration import check_same_steel, read_calibration

        cal = read_calibration(args.calibration)
        check_same_steel(cal, steel, args.calibration)
        return cal if args.spread is None else Calibration(cal.law, cal.calibrated_on, args.spread)
    spread = DEFAULT_SPREAD if args.spread is None else args.spread
    law = scaled(DEFAULT_LAW, 1.0, args.impact_ratio)
    rates = place_rates(rec, depth_rates(rec, law))
    on = {"mill": str(rec.folder), "impact_ratio": args.impact_ratio, "liner_steel": steel}
    life = getattr(args, "calibrate_life", None)
    if args.calibrate_height is not None or life is not None:
        # --calibrate-life starts here and is finished on the life's steps (calibration.through_life)
        option, figure = (
            ("--calibrate-life", life) if life is not None else ("--calibrate-height", args.calibrate_height)
        )
        h0, h1, hours = parse_height_figure(figure, option)
        target = initial_height_rate(h0, h1, hours)
        model = rates["top"]["mean_mm_per_1000h"] - rates["plate"]["mean_mm_per_1000h"]
        what = "lifter height loss of the new lifter (first-order decay), mm per 1000 h"
        on.update(figure=f"lifters {h0:g} -> {h1:g} mm in {hours:g} h", target=target, what=what)
        if life is not None:
            on.update(h1_mm=h1, option="--calibrate-life")
    elif args.calibrate_mass is not None:
        power = rec.summary["power"]["measured"]["net_per_metre_W_m"]
        mass = sum(r["mass_kg_per_1000h_per_metre"] for r in rates.values())  # kg per 1000 h per metre
        model = 1e3 * mass / (power / 1e3 * 1000.0)  # g per kWh: kg per 1000 h over kWh per 1000 h
        target = args.calibrate_mass
        on.update(figure=f"{target:g} g/kWh", target=target, what="liner mass per kWh of net power, g/kWh")
    else:
        return Calibration(law, {"uncalibrated": "order-of-magnitude constants (docs: liner life)"}, spread)
    if not model > 0:
        raise InputError(f"--mill {rec.folder}: the run wears nothing where the figure was measured; cannot calibrate")
    cal = Calibration(scaled(DEFAULT_LAW, target / model, args.impact_ratio), on, spread)
    return cal


#: the stages of summary.json's wall_time_s, in the words of the last line
STAGE_WORDS = {
    "mill_reruns": "mill re-runs (DEM)",
    "wear_and_profile": "wear and profile update",
    "read": "reading mill runs",
    "report": "outputs",
}


def main(args: argparse.Namespace) -> int:
    from ..commandkit.settings import command_scene
    from ..commandkit.timing import StageClock, time_line
    from ..console import sayer
    from ..results.output_folder import claim_output, default_out
    from ..results.timeseries import write_summary
    from .profile import LifterProfile
    from .report import life_summary, write_life_outputs
    from .wear import read_mill_record

    clock = StageClock()
    check_args(args)
    scene = command_scene(args.scene, args.set)
    if scene.liner is None or not scene.liner.mill_radius > 0:
        raise InputError(f"scene {args.scene}: needs a liner on a curved shell (liner-segment, liner-panel)")
    say = sayer(args.quiet)
    lp = LifterProfile.from_liner(scene.liner)
    for name, limit, new in (
        ("--reline-height", args.reline_height, lp.height_above_plate),
        ("--reline-plate", args.reline_plate, lp.plate_left),
    ):
        if limit >= 1e3 * new:
            raise InputError(f"{name} {limit:g} mm: must be below the new liner's {1e3 * new:g} mm")
    r = scene.ball.radius
    with clock.stage("read"):
        rec = read_mill_record(args.mill, lp.mill_profile(r))
    if rec.n_lifters != lp.n_lifters:
        raise InputError(f"--mill {args.mill}: a mill of {rec.n_lifters} lifters, not this scene's {lp.n_lifters}")
    from .calibration import liner_steel

    cal = calibrate(args, rec, liner_steel(scene.liner.material))
    if args.cycles > 1 and "options" not in rec.summary:
        raise InputError(f"--mill {args.mill}: its summary.json has no options to run the mill again with (--cycles 1)")
    out = args.out if args.out is not None else default_out(Path(args.scene).stem, prefix="life-")
    target = claim_output(out, "life", force=args.force)
    runner, made = None, list[str]()
    if args.cycles > 1:
        mills = target.open(["mills"], note=lambda: kept_mills_note(target)) / "mills"
        runner = _mill_runner(scene, rec, mills, args, say, made)
    with target.staged(keep=["mills"] if runner is not None else [], collective=False) as stage:
        summary, cal = life_summary(args, scene, lp, rec, cal, runner, say, clock)
        if runner is not None:
            for old in mills.glob("cycle-*"):
                if old.name not in made:  # an earlier life's re-run that this one did not reach
                    shutil.rmtree(old)
        with clock.stage("report"):
            write_life_outputs(stage, summary, rec, cal, plots=not args.no_plots)
            (stage / "calibration.json").write_text(cal.to_json() + "\n")
            summary.update(wall_times(clock))
            write_summary(stage, summary)
    first = summary["relining"]
    say(
        f"life: {summary['rates'][0]['top']['mean_mm_per_1000h']:.3g} mm per 1000 h off the lifters' tops, "
        f"{summary['rates'][0]['leading_face']['mean_mm_per_1000h']:.3g} off their leading faces, "
        f"{summary['rates'][0]['plate']['mean_mm_per_1000h']:.3g} off the plate; relining after "
        f"{first['hours']:.0f} h ({first['criterion']})"
    )
    say(time_line(summary["wall_time_s"], STAGE_WORDS))
    say(f"results in {target.shown}/" + target.replaced_note())
    return 0


def wall_times(clock) -> dict:
    """summary.json's wall times (s): per stage of the command, and per cycle."""
    return {
        "wall_time_s": clock.record(),
        "wall_time_s_per_cycle": {k: list(clock.laps.get(k, [])) for k in ("wear_and_profile", "mill_reruns")},
        "wall_time_is": "this command's wall seconds: reading the mill runs (read), the wear and profile update "
        "(wear_and_profile), the mill re-run on each worn profile (mill_reruns, DEM), the outputs and figures "
        "(report), the rest (other: the scene, the calibration, ...) and the whole (total)",
    }


def kept_mills_note(target) -> str:
    """What an interrupted life run leaves: its finished mill re-runs, reused by a rerun."""
    from ..commandkit.store import kept_note

    n = len(list((target.path / "mills").glob("cycle-*/summary.json")))
    return kept_note([(n, "mill re-run", f"{target.shown}/mills/")], "the life itself is not written")


def _mill_runner(scene, rec, mills: Path, args, say, made: list[str]):
    """run(profile, cycle) -> the folder of a mill run on that worn profile (the first run's options).

    Each re-run is kept as ``mills/cycle-K/`` with the key of what decides it (the scene, the mill's
    options, the worn profile, the version; :func:`~millimpact.commandkit.store.piece_key`) in its
    summary.json, written last: a rerun of an interrupted life takes a cycle whose key matches
    (the steps before it are the same, so its profile is) and runs the others again. A run is
    made in a hidden ``.cycle-K.partial`` folder and renamed when complete. ``made`` gets each
    cycle's folder name.
    """
    from dataclasses import asdict, replace

    from .. import __version__
    from ..commandkit.store import piece_key
    from ..dem.mill.run import run_mill
    from ..dem.mill.setup import MillOptions, plan_mill
    from ..scene.toml_io import dump_scene

    opts = MillOptions(**rec.summary["options"])
    if args.revolutions is not None:
        opts = replace(opts, revolutions=args.revolutions)

    def run(lp, cycle: int) -> Path:
        folder = mills / f"cycle-{cycle}"
        made.append(folder.name)
        # the profile to a nanometre (a nano-degree): a step's profile found by a search for its hours
        # differs at round-off with the constants' scale, which does not change the run
        profile = {k: round(v, 9) if isinstance(v, float) else v for k, v in asdict(lp).items()}
        key = piece_key(
            {"scene": dump_scene(scene), "options": asdict(opts), "profile": profile, "version": __version__}
        )
        try:
            if json.loads((folder / "summary.json").read_text()).get("life_key") == key:
                say(f"  life: cycle {cycle}: the mill run on this profile kept in {folder} from an earlier run")
                return folder
        except (OSError, ValueError):
            pass
        partial = mills / f".cycle-{cycle}.partial"
        for old in (folder, partial):  # this command's own: another profile's run, or an interrupted one
            shutil.rmtree(old, ignore_errors=True)
        partial.mkdir(parents=True)
        setup = plan_mill(scene, opts, profile=lp.mill_profile(scene.ball.radius))
        summary = run_mill(scene, opts, partial, plots=False, setup=setup, quiet=args.quiet)
        summary["life_key"] = key
        (partial / "summary.json").write_text(json.dumps(summary, default=str, indent=1) + "\n")
        partial.rename(folder)
        return folder

    return run
