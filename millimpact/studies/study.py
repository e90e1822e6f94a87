"""``millimpact study``: the paper's parameter studies (section 4) and sweeps of any scene field.

A study is a list of scenes that differ in one field (``dataclasses.replace`` copies of a base scene,
:meth:`Scene.with_value`). Each case is one ordinary run, written as its own run folder under the
study's output folder (the ``millimpact run`` contract: ``summary.json`` with the resolved scene,
``timeseries.csv``, ...). A case folder also stores a hash of what determines its result (the
resolved scene as TOML, the method and its options), so a re-run only computes the cases that
changed. Cases run one after another, or ``--jobs N`` at a time as separate processes (each case
serial); under ``mpirun`` each case runs on all ranks, one after another.

The study itself writes (rank 0): ``contact_point.png`` (the paper's four contact-point panels,
all cases overlaid, around the impact), ``contact_point_run.png`` (impact and the first ringing, 2 ms),
``contact_force.png`` (each case with its Hertz curve), ``trends.png`` (peaks against the
parameter beside Hertz), ``peaks.csv`` / ``peaks.md`` (peaks and timings), ``study.md`` (the trends
found, fitted exponents, beside the paper's conclusions (2)-(5) and Hertz's scaling laws) and
``study.json`` (all of it, machine-readable; written last).
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from ..commandkit.settings import parse_options
from ..commandkit.store import kept_note
from ..console import sayer
from ..errors import InputError, MillimpactError
from ..methods.registry import method_entry
from ..results.output_folder import claim_output, default_out, is_millimpact_output
from ..scene.builtin import BUILTIN_STUDIES
from .sweep import CaseRun, Study, StudyInterrupted, define_study, describe_reuse, run_cases, study_base

if TYPE_CHECKING:  # the report imports numpy: loaded when a study reports (`millimpact --help` stays fast)
    from .report import StudyAnalysis


HELP = "run a parameter study: poisson, velocity, radius, thickness (the paper's), or --param FIELD=v1,v2,..."

#: The default method of a study: the fastest method within 1 % of the converged reference on F_max
#: and t_c. The reference is full P2 (static Hertz -0.1 % on the contact radius, the half-space
#: impact +1.0 % / -0.7 % on F_max / t_c: benchmarks/static_hertz.py, full_hertz.py). On paper-rig
#: (benchmarks/reduced_vs_full.py) improved is within 0.23 % of full P2 on F_max and 0.03 % on
#: t_c; traditional (and full P1) keep the P1 far mesh's stiffness: 2.5-5.7 % on F_max against full
#: P2, although traditional is within 0.2 % of full P1 on the same mesh (benchmarks/study_method.py).
#: traditional is ~10x faster over the impact: choose it with --method traditional for quick trends.
DEFAULT_METHOD = "improved"
METHOD_CHOICE = (
    "the fastest method within 1 % of the converged reference (full P2) on F_max and t_c: improved "
    "-0.23 % / -0.03 % on paper-rig; traditional, ~10x faster, is within 0.2 % of full P1 but "
    "2.5-5.7 % off full P2 (the P1 far mesh is too stiff)"
)

DESCRIPTION = f"""\
Run a parameter study: one run per value of a scene field, each written as a run folder under
--out (summary.json with the resolved scene, timeseries.csv, figures), then figures with all cases
overlaid, a table of peaks and timings (peaks.csv, peaks.md) and study.md: the trends found (fitted
exponents of peak force, stress, duration ... against the parameter) beside the paper's
conclusions and Hertz's scaling laws (F ~ v^(6/5) R^2, t_c ~ v^(-1/5) R).

