"""The table engine: DEM contact tables, one impact per (speed, angle[, radius]), the reduction reused
(its command line, ``millimpact table``, is :mod:`.table_command`).

DEM codes describe a ball-liner contact by a few numbers: normal and tangential restitution against
impact speed and angle, a force law, the energy the liner keeps. A table runs one impact per case
and writes them as rows (:mod:`.table_report`: ``contact_table.csv`` / ``.json`` / ``.h5``, figures,
fitted laws).

Cases. The angle is measured from the face normal n, in the plane the scene's impact vector defines
(the scene's tangential direction; for a normal scene, the plane x = x_p through the impact point,
which holds n for the block and every liner face and keeps the half model's symmetry plane):
``v = V (-cos(angle) n + sin(angle) t)``. Each case runs the impact only: to ``gap / v_n +
CUT_CONTACT_TIMES t_c`` (Hertz t_c of its normal speed), not the scene's end time.

Reuse. Cases of one radius whose normal speeds lie on one rung of a fixed ladder, [BAND_BASE
BAND_RATIO^k, BAND_BASE BAND_RATIO^(k+1)) (:func:`band_rung`), and whose own symmetry is the same
(a normal impact on a back-clamped block keeps a quarter, an oblique one a half), share one mesh and
one offline reduction (the reduced methods): the band's mesh has h_contact = a_max / 4 of the rung's
slow edge and the zone (and contact candidates), the modal cutoff and the time step t_c / 100 of a
normal impact at its fast edge (the band scene, :func:`band_settings`), one gap, so every case of
the band runs on the same reduced model, with the same factorized step operators and contact
operator W, from its own initial velocity (:func:`millimpact.methods.reduced.run_reduced_case`).
The ladder is fixed, not fitted to the table's speeds, so that a case's mesh, reduction and result
depend on the case alone: the same case in two tables (a fixed grid and an adaptive one,
:mod:`.table_adaptive`) is the same computation and the same key. ``full`` and ``hertz`` run each
case as a standalone run (no reduction to reuse).

Reruns. Each finished case is kept as ``cases/<key>.json`` (key: a hash of the case's resolved
scene, the method, its options and the version); a rerun computes only missing or changed cases,
and an interrupted table keeps the finished ones.

Parallel. Under ``mpirun -n N``, ``--ranks-per-case K`` splits MPI_COMM_WORLD into N / K groups of K
ranks (``Comm.Split``); the groups take the next case from a shared state (an MPI window on rank 0,
read and written under an exclusive lock), so a slow case does not idle the others. Bands and
their cases are taken dearest first (the fastest normal speed first: :func:`costliest_first`). A
group stays on its band while it has cases and then starts a band no group works on
(:func:`next_case`), so groups build different bands' reductions rather than each building every
band; each keeps the reduced model of its current band only. Rank 0 gathers the rows and prints
the progress.
"""

from __future__ import annotations

import math
import os
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from .. import __version__
from ..commandkit.settings import command_scene
from ..commandkit.store import PieceStore, kept_note, piece_key
from ..console import sayer
from ..errors import InputError, MillimpactError
from ..results.output_folder import OutputFolder, claim_output
from ..scene.impact_direction import oblique_velocity
from ..scene.schema import Scene
from ..scene.toml_io import dump_scene

if TYPE_CHECKING:
    import numpy as np
# numpy, the plan (scipy), the methods and PETSc are imported where a table computes, so that
# building the command line (`millimpact --help`) imports none of them

