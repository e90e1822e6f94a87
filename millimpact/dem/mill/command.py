"""``millimpact mill SCENE --revolutions R``: a slice of the mill in Yade and its ball-liner impact spectrum.

The scene's liner (shell radius, lifters' count, height, top, face angle, spacing) makes the mill's
profile round the whole shell (:mod:`~millimpact.dem.mill.geometry`); balls of the scene's radius
fill a slice of it (:mod:`~millimpact.dem.mill.setup`); Yade turns it at a fraction of the critical
speed (``millimpact/dem/mill/yade_scripts/mill_slice.py``) and logs every new ball-liner contact; the log
becomes ``impacts.csv`` (:mod:`~millimpact.dem.mill.log`) and the reports
(:mod:`~millimpact.dem.mill.report`); the net power and the charge's shape are set beside the
empirical models (:mod:`~millimpact.dem.mill.power`).
"""

from __future__ import annotations

import argparse
import sys

from ...console import say
from ...errors import InputError
from ...results.output_folder import FORCE_HELP, OUT_HELP

HELP = "a slice of the mill in Yade (or LIGGGHTS on MPI ranks): the impact spectrum, shoulder and toe, net power"

DESCRIPTION = """\
Build a slice of the mill from SCENE's liner (the lifters round the whole shell at the scene's
spacing), fill it with balls of the scene's radius (--balls N, or --fill F: the fraction of the
mill's volume the ball bed fills, 0.05-0.5; default --fill 0.1), turn it at --speed-fraction S of
the critical speed n_c = 42.3 / sqrt(D) rpm (default 0.75) in Yade (Hertz-Mindlin contacts with
--restitution or Thornton's e; or --law DIR, a law `millimpact export TABLE --to yade` wrote: each
ball-liner contact's e_n from the table at its impact speed and angle), and log every ball-liner
impact after a warm-up.

Writes DIR/impacts.csv (one row per impact: time_s, ball_radius_m, normal_speed_m_s,
tangential_speed_m_s, impact_energy_J, place, arc_position_m), spectrum.png and spectrum.csv
(impact energy against the cumulative number of impacts per revolution), impacts_per_revolution.csv
(by place), charge.png, summary.json (shoulder and toe angles, energy balance, the run's
settings; the net power drawn, per metre of mill length, and toe and shoulder beside Morrell's
C-model and correlations and Austin's SAG equation for the run's mill: "power", "charge_shape") and
yade/ (the script, its input and its raw output). Needs Yade (apt-get install yade).

--engine liggghts runs a balls-only charge in LIGGGHTS instead (apt-get install liggghts), as
`mpirun -n N liggghts` on --ranks N MPI processes: the slice, or with --length full|METRES the mill's
length between steel end plates that turn with the shell. It writes summary.json (net power
beside Morrell and Austin, toe and shoulder, the run's cost in steps per second), charge.png and
liggghts/ (the script, its inputs, torque.txt, charge.dump, the log); no impacts, spectrum or abrasion.

  millimpact mill liner-panel --revolutions 2 --balls 200 --out out/mill
  millimpact mill liner-panel --revolutions 3 --fill 0.1 --speed-fraction 0.8 --out out/mill80
  millimpact mill liner-panel --revolutions 2 --balls 200 --law out/dem-yade --out out/mill-law
  millimpact mill liner-panel --revolutions 1 --engine liggghts --ranks 2 --out out/mill-lig
  millimpact mill liner-panel --revolutions 1 --engine liggghts --ranks 2 --length full --out out/mill-full
"""

