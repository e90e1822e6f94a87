"""``millimpact table``: the command line of the contact table (its arguments, checked, and the
lines it prints); the engine that defines and computes the cases is :mod:`.table`.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

from ..commandkit.settings import parse_options
from ..errors import InputError, MillimpactError
from ..results.output_folder import FORCE_HELP, OUT_HELP, claim_output, default_out
from .table import run_table, table_scene

HELP = "DEM contact tables: restitution and force laws over impact speed x angle (x radius)"

DESCRIPTION = """\
Run one impact per (speed, angle[, radius]) of SCENE and write a DEM contact table: contact_table.csv
(with units and definitions in its # header), contact_table.json, contact_table.h5, the fitted laws
(contact_laws.json: e_n power law, Thornton's V_y, Hertz E*) and figures (e_n against speed, e_t
against tan(angle)/mu, peak force against speed). The angle is measured from the face normal in the
plane of the scene's impact vector. Each case runs the impact only. With improved, traditional and
modal-p2, cases whose normal speeds lie within a factor 1.5 share one mesh, one reduction and its
factorizations. Finished cases are kept in DIR/cases/ and a rerun computes only what is missing.
Under mpirun, --ranks-per-case K makes groups of K ranks that take cases from a shared counter.

With --tolerance TOL the table chooses its cases: --velocity V_LOW,V_HIGH and --angle A_LOW,A_HIGH
give the ranges, a 4 x 3 grid starts the law (--start-grid; the DEM export's law: zeta and E*
bilinear in ln speed and angle), cases at the centres of its cells check it (all in one batch
while --max-cases pays for them, else those where the grid's second differences predict the
largest error first), and a cell that misses (e_n or e_t off by more than TOL, F_max by 2 TOL relative)
gets a new grid line, until every cell passes or --max-cases is spent (then a warning, exit 0).
The rows say role grid or check; checks.csv holds each check's error, adaptive_points.png shows
the chosen points.

Examples:
  millimpact table paper-rig --velocity 0.5,1,2,4,8 --angle 0,15,30,45,60
  millimpact table liner-segment --velocity 2,4,8 --angle 0,30,60 --out out/liner-table
  mpirun -n 4 millimpact table paper-rig --velocity 1,3 --angle 0,30 --ranks-per-case 1
  millimpact table paper-rig-plastic --velocity 0.5,10 --angle 0,60 --tolerance 0.01 --max-cases 30
"""

#: the largest --tolerance: e_n and e_t lie in [0, 1], and F_max within 2 x 0.5 = 100 % says nothing
MAX_TOLERANCE = 0.5
#: the most cases --max-cases allows
MAX_CASES = 10000
#: an adaptive table starts from START_SPEEDS speeds x START_ANGLES angles (START_SPEEDS at one angle):
#: e_n and F_max change more along ln v (yield, F_max ~ v^1.2) than along the angle
START_SPEEDS, START_ANGLES = 4, 3
#: the most speeds or angles --start-grid allows
MAX_START = 20


def parse_list(
    text: str | None, option: str, low: float, high: float, low_open: bool, high_open: bool, unit: str
) -> list[float]:
    """Comma-separated numbers of ``option``, each in the range; one :class:`InputError` line otherwise."""
    rng = f"{'(' if low_open else '['}{low:g}, {high:g}{')' if high_open else ']'} {unit}".rstrip()
    if text is None or not text.strip():
        raise InputError(f"{option}: give a comma-separated list of numbers in {rng}")
    out = []
    for part in text.split(","):
        try:
            v = float(part)
        except ValueError:
            raise InputError(
                f"{option} {text!r}: {part.strip()!r} is not a number (a comma-separated list in {rng})"
            ) from None
        if not math.isfinite(v) or v < low or v > high or (low_open and v == low) or (high_open and v == high):
            raise InputError(f"{option} {text!r}: {v:g} is outside {rng}")
        if v in out:  # a repeated case would be a duplicate row, weighting the fitted laws
            raise InputError(
                f"{option} {text!r}: {v:g} is repeated (each value once: a duplicate row would weight the fitted laws)"
            )
        out.append(v)
    return out


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("scene", nargs="?", help="built-in scene name or TOML file (default: paper-rig)")
    p.add_argument("--velocity", required=True, metavar="V1,V2,...", help="impact speeds, m/s (> 0, <= 100)")
    p.add_argument(
        "--angle", default="0", metavar="A1,A2,...", help="angles from the face normal, deg, in [0, 90) (default 0)"
    )
    p.add_argument("--radius", metavar="R1,R2,...", help="ball radii, m (default the scene's)")
    p.add_argument(
        "--method",
        default="improved",
        help="solution method (default improved; the reduced methods reuse one reduction per mesh band)",
    )
    p.add_argument("--out", help=OUT_HELP.format(default="out/table-SCENE") + "; finished cases in it are reused")
    p.add_argument("--force", action="store_true", help=FORCE_HELP)
    p.add_argument("--set", action="append", default=[], metavar="FIELD=VALUE", help="override a scene field")
    p.add_argument("--option", action="append", default=[], metavar="KEY=VALUE", help="a method option")
    p.add_argument(
        "--ranks-per-case",
        type=int,
        default=1,
        metavar="K",
        help="under mpirun: ranks per case (divides the rank count; default 1)",
    )
    p.add_argument(
        "--tolerance",
        type=float,
        metavar="TOL",
        help="choose the cases: refine until the law is within TOL in e_n and e_t and 2 TOL relative in "
        "F_max at every checked point, in (0, 0.5); --velocity and --angle then give the ranges' ends",
    )
    p.add_argument(
        "--max-cases",
        type=int,
        metavar="N",
        help="with --tolerance: at most N finite-element cases, grid and checks (default 30)",
    )
    p.add_argument(
        "--start-grid",
        metavar="NxM",
        help=f"with --tolerance: the starting grid, N speeds x M angles, each in [2, {MAX_START}] "
        f"(default {START_SPEEDS}x{START_ANGLES}; M is unused at one angle)",
    )
    p.add_argument("-q", "--quiet", action="store_true", help="no progress output")


def command_scene(args: argparse.Namespace):
    """The scene the table's cases start from: SCENE with its ``--set`` assignments, validated
    together (before any case is defined or computed)."""
    return table_scene(args.scene, args.set)


def adaptive_ranges(
    args: argparse.Namespace, speeds: list[float], angles: list[float], radii: list[float] | None
) -> tuple[float, int, tuple[int, int]]:
    """The tolerance, budget and starting grid (speeds, angles) of an adaptive table, checked with
    its ranges (one InputError line)."""
    tol = args.tolerance
    if not (math.isfinite(tol) and 0.0 < tol < MAX_TOLERANCE):
        raise InputError(f"--tolerance {tol:g}: outside (0, {MAX_TOLERANCE:g}) (e_n and e_t; F_max: 2 x, relative)")
    if len(speeds) != 2 or speeds[0] >= speeds[1]:
        raise InputError(f"--velocity {args.velocity!r}: with --tolerance, the range's ends V_LOW,V_HIGH (m/s)")
    if len(angles) > 2 or (len(angles) == 2 and angles[0] >= angles[1]):
        raise InputError(f"--angle {args.angle!r}: with --tolerance, one angle or the range's ends A_LOW,A_HIGH (deg)")
    if radii is not None and len(radii) > 1:
        raise InputError(f"--radius {args.radius!r}: with --tolerance, one ball radius")
    n_v, n_a = start_grid(getattr(args, "start_grid", None))
    low = n_v * (n_a if len(angles) == 2 else 1)
    n = 30 if args.max_cases is None else args.max_cases
    if not low <= n <= MAX_CASES:
        grid = f"{n_v} speeds x {n_a} angles" if low > n_v else f"{n_v} speeds"
        raise InputError(f"--max-cases {n}: outside [{low}, {MAX_CASES}] (the starting grid is {grid})")
    return tol, n, (n_v, n_a)


def start_grid(text: str | None) -> tuple[int, int]:
    """--start-grid NxM as (speeds, angles), each in [2, MAX_START] (one InputError line otherwise)."""
    if text is None:
        return START_SPEEDS, START_ANGLES
    try:
        n_v, n_a = (int(x) for x in text.lower().split("x"))
    except ValueError:
        raise InputError(f"--start-grid {text!r}: give NxM, N speeds x M angles (e.g. 4x3)") from None
    if not (2 <= n_v <= MAX_START and 2 <= n_a <= MAX_START):
        raise InputError(f"--start-grid {text!r}: N and M must lie in [2, {MAX_START}]")
    return n_v, n_a


def main(args: argparse.Namespace) -> int:
    speeds = parse_list(args.velocity, "--velocity", 0.0, 100.0, True, False, "m/s")
    angles = parse_list(args.angle, "--angle", 0.0, 90.0, False, True, "deg")
    radii = parse_list(args.radius, "--radius", 1e-4, 1.0, False, False, "m") if args.radius else None
    options = parse_options(args.option)
    adaptive = args.tolerance is not None
    if adaptive:
        tolerance, max_cases, start = adaptive_ranges(args, speeds, angles, radii)
    elif args.max_cases is not None:
        raise InputError("--max-cases: only with --tolerance (an adaptive table's budget)")
    elif args.start_grid is not None:
        raise InputError("--start-grid: only with --tolerance (an adaptive table's first cases)")
    name = args.scene or "paper-rig"
    target = claim_output(
        args.out if args.out is not None else default_out(Path(name).stem, prefix="table-"), "table", force=args.force
    )  # before any computing
    out = target.shown
    if adaptive:
        from .table_adaptive import run_adaptive_table
        from .table_report import largest_errors_text, summary_line

        rows, summary = run_adaptive_table(
            args.scene,
            (speeds[0], speeds[1]),
            (angles[0], angles[-1]),
            radii[0] if radii else None,
            args.method,
            options,
            target,
            tolerance,
            max_cases,
            args.set,
            args.ranks_per_case,
            args.quiet,
            start,
        )
        if summary is not None and not args.quiet:
            print(f"  adaptive: {summary_line(summary)}", flush=True)
        if summary is not None and not summary["reached"]:
            print(
                f"millimpact: warning: tolerance {tolerance:g} not reached within --max-cases {max_cases}: largest "
                f"checked error {largest_errors_text(summary)} ({out}/checks.csv); raise --max-cases or --tolerance",
                file=sys.stderr,
                flush=True,
            )
    else:
        rows = run_table(
            args.scene, speeds, angles, radii, args.method, options, target, args.set, args.ranks_per_case, args.quiet
        )
    failed = [r for r in rows if not str(r.get("status", "")).startswith("ok")]
    if rows and not args.quiet:
        extra = ", checks.csv, adaptive_points.png" if adaptive else ""
        print(
            f"  results in {out}/ (contact_table.csv, contact_table.json, contact_table.h5, contact_laws.json, "
            f"e_n_speed.png, e_t_angle.png, force_speed.png{extra}){target.replaced_note()}",
            flush=True,
        )
    if failed:
        raise MillimpactError(
            f"{len(failed)} of {len(rows)} case(s) failed; see the status column of {out}/contact_table.csv"
        )
    return 0