#: the bands' ratio of normal speeds: a band holds the normal speeds [BAND_BASE BAND_RATIO^k,
#: BAND_BASE BAND_RATIO^(k+1)) (a_max ~ v^(2/5): a factor 1.5 in speed is 1.18 in a_max, so a case at
#: the rung's slow edge has 4 and one at its fast edge 4.7 elements across its contact radius)
BAND_RATIO = 1.5
#: the speed (m/s) the band ladder's rungs are counted from: a fixed ladder, so that a case's band
#: (and so its mesh and result) does not depend on which other cases the table holds
BAND_BASE = 1.0
#: each case runs to gap / v_n + CUT_CONTACT_TIMES Hertz contact times, CUT_CONTACT_TIMES being
#: :data:`millimpact.methods.free_phase.FIRST_SPAN_CONTACTS` (1.5): past the separation (plastic and
#: finite-body contacts last up to ~1.1 t_c; a contact still on at the end is flagged in the status
#: column), and exactly the reduced methods' first integrator segment, so no free-vibration modes
#: are computed for the rest (2.8 s a case on the rig)
#: methods whose offline reduction the cases of a band share
REUSED_METHODS = ("improved", "traditional", "modal-p2")


@dataclass(frozen=True)
class TableCase:
    """One impact of a table: speed (m/s), angle from the face normal (deg), ball radius (m), its
    scene (with the band's mesh sizes) and key."""

    index: int
    speed: float
    angle: float
    radius: float
    band: int
    scene: Scene
    key: str
    band_scene: Scene | None = None  #: a normal impact at the band's fastest speed: its reduction serves the band
    band_key: str = ""  #: the band scene's key: a group keeps a band's reduction under it


def table_scene(name: str | None, sets: Sequence[str] = ()) -> Scene:
    """The scene a table starts from: ``name`` (None: the default scene) with the ``--set``
    assignments, validated together; the cases set the impact velocity themselves."""
    return command_scene(name, sets, {"impact.velocity": "the table's --velocity and --angle"})


case_velocity = oblique_velocity  # the name the table and the damage map call it by


def band_rung(normal_speed: float) -> int:
    """The rung k of the band ladder that holds ``normal_speed`` (m/s): BAND_BASE BAND_RATIO^k <=
    v_n < BAND_BASE BAND_RATIO^(k+1). A speed within 1e-9 of a rung (relative, in rungs) of its upper
    edge counts as above it, so that v cos(angle) rounding to either side of an edge is one band."""
    return math.floor(math.log(normal_speed / BAND_BASE) / math.log(BAND_RATIO) + 1e-9)


def define_cases(
    base: Scene,
    speeds: Sequence[float],
    angles: Sequence[float],
    radii: Sequence[float],
    method: str,
    options: dict,
    pairs: Sequence[tuple[float, float]] | None = None,
) -> list[TableCase]:
    """The table's cases, grouped in bands that share a mesh (module docstring), each case's scene
    carrying its band's h_contact, zone radius, gap, cutoff, time step and symmetry. ``pairs``
    (speed, angle), when given, replace the product speeds x angles (the damage map's bins, the
    adaptive table's batches). A case's scene, key and band scene depend on the case alone (its
    radius, its rung of the band ladder and its own symmetry), not on the other cases."""
    from ..scene.plan import decide_symmetry

    bands: dict[tuple[float, int, str], list[tuple[float, float, Scene]]] = {}
    for r in radii:
        b = base.with_value("ball.radius", r) if r != base.ball.radius else base
        for v, a in pairs if pairs is not None else [(v, a) for v in speeds for a in angles]:
            sc = b.with_value("impact.velocity", case_velocity(b, v, a))
            bands.setdefault((r, band_rung(sc.normal_speed), decide_symmetry(sc)[0]), []).append((v, a, sc))
    cases = []
    for band, (r, rung, sym) in enumerate(sorted(bands)):
        sets, fast = band_settings(base, r, rung, sym, method)
        fast_key = case_key(fast, method, options)
        for v, a, sc in bands[(r, rung, sym)]:
            for k, val in sets.items():
                sc = sc.with_value(k, val)
            cases.append((v, a, r, band, sc, fast, fast_key))
    cases.sort(key=lambda c: (c[2], c[0], c[1]))
    return [
        TableCase(i, v, a, r, b, sc, case_key(sc, method, options), fast, fast_key)
        for i, (v, a, r, b, sc, fast, fast_key) in enumerate(cases)
    ]


