"""``millimpact damage``: the liner's damage map from a mill's impact log (impacts.csv).

Reads the impacts (:func:`millimpact.dem.impacts.read_impacts`), bins them by place, arc position,
normal speed and angle (:mod:`millimpact.damage.bins`), computes each bin's impact with the table engine on the
liner scene with its impact moved to the bin's place, and the repeated-impact response of each
place's dominant bin, and writes per place and revolution the energy absorbed, the plastic work,
the dent growth and the plastic strain's trend (:mod:`millimpact.damage.damage_map`). Finished bins and sequences
are kept in DIR/cases and DIR/repeat: an interrupted map continues where it stopped.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

from ..errors import InputError
from ..results.output_folder import FORCE_HELP, OUT_HELP
from .adaptive_bins import BINS_FROM, DEFAULT_BINS_FROM

HELP = "the liner's damage map: energy, plastic work and dent growth per place and revolution"

DESCRIPTION = """\
Bin the impacts of a mill's DEM log (impacts.csv: millimpact mill) by place (lifter face, lifter top,
plate, position along the arc), normal speed and angle; compute each bin's impact with the table
engine on SCENE (a liner scene) with the impact moved to the bin's place, and the repeated-impact
response of each place's dominant bin; write per place and per revolution the energy absorbed, the
plastic work, the dent growth (shakedown or ratcheting, impacts to shakedown) and the trend of the
largest plastic strain: damage.csv, bins.csv, profile.csv, damage.json, damage_map.png.
Speed bins keep Thornton's restitution within --restitution-tolerance across each bin, with the
yield-onset speed V_y as an edge (bins below it add no plastic work); at most --max-bins bins.
With --bins-from adaptive, a placed scene's bins are read from the adaptive table engine's cases
where they need fewer cases than the bins, within --restitution-tolerance (damage.json's
bins_from says where and the largest checked error); else, and by default, each bin is one case.
Finished bins are kept in DIR/cases and DIR/repeat: a rerun continues an interrupted map.
The model stops at small strain (plastic strain ~0.1), removes no material (no wear) and has no
fatigue cracking.

Examples:
  millimpact damage liner-segment --impacts out/mill/impacts.csv --revolutions 2 --out out/damage
  mpirun -n 2 millimpact damage liner-segment --impacts impacts.csv --revolutions 2 --ranks-per-case 1
