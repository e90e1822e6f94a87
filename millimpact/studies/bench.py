"""``millimpact bench [SCENE]``: speed against accuracy for every method.

Every method runs at several resolutions, each run in its own Python process (so its peak memory,
``resource.getrusage(RUSAGE_SELF).ru_maxrss`` at its end, is its own), and is scored against a
converged reference run of the same scene:

=================  ================================================================
entry              resolutions
=================  ================================================================
``hertz``          none (closed-form ODE, one run)
``hertz-modal``    block modes up to f_cut = 2, 4, 8 / t_c (coarse block mesh)
``traditional``    mesh levels (h_contact = a_max / 1.5, 2, 3; h_far 2, 1.5, 1 x base)
``improved``       mesh levels, as above
``modal-p2``       mesh levels
``full-p1``        ``full`` P1, mesh levels
``full-p2``        ``full`` P2, mesh levels
``full-cp``        ``full`` P1 with the explicit ``central-penalty`` integrator, mesh levels
=================  ================================================================

The reference is ``full`` P2 one level finer than the finest bench level (h_contact = a_max / 4,
h_far the base) with half the contact step (t_c / 200). It is cached under
``$MILLIMPACT_BENCH_CACHE`` (default ``out/bench-cache``), keyed by a sha256 of the resolved scene,
method and options; its own convergence (reference levels 1..3 against level 4) is drawn in
``reference_convergence.png``. ``base`` is the plan's h_far (smallest body size / 4).

Errors (relative to the reference): peak contact force F_max, contact duration t_c, impulse of
the first pulse, and the L2-in-time errors ||x - x_ref|| / ||x_ref|| of the contact force (over
[0, gap/v + 2 t_c], step t_c / 400) and of gauge A's stress (over the whole run, step
t_c / 100), after linear interpolation onto those common grids.

Output under ``--out``: ``bench.csv`` (one row per run, ``method`` column, units in the header),
``pareto.png`` (log-log error against wall time, one line per method, for the force L2, F_max and
gauge errors), ``reference_convergence.png``, ``bench.json`` (rows, reference, machine, the
ratio of wall times of ``improved`` to ``full`` at equal error). Wall times are measured side by
side in one bench on a shared machine: compare ratios, not absolute seconds.
"""

from __future__ import annotations

import argparse
import csv
import hashlib
import json
import logging
import math
import os
import platform
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # numpy is imported where the command computes (`millimpact --help` stays fast)
    import numpy as np

from ..console import sayer
from ..errors import InputError
from ..interrupts import children_signals
from ..results.output_folder import FORCE_HELP, OUT_HELP

log = logging.getLogger(__name__)

HELP = "chart speed against accuracy for every method (CSV, Pareto figure, reference convergence)"
DESCRIPTION = __doc__

#: bench entry -> (run method, fixed options, resolution kind)
ENTRIES: dict[str, tuple[str, dict, str]] = {
    "hertz": ("hertz", {}, "none"),
    "hertz-modal": ("hertz-modal", {}, "f_cut"),
    "traditional": ("traditional", {}, "mesh"),
    "improved": ("improved", {}, "mesh"),
    "modal-p2": ("modal-p2", {}, "mesh"),
    "full-p1": ("full", {"degree": 1}, "mesh"),
    "full-p2": ("full", {"degree": 2}, "mesh"),
    # the integrator's default safety (0.9 of the linear critical step) diverged on the sphere
    # impact in the stability sweep (millimpact stability: stable at 0.7, failed at 0.9): 0.6
    "full-cp": ("full", {"degree": 1, "integrator": "central-penalty", "critical_step_safety": 0.6}, "mesh"),
}
#: mesh levels: (a_max / h_contact, h_far / base)
MESH_LEVELS = ((1.5, 2.0), (2.0, 1.5), (3.0, 1.0))
REFERENCE_LEVELS = ((1.5, 2.0), (2.0, 1.5), (3.0, 1.0), (4.0, 1.0))
F_CUT_FACTORS = (2.0, 4.0, 8.0)  # x 1 / t_c
#: quick: the coarsest meshes on which every method runs (h_far 3 x base failed the reduced
#: methods' effective-matrix factorization); the reference is the finer level itself, at half the step
QUICK_MESH_LEVELS = ((1.2, 2.0), (1.5, 2.0))
QUICK_REFERENCE_LEVELS = ((1.2, 2.0), (1.5, 2.0))
QUICK_F_CUT = (2.0, 4.0)
#: a run whose energy drifts by more than this share of the impact energy, or whose F_max is off by
#: more than 100 %, is marked "unstable" (its errors stay in the CSV but out of the figures)
UNSTABLE_ENERGY_DRIFT = 0.5
#: default simulated time after first contact, in t_c (impact plus the block's first ringing)
DEFAULT_END_TC = 4.0
CACHE_ENV = "MILLIMPACT_BENCH_CACHE"