def band_settings(base: Scene, radius: float, rung: int, symmetry: str, method: str) -> tuple[dict[str, object], Scene]:
    """The settings a band's cases share and the scene its reduction is built for (module
    docstring): h_contact = a_max / ELEMENTS_ACROSS_CONTACT and the gap GAP_FACTOR delta_max at
    the rung's slow edge, the cutoff F_CUT_FACTOR / t_c, the step t_c / STEPS_PER_CONTACT and the
    zone at its fast edge (a normal impact at that speed: the band scene), the band's symmetry;
    the fine radius 1.5 a_max at the fast edge; each unless the base scene sets it."""
    from ..scene.plan import (
        ELEMENTS_ACROSS_CONTACT,
        F_CUT_FACTOR,
        GAP_FACTOR,
        STEPS_PER_CONTACT,
        make_plan,
        scene_hertz,
    )

    b = base.with_value("ball.radius", radius) if radius != base.ball.radius else base
    slow = b.with_value("impact.velocity", case_velocity(b, BAND_BASE * BAND_RATIO**rung, 0.0))
    fast = b.with_value("impact.velocity", case_velocity(b, BAND_BASE * BAND_RATIO ** (rung + 1), 0.0))
    hs, hf = scene_hertz(slow), scene_hertz(fast)
    sets: dict[str, object] = {
        "model.h_contact": base.model.h_contact or hs.a_max / ELEMENTS_ACROSS_CONTACT,
        "impact.gap": base.impact.gap or GAP_FACTOR * hs.delta_max,
        # the reduction's cutoff and the time step for the shortest contact of the band: one step
        # size, so the cases share the factorized step operators too
        "model.f_cut": base.model.f_cut or F_CUT_FACTOR / hf.contact_time,
        "time.dt_contact": base.time.dt_contact or hf.contact_time / STEPS_PER_CONTACT,
        "model.symmetry": symmetry,
    }
    sets["model.zone_radius"] = base.model.zone_radius or _band_zone(fast, sets, method)
    for k, val in sets.items():
        fast = fast.with_value(k, val)
    # the mesh's fine radius (1.5 a_max) at the fast edge too, in every case's scene: a standalone
    # run of a case's scene meshes the band's mesh
    sets["model.fine_radius"] = base.model.fine_radius or make_plan(fast).fine_radius
    fast = fast.with_value("model.fine_radius", sets["model.fine_radius"])
    return sets, fast.with_value("outputs.xdmf", False).with_value("time.end", case_t_end(fast))


def _band_zone(fast: Scene, sets: dict, method: str) -> float | None:
    """The contact-zone radius of a band: the method's zone for its band scene (m)."""
    from ..scene.plan import make_plan

    sc = fast
    for k, val in sets.items():
        sc = sc.with_value(k, val)
    plan = make_plan(sc)
    if method in REUSED_METHODS:
        from ..methods.reduced import reduced_plan

        return reduced_plan(sc, plan)[1].zone_radius
    return plan.zone_radius


def case_key(scene: Scene, method: str, options: dict) -> str:
    """The key a finished case is stored under: its resolved scene, method, options and version."""
    return piece_key(
        {"scene": dump_scene(scene), "method": method, "options": sorted(options.items()), "version": __version__}
    )


# --- one case -----------------------------------------------------------------------------------------
def case_t_end(scene: Scene) -> float:
    """gap / v_n + CUT_CONTACT_TIMES t_c, rounded down to whole contact steps (s): the reduced
    methods' first integrator segment holds the whole case, and every case of a band steps with
    the band's dt_contact itself, so they share its factorization and W."""
    from ..methods.free_phase import FIRST_SPAN_CONTACTS as CUT_CONTACT_TIMES
    from ..scene.plan import make_plan

    plan = make_plan(scene)
    t = plan.gap / plan.normal_speed + CUT_CONTACT_TIMES * plan.hertz.contact_time
    return max(1, math.floor(t / plan.dt_contact * (1 + 1e-12))) * plan.dt_contact