"""


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("scene", help="a liner scene: built-in name (liner-segment, liner-panel) or TOML file")
    p.add_argument("--impacts", required=True, metavar="CSV", help="the impact log (impacts.csv of millimpact mill)")
    p.add_argument("--out", help=OUT_HELP.format(default="out/damage-SCENE") + "; finished bins in it are reused")
    p.add_argument(
        "--revolutions",
        type=float,
        metavar="N",
        help="mill revolutions the log covers (default: those of the millimpact mill summary.json beside the log)",
    )
    p.add_argument(
        "--lifters",
        type=int,
        metavar="N",
        help="lifters the log's impacts are folded from (rates per lifter; default: the mill's, from the "
        "summary.json beside the log, else 1: the whole log)",
    )
    p.add_argument(
        "--slice-length",
        type=float,
        metavar="M",
        help="axial length of the DEM slice, m (spreads a place's impacts; default the liner's length)",
    )
    p.add_argument("--max-bins", type=int, default=30, metavar="N", help="at most this many bins (default 30)")
    p.add_argument(
        "--restitution-tolerance",
        type=float,
        default=0.02,
        metavar="DE",
        help="largest spread of Thornton's restitution across a speed bin (default 0.02)",
    )
    p.add_argument(
        "--bins-from",
        choices=BINS_FROM,
        default=DEFAULT_BINS_FROM,
        help="the bins' responses: adaptive (a placed scene's bins interpolated from the adaptive table "
        "engine's cases where they need fewer cases than the bins, within --restitution-tolerance; else one "
        f"case per bin) or cases (one case per bin); default {DEFAULT_BINS_FROM}",
    )
    p.add_argument("--angle-bins", type=int, default=2, metavar="N", help="angle bins per place (default 2)")
    p.add_argument(
        "--arc-bins",
        type=int,
        default=1,
        metavar="N",
        help="arc-position bins per place, each its own placed scene (default 1)",
    )
    p.add_argument(
        "--cell", type=float, default=0.01, metavar="M", help="width of the profile's arc cells, m (default 0.01)"
    )
    p.add_argument(
        "--repeat-impacts",
        type=int,
        default=6,
        metavar="N",
        help="impacts of each place's repeated-impact sequence (default 6; 0: none)",
    )
    p.add_argument("--method", default="improved", help="solution method of the bins (default improved)")
    p.add_argument("--set", action="append", default=[], metavar="FIELD=VALUE", help="override a scene field")
    p.add_argument("--option", action="append", default=[], metavar="KEY=VALUE", help="a method option")
    p.add_argument(
        "--ranks-per-case",
        type=int,
        default=1,
        metavar="K",
        help="under mpirun: ranks per bin (divides the rank count; default 1)",
    )
    p.add_argument("--force", action="store_true", help=FORCE_HELP)
    p.add_argument("-q", "--quiet", action="store_true", help="no progress output")


def mill_summary(impacts_path: Path) -> dict:
    """The summary.json that ``millimpact mill`` wrote beside the log ({} if there is none or it is unreadable)."""
    try:
        summary = json.loads((impacts_path.parent / "summary.json").read_text())
    except (OSError, ValueError):
        return {}
    return summary if isinstance(summary, dict) else {}


def revolutions_of(args: argparse.Namespace, impacts_path: Path) -> float:
    """--revolutions, else the logged revolutions of the mill's summary.json beside the log (``clock.revolutions``;
    a top-level ``revolutions`` also counts); InputError if neither."""
    rev = args.revolutions
    if rev is None:
        summary = mill_summary(impacts_path)
        try:
            rev = float(summary["revolutions"] if "revolutions" in summary else summary["clock"]["revolutions"])
        except (KeyError, ValueError, TypeError):
            raise InputError(
                f"--revolutions: give the number of mill revolutions {impacts_path} covers (no "
                f"revolutions in {impacts_path.parent / 'summary.json'})"
            ) from None
    if not (math.isfinite(rev) and rev > 0):
        raise InputError(f"--revolutions {rev:g}: must be > 0")
    return rev


def lifters_of(args: argparse.Namespace, impacts_path: Path) -> int:
    """--lifters, else the mill's lifter count from its summary.json beside the log (``mill.lifters``), else 1."""
    if args.lifters is not None:
        return args.lifters
    try:
        return max(1, int(mill_summary(impacts_path)["mill"]["lifters"]))
    except (KeyError, ValueError, TypeError):
        return 1


def check_log_liner(scene, impacts_path: Path) -> None:
    """One line when the mill's summary.json beside the log names a mill other than the scene's
    liner (its diameter, lifter count or lifter height): the log's places and arc positions belong
    to that mill's liner. Nothing to check without a summary."""
    mill = mill_summary(impacts_path).get("mill")
    if not isinstance(mill, dict):
        return
    from ..dem.mill.geometry import build_profile

    mine = build_profile(scene.liner, scene.ball.radius)
    try:
        theirs = (float(mill["diameter_m"]), int(mill["lifters"]), float(mill["lifter_height_m"]))
    except (KeyError, TypeError, ValueError):
        return
    ours = (mine.diameter, mine.n_lifters, mine.lifter_height)
    if theirs[1] != ours[1] or any(not math.isclose(a, b, rel_tol=1e-6) for a, b in zip(theirs[::2], ours[::2])):
        logged = mill_summary(impacts_path).get("scene", "another scene")
        raise InputError(
            f"--impacts {impacts_path}: logged by millimpact mill on {logged} (D {theirs[0]:g} m, "
            f"{theirs[1]} lifters {theirs[2]:g} m high), not on the liner of {scene.name} (D "
            f"{ours[0]:g} m, {ours[1]} lifters {ours[2]:g} m high); give the log of that scene's mill"
        )


