"""The sweep engine of studies: a study is a list of cases (a name, a value and a resolved scene); each case is
one ordinary run written as a run folder, keyed by a hash of what determines its result (resolved scene, method,
options) so a re-run computes only what changed. Cases run one after another, ``jobs`` at a time as processes,
or under ``mpirun`` on all ranks. :func:`run_cases` returns the cases' summaries and series (:class:`CaseRun`).
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import re
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .. import share_blas_threads
from ..commandkit.settings import apply_sets
from ..commandkit.store import piece_key
from ..console import sayer
from ..errors import InputError, MillimpactError
from ..scene.builtin import BUILTIN_STUDIES, StudySpec, resolve_scene, study_scene
from ..scene.schema import Scene, parse_value
from ..scene.toml_io import dump_scene


# --- study definition ----------------------------------------------------------------------------
@dataclass(frozen=True)
class StudyCase:
    """One case: its folder name, the scene value set, the value shown (u, mm, m/s) and the scene."""

    index: int
    folder: str
    label: str  #: legend label, e.g. "v = 3 m/s"
    value: Any  #: the value given to the scene field
    x: float  #: the abscissa of trends and fits (the shown value); nan if not numeric
    scene: Scene


@dataclass(frozen=True)
class Study:
    """A one-parameter sweep: the field, how it is shown, its cases and, for the paper's studies,
    the paper's conclusion."""

    name: str
    param: str
    symbol: str  #: short name of the parameter (u, v, r, b or the field's last part)
    xlabel: str  #: axis label with unit
    base: str
    cases: tuple[StudyCase, ...]
    paper: StudySpec | None = None


def safe_name(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9.=+-]+", "_", text).strip("_")


def split_values(text: str) -> list[str]:
    """Split ``v1,v2,...`` at the commas outside brackets and quotes (values may be TOML arrays)."""
    parts: list[str] = []
    cur: list[str] = []
    depth, quote = 0, ""
    for ch in text:
        if quote:
            quote = "" if ch == quote else quote
        elif ch in "\"'":
            quote = ch
        elif ch == "[":
            depth += 1
        elif ch == "]":
            depth -= 1
        elif ch == "," and depth == 0:
            parts.append("".join(cur).strip())
            cur = []
            continue
        cur.append(ch)
    parts.append("".join(cur).strip())
    return parts


def parse_param(text: str) -> tuple[str, list[Any]]:
    """``FIELD=v1,v2,...`` -> (field, [values parsed as TOML])."""
    field_, sep, values = text.partition("=")
    field_ = field_.strip()
    if not sep or not field_ or not values.strip():
        raise InputError(f"--param {text!r}: expected FIELD=v1,v2,... (e.g. --param ball.radius=0.015,0.02,0.025)")
    raw = split_values(values)
    if any(not r for r in raw):
        raise InputError(f"--param {text!r}: an empty value in the list")
    if len(raw) < 2:
        raise InputError(
            f"--param {text!r}: a study needs at least two values (one value: millimpact run --set {field_}={raw[0]})"
        )
    return field_, [parse_value(r) for r in raw]


def apply_study_sets(scene: Scene, sets: Sequence[str], param: str) -> Scene:
    """``scene`` with every ``--set FIELD=VALUE``, validated together (order does not matter); the
    study parameter ``param`` is the study's to set."""
    return apply_sets(scene, sets, {param: f"the study parameter {param}"})


def study_base(name: str | None, param: str | None, base: str | None, sets: Sequence[str]) -> Scene:
    """The scene a study's cases vary, with the ``--set`` assignments: ``base`` (default
    study-base) for a ``--param`` sweep, the built-in study ``name``'s own base otherwise."""
    if param is not None:
        return apply_study_sets(resolve_scene(base or "study-base"), sets, parse_param(param)[0])
    spec = BUILTIN_STUDIES.get(name or "")
    if spec is None:
        define_study(name, param, base, sets)  # the one line saying what is wrong
        raise AssertionError(f"define_study accepted the unknown study {name!r}")
    return apply_study_sets(resolve_scene(spec.base), sets, spec.param)


