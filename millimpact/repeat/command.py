"""``millimpact repeat``: N impacts at one spot, each from the previous one's residual state."""

from __future__ import annotations

import argparse
import json
import math

from ..results.output_folder import FORCE_HELP, OUT_HELP

HELP = "repeated impacts at one spot: restitution, dent and plastic work per impact; shakedown or ratcheting"

DESCRIPTION = """\
Run N impacts of SCENE's ball at one spot, each starting from the previous impact's residual state
(plastic strain, hardening, residual stress and the dent, which the next contact sees); the ball is
launched again each time. One mesh and one reduction serve the whole sequence. Writes impacts.csv
(one row per impact), restitution.png and dent.png against the impact number, and summary.json /
summary.txt with the verdict (elastic shakedown, plastic shakedown, ratcheting or undecided) and its
numbers. Each finished impact is kept in DIR/impacts/: an interrupted sequence keeps them and the
same command continues it.

--velocities and --angles take one value (every impact) or one per impact. --offset DX,DY (m, the
face coordinates of impact.point): the even impacts land shifted by it from the odd ones.

Examples:
  millimpact repeat paper-rig-plastic --impacts 5 --out out/repeat
  millimpact repeat paper-rig-plastic --impacts 10 --velocities 3 --offset 0.0006,0 --out out/repeat-offset
  millimpact repeat paper-rig-plastic --impacts 3 --velocities 2,3,4 --set model.h_contact=0.0006 --out out/r
"""

METHODS = ("improved", "traditional", "modal-p2", "full")
#: the most impacts of one sequence: each impact is a transient FE solve (~10 s on the coarse
#: paper-rig-plastic, ~70 s at the plan's sizes), so 1000 are a day's computing; the impacts'
#: files are numbered with three digits
MAX_IMPACTS = 1000


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("scene", nargs="?", help="built-in scene name or TOML file (default: paper-rig-plastic)")
    p.add_argument("--impacts", type=int, required=True, metavar="N", help=f"number of impacts, 1 to {MAX_IMPACTS}")
    p.add_argument(
        "--velocities", metavar="V1,...", help="impact speeds, m/s: one, or one per impact (default the scene's speed)"
    )
    p.add_argument(
        "--angles",
        metavar="A1,...",
        help="angles from the face normal, deg in [0, 90): one, or one per impact (default the scene's)",
    )
    p.add_argument(
        "--offset",
        metavar="DX,DY",
        help="the even impacts' shift from the odd ones on the face, m (impact.point's coordinates; default none)",
    )
    p.add_argument("--method", default="improved", help="improved (default), traditional, modal-p2 or full")
    p.add_argument(
        "--out",
        required=True,
        help=OUT_HELP.replace(" (default {default})", " (required)") + "; its finished impacts are reused",
    )
    p.add_argument("--force", action="store_true", help=FORCE_HELP)
    p.add_argument("--set", action="append", default=[], metavar="FIELD=VALUE", help="override a scene field")
    p.add_argument("--option", action="append", default=[], metavar="KEY=VALUE", help="a method option")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress output")


def parse_numbers(text: str | None, option: str, n: int, default: float) -> list[float]:
    """One number or ``n`` comma-separated numbers of ``option`` as a list of ``n``."""
    from ..errors import InputError

    if text is None:
        return [default] * n
    try:
        vals = [float(x) for x in text.split(",")]
    except ValueError:
        raise InputError(f"{option} {text!r}: give numbers separated by commas") from None
    if len(vals) == 1:
        return vals * n
    if len(vals) != n:
        raise InputError(f"{option} {text!r}: {len(vals)} values for --impacts {n}; give one or {n}")
    return vals