def check_settings(args: argparse.Namespace) -> None:
    """One line for a setting out of range."""
    if args.lifters is not None and args.lifters < 1:
        raise InputError(f"--lifters {args.lifters}: must be >= 1")
    if args.slice_length is not None and not (math.isfinite(args.slice_length) and args.slice_length > 0):
        raise InputError(f"--slice-length {args.slice_length:g}: must be > 0 m")
    if args.angle_bins < 1 or args.arc_bins < 1:
        raise InputError("--angle-bins / --arc-bins: must be >= 1")
    if not (math.isfinite(args.cell) and args.cell > 0):
        raise InputError(f"--cell {args.cell:g}: must be > 0 m")
    if args.repeat_impacts < 0:
        raise InputError(f"--repeat-impacts {args.repeat_impacts}: must be >= 0")
    if args.ranks_per_case < 1:
        raise InputError(f"--ranks-per-case {args.ranks_per_case}: must be >= 1")
    from .damage_map import check_repeat_method

    check_repeat_method(args.method, args.repeat_impacts)


def command_scene(args: argparse.Namespace):
    """The liner scene of the map: SCENE with its ``--set`` assignments, validated together
    (before the impacts are read or any bin computed); the bins set the impact velocity."""
    from ..commandkit.settings import command_scene as resolve

    return resolve(args.scene, args.set, {"impact.velocity": "the bins' speeds and angles (from IMPACTS)"})


#: the stages of damage.json's wall_time_s, in the words of the last lines
STAGE_WORDS = {
    "bins": "bins (table cases)",
    "repeated_impacts": "repeated impacts",
    "plan": "binning and placing",
    "read_impacts": "reading the log",
    "report": "outputs",
}


def main(args: argparse.Namespace) -> int:
    from mpi4py import MPI

    from ..commandkit.settings import parse_options
    from ..commandkit.timing import StageClock, time_line
    from ..console import sayer
    from ..dem.impacts import ball_impacts, kind_totals, read_impacts
    from ..results.output_folder import claim_output, default_out
    from .damage_map import MapSettings, plan_map, run_damage_map

    clock = StageClock()
    check_settings(args)
    scene = command_scene(args)
    if scene.liner is None:
        raise InputError(
            f"scene {args.scene}: has no liner (the damage map needs a liner scene: liner-segment, "
            "liner-panel or a TOML file with a [liner] table)"
        )
    path = Path(args.impacts)
    check_log_liner(scene, path)
    world = MPI.COMM_WORLD
    say = sayer(args.quiet, world)
    with clock.stage("read_impacts"):
        logged = read_impacts(path, say)
    # the map computes the balls' impacts; the rock's (a SAG charge's log) are set beside them per place
    impacts = ball_impacts(logged)
    if len(impacts) == 0:
        raise InputError(f"--impacts {path}: no ball impacts (the map computes the balls' impacts on the liner)")
    settings = MapSettings(
        revolutions=revolutions_of(args, path),
        lifters=lifters_of(args, path),
        slice_length_m=args.slice_length,
        max_bins=args.max_bins,
        tolerance=args.restitution_tolerance,
        bins_from=args.bins_from,
        angle_bins=args.angle_bins,
        arc_bins=args.arc_bins,
        cell_m=args.cell,
        method=args.method,
        options=parse_options(args.option),
        repeat_impacts=args.repeat_impacts,
        ranks_per_case=args.ranks_per_case,
        rock_per_place=kind_totals(logged, "rock", revolutions_of(args, path), lifters_of(args, path))
        if len(impacts) < len(logged)
        else None,
    )
    if world.size % args.ranks_per_case or args.ranks_per_case > world.size:
        raise InputError(f"--ranks-per-case {args.ranks_per_case}: must divide the number of ranks ({world.size})")
    # bins, placed scenes, cases: a setting every bin hits is one line before any folder
    with clock.stage("plan"):
        prepared = plan_map(scene, impacts, settings, say)
    out = args.out if args.out is not None else default_out(Path(args.scene).stem, prefix="damage-")
    # before computing: checks, lock, leftovers (collective); an interruption's one line says which
    # finished bins and sequences are kept (damage_map.kept_bins_note)
    target = claim_output(out, "damage", force=args.force, comm=world)
    summary = run_damage_map(
        scene, impacts, target, settings, str(path), quiet=args.quiet, comm=world, prepared=prepared, clock=clock
    )
    say("  " + time_line(summary["wall_time_s"], STAGE_WORDS))
    if not args.quiet and world.rank == 0:
        print(
            f"  results in {target.shown}/ (damage.csv, bins.csv, profile.csv, damage.json, damage_map.png)"
            + target.replaced_note(),
            flush=True,
        )
    return 0