def run_case(case: TableCase, method: str, options: dict, setups: dict, comm) -> dict[str, Any]:
    """The row of one case (:func:`millimpact.studies.table_report.case_row`), computing it on
    ``comm``; a reduced method reuses (or builds and keeps in ``setups``) its band's reduction."""
    from ..methods.run import compute
    from ..scene.plan import make_plan
    from .table_report import case_row

    t0 = time.perf_counter()
    scene = case.scene.with_value("outputs.xdmf", False).with_value("time.end", case_t_end(case.scene))
    plan = make_plan(scene)
    reused = False
    if method in REUSED_METHODS:
        from ..methods.reduced import build_reduced_setup, run_reduced_case

        # the state update u = u_pred + W lambda with the band's shared W: one solve a step instead
        # of the saddle-point solver's several (exact with the factorization; the rig: 8.6 -> 3.3 s
        # a reused case)
        options = {"contact_solve": "schur", **options}
        if case.band_key not in setups:
            # built for the band scene (its fast edge): its contact candidates cover every case's patch
            assert case.band_scene is not None  # banded cases carry their band scene
            fast = case.band_scene
            setups[case.band_key] = build_reduced_setup(
                fast, make_plan(fast), dict(options), method, comm, share_operators=True
            )
        else:
            reused = True
        # the case's scene carries the band's mesh sizes, zone, gap, cutoff and symmetry: its plan
        # describes the setup's mesh with its own velocity, time steps and probes
        out = run_reduced_case(
            setups[case.band_key], scene, plan, dict(options), False, t_end=scene.time.end, impact_only=True
        )
    else:
        out, _ = compute(scene, method, dict(options), False)
    row = case_row(case, plan, out, time.perf_counter() - t0)
    row["reduction_reused"] = reused
    if method in REUSED_METHODS:
        # the band's constraint and fixed-interface modes came from the on-disk cache (reduction.cache)
        row["reduction_from_cache"] = any(b.from_cache for b in setups[case.band_key].red.bodies)
    return row


# --- the table ----------------------------------------------------------------------------------------
@dataclass
class TableRun:
    """A table's computing on every rank: its base scene, method, claimed output and ``cases/``
    folder, this rank's group of ranks, and the group's kept reduction (by band key)."""

    base: Scene
    method: str
    options: dict
    target: OutputFolder
    folder: Path
    world: Any
    group: Any
    say: Callable[..., None]
    setups: dict = field(default_factory=dict)
    #: keep every band's reduction below this resident memory per rank (GB; 0: the current band's only)
    keep_gb: float = 0.0

    @property
    def n_groups(self) -> int:
        return self.world.size // self.group.size

    def compute(self, cases: Sequence[TableCase], said: Callable[[int, int], None] | None = None) -> dict[int, dict]:
        """Each case's row by its index, on rank 0 ({} on the others): from ``cases/``, or computed by
        the groups (collective). ``said(n_stored, n_todo)`` prints the line before computing."""
        store = PieceStore(self.folder)
        done = {c.index: row for c in cases if (row := store.load(c.key)) is not None}
        # computed band after band (a group keeps only its current band's reduction), listed by speed
        todo = sorted([c for c in cases if c.index not in done], key=lambda c: (c.band, c.index))
        if said is not None:
            said(len(done), len(todo))
        rows = (
            compute_cases(
                todo,
                self.method,
                self.options,
                self.folder,
                self.world,
                self.group,
                self.say,
                self.setups,
                self.keep_gb,
            )
            if todo
            else []
        )
        gathered = self.world.gather(rows, root=0)
        if self.world.rank != 0 or gathered is None:
            return {}
        for part in gathered:
            for r in part:
                done[r["case"]] = r
        return done