Built-in studies (the paper's section 4 run on scene study-base: r = 20 mm, v = 3 m/s, b = 40 mm,
u = 1; velocity-plastic is the restitution e(V) of paper-rig-plastic, with restitution.png beside
Thornton's curve):

{chr(10).join(f"  {n:<17s} {s.label} = {', '.join(f'{v:g}' for v in s.display)} {s.unit} (on {s.base})" for n, s in BUILTIN_STUDIES.items())}

Examples:
  millimpact study velocity
  millimpact study radius --jobs 2 --out out/radius
  millimpact study --param block.material.density=7000,7800,8600 --base study-base
  millimpact study velocity --end 3e-4 --set model.h_far=0.008     (short impacts, coarse mesh)

Default method: {DEFAULT_METHOD} ({METHOD_CHOICE}).
A re-run computes only the cases whose resolved scene, method or method options changed (--force:
all). Bad input (unknown field, value out of range) stops before any case runs, exit status 2.
"""


#: a "little" change in the paper's sense: below this relative change over the study's range
# --- command line -----------------------------------------------------------------------------------
def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "name", nargs="?", help="built-in study: " + ", ".join(BUILTIN_STUDIES) + "; with --param, a name for the sweep"
    )
    p.add_argument(
        "--param",
        metavar="FIELD=V1,V2,...",
        help="sweep any scene field, e.g. ball.radius=0.015,0.02 or impact.velocity=2,4 (a speed "
        "along the base's direction) or impact.velocity=[0,-3,0],[1,-3,0]",
    )
    p.add_argument("--base", help="base scene of a --param sweep (built-in name or TOML file; default study-base)")
    p.add_argument(
        "--method",
        default=None,
        help=f"solution method of every case (default {DEFAULT_METHOD}: {METHOD_CHOICE.replace('%', '%%')})",
    )
    p.add_argument(
        "--option",
        action="append",
        metavar="KEY=VALUE",
        default=[],
        help="method option for every case, e.g. --option modes=20 --option integrator=newmark",
    )
    p.add_argument(
        "--out",
        help="output folder (default out/study-NAME); each case in a subfolder; a rerun "
        "replaces what millimpact wrote there and keeps your other files (docs/outputs.md)",
    )
    p.add_argument(
        "--jobs",
        type=int,
        default=1,
        help="cases computed at the same time, as separate processes (each case serial; default 1)",
    )
    p.add_argument(
        "--set",
        action="append",
        metavar="FIELD=VALUE",
        default=[],
        help="override a scene field in every case, e.g. --set model.h_far=0.008",
    )
    p.add_argument(
        "--end",
        type=float,
        metavar="SECONDS",
        help="simulated time of every case (= --set time.end=...; e.g. 3e-4 for the impact only)",
    )
    p.add_argument(
        "--force",
        action="store_true",
        help="recompute every case (ignore the cache); also write into "
        "--out if it holds files millimpact did not write (same-named entries are replaced, and named)",
    )
    p.add_argument("--no-case-figures", action="store_true", help="skip each case's own PNG figures")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress output")


@dataclass
class StudyResult:
    """A finished study: its definition, the case runs, the analysis and the output folder."""

    study: Study
    runs: list[CaseRun]
    analysis: StudyAnalysis | None
    out: Path
    wall_time_s: float

    @property
    def failed(self) -> list[CaseRun]:
        return [r for r in self.runs if r.status == "failed"]


def run_study(
    name: str | None = None,
    param: str | None = None,
    base: str | None = None,
    sets: Sequence[str] = (),
    end: float | None = None,
    method: str | None = None,
    options: dict | None = None,
    out: Path | None = None,
    jobs: int = 1,
    force: bool = False,
    case_figures: bool = True,
    quiet: bool = False,
    subset: Sequence[int] | None = None,
    comm=None,
) -> StudyResult:
    """Define, run (cached) and report a study (see :func:`define_study`); the API behind
    ``millimpact study`` and the demos. ``method`` None takes :data:`DEFAULT_METHOD`."""
    if jobs < 1:
        raise InputError(f"--jobs {jobs}: must be >= 1")
    if comm is not None and comm.size > 1 and jobs > 1:
        raise InputError(f"--jobs {jobs}: under mpirun each case runs on all ranks; use --jobs 1")
    if end is not None and not (math.isfinite(end) and end > 0):
        raise InputError(f"--end {end}: must be > 0 s")
    chosen = method or DEFAULT_METHOD
    method_entry(chosen)  # an unknown name: one line listing the methods
    method_note = f"default: {METHOD_CHOICE}" if method is None else "chosen with --method"
    options = dict(options or {})
    study = define_study(name, param, base, sets, end, subset)
    target = claim_output(
        out if out is not None else default_out(study.name, prefix="study-"), "study", force=force, comm=comm
    )
    out, shown = target.path, target.shown
    rank0 = comm is None or comm.rank == 0
    say = sayer(quiet, comm)
    say(
        f"study {study.name}: {study.param} on {study.base}, {len(study.cases)} cases "
        f"({', '.join(c.label for c in study.cases)}) -> {shown}/"
    )
    say(f"  method {chosen} ({method_note})")
    target.open(
        [c.folder for c in study.cases],
        note=lambda: kept_note(
            [(sum((out / c.folder / "summary.json").is_file() for c in study.cases), "case", f"{shown}/")],
            "study.md is not written",
        ),
    )
    from .report import write_study

    t0 = time.perf_counter()
    try:
        runs = run_cases(
            study,
            out,
            chosen,
            options,
            jobs=jobs,
            progress=sys.stdout.isatty(),
            force=force,
            figures=case_figures,
            comm=comm,
            quiet=quiet,
        )
        wall = time.perf_counter() - t0
        a = None
        if rank0:  # the report replaces the last one; every case folder (of any earlier study too) stays
            cases = [p.name for p in out.iterdir() if p.is_dir() and is_millimpact_output(p)]
            with target.staged(keep=cases, collective=False) as stage:
                a = write_study(study, runs, stage, chosen, method_note, wall)
    except StudyInterrupted:
        raise
    except KeyboardInterrupt as exc:  # outside the case loop (before it, or during the report)
        done = sum((out / c.folder / "summary.json").is_file() for c in study.cases)
        raise StudyInterrupted(done, len(study.cases), 143 if type(exc).__name__ == "Terminated" else 130) from None
    res = StudyResult(study, runs, a, out, wall)
    if rank0:
        n_comp = sum(r.status == "computed" for r in runs)
        say(
            f"study {study.name}: {n_comp} computed, {len(runs) - n_comp - len(res.failed)} cached, "
            f"{len(res.failed)} failed; wall time {wall:.1f} s"
        )
        if n_comp:
            say("  " + describe_reuse(runs)[1])
        assert a is not None  # rank 0 wrote the report
        for f in a.fits[:3]:
            say(f"  {f['name']:<42s} ~ {study.symbol}^{f['k']:.3f}   (Hertz {study.symbol}^{f['k_hertz']:.3f})")
        for c in a.paper_checks:
            say(f"  paper: {c['claim']}: {c['verdict']}")
        say(
            f"  results in {shown}/ (study.md, peaks.md, peaks.csv, contact_point.png, contact_force.png, trends.png; "
            "one run folder per case)" + target.replaced_note()
        )
    return res


def command_scene(args: argparse.Namespace):
    """The scene the study's cases vary, with its ``--set`` assignments validated together
    (before any case is defined or computed)."""
    return study_base(args.name, args.param, args.base, args.set)


def main(args: argparse.Namespace) -> int:
    size = int(os.environ.get("OMPI_COMM_WORLD_SIZE", os.environ.get("PMI_SIZE", "1")))
    comm = None
    if size > 1:
        from mpi4py import MPI

        comm = MPI.COMM_WORLD
    options = parse_options(args.option)
    res = run_study(
        args.name,
        args.param,
        args.base,
        args.set,
        args.end,
        args.method,
        options,
        args.out,
        args.jobs,
        args.force,
        not args.no_case_figures,
        args.quiet,
        comm=comm,
    )
    if res.failed:
        raise MillimpactError(
            f"{len(res.failed)} case(s) failed: " + "; ".join(f"{r.case.label}: {r.error}" for r in res.failed)
        )
    return 0