#: the charges (millimpact.dem.mill.charge.CHARGES: argparse's choices without importing numpy)
CHARGE_NAMES = ("balls", "sag")
#: the DEM codes that run the mill
ENGINES = ("yade", "liggghts")


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("scene", help="a built-in scene with a liner (liner-segment, liner-panel) or a TOML file")
    p.add_argument(
        "--revolutions", type=float, required=True, metavar="R", help="revolutions logged (after the warm-up)"
    )
    p.add_argument(
        "--charge",
        choices=CHARGE_NAMES,
        default="balls",
        help="balls (the default), or sag: balls and rock (--fill the whole charge, --ball-fill the balls)",
    )
    p.add_argument("--balls", type=int, metavar="N", help="number of balls (or --fill)")
    p.add_argument(
        "--fill",
        type=float,
        metavar="F",
        help="fraction of the mill's volume the bed fills, 0.05-0.5 (default 0.1 of balls; with "
        "--charge sag the whole charge, default 0.28)",
    )
    _add_sag_arguments(p)
    p.add_argument(
        "--speed-fraction",
        type=float,
        default=0.75,
        metavar="S",
        help="fraction of the critical speed n_c = 42.3/sqrt(D) rpm, in (0, 2] (default 0.75)",
    )
    p.add_argument(
        "--restitution",
        type=float,
        metavar="E",
        help="coefficient of restitution of every contact (default: Thornton's e at the shell speed "
        "from the scene's yield stresses)",
    )
    p.add_argument(
        "--law",
        metavar="DIR",
        help="a contact law exported for Yade (millimpact export TABLE --to yade --out DIR): each "
        "ball-liner contact's e_n from its impact speed and angle (instead of --restitution)",
    )
    p.add_argument(
        "--law-every",
        type=int,
        metavar="STEPS",
        help="with --law: steps between the law's updates of new contacts (default: the impact "
        "check's, 1/8 of the shortest contact)",
    )
    p.add_argument(
        "--friction", type=float, metavar="MU", help="Coulomb friction (default: the scene's contact.friction)"
    )
    p.add_argument(
        "--stiffness-scale",
        type=float,
        default=0.01,
        metavar="K",
        help="factor on Young's moduli in the DEM (default 0.01: soft contacts, 6x fewer steps; 1 = steel)",
    )
    p.add_argument(
        "--warmup", type=float, default=1.0, metavar="REV", help="revolutions run before logging starts (default 1)"
    )
    p.add_argument(
        "--thickness",
        type=float,
        default=2.0,
        metavar="DIAMETERS",
        help="the slice's thickness along the axis, in ball diameters (default 2)",
    )
    p.add_argument("--seed", type=int, default=0, help="seed of the balls' starting jitter (default 0)")
    p.add_argument(
        "--threads",
        type=int,
        metavar="N",
        help="Yade's OpenMP threads, 1-64 (default 1, or MILLIMPACT_YADE_THREADS): more only on idle cores",
    )
    _add_engine_arguments(p)
    p.add_argument("--set", action="append", metavar="FIELD=VALUE", help="override a scene field")
    p.add_argument("--out", help=OUT_HELP.format(default="out/mill-SCENE"))
    p.add_argument("--force", action="store_true", help=FORCE_HELP)
    p.add_argument("--no-plots", action="store_true", help="skip spectrum.png and charge.png")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress output")


def _add_sag_arguments(p: argparse.ArgumentParser) -> None:
    """The options of a SAG charge: rock sizes, contacts, slurry."""
    sag = p.add_argument_group("a SAG charge (--charge sag)")
    sag.add_argument(
        "--ball-fill",
        type=float,
        metavar="J_B",
        help="the balls' share of the mill's volume, (0, --fill] (default 0.12)",
    )
    sag.add_argument("--rock-top-size", type=float, metavar="M", help="the largest rock's diameter, m (default 0.2)")
    sag.add_argument(
        "--rock-cutoff",
        type=float,
        metavar="M",
        help="rock finer than this (m) is slurry, its volume given to the rock modelled (default 0.1)",
    )
    sag.add_argument(
        "--rock-restitution", type=float, metavar="E", help="restitution of contacts with rock (default 0.3)"
    )
    sag.add_argument(
        "--rock-friction", type=float, metavar="MU", help="Coulomb friction of contacts with rock (default 0.6)"
    )
    sag.add_argument(
        "--rolling-resistance",
        type=float,
        metavar="MU_R",
        help="the rock's rolling resistance, M <= MU_R R F_n, in [0, 1] (default 0.2)",
    )
    sag.add_argument(
        "--slurry-density",
        type=float,
        metavar="RHO",
        help="slurry (kg/m^3) filling the bed's voids, carried as mass on the particles: 0 (dry, the "
        "default) or 1000-2500",
    )


def _add_engine_arguments(p: argparse.ArgumentParser) -> None:
    """The DEM engine and, for LIGGGHTS, its ranks and the mill's length."""
    eng = p.add_argument_group("the DEM engine")
    eng.add_argument(
        "--engine",
        choices=ENGINES,
        default="yade",
        help="yade (the default: impacts, spectrum, abrasion, SAG charges) or liggghts (a balls-only charge on "
        "MPI ranks: power, toe and shoulder; a slice or the whole mill)",
    )
    eng.add_argument(
        "--ranks", type=int, metavar="N", help="with --engine liggghts: MPI processes, mpirun -n N (default 1)"
    )
    eng.add_argument(
        "--length",
        metavar="full|METRES",
        help="with --engine liggghts: the mill's length between steel end plates turning with the shell "
        "(full: the scene's mill length, else half its diameter), instead of the slice",
    )


def command_scene(args: argparse.Namespace):
    """The liner scene of the mill: SCENE with its ``--set`` assignments, validated together
    (before the mill is planned or Yade runs)."""
    from ...commandkit.settings import command_scene as resolve

    return resolve(args.scene, args.set)