@dataclass
class RunSpec:
    """One bench run: a scene (name or file) with field overrides, a method and its options."""

    entry: str
    method: str
    scene: str
    sets: dict[str, Any]
    options: dict[str, Any]
    resolution: str
    level: float

    def key(self, resolved: dict) -> str:
        """Cache key: sha256 of the resolved scene, method and options."""
        from .. import __version__

        blob = json.dumps(
            {"scene": resolved, "method": self.method, "options": self.options, "version": __version__},
            sort_keys=True,
            default=str,
        )
        return hashlib.sha256(blob.encode()).hexdigest()[:24]


@dataclass
class RunResult:
    """What one run measured (SI units)."""

    spec: RunSpec
    ok: bool
    wall_s: float = math.nan
    peak_rss_mb: float = math.nan
    dofs: int = 0
    solved_dofs: int = 0
    metrics: dict = field(default_factory=dict)
    series: dict | None = None
    error: str = ""


# --- the worker (one run in its own process) -------------------------------------------------------
def _worker(spec_json: str, out_dir: str) -> int:
    """Run one spec; write ``result.json`` and ``series.npz`` into ``out_dir``."""
    import resource

    import numpy as np

    from ..geometry.mesh import create_mesh
    from ..methods.run import compute
    from ..results.timeseries import contact_metrics
    from ..scene.builtin import resolve_scene
    from ..scene.plan import make_plan

    spec = json.loads(spec_json)
    scene = resolve_scene(spec["scene"])
    for k, v in spec["sets"].items():
        scene = scene.with_value(k, v)
    out = Path(out_dir)
    if spec["method"] != "hertz":
        # warm the mesh cache outside the timed region (gmsh runs once per mesh, not per method)
        from mpi4py import MPI

        plan = make_plan(scene)
        wscene = scene
        if spec["method"] == "hertz-modal" and scene.model.h_contact is None:
            from ..methods.hertz_modal import COARSE_H_CONTACT

            wscene = scene.with_value("model.h_contact", COARSE_H_CONTACT * plan.hertz.a_max)
        create_mesh(wscene, make_plan(wscene), MPI.COMM_WORLD)
    t0 = time.perf_counter()
    res, plan = compute(scene, spec["method"], dict(spec["options"]), progress=False)
    wall = time.perf_counter() - t0
    m = contact_metrics(res.series)
    model = res.model
    dofs = int(model.get("fe_dofs", model.get("dofs", 1)))
    solved = int(model.get("reduced_dofs", model.get("dofs", 1)))
    rss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # kB -> MB (Linux)
    np.savez(out / "series.npz", **{k: np.asarray(v) for k, v in res.series.columns.items()})
    (out / "result.json").write_text(
        json.dumps(
            {
                "wall_s": wall,
                "peak_rss_mb": rss,
                "dofs": dofs,
                "solved_dofs": solved,
                "metrics": m,
                "results": {k: v for k, v in res.results.items() if isinstance(v, (int, float))},
                "t_c_hertz_s": plan.hertz.contact_time,
                "gap_m": plan.gap,
                "speed_m_s": plan.hertz.speed,
                "model": {k: v for k, v in model.items() if isinstance(v, (int, float, str))},
            },
            indent=1,
            default=float,
        )
    )
    return 0