def _resident_gb() -> float:
    """This process's resident memory (GB; Linux /proc, 0 where it cannot be read)."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("VmRSS:"):
                return float(line.split()[1]) / 1024.0**2
    except OSError:
        pass
    return 0.0


def keep_budget_gb(world) -> float:
    """The resident memory (GB) below which a rank keeps every band's reduction it builds: two fifths
    of the machine's memory shared by the ranks on it (the world's ranks; 0 where unknown), the
    rest left to a case's own solve. Measured: a rank of the plastic rig's adaptive table holds
    3.3 GB after its 10 m/s band's reduction."""
    try:
        total = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") / 1024.0**3
    except (ValueError, OSError, AttributeError):
        return 0.0
    return 0.4 * total / world.size


def check_table_method(method: str, ranks_per_case: int) -> None:
    """InputError (one line) unless ``method`` is one and ``ranks_per_case`` divides the ranks."""
    from mpi4py import MPI

    from ..methods.registry import method_entry

    world = MPI.COMM_WORLD
    if ranks_per_case < 1 or ranks_per_case > world.size or world.size % ranks_per_case:
        raise InputError(
            f"--ranks-per-case {ranks_per_case}: must divide the number of ranks ({world.size}) "
            f"and be between 1 and {world.size}"
        )
    method_entry(method)
    if method not in REUSED_METHODS and method != "hertz" and world.size // ranks_per_case > 1:
        # full and hertz-modal run on MPI_COMM_WORLD, not on a group: cases cannot be spread
        raise InputError(
            f"--method {method} with {world.size // ranks_per_case} groups: this method runs on all "
            f"ranks; use --ranks-per-case {world.size} (or a reduced method, or hertz)"
        )