def options_from_args(args: argparse.Namespace):
    """The :class:`~millimpact.dem.mill.setup.MillOptions` of the command line, checked."""
    from .setup import MillOptions, check_mill_options

    opts = MillOptions(
        revolutions=args.revolutions,
        balls=args.balls,
        fill=args.fill,
        speed_fraction=args.speed_fraction,
        restitution=args.restitution,
        friction=args.friction,
        stiffness_scale=args.stiffness_scale,
        warmup=args.warmup,
        thickness=args.thickness,
        seed=args.seed,
        law=args.law,
        law_every=args.law_every,
        charge=args.charge,
        ball_fill=args.ball_fill,
        rock_top_size=args.rock_top_size,
        rock_cutoff=args.rock_cutoff,
        rock_restitution=args.rock_restitution,
        rock_friction=args.rock_friction,
        rolling_resistance=args.rolling_resistance,
        slurry_density=args.slurry_density,
    )
    check_mill_options(opts)
    return opts


def _restitution_text(setup) -> str:
    if setup.law is None:
        return f"e {setup.restitution:.3g} ({setup.restitution_source})"
    return f"{setup.restitution_source}, updated every {setup.law_every} steps"


def main(args: argparse.Namespace) -> int:
    from ...results.output_folder import claim_output, default_out
    from ...results.timeseries import write_summary
    from ..yade import yade_executable
    from .liggghts_mill import check_engine_options
    from .run import run_mill
    from .setup import plan_mill

    # every check before any folder is made: options, scene, the plan, Yade, then --out
    if args.threads is not None and not 1 <= args.threads <= 64:
        raise InputError(f"--threads {args.threads}: must be an integer in [1, 64]")
    check_engine_options(args)
    if getattr(args, "engine", "yade") == "liggghts":
        return _main_liggghts(args)
    opts = options_from_args(args)
    scene = command_scene(args)
    setup = plan_mill(scene, opts)
    yade_executable()
    out = args.out if args.out is not None else default_out(scene.name, prefix="mill-")
    target = claim_output(out, "mill", force=args.force)  # before the DEM run: checks, lock, leftovers
    quiet = getattr(args, "quiet", False)
    if not quiet:
        say(
            f"mill: scene '{scene.name}', D {setup.profile.diameter:g} m, {setup.profile.n_lifters} lifters, "
            f"{setup.n_balls} balls of {2e3 * setup.ball_radius:g} mm in a {1e3 * setup.thickness:.0f} mm slice, "
            f"{100 * setup.speed_fraction:g} % of n_c = {setup.critical_rpm:.3g} rpm; "
            f"{_restitution_text(setup)}, mu {setup.friction:g}, moduli x {setup.stiffness_scale:g}; "
            f"{(setup.warmup_s + setup.run_s) / setup.dt:.3g} steps of {setup.dt:.3g} s",
            file=sys.stderr,
        )
    from ..yade import YadeError

    try:
        with target.staged(collective=False) as stage:
            summary = run_mill(
                scene, opts, stage, plots=not args.no_plots, setup=setup, quiet=quiet, threads=args.threads
            )
            write_summary(stage, summary)
    except YadeError as exc:  # say what the folder keeps (nothing of this run is published)
        raise YadeError(f"{exc}; {target.note}") from None
    if quiet:
        return 0
    n = summary["impacts_per_revolution"]
    who = "ball impacts" if "rock_impacts" in summary else "impacts"
    say(
        f"{who} per revolution: {n['all']:.4g} (lifter faces {n['lifter_face']:.4g}, tops {n['lifter_top']:.4g}, "
        f"plate {n['plate']:.4g}); {_charge_text(summary)}; "
        f"energy balance error {100 * (summary['energy_balance']['relative_error'] or 0):.2f} %"
    )
    if "rock_impacts" in summary:
        share = summary["charge"]["ball_contacts_on_rock_share"]
        say(
            f"rock impacts per revolution: {summary['rock_impacts']['impacts_per_revolution']['all']:.4g}; "
            + ("" if share is None else f"{100 * share:.0f} % of the balls' contacts land on rock; ")
            + f"friction work at the liner {summary['abrasion']['friction_work_J_per_revolution']:.4g} J per revolution"
        )
    for line in _comparison_lines(summary):
        say(line)
    say(f"results in {target.shown}/" + target.replaced_note())
    return 0


def _charge_text(summary: dict) -> str:
    """Shoulder and toe, or that the charge centrifuges (no shoulder: the balls ring the shell)."""
    if summary["shoulder_deg"] is None or summary["toe_deg"] is None:
        share = summary.get("centrifuged_fraction")
        return "no shoulder or toe: the charge centrifuges" + (
            f" ({100 * share:.0f} % of the balls turn with the shell)" if share is not None else ""
        )
    return f"shoulder {summary['shoulder_deg']:.4g} deg, toe {summary['toe_deg']:.4g} deg"