def run_spec(spec: RunSpec, folder: Path, timeout: float = 7200) -> RunResult:
    """Run ``spec`` in a fresh ``python -m millimpact.studies.bench --worker`` process; results in
    ``folder``."""
    folder.mkdir(parents=True, exist_ok=True)
    payload = json.dumps(spec.__dict__, default=float)
    env = dict(os.environ, MPLBACKEND="Agg")
    with open(folder / "worker.log", "w") as log_fh, children_signals():
        proc = subprocess.run(
            [sys.executable, "-m", "millimpact.studies.bench", "--worker", payload, str(folder)],
            stdout=log_fh,
            stderr=subprocess.STDOUT,
            env=env,
            timeout=timeout,
        )
    if proc.returncode != 0 or not (folder / "result.json").exists():
        tail = (folder / "worker.log").read_text().strip().splitlines()[-1:] or ["?"]
        return RunResult(spec, False, error=f"exit {proc.returncode}: {tail[0][:200]}")
    return load_result(spec, folder)


def load_result(spec: RunSpec, folder: Path) -> RunResult:
    """Read a finished run's folder."""
    import numpy as np

    r = json.loads((folder / "result.json").read_text())
    with np.load(folder / "series.npz") as z:
        series = {k: z[k] for k in z.files}
    return RunResult(
        spec,
        True,
        r["wall_s"],
        r["peak_rss_mb"],
        r["dofs"],
        r["solved_dofs"],
        {
            **r["metrics"],
            "t_c_hertz_s": r["t_c_hertz_s"],
            "gap_m": r["gap_m"],
            "speed_m_s": r["speed_m_s"],
            **{f"result_{k}": v for k, v in r["results"].items()},
        },
        series,
    )


# --- errors against the reference ------------------------------------------------------------------
def _l2_rel(t: np.ndarray, x: np.ndarray, t_ref: np.ndarray, x_ref: np.ndarray, grid: np.ndarray) -> float:
    """||x - x_ref|| / ||x_ref|| on ``grid`` after linear interpolation (zero outside a series)."""
    import numpy as np

    a = np.interp(grid, t, x, left=0.0, right=0.0)
    b = np.interp(grid, t_ref, x_ref, left=0.0, right=0.0)
    nb = np.linalg.norm(b)
    return float(np.linalg.norm(a - b) / nb) if nb > 0 else math.nan


def score(run: RunResult, ref: RunResult, gauge: str | None) -> dict[str, float]:
    """Relative errors of a run against the reference (module docstring)."""
    import numpy as np

    m, r = run.metrics, ref.metrics
    t_c = r["t_c_hertz_s"]
    t0 = r["gap_m"] / r["speed_m_s"]
    out = {
        "err_F_max": m["peak_contact_force_N"] / r["peak_contact_force_N"] - 1.0,
        "err_t_c": m["contact_duration_s"] / r["contact_duration_s"] - 1.0,
        "err_impulse": m["impulse_N_s"] / r["impulse_N_s"] - 1.0,
    }
    s, sr = run.series, ref.series
    assert s is not None and sr is not None, "a scored run and its reference carry their series"
    grid = np.arange(0.0, t0 + 2.0 * t_c, t_c / 400.0)
    out["err_force_L2"] = _l2_rel(s["time_s"], s["contact_force_N"], sr["time_s"], sr["contact_force_N"], grid)
    col = f"gauge_{gauge}_stress_Pa" if gauge else None
    if col and col in s and col in sr:
        t_end = min(float(s["time_s"][-1]), float(sr["time_s"][-1]))
        g = np.arange(0.0, t_end, t_c / 100.0)
        out["err_gauge_L2"] = _l2_rel(s["time_s"], s[col], sr["time_s"], sr[col], g)
    else:
        out["err_gauge_L2"] = math.nan
    return out