def open_table(
    base: Scene, method: str, options: dict, out: Path | OutputFolder, ranks_per_case: int, quiet: bool
) -> TableRun:
    """Open ``out`` (a folder, or one claimed with :func:`claim_output`) and its ``cases/`` and
    split the ranks into groups of ``ranks_per_case`` (collective)."""
    from mpi4py import MPI

    world = MPI.COMM_WORLD
    target = out if isinstance(out, OutputFolder) else claim_output(out, "table")
    folder = target.open(["cases"], note=lambda: kept_cases_note(target)) / "cases"
    if world.rank == 0:
        folder.mkdir(exist_ok=True)
    world.barrier()
    group = world.Split(world.rank // ranks_per_case, world.rank)
    return TableRun(base, method, options, target, folder, world, group, sayer(quiet, world))


def run_table(
    scene_name: str | None,
    speeds: Sequence[float],
    angles: Sequence[float],
    radii: Sequence[float] | None,
    method: str,
    options: dict,
    out: Path | OutputFolder,
    sets: Sequence[str] = (),
    ranks_per_case: int = 1,
    quiet: bool = False,
) -> list[dict]:
    """Compute (or take from ``out/cases``) every case and write the table (rank 0) into ``out``, a
    folder or one claimed with :func:`~millimpact.results.output_folder.claim_output`. Returns the rows."""
    from .table_report import write_table

    check_table_method(method, ranks_per_case)
    base = table_scene(scene_name, sets)
    cases = define_cases(base, speeds, angles, radii or [base.ball.radius], method, options)
    run = open_table(base, method, options, out, ranks_per_case, quiet)
    n_bands = len({c.band for c in cases})

    def said(n_done: int, n_todo: int) -> None:
        run.say(
            f"table {base.name}: {len(speeds)} speeds x {len(angles)} angles x {len(radii or [0])} radii = "
            f"{len(cases)} cases in {n_bands} mesh band(s), method {method}; {n_done} from {run.folder}, {n_todo} "
            f"to compute on {run.n_groups} group(s) of {ranks_per_case} rank(s)"
        )

    done = run.compute(cases, said)
    if run.world.rank != 0:
        return []
    all_rows = [done[c.index] for c in cases if c.index in done]
    with run.target.staged(keep=["cases"], collective=False) as stage:
        write_table(stage, base, cases, all_rows, method, options)
    return all_rows


def kept_cases_note(target: OutputFolder) -> str:
    """What an interrupted table leaves: its finished cases, reused by a rerun."""
    return kept_note(
        [(PieceStore(target.path / "cases").count(), "case", f"{target.shown}/cases/")],
        "the table itself is not written",
    )


def next_case(
    state: np.ndarray, band_sizes: Sequence[int], current: int | None, held: Sequence[int] = ()
) -> tuple[int, int] | None:
    """Pick a group's next case from the shared ``state`` = [done, taken per band..., groups per
    band...] (updated in place): (band, index within the band), or None when all are taken.

    A group stays on its band while it has cases (its reduction is built); then it leaves it and
    takes the first band in order that no group works on, so groups build different bands rather
    than each building every band (the 100-case table at 2 ranks built 12 reductions for 6
    bands); only when every band with cases left has a group does it join the one with the most
    cases left per group. ``held``: the bands whose reduction the group keeps from an earlier
    batch (an adaptive table's); among the bands it may take, it takes those first (no build)."""
    nb = len(band_sizes)
    taken, groups = state[1 : 1 + nb], state[1 + nb : 1 + 2 * nb]
    left = [band_sizes[b] - int(taken[b]) for b in range(nb)]
    if current is not None and left[current] > 0:
        band = current
    else:
        if current is not None:
            groups[current] -= 1
        open_ = [b for b in range(nb) if left[b] > 0]
        if not open_:
            return None
        free = [b for b in open_ if groups[b] == 0]
        mine = [b for b in (free or open_) if b in held]
        if free:
            band = (mine or free)[0]
        else:
            band = max(mine or open_, key=lambda b: left[b] / (groups[b] + 1))
        groups[band] += 1
    index = int(taken[band])
    taken[band] += 1
    return band, index


def costliest_first(todo: Sequence[TableCase]) -> list[list[TableCase]]:
    """``todo`` by band, the bands and the cases within each in the order of their expected cost,
    the dearest first: by the fastest normal speed (the contact steps, the yielding and the band's
    mesh grow with it), then the ball's radius. Longest processing time first (Graham, SIAM J.
    Appl. Math. 17, 1969): the groups' cheap cases come last and even out their finishing times,
    where the table in speed order ended with every group on its slowest-running band (the
    100-case plastic table: ~50 s cases of the 10 m/s band against ~12 s at 0.5 m/s); and a
    rank's memory peaks in its first band (the largest mesh) instead of growing band by band, so
    a table that does not fit stops at once."""
    bands: dict[int, list[TableCase]] = {}
    for c in todo:
        bands.setdefault(c.band, []).append(c)

    def cost(g: list[TableCase]) -> tuple[float, float]:
        return max(c.scene.normal_speed for c in g), g[0].radius

    order = sorted(bands.values(), key=cost, reverse=True)
    return [sorted(g, key=lambda c: -c.scene.normal_speed) for g in order]


def compute_cases(
    todo: list[TableCase],
    method: str,
    options: dict,
    folder: Path,
    world,
    group,
    say,
    setups: dict | None = None,
    keep_gb: float = 0.0,
) -> list[dict]:
    """This group's share of ``todo`` (``group``: this rank's group of ranks of ``world``): cases
    taken from a shared state (:func:`next_case`) on world rank 0 until none is left, each finished
    case stored as ``folder/<key>.json``; the rows this group computed (the table's and the damage
    map's bins). ``setups``: the group's reduction by band key, kept by the caller between calls
    (the adaptive table's batches); a fresh one per call by default. A new band's reduction is
    added to them while this rank's resident memory is below ``keep_gb`` (GB), else replaces
    them (0: only the current band's is kept)."""
    import numpy as np
    from mpi4py import MPI

    from ..integration.solvers import destroy_petsc_tree, release_petsc_garbage, reset_option_usage, unused_options

    by_band = costliest_first(todo)
    sizes = [len(c) for c in by_band]
    n_state = 1 + 2 * len(by_band)
    # [cases done, taken per band, groups per band] on world rank 0 (Allocate: Create fails outside
    # mpirun in Open MPI); read, changed and written under an exclusive lock
    win = MPI.Win.Allocate(8 * n_state if world.rank == 0 else 0, 8, comm=world)
    if world.rank == 0:
        win.Lock(0)
        np.frombuffer(win.tomemory(), dtype="i8")[:] = 0  # type: ignore[call-overload]  # mpi4py's buffer
        win.Unlock(0)
    world.barrier()
    one, got = np.ones(1, dtype="i8"), np.zeros(1, dtype="i8")
    state = np.zeros(n_state, dtype="i8")
    current: int | None = None
    setups = {} if setups is None else setups
    rows = []
    warned = False
    t0 = time.perf_counter()
    try:
        while True:
            pick = None
            if group.rank == 0:
                held = [b for b, band in enumerate(by_band) if band[0].band_key in setups]
                win.Lock(0, MPI.LOCK_EXCLUSIVE)
                win.Get(state, 0)
                win.Flush(0)
                pick = next_case(state, sizes, current, held)
                win.Put(state, 0)
                win.Unlock(0)
            pick = group.bcast(pick, root=0)
            if pick is None:
                break
            current = pick[0]
            case = by_band[pick[0]][pick[1]]
            # a group takes a band's cases until none is left (next_case): in a table computed at once
            # a band's reduction is not needed again once it moves on, and keeping them all grew a rank
            # to 12 GB on the 100-case table; an adaptive table's batches come back to bands
            # (keep_gb: kept while this rank's memory allows)
            keep_others = case.band_key in setups or _resident_gb() < keep_gb
            for band in [] if keep_others else [b for b in setups if b != case.band_key]:
                dropped = setups.pop(band)
                release_petsc_garbage(dropped.model.V.mesh.comm)
                destroy_petsc_tree(dropped)  # its Python handles alone would keep it (see there)
                del dropped  # and its mesh, spaces and forms with the name
            # the last case's dropped objects: parked on the communicator they were made on (the
            # mesh's), not the group's; 17.5 MB a case on a coarse hertz-halfspace table until freed
            release_petsc_garbage(group)
            if case.band_key in setups:
                release_petsc_garbage(setups[case.band_key].model.V.mesh.comm)
            reset_option_usage()
            try:
                row = run_case(case, method, options, setups, group)
            except (MillimpactError, RuntimeError, ValueError, ArithmeticError) as exc:
                row = {
                    "case": case.index,
                    "key": case.key,
                    "impact_speed_m_s": case.speed,
                    "impact_angle_deg": case.angle,
                    "ball_radius_m": case.radius,
                    "status": f"failed: {type(exc).__name__}: {str(exc).splitlines()[0][:300]}",
                }
            # a case that reused its band's reduction did not read the options of building it
            ran = str(row.get("status", "")).startswith("ok") and not row.get("reduction_reused")
            unused = unused_options(options) if ran and not warned else None
            if unused:  # as study and run: said once, after the first case that ran (even with -q)
                warned = True
                if world.rank == 0:
                    print(
                        f"millimpact: warning: options that nothing in this table's runs used (misspelled, or for "
                        f"a solver method {method} does not have): {', '.join('-' + k for k in unused)}",
                        file=sys.stderr,
                        flush=True,
                    )
            if group.rank == 0:
                PieceStore(folder).save(case.key, row)
                win.Lock(0)
                win.Fetch_and_op(one, got, 0, 0, MPI.SUM)  # state[0]: cases done
                win.Unlock(0)
                rows.append(row)
                n_done = int(got[0]) + 1
                el = time.perf_counter() - t0
                say(
                    f"  [{n_done}/{len(todo)}] v = {case.speed:g} m/s, angle {case.angle:g} deg: e_n "
                    f"{row.get('restitution_normal', float('nan')):.4f}, {row['status']}, "
                    f"{row.get('wall_time_s', 0.0):.1f} s{' (reduction reused)' if row.get('reduction_reused') else ''}"
                    f" (elapsed {el:.0f} s, ~{el / n_done * (len(todo) - n_done):.0f} s left)"
                )
    finally:
        world.barrier()
        win.Free()
    return rows