def with_param(base: Scene, param: str, value: Any) -> Scene:
    """``base`` with ``param`` set to ``value``; a number for ``impact.velocity`` is the speed along
    the base's direction (as the paper's velocity study)."""
    if param == "impact.velocity" and isinstance(value, (int, float)) and not isinstance(value, bool):
        n = base.impact.speed
        return base.with_value(param, [c / n * float(value) for c in base.impact.velocity])
    return base.with_value(param, value)


def define_study(
    name: str | None,
    param: str | None = None,
    base: str | None = None,
    sets: Sequence[str] = (),
    end: float | None = None,
    subset: Sequence[int] | None = None,
) -> Study:
    """The cases of a built-in study ``name`` or of a sweep ``param = "FIELD=v1,v2,..."`` of any
    scene field on ``base`` (default study-base), with the ``--set`` overrides and an optional end
    time (s) applied to every case; ``subset``: indices of the values to keep (reduced-size demos).
    Every case scene is validated (and planned) here, so bad input is refused before anything runs."""
    if param is None:
        if name is None:
            raise InputError(
                "study: give a built-in study (" + ", ".join(BUILTIN_STUDIES) + ") or --param FIELD=v1,v2,..."
            )
        if name not in BUILTIN_STUDIES:
            raise InputError(
                f"study {name!r}: unknown; built-in studies are {', '.join(BUILTIN_STUDIES)} "
                "(or use --param FIELD=v1,v2,...)"
            )
        if base is not None:
            raise InputError(f"--base: the built-in study {name} runs on its own base ({BUILTIN_STUDIES[name].base})")
        spec = BUILTIN_STUDIES[name]
        symbol = spec.label.split()[0]
        entries = []
        for v, shown in zip(spec.values, spec.display):
            scene = apply_study_sets(study_scene(spec, v), sets, spec.param)
            unit = f" {spec.unit}" if spec.unit else ""
            entries.append(
                (v, float(shown), f"{symbol} = {shown:g}{unit}", safe_name(f"{symbol}{shown:g}{spec.unit}"), scene)
            )
        xlabel = f"{spec.label}" + (f" [{spec.unit}]" if spec.unit else "")
        study_name, param_name, base_name, paper = name, spec.param, spec.base, spec if spec.paper_conclusion else None
    else:
        field_, values = parse_param(param)
        base_name = base or "study-base"
        base_scene = study_base(name, param, base, sets)
        symbol = field_.split(".")[-1]
        if name is not None and name in BUILTIN_STUDIES:
            raise InputError(f"study name {name!r} is a built-in study; with --param give another name or none")
        entries = []
        for v in values:
            scene = with_param(base_scene, field_, v)
            shown = float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else math.nan
            text = (
                f"{v:g}"
                if not math.isnan(shown)
                else (",".join(f"{c:g}" for c in v) if isinstance(v, list) else str(v))
            )
            entries.append((v, shown, f"{symbol} = {text}", safe_name(f"{symbol}={text}"), scene))
        if len({e[3] for e in entries}) != len(entries):
            raise InputError(f"--param {param!r}: repeated values")
        study_name = name or f"param-{safe_name(field_)}"
        xlabel, param_name, paper = field_, field_, None
    if subset is not None:
        entries = [entries[i] for i in subset]
    from ..scene.plan import make_plan  # numpy and scipy: once the names and values are read

    cases = []
    for i, (v, shown, label, folder, scene) in enumerate(entries):
        if end is not None:
            scene = scene.with_value("time.end", float(end))
        scene = dataclasses.replace(scene, name=f"{study_name}-{folder}")
        make_plan(scene)  # refuses sizes the plan cannot mesh (SceneError names the field)
        cases.append(StudyCase(i, folder, label, v, shown, scene))
    return Study(study_name, param_name, symbol, xlabel, base_name, tuple(cases), paper)