# --- plan of the bench -----------------------------------------------------------------------------
def bench_specs(
    scene_name: str, end: float, entries: list[str], quick: bool, base_far: float, a_max: float, t_c: float
) -> list[RunSpec]:
    """The runs of a bench (without the reference)."""
    levels = QUICK_MESH_LEVELS if quick else MESH_LEVELS
    specs = []
    for e in entries:
        method, opts, kind = ENTRIES[e]
        base_sets = {"time.end": end, "outputs.xdmf": False, "outputs.figures": False}
        if kind == "none":
            specs.append(RunSpec(e, method, scene_name, base_sets, dict(opts), "-", 0))
        elif kind == "f_cut":
            for f in QUICK_F_CUT if quick else F_CUT_FACTORS:
                specs.append(
                    RunSpec(e, method, scene_name, base_sets, {**opts, "f_cut": f / t_c}, f"f_cut = {f:g}/t_c", f)
                )
        else:
            for i, (ac, fr) in enumerate(levels):
                sets = {**base_sets, "model.h_contact": a_max / ac, "model.h_far": base_far * fr}
                specs.append(
                    RunSpec(
                        e,
                        method,
                        scene_name,
                        sets,
                        dict(opts),
                        f"h_c = a_max/{ac:g}, h_far = {base_far * fr * 1e3:.3g} mm",
                        i + 1,
                    )
                )
    return specs


def reference_specs(
    scene_name: str, end: float, quick: bool, base_far: float, a_max: float, t_c: float
) -> list[RunSpec]:
    """The reference's convergence levels (the last one is the reference)."""
    out = []
    levels = QUICK_REFERENCE_LEVELS if quick else REFERENCE_LEVELS
    for i, (ac, fr) in enumerate(levels):
        sets = {
            "time.end": end,
            "outputs.xdmf": False,
            "outputs.figures": False,
            "model.h_contact": a_max / ac,
            "model.h_far": base_far * fr,
            "time.dt_contact": t_c / 200.0,
        }
        out.append(
            RunSpec(
                "reference",
                "full",
                scene_name,
                sets,
                {"degree": 2},
                f"P2, h_c = a_max/{ac:g}, h_far = {base_far * fr * 1e3:.3g} mm, dt = t_c/200",
                i + 1,
            )
        )
    return out


def cached_run(spec: RunSpec, cache: Path, say) -> RunResult:
    """A reference-level run from the cache, or run (and store) it."""
    from ..scene.builtin import resolve_scene
    from ..scene.toml_io import scene_to_dict

    scene = resolve_scene(spec.scene)
    for k, v in spec.sets.items():
        scene = scene.with_value(k, v)
    folder = cache / spec.key(scene_to_dict(scene))
    if (folder / "result.json").exists():
        say(f"  reference level {spec.level:g} ({spec.resolution}): cached {folder}")
        return load_result(spec, folder)
    say(f"  reference level {spec.level:g} ({spec.resolution}): running ...")
    res = run_spec(spec, folder)
    if not res.ok:
        raise RuntimeError(f"reference run failed ({spec.resolution}): {res.error} (log {folder}/worker.log)")
    say(f"    {res.wall_s:.1f} s, {res.dofs} dofs")
    return res


# --- output ----------------------------------------------------------------------------------------
CSV_FIELDS = [
    "method",
    "run_method",
    "resolution",
    "level",
    "options",
    "status",
    "wall_s",
    "peak_rss_MB",
    "dofs",
    "solved_dofs",
    "F_max_N",
    "t_c_s",
    "impulse_N_s",
    "err_F_max",
    "err_t_c",
    "err_impulse",
    "err_force_L2",
    "err_gauge_L2",
    "note",
]