def build_impacts(scene, n: int, velocities: str | None, angles: str | None, offset: str | None):
    """The sequence's ImpactSpecs from the command line (one InputError line for a bad one)."""
    import numpy as np

    from ..errors import InputError
    from .sequence import ImpactSpec

    if not 1 <= n <= MAX_IMPACTS:
        raise InputError(
            f"--impacts {n}: must lie in [1, {MAX_IMPACTS}] (each impact is a transient solve: "
            f"{MAX_IMPACTS} take about a day)"
        )
    v = np.asarray(scene.impact.velocity, float)
    nrm = np.asarray(scene.contact_normal, float)
    v_n = -float(v @ nrm)
    angle0 = math.degrees(math.atan2(float(np.linalg.norm(v + v_n * nrm)), v_n))
    speeds = parse_numbers(velocities, "--velocities", n, scene.impact.speed)
    angs = parse_numbers(angles, "--angles", n, round(angle0, 12))
    shift = (0.0, 0.0)
    if offset is not None:
        d = parse_numbers(offset, "--offset", 2, 0.0)
        if len(offset.split(",")) != 2 or not all(math.isfinite(x) for x in d):
            raise InputError(f"--offset {offset!r}: give DX,DY in m")
        shift = (d[0], d[1])
    return [ImpactSpec(speeds[k], angs[k], shift if k % 2 else (0.0, 0.0)) for k in range(n)]


def command_scene(args: argparse.Namespace):
    """The scene of the sequence: SCENE (default paper-rig-plastic) with its ``--set`` assignments,
    validated together (before any impact is defined or computed)."""
    from ..commandkit.settings import command_scene as resolve

    return resolve(args.scene or "paper-rig-plastic", args.set)


def main(args: argparse.Namespace) -> int:
    from mpi4py import MPI

    from ..commandkit.settings import parse_options
    from ..console import enable_stages, say
    from ..errors import InputError
    from ..results.output_folder import claim_output, owned_names, read_manifest
    from .report import verdict_text, write_sequence
    from .sequence import check_sequence, run_sequence
    from .verdict import classify

    comm = MPI.COMM_WORLD
    enable_stages(not args.quiet)  # the model's stages (meshing, reduction) as they start and end
    if not 1 <= args.impacts <= MAX_IMPACTS:  # before the scene: a huge N is refused at once
        build_impacts(None, args.impacts, None, None, None)
    if args.method not in METHODS:
        raise InputError(f"--method {args.method}: choose one of {', '.join(METHODS)}")
    scene = command_scene(args)
    impacts = build_impacts(scene, args.impacts, args.velocities, args.angles, args.offset)
    options = parse_options(args.option)
    check_sequence(scene, impacts, args.method)  # the plan's refusals: before the folder
    # before computing: checks, lock, leftovers (collective; docs/outputs.md)
    target = claim_output(args.out, "repeat", force=args.force, comm=comm)
    out = target.path
    old = read_manifest(out) if comm.rank == 0 and out.is_dir() else None
    store = target.open(["impacts"], note=lambda: kept_impacts_note(target)) / "impacts"
    quiet = args.quiet or comm.rank != 0
    if comm.rank == 0:
        store.mkdir(exist_ok=True)
        names = owned_names(old, "repeat")
        if old is not None and (names is None or "summary.json" in names):
            # the earlier sequence's summary: complete again only when this sequence is
            (out / "summary.json").unlink(missing_ok=True)
    comm.barrier()
    done_before = len(list(store.glob("impact-*.json")))
    if not quiet:
        say(
            f"repeat {scene.name}: {len(impacts)} impact{'' if len(impacts) == 1 else 's'}, method {args.method}"
            + (f"; {done_before} finished impact file(s) in {store}" if done_before else "")
        )
    outcomes = run_sequence(
        scene, impacts, args.method, options, comm, progress=None if quiet else say, store_dir=store
    )
    verdict = classify(outcomes)
    if comm.rank == 0:
        details = []
        for k in range(1, len(outcomes) + 1):
            try:
                details.append(json.loads((store / f"impact-{k:03d}.json").read_text()).get("details", {}))
            except (OSError, ValueError):
                details.append({})
        with target.staged(keep=["impacts"], collective=False) as stage:
            summary = write_sequence(stage, scene, args.method, impacts, outcomes, verdict, details, {})
        if not args.quiet:
            say(verdict_text(verdict))
            for note in summary["notes"]:
                say(f"  note: {note}")
            say(
                f"  results in {target.shown}/ ({', '.join([*summary['files'], 'summary.json', 'summary.txt'])})"
                + target.replaced_note()
            )
    return 0


def kept_impacts_note(target) -> str:
    """What an interrupted sequence leaves (the CLI's one line on Ctrl-C): its finished impacts."""
    from ..commandkit.store import kept_note

    n = len(list((target.path / "impacts").glob("impact-*.json")))
    return kept_note([(n, "impact", f"{target.shown}/impacts/")], f"{target.shown}/ has no summary.json: incomplete")