def case_key(scene: Scene, method: str, options: dict) -> str:
    """The key of what determines a case's result: the resolved scene (TOML), method and options
    (:func:`millimpact.commandkit.store.piece_key`)."""
    return piece_key({"scene": dump_scene(scene), "method": method, "options": options})


def cached_summary(folder: Path, key: str) -> dict | None:
    """The summary of a complete case folder computed with ``key``, else None."""
    try:
        s = json.loads((folder / "summary.json").read_text())
    except (OSError, ValueError):
        return None
    if s.get("study", {}).get("cache_key") != key or not (folder / "timeseries.csv").is_file():
        return None
    return s


# --- running the cases ----------------------------------------------------------------------------
@dataclass(frozen=True)
class CaseTask:
    """What a worker needs to compute and write one case."""

    scene: Scene
    method: str
    options: dict
    folder: str
    meta: dict
    figures: bool
    progress: bool


def compute_case(task: CaseTask, comm=None) -> dict:
    """Compute one case and write its run folder (staged: complete or absent). Returns a small
    report: ``{"ok": True, "wall_time_s": ...}`` or ``{"ok": False, "error": ..., "input": bool}``
    (errors are returned, not raised, so they cross process boundaries intact)."""
    from ..methods.run import build_summary, compute, write_run
    from ..results.output_folder import staged_output

    try:
        t0 = time.perf_counter()
        out, plan = compute(task.scene, task.method, dict(task.options), task.progress)
        wall = time.perf_counter() - t0
        summary = build_summary(task.scene, plan, out, wall)
        summary["study"] = task.meta
        with staged_output(Path(task.folder), comm) as stage:
            write_run(stage, task.scene, plan, out, summary, figures=task.figures, comm=comm)
        warnings = [n for n in summary.get("notes", []) if n.startswith("warning: options")]
        return {"ok": True, "wall_time_s": wall, "warnings": warnings}
    except InputError as exc:
        return {"ok": False, "input": True, "error": str(exc)}
    except MillimpactError as exc:
        return {"ok": False, "input": False, "error": f"{type(exc).__name__}: {exc}"}


def _worker(task: CaseTask) -> dict:
    """Process-pool entry: one case, serial."""
    import faulthandler
    import logging
    import signal

    # Ctrl-C reaches the whole process group: the parent stops the workers, they stay quiet
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    faulthandler.enable()  # a worker's native crash says where (the parent sees only a broken pool)

    logging.basicConfig(level=logging.WARNING)
    if os.environ.get("MILLIMPACT_TEST_WORKER_EXIT") == os.path.basename(task.folder):
        os._exit(1)  # tests/studies/test_study.py: a worker that ends without a word
    return compute_case(task, None)


def stop_workers(procs: list, grace_s: float = 1.0) -> list:
    """Stop pool workers: SIGTERM, then SIGKILL for those still alive after ``grace_s``. A worker
    that has initialised PETSc has PETSc's signal handler, which answers SIGTERM with MPI_Abort;
    in an MPI singleton that call can hang for ever, keeping the worker (and the pipes it holds)
    alive after the study has exited. Returns the workers that needed the SIGKILL."""
    for proc in procs:
        proc.terminate()
    deadline = time.monotonic() + grace_s
    for proc in procs:
        proc.join(max(0.0, deadline - time.monotonic()))
    killed = [proc for proc in procs if proc.is_alive()]
    for proc in killed:
        proc.kill()
        proc.join(5.0)
    return killed


def lost_worker_codes(procs: list, killed: list) -> list[int]:
    """The exit codes of the workers that ended by themselves, from a broken pool's processes once
    all have ended. The pool answers a lost worker by SIGTERM to the others (exit code -15), and
    ``stop_workers`` SIGKILLs those that outlive that (``killed``, exit code -9): these codes are
    the study's own, said only when no other is there (a worker killed from outside by SIGTERM).

    A worker in ``killed`` counts with its own code when that is not -9: the pool's thread reaps
    the workers while ``stop_workers`` polls them, and a poll that loses that race (waitpid: no
    such child, before the thread has stored the code) reads a lost worker as alive (CI run,
    2026-11-28: the lost worker's [1] was missing and [-15] said alone)."""
    import signal

    codes = {
        p.exitcode for p in procs if p.exitcode not in (None, 0) and not (p in killed and p.exitcode == -signal.SIGKILL)
    }
    return sorted({c for c in codes if c != -signal.SIGTERM} or codes)