def write_csv(rows: list[dict], path: Path) -> None:
    """bench.csv: one row per run; errors are relative (signed for scalars, L2 norms >= 0)."""
    with open(path, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=CSV_FIELDS, extrasaction="ignore")
        w.writeheader()
        for r in rows:
            w.writerow({k: (f"{v:.6g}" if isinstance(v, float) else v) for k, v in r.items()})


def read_csv(path: Path) -> list[dict[str, str]]:
    """The rows of a bench.csv."""
    with open(path) as fh:
        return list(csv.DictReader(fh))


ERRORS = (
    ("err_force_L2", "contact force, L2-in-time error"),
    ("err_F_max", "|F_max error|"),
    ("err_gauge_L2", "gauge A stress, L2-in-time error"),
)


def plot_pareto(rows: list[dict], path: Path, title: str) -> None:
    """Log-log error against wall time, one line per method, a panel per error measure."""
    import numpy as np

    from ..results.plots import pyplot

    plt = pyplot()

    methods = [m for m in ENTRIES if any(r["method"] == m and r["status"] == "ok" for r in rows)]
    fig, axes = plt.subplots(1, len(ERRORS), figsize=(5.2 * len(ERRORS), 4.6))
    cmap = plt.get_cmap("tab10")
    for ax, (key, label) in zip(axes, ERRORS):
        for i, m in enumerate(methods):
            rs = sorted([r for r in rows if r["method"] == m and r["status"] == "ok"], key=lambda r: r["wall_s"])
            x = np.array([r["wall_s"] for r in rs])
            y = np.abs(np.array([r[key] for r in rs], dtype=float))
            ok = np.isfinite(y) & (y > 0)
            if not ok.any():
                continue
            ax.loglog(x[ok], y[ok], "o-", color=cmap(i), label=m, ms=5)
        ax.set_xlabel("wall time (s, one process, shared 2-core machine)")
        ax.set_ylabel(f"{label} (relative)")
        ax.grid(True, which="both", alpha=0.3)
        ax.set_title(label, fontsize=10)
    axes[0].legend(fontsize=8)
    fig.suptitle(title, fontsize=11)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_reference_convergence(levels: list[RunResult], path: Path, title: str) -> dict[str, Any]:
    """The reference levels' errors against the finest (F_max, t_c, force L2) against h_contact,
    with fitted rates; returns the numbers."""
    import numpy as np

    from ..results.plots import pyplot

    plt = pyplot()

    ref = levels[-1]
    h = np.array([lv.spec.sets["model.h_contact"] for lv in levels[:-1]])
    errs = {
        k: np.array([abs(score(lv, ref, "A")[k]) for lv in levels[:-1]])
        for k in ("err_F_max", "err_t_c", "err_force_L2", "err_gauge_L2")
    }
    fig, ax = plt.subplots(figsize=(6.4, 4.6))
    rates = {}
    for k, lab in (
        ("err_F_max", "F_max"),
        ("err_t_c", "t_c"),
        ("err_force_L2", "contact force L2"),
        ("err_gauge_L2", "gauge A L2"),
    ):
        y = errs[k]
        ok = np.isfinite(y) & (y > 0)
        if ok.sum() >= 1:
            if ok.sum() >= 2:
                rates[k] = float(np.polyfit(np.log(h[ok]), np.log(y[ok]), 1)[0])
            ax.loglog(h[ok] * 1e3, y[ok], "o-", label=f"{lab}" + (f" (rate {rates[k]:.2g})" if k in rates else ""))
    ax.set_xlabel("h_contact (mm)")
    ax.set_ylabel("relative difference to the finest level")
    ax.set_title(title + f"\nfinest: {ref.spec.resolution}, {ref.dofs} dofs", fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return {
        "h_contact_m": h.tolist(),
        "errors": {k: v.tolist() for k, v in errs.items()},
        "rates": rates,
        "finest": {
            "resolution": ref.spec.resolution,
            "dofs": ref.dofs,
            "wall_s": ref.wall_s,
            "F_max_N": ref.metrics["peak_contact_force_N"],
            "t_c_s": ref.metrics["contact_duration_s"],
        },
    }


def equal_error_ratio(rows: list[dict], a: str, b: str, key: str = "err_force_L2") -> dict[str, Any]:
    """Wall time of method ``a`` over method ``b`` at equal error: both methods' (log wall, log
    error) lines interpolated at the error levels they share; the geometric mean of the ratios
    there, else (no overlap) None with each method's range."""
    import numpy as np

    def line(m):
        rs = [r for r in rows if r["method"] == m and r["status"] == "ok" and np.isfinite(r[key]) and r[key] != 0]
        pts = sorted((math.log(abs(r[key])), math.log(r["wall_s"])) for r in rs)
        return np.array(pts) if pts else np.zeros((0, 2))

    la, lb = line(a), line(b)
    out: dict[str, Any] = {
        "a": a,
        "b": b,
        "error": key,
        "a_error_range": [float(np.exp(la[:, 0].min())), float(np.exp(la[:, 0].max()))] if len(la) else None,
        "b_error_range": [float(np.exp(lb[:, 0].min())), float(np.exp(lb[:, 0].max()))] if len(lb) else None,
    }
    if len(la) < 1 or len(lb) < 1:
        out["ratio"] = None
        return out
    lo, hi = max(la[:, 0].min(), lb[:, 0].min()), min(la[:, 0].max(), lb[:, 0].max())
    if lo > hi:
        out["ratio"] = None
        return out
    e = np.linspace(lo, hi, 5)
    ta = np.interp(e, la[:, 0], la[:, 1])
    tb = np.interp(e, lb[:, 0], lb[:, 1])
    out["ratio"] = float(np.exp(np.mean(ta - tb)))
    out["at_errors"] = [float(np.exp(lo)), float(np.exp(hi))]
    return out


# --- command line ----------------------------------------------------------------------------------
def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("scene", nargs="?", help="built-in scene name or TOML file (default: paper-rig)")
    p.add_argument("--out", help=OUT_HELP.format(default="out/bench-SCENE"))
    p.add_argument("--force", action="store_true", help=FORCE_HELP)
    p.add_argument("--quick", action="store_true", help="tiny sizes (tests): two coarse mesh levels, short run")
    p.add_argument("--methods", default=",".join(ENTRIES), help=f"comma-separated subset of {', '.join(ENTRIES)}")
    p.add_argument("--end", type=float, help=f"simulated time, s (default gap/v + {DEFAULT_END_TC:g} t_c)")


@dataclass
class _BenchSetup:
    """What a bench runs: the ``scene`` (``scene_name``: a built-in name or a TOML file's absolute
    path, passed to the runs), the bench ``entries``, the simulated time ``end`` (s), the plan's
    ``base_far`` (m), Hertz a_max (m) and t_c (s), the claimed output ``target`` and the
    reference ``cache`` folder."""

    scene: Any
    scene_name: str
    entries: list[str]
    end: float
    base_far: float
    a_max: float
    t_c: float
    target: Any
    cache: Path


def _bench_setup(args: argparse.Namespace) -> _BenchSetup:
    """Read the command line: refuse mpirun, unknown ``--methods`` and an ``--end`` (s) before
    contact; plan the scene; claim the output folder (before any run) and say what will run."""
    from mpi4py import MPI

    from ..results.output_folder import claim_output, default_out
    from ..scene.builtin import DEFAULT_SCENE, resolve_scene
    from ..scene.plan import make_plan

    if MPI.COMM_WORLD.size > 1:
        raise InputError("millimpact bench runs its own processes: start it without mpirun")
    entries = [x.strip() for x in args.methods.split(",") if x.strip()]
    unknown = [x for x in entries if x not in ENTRIES]
    if unknown or not entries:
        raise InputError(f"--methods {args.methods!r}: choose from {', '.join(ENTRIES)}")
    scene_name = args.scene or DEFAULT_SCENE
    scene = resolve_scene(scene_name)
    if scene_name.endswith(".toml"):
        scene_name = str(Path(scene_name).resolve())
    plan = make_plan(scene)
    h = plan.hertz
    end = (
        args.end
        if args.end is not None
        else plan.gap / h.speed + (1.2 if args.quick else DEFAULT_END_TC) * h.contact_time
    )
    if not (end > plan.gap / h.speed):
        raise InputError(f"--end = {end!r} s: must exceed the flight to contact, {plan.gap / h.speed:.3g} s")
    target = claim_output(
        args.out if args.out is not None else default_out(scene.name, prefix="bench-"), "bench", force=args.force
    )  # before the runs
    cache = Path(os.environ.get(CACHE_ENV, "out/bench-cache"))
    print(
        f"bench of scene '{scene.name}': {', '.join(entries)}; end {end * 1e6:.4g} us"
        + (" (quick)" if args.quick else "")
        + f" -> {target.shown}/",
        flush=True,
    )
    return _BenchSetup(scene, scene_name, entries, end, plan.h_far, h.a_max, h.contact_time, target, cache)


#: the CSV columns of a failed run, all NaN
_FAILED_NAN_FIELDS = (
    "F_max_N",
    "t_c_s",
    "impulse_N_s",
    "err_F_max",
    "err_t_c",
    "err_impulse",
    "err_force_L2",
    "err_gauge_L2",
)


def _bench_row(i: int, n: int, spec: RunSpec, res: RunResult, ref: RunResult, gauge: str | None, say) -> dict:
    """The CSV row of run ``i`` (of ``n``): its cost (wall s, peak MB, DOFs), results (N, s, N s)
    and errors against ``ref`` (:func:`score`); "unstable" when an error is not finite, F_max is
    off by more than 100 % or the energy drift exceeds UNSTABLE_ENERGY_DRIFT; says one line."""
    row: dict[str, Any] = {
        "method": spec.entry,
        "run_method": spec.method,
        "resolution": spec.resolution,
        "level": spec.level,
        "options": json.dumps(spec.options, sort_keys=True),
    }
    if not res.ok:
        row.update(
            status="failed",
            wall_s=math.nan,
            peak_rss_MB=math.nan,
            dofs=0,
            solved_dofs=0,
            **{k: math.nan for k in _FAILED_NAN_FIELDS},
            note=res.error,
        )
        say(f"  [{i + 1}/{n}] {spec.entry:12s} {spec.resolution:40s} FAILED: {res.error}")
        return row
    drift = res.metrics.get("result_energy_drift_max_rel", 0.0)
    sc = score(res, ref, gauge)
    bad = (
        not all(math.isfinite(sc[k]) for k in ("err_F_max", "err_t_c", "err_force_L2"))
        or abs(sc["err_F_max"]) > 1.0
        or drift > UNSTABLE_ENERGY_DRIFT
    )
    row.update(
        status="unstable" if bad else "ok",
        wall_s=res.wall_s,
        peak_rss_MB=res.peak_rss_mb,
        dofs=res.dofs,
        solved_dofs=res.solved_dofs,
        F_max_N=res.metrics["peak_contact_force_N"],
        t_c_s=res.metrics["contact_duration_s"],
        impulse_N_s=res.metrics["impulse_N_s"],
        **sc,
        note=f"energy drift {drift:.3g}" if bad else "",
    )
    say(
        f"  [{i + 1}/{n}] {spec.entry:12s} {spec.resolution:40s} {row['status']:8s} {res.wall_s:7.1f} s "
        f"{res.peak_rss_mb:6.0f} MB {res.dofs:7d} dofs  F_max {100 * sc['err_F_max']:+6.2f} %  "
        f"force L2 {100 * sc['err_force_L2']:6.2f} %  gauge L2 {100 * sc['err_gauge_L2']:6.2f} %"
    )
    return row


def _write_bench(
    stage: Path, setup: _BenchSetup, rows: list[dict], ref_levels: list[RunResult], quick: bool, t_all: float
) -> dict[str, dict[str, Any]]:
    """Write bench.csv, pareto.png, reference_convergence.png and bench.json into ``stage``;
    returns the wall-time ratios at equal error (:func:`equal_error_ratio`) of the pairs run."""
    scene, ref = setup.scene, ref_levels[-1]
    write_csv(rows, stage / "bench.csv")
    title = f"{scene.name}: error against wall time (reference: full {ref.spec.resolution})"
    plot_pareto(rows, stage / "pareto.png", title)
    conv = plot_reference_convergence(
        ref_levels, stage / "reference_convergence.png", f"{scene.name}: convergence of the reference (full P2)"
    )
    ratios = {
        f"{a}/{b}": equal_error_ratio(rows, a, b)
        for a, b in (("improved", "full-p2"), ("improved", "full-p1"), ("traditional", "full-p1"))
        if a in setup.entries and b in setup.entries
    }
    meta = {
        "scene": scene.name,
        "end_s": setup.end,
        "quick": quick,
        "reference": conv,
        "equal_error_wall_ratio": ratios,
        "machine": {
            "node": platform.node(),
            "cpus": os.cpu_count(),
            "python": platform.python_version(),
            "note": "shared machine: wall times are noisy, compare ratios",
        },
        "total_wall_s": time.perf_counter() - t_all,
        "rows": rows,
    }
    (stage / "bench.json").write_text(json.dumps(meta, indent=1, default=float))
    return ratios


def main(args: argparse.Namespace) -> int:
    """``millimpact bench``: the reference levels (cached), then every entry's runs, each scored
    against the finest reference level; writes the CSV, figures and JSON (module docstring)."""
    setup = _bench_setup(args)
    target = setup.target
    out = target.shown
    t_all = time.perf_counter()
    say = sayer()
    ref_levels = [
        cached_run(s, setup.cache, say)
        for s in reference_specs(setup.scene_name, setup.end, args.quick, setup.base_far, setup.a_max, setup.t_c)
    ]
    ref = ref_levels[-1]
    gauge = setup.scene.gauges[0].name if setup.scene.gauges else None
    specs = bench_specs(setup.scene_name, setup.end, setup.entries, args.quick, setup.base_far, setup.a_max, setup.t_c)
    rows: list[dict] = []
    with target.staged() as stage:
        for i, spec in enumerate(specs):
            res = run_spec(spec, stage / "runs" / f"{i:02d}-{spec.entry}")
            rows.append(_bench_row(i, len(specs), spec, res, ref, gauge, say))
        ratios = _write_bench(stage, setup, rows, ref_levels, args.quick, t_all)
    for k, r in ratios.items():
        if r.get("ratio") is not None:
            say(
                f"wall time {k} at equal contact-force L2 error ({r['at_errors'][0]:.2g}-{r['at_errors'][1]:.2g}): "
                f"{r['ratio']:.3g}"
            )
        else:
            say(f"wall time {k}: no common error range ({r['a_error_range']} vs {r['b_error_range']})")
    say(
        f"bench done in {time.perf_counter() - t_all:.0f} s: {out}/bench.csv, pareto.png, reference_convergence.png"
        + target.replaced_note()
    )
    return 0


if __name__ == "__main__":
    if len(sys.argv) == 4 and sys.argv[1] == "--worker":
        logging.basicConfig(level=logging.WARNING)
        sys.exit(_worker(sys.argv[2], sys.argv[3]))
    sys.exit("usage: millimpact bench ... (python -m millimpact.studies.bench --worker SPEC DIR is internal)")