def _percent(x: float | None) -> str:
    return "n/a" if x is None else f"{100 * x:+.0f} %"


def _comparison_lines(summary: dict, where: str = "in the slice") -> list[str]:
    """The two printed lines: net power (``where``: the run's extent) against Morrell and Austin;
    toe and shoulder against Morrell."""
    pw, shape = summary["power"], summary["charge_shape"]
    m = pw["measured"]
    if m["net_W"] is None:
        power = "net power: n/a (no drive-work samples after the warm-up)"
    else:
        length = (
            ""
            if m["net_mill_W"] is None
            else f", {m['net_mill_W'] / 1e3:.4g} kW for the mill's {m['mill_length_m']:g} m"
        )
        power = (
            f"net power {m['net_W']:.4g} W {where} = {m['net_per_metre_W_m'] / 1e3:.4g} kW/m{length}; "
            f"at the shell, Morrell k P_C {pw['morrell_shell_per_metre_W_m'] / 1e3:.4g} kW/m "
            f"({_percent(pw['morrell_shell_relative_difference'])}; P_C {pw['morrell_net_per_metre_W_m'] / 1e3:.4g}), "
            f"Austin less no-load {pw['austin_shell_per_metre_W_m'] / 1e3:.4g} kW/m "
            f"({_percent(pw['austin_shell_relative_difference'])}; pinion {pw['austin_per_metre_W_m'] / 1e3:.4g}); "
            f"J {pw['model_inputs']['fill']:.3f}"
        )

    def angle(name: str) -> str:
        value, diff = shape[f"{name}_deg"], shape[f"{name}_difference_deg"]
        got = "n/a" if value is None else f"{value:.0f} deg"
        off = "" if diff is None else f" ({diff:+.0f})"
        return f"{name} {got}, Morrell {shape[f'morrell_{name}_deg']:.0f} deg{off}"

    return [power, f"charge shape: {angle('toe')}; {angle('shoulder')}"]


def _main_liggghts(args: argparse.Namespace) -> int:
    """``--engine liggghts``: the plan in LIGGGHTS on ``--ranks`` MPI processes (a slice, or
    ``--length`` between end plates); summary.json, charge.png and liggghts/."""
    from ...results.output_folder import claim_output, default_out
    from ...results.timeseries import write_summary
    from ..programs import DemCodeError
    from .liggghts_mill import liggghts_command, plan_liggghts_mill, run_liggghts_mill

    opts = options_from_args(args)
    scene = command_scene(args)
    ranks = args.ranks or 1
    plan = plan_liggghts_mill(scene, opts, args.length, ranks)
    liggghts_command(ranks)
    setup = plan.setup
    out = args.out if args.out is not None else default_out(scene.name, prefix="mill-")
    target = claim_output(out, "mill", force=args.force)
    quiet = getattr(args, "quiet", False)
    if not quiet:
        say(
            f"mill (LIGGGHTS, {ranks} rank{'s' if ranks > 1 else ''}): scene '{scene.name}', "
            f"D {setup.profile.diameter:g} m, {setup.profile.n_lifters} lifters, {setup.n_balls} balls of "
            f"{2e3 * setup.ball_radius:g} mm, {plan.length:.4g} m long ({plan.length_source}), "
            f"{100 * setup.speed_fraction:g} % of n_c = {setup.critical_rpm:.3g} rpm; e {setup.restitution:.3g}, "
            f"mu {setup.friction:g}, moduli x {setup.stiffness_scale:g}; "
            f"{plan.warm_steps + plan.run_steps} steps of {setup.dt:.3g} s",
            file=sys.stderr,
        )
    try:
        with target.staged(collective=False) as stage:
            summary = run_liggghts_mill(scene, opts, stage, plan, plots=not args.no_plots, quiet=quiet)
            write_summary(stage, summary)
    except DemCodeError as exc:
        raise DemCodeError(f"{exc}; {target.note}") from None
    if quiet:
        return 0
    cost = summary["liggghts"]
    rate = "n/a" if cost["steps_per_s"] is None else f"{cost['steps_per_s']:.4g}"
    rev = cost["projected_s_per_revolution"]
    say(
        f"{_charge_text(summary)}; {cost['steps']} steps at {rate} steps/s on {ranks} rank(s)"
        + ("" if rev is None else f", {rev:.4g} s a revolution at the logged part's rate")
    )
    where = f"in the {plan.length:g} m mill" if plan.end_plates else "in the slice"
    for line in _comparison_lines(summary, where):
        say(line)
    say(f"results in {target.shown}/" + target.replaced_note())
    return 0