def remove_stages(out: Path, folders: list[str]) -> None:
    """Remove the staging folders (``.<case>.partial-*``, see ``staged_output``) that stopped
    workers left: never complete, and not the user's."""
    import shutil

    for folder in folders:
        for stage in out.glob(f".{folder}.partial-*"):
            shutil.rmtree(stage, ignore_errors=True)


@dataclass
class CaseRun:
    """A case after the run: computed or taken from the cache, its summary and time series."""

    case: StudyCase
    status: str  #: computed | cached | failed
    summary: dict | None = None
    series: Any = None
    error: str = ""
    wall_time_s: float = math.nan  #: wall time of the computation (from the summary if cached)


def describe_reuse(runs: Sequence[CaseRun]) -> tuple[dict, str]:
    """What the computed cases took from the caches instead of computing: the mesh (the mesh
    cache: same geometry and sizes) and each body's Craig-Bampton reduction (the reduction cache,
    ``MILLIMPACT_REDUCTION_CACHE``: same matrices), from each case's ``summary.json``. Cases that
    move the impact place change the struck body's mesh and zone, so only the ball can be reused
    then. Returns (counts for ``study.json``, one line for the terminal)."""
    computed = [r.summary for r in runs if r.status == "computed" and r.summary]
    mesh = sum(bool(s.get("model", {}).get("mesh", {}).get("cached")) for s in computed)
    bodies: dict[str, int] = {}
    for s in computed:
        for name, b in (s.get("model", {}).get("reduction", {}) or {}).get("bodies", {}).items():
            bodies[name] = bodies.get(name, 0) + bool(b.get("from_cache"))
    counts = {"computed_cases": len(computed), "mesh_from_cache": mesh, "reduction_from_cache": bodies}
    parts = [f"the mesh in {mesh}"] + [f"the {name}'s reduction in {k}" for name, k in bodies.items()]
    text = f"reused from the caches, of the {len(computed)} case(s) run: " + ", ".join(parts)
    return counts, text


class StudyInterrupted(KeyboardInterrupt):
    """Ctrl-C or SIGTERM during a study: the finished cases stay (each case folder is complete or
    absent), the workers are stopped; the message says how many cases are done."""

    def __init__(self, done: int, total: int, code: int):
        super().__init__(
            f"{done} of {total} cases done (their folders are complete); rerun the same command to "
            "finish the rest" + (" and write the study's report" if done == total else "")
        )
        self.exit_code = code


@dataclass
class _CaseLoop:
    """The state a study's run passes between its steps: what to run (``study`` into ``out`` with
    ``method`` and ``options``, the cases' cache ``keys``), the cases' :class:`CaseRun` records, the
    indices still ``todo``, and the progress said so far (cases ``done``, the wall times (s) of
    those computed, the warnings said once)."""

    study: Study
    out: Path
    method: str
    options: dict
    keys: list[str]
    runs: list[CaseRun]
    todo: list[int]
    jobs: int
    progress: bool
    figures: bool
    quiet: bool
    rank0: bool
    say: Any
    t_start: float = 0.0
    done: int = 0
    computed_walls: list[float] = dataclasses.field(default_factory=list)
    warned: set[str] = dataclasses.field(default_factory=set)

    @property
    def n(self) -> int:
        return len(self.study.cases)

    def task(self, i: int) -> CaseTask:
        """What a worker needs to compute case ``i``, with the study's metadata for its summary."""
        c = self.study.cases[i]
        meta = {
            "name": self.study.name,
            "param": self.study.param,
            "value": c.value,
            "x": c.x,
            "label": c.label,
            "method_options": self.options,
            "cache_key": self.keys[i],
        }
        return CaseTask(
            c.scene,
            self.method,
            dict(self.options),
            str(self.out / c.folder),
            meta,
            self.figures,
            self.progress and self.jobs == 1 and not self.quiet,
        )

    def report(self, i: int, res: dict) -> None:
        """Record case ``i``'s result ``res`` (:func:`compute_case`) and say one line with the
        overall progress and the time left (s); a case refused for its input raises InputError."""
        self.done += 1
        r, n, done = self.runs[i], self.n, self.done
        for w in res.get("warnings", []):  # the same for every case: said once, even with -q
            if w not in self.warned and self.rank0:
                self.warned.add(w)
                print(f"millimpact: {w}", file=sys.stderr, flush=True)
        if res["ok"]:
            r.status, r.wall_time_s = "computed", res["wall_time_s"]
            self.computed_walls.append(res["wall_time_s"])
            left = len(self.todo) - len(self.computed_walls)
            elapsed = time.perf_counter() - self.t_start
            # cases finish about jobs at a time: the time per finished case already includes that
            eta = f", ~{elapsed / len(self.computed_walls) * left:.0f} s left" if left else ""
            self.say(
                f"  [{done}/{n}] {r.case.label:<22s} computed in {res['wall_time_s']:.1f} s "
                f"(elapsed {elapsed:.0f} s{eta})"
            )
        else:
            r.status, r.error = "failed", res["error"]
            self.say(f"  [{done}/{n}] {r.case.label:<22s} FAILED: {res['error']}")
            if res.get("input"):
                raise InputError(f"case {r.case.label}: {res['error']}")


def _take_cached(loop: _CaseLoop, force: bool, comm) -> None:
    """Fill ``loop`` with the cases whose complete folder was computed with the same key (rank 0
    reads them; ``force``: none) and the list of the others to compute, shared with all ranks;
    says one line per cached case."""
    if loop.rank0:
        for i, c in enumerate(loop.study.cases):
            s = None if force else cached_summary(loop.out / c.folder, loop.keys[i])
            if s is not None:
                loop.runs[i].status, loop.runs[i].summary = "cached", s
                loop.runs[i].wall_time_s = float(s.get("wall_time_s", math.nan))
            else:
                loop.todo.append(i)
    if comm is not None and comm.size > 1:
        loop.todo = comm.bcast(loop.todo, root=0)
    loop.t_start = time.perf_counter()
    for r in loop.runs:
        if r.status == "cached":
            loop.done += 1
            loop.say(f"  [{loop.done}/{loop.n}] {r.case.label:<22s} cached ({loop.out / r.case.folder})")


def _run_in_pool(loop: _CaseLoop) -> list[int]:
    """Compute ``loop.todo`` in ``loop.jobs`` spawned worker processes (one serial case each);
    returns the cases left to compute in this process: none, or those a worker that ended without
    a word left unfinished (its folders' stages removed). Ctrl-C or an error stops the workers and
    removes their stages (StudyInterrupted for an interrupt)."""
    import concurrent.futures as cf
    import multiprocessing as mp

    todo, out, study = loop.todo, loop.out, loop.study
    # each case serial: no threaded BLAS fighting over the cores the other cases use
    share_blas_threads(min(loop.jobs, len(todo)))
    for var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(var, "1")
    # spawn, not fork: a forked child would inherit the parent's MPI/PETSc state
    serial: list[int] = []
    with cf.ProcessPoolExecutor(max_workers=min(loop.jobs, len(todo)), mp_context=mp.get_context("spawn")) as pool:
        futures = {pool.submit(_worker, loop.task(i)): i for i in todo}
        try:
            for fut in cf.as_completed(futures):
                loop.report(futures[fut], fut.result())
        except cf.process.BrokenProcessPool:
            # a worker ended without a word (killed, or a library's exit(): CI runs saw gmsh's,
            # fixed in geometry.builders.gmsh_session): its cases and those not yet finished
            # are computed again here, one after the other, and the exit codes said. The codes
            # are read once every worker has ended and been reaped: the pool's thread SIGTERMs
            # the other workers while this one wakes, and reaps the lost one later (read at
            # once, the codes were [1], [-15], [-15, 1] or unknown from run to run)
            procs = list((getattr(pool, "_processes", None) or {}).values())
            killed = stop_workers(procs)
            pool.shutdown(wait=True)  # its thread joins every worker
            codes = lost_worker_codes(procs, killed)
            serial = [i for i in todo if loop.runs[i].status == "pending"]
            remove_stages(out, [study.cases[i].folder for i in serial])
            if loop.rank0:
                print(
                    f"millimpact: warning: a study worker process ended without a word (exit codes "
                    f"{codes or 'unknown'}); computing its {len(serial)} unfinished case(s) in this process",
                    file=sys.stderr,
                    flush=True,
                )
        except BaseException as exc:
            for f in futures:
                f.cancel()
            # stop the running cases now: the executor has no public handle on its processes,
            # and waiting would take minutes
            stop_workers(list((getattr(pool, "_processes", None) or {}).values()))
            pool.shutdown(wait=True, cancel_futures=True)
            remove_stages(out, [study.cases[i].folder for i in todo])
            if isinstance(exc, KeyboardInterrupt):
                raise StudyInterrupted(
                    loop.done, loop.n, getattr(exc, "exit_code", 143 if type(exc).__name__ == "Terminated" else 130)
                ) from None
            raise
    return serial


def _run_serial(loop: _CaseLoop, serial: list[int], comm) -> None:
    """Compute the cases ``serial`` in this process (on all ranks of ``comm``), one after the
    other; Ctrl-C raises StudyInterrupted with the count of cases done."""
    try:
        for i in serial:
            if loop.progress and not loop.quiet:
                loop.say(f"  [{loop.done + 1}/{loop.n}] {loop.study.cases[i].label:<22s} computing ...")
            loop.report(i, compute_case(loop.task(i), comm))
    except KeyboardInterrupt as exc:
        raise StudyInterrupted(loop.done, loop.n, 143 if type(exc).__name__ == "Terminated" else 130) from None


def _read_results(runs: list[CaseRun], out: Path) -> None:
    """Read each computed or cached case's summary (if not yet read) and time series from its
    folder under ``out``."""
    from ..results.timeseries import TimeSeries

    for r in runs:
        if r.status in ("computed", "cached"):
            folder = out / r.case.folder
            if r.summary is None:
                r.summary = json.loads((folder / "summary.json").read_text())
            r.series = TimeSeries.read_csv(folder / "timeseries.csv")


def run_cases(
    study: Study,
    out: Path,
    method: str,
    options: dict,
    jobs: int = 1,
    progress: bool = True,
    force: bool = False,
    figures: bool = True,
    comm=None,
    quiet: bool = False,
) -> list[CaseRun]:
    """Run (or take from the cache) every case of ``study`` into ``out/<case>``; prints one line a
    case with the overall progress. ``comm`` (size > 1): each case runs on all its ranks."""
    rank0 = comm is None or comm.rank == 0
    loop = _CaseLoop(
        study,
        out,
        method,
        options,
        keys=[case_key(c.scene, method, options) for c in study.cases],
        runs=[CaseRun(c, "pending") for c in study.cases],
        todo=[],
        jobs=jobs,
        progress=progress,
        figures=figures,
        quiet=quiet,
        rank0=rank0,
        say=sayer(quiet, comm),
    )
    _take_cached(loop, force, comm)
    serial = list(loop.todo)  # the cases this process computes itself, one after the other
    if loop.todo and jobs > 1 and len(loop.todo) > 1:
        serial = _run_in_pool(loop)
    _run_serial(loop, serial, comm)
    if rank0:
        _read_results(loop.runs, out)
    return loop.runs
