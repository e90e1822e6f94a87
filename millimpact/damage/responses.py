"""Each bin's response: one impact with the table engine (:mod:`millimpact.studies.table`), and the
repeated-impact response of each place's dominant bin (:mod:`millimpact.repeat.sequence`).

Cases. The bins of one placed scene (one place and arc position) become the cases of one table
(:func:`millimpact.studies.table.define_cases` with the bins' (speed, angle) pairs): cases whose
normal speeds lie within the table's BAND_RATIO share one mesh and one offline reduction and its
factorizations. Places do not share a mesh: the contact zone (the refined, unreduced part of the
liner) sits at the impact point, so each place has its own mesh, reduction and contact operator;
what they share is the scene (liner shape, materials, ball), the mesh cache and the reduction
cache on disk (a rerun, or another map of the same liner, takes them from there) and, under
``mpirun``, the table's groups of ranks, which take cases of every place from one shared counter.

Reruns. A case is stored as ``cases/<key>.json`` when it finishes (the table's rule: the key
hashes the case's scene, method, options and version), a repeated-impact sequence as
``repeat/<key>.json``; a rerun of the map computes only what is missing.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .. import __version__
from ..commandkit.store import PieceStore, piece_key
from ..errors import InputError, SceneError
from ..repeat.sequence import ImpactSpec
from ..scene.schema import Scene
from ..scene.toml_io import dump_scene
from ..studies.table import TableCase, define_cases
from .bins import Bin
from .places import PlacedScene

#: a case runner: computes ``todo`` (TableCases) and stores each row as ``folder/<key>.json`` as it
#: finishes (:class:`millimpact.commandkit.store.PieceStore`); ``say`` prints progress on rank 0
CaseRunner = Callable[[list, Path, Callable], None]


@dataclass(frozen=True)
class BinCase:
    """A bin, its placed scene and its table case (None when the bin is refused)."""

    bin: Bin
    placed: PlacedScene
    case: TableCase | None
    refused: str = ""


def define_bin_cases(bins: Sequence[Bin], placed: dict[int, PlacedScene], method: str, options: dict) -> list[BinCase]:
    """The table case of every bin: bins on one placed scene form one table's cases (their bands
    share a mesh and a reduction); bands are numbered across places, a case's index is its bin's."""
    out: dict[int, BinCase] = {}
    groups: dict[str, list[Bin]] = {}
    for b in bins:
        ps = placed[b.index]
        if ps.scene is None:
            out[b.index] = BinCase(b, ps, None, ps.refused)
        elif b.normal_speed_m_s <= 0.0 or b.angle_deg >= 90.0:
            out[b.index] = BinCase(
                b, ps, None, "no normal speed: grazing impacts (angle 90 deg) have no normal response"
            )
        else:
            groups.setdefault(dump_scene(ps.scene), []).append(b)
    offset = 0
    for members in groups.values():
        scene = placed[members[0].index].scene
        assert scene is not None  # only placed bins were grouped
        try:
            cases = define_cases(
                scene, [], [], [scene.ball.radius], method, options, pairs=[(b.speed_m_s, b.angle_deg) for b in members]
            )
        except (SceneError, InputError):
            # a bin the scene's settings cannot mesh (a --set h_contact too coarse for a slow bin's
            # contact zone): refused with the scene's reason, the others banded together as before
            cases, ok = [], []
            for b in members:
                try:
                    define_cases(
                        scene, [], [], [scene.ball.radius], method, options, pairs=[(b.speed_m_s, b.angle_deg)]
                    )
                except (SceneError, InputError) as exc:
                    out[b.index] = BinCase(b, placed[b.index], None, str(exc))
                else:
                    ok.append(b)
            try:
                cases = (
                    define_cases(
                        scene,
                        [],
                        [],
                        [scene.ball.radius],
                        method,
                        options,
                        pairs=[(b.speed_m_s, b.angle_deg) for b in ok],
                    )
                    if ok
                    else []
                )
            except (SceneError, InputError):
                # bins that mesh alone but not in one band: each alone
                for b in ok:
                    cases += define_cases(
                        scene, [], [], [scene.ball.radius], method, options, pairs=[(b.speed_m_s, b.angle_deg)]
                    )
                    cases[-1] = dataclasses.replace(cases[-1], band=len(cases) - 1)
        by_pair = {(c.speed, c.angle): c for c in cases}
        for b in members:
            c = by_pair.get((b.speed_m_s, b.angle_deg))
            if c is not None:
                out[b.index] = BinCase(b, placed[b.index], dataclasses.replace(c, index=b.index, band=c.band + offset))
        offset += 1 + max((c.band for c in cases), default=0)
    return [out[b.index] for b in bins]


def table_runner(method: str, options: dict, ranks_per_case: int = 1) -> CaseRunner:
    """The table engine as a case runner: MPI groups of ``ranks_per_case`` ranks take cases from a
    shared counter, a band's reduction is reused (:func:`millimpact.studies.table.compute_cases`)."""

    def run(todo: list, folder: Path, say: Callable) -> None:
        from mpi4py import MPI

        from ..studies.table import compute_cases

        world = MPI.COMM_WORLD
        group = world.Split(world.rank // ranks_per_case, world.rank)
        try:
            compute_cases(sorted(todo, key=lambda c: (c.band, c.index)), method, options, folder, world, group, say)
        finally:
            group.Free()

    return run


def compute_bin_rows(
    bin_cases: Sequence[BinCase], folder: Path, runner: CaseRunner, say: Callable, comm=None
) -> dict[int, dict]:
    """Each computable bin's table row (bin index -> row), computing the missing ones with
    ``runner`` (stored in ``folder`` as they finish, so an interrupted map keeps them)."""
    have = [(bc, bc.case) for bc in bin_cases if bc.case is not None]
    if comm is None or comm.rank == 0:
        folder.mkdir(parents=True, exist_ok=True)
    if comm is not None:
        comm.barrier()
    store = PieceStore(folder)
    todo = [case for _, case in have if store.load(case.key) is None]
    say(
        f"bins: {len(have)} to compute by the table engine, {len(have) - len(todo)} from {folder}, "
        f"{len(todo)} to run" + (f"; {len(bin_cases) - len(have)} refused" if len(have) < len(bin_cases) else "")
    )
    if todo:
        runner(todo, folder, say)
    if comm is not None:
        comm.barrier()
    rows = {}
    for bc, case in have:
        row = store.load(case.key)
        if row is not None:
            rows[bc.bin.index] = row
    return rows


# --- repeated impacts ------------------------------------------------------------------------------
def repeat_key(scene: Scene, speed: float, angle: float, n: int, method: str, options: dict) -> str:
    """The key of a stored sequence: its scene, impact, count, method, options and version."""
    return piece_key(
        {
            "scene": dump_scene(scene),
            "speed": speed,
            "angle": angle,
            "impacts": n,
            "method": method,
            "options": sorted(options.items()),
            "version": __version__,
        }
    )


def run_repeat(
    bc: BinCase,
    n: int,
    method: str,
    options: dict,
    petsc_options: dict,
    folder: Path,
    run_sequence: Callable,
    classify: Callable,
    comm,
    say: Callable,
) -> dict[str, Any]:
    """The repeated-impact response at the bin's place: ``n`` identical impacts at its representative
    speed and angle, each from the previous one's residual state; stored in ``folder`` as
    ``<key>.json`` ({"outcomes": [...], "verdict": {...}}) when done, or taken from there."""
    case = bc.case
    assert case is not None  # a refused bin has no repeated impacts
    scene = case.scene
    key = repeat_key(scene, case.speed, case.angle, n, method, options)
    store = PieceStore(folder)
    got = store.load(key)
    if got is not None:
        say(f"  repeat at bin {bc.bin.index} ({bc.bin.place}): {n} impacts from {folder}")
        return {**got, "key": key}
    spec = ImpactSpec(speed_m_s=case.speed, angle_deg=case.angle)
    say(
        f"  repeat at bin {bc.bin.index} ({bc.bin.place}, v = {case.speed:.4g} m/s, angle {case.angle:.3g} deg): "
        f"{n} impacts"
    )
    # the sequence keeps each finished impact and its plastic state: an interrupted sequence
    # continues from its last impact
    outcomes = run_sequence(
        scene,
        [spec] * n,
        method=method,
        petsc_options=petsc_options,
        comm=comm,
        progress=say,
        store_dir=folder / f"{key}.impacts",
    )
    rows = [
        dataclasses.asdict(o) if dataclasses.is_dataclass(o) and not isinstance(o, type) else dict(o) for o in outcomes
    ]
    v = classify(outcomes)
    verdict = {
        "kind": v.kind,
        "impacts_to_shakedown": v.impacts_to_shakedown,
        "numbers": {k: (float(x) if isinstance(x, (int, float)) else x) for k, x in dict(v.numbers).items()},
    }
    result = {
        "bin": bc.bin.index,
        "place": bc.bin.place,
        "speed_m_s": case.speed,
        "angle_deg": case.angle,
        "outcomes": rows,
        "verdict": verdict,
    }
    if comm is None or comm.rank == 0:
        store.save(key, result)
    return {**result, "key": key}


def finite(x: Any) -> float:
    """``x`` as a float, NaN when it is not a finite number."""
    try:
        v = float(x)
    except (TypeError, ValueError):
        return math.nan
    return v if math.isfinite(v) else math.nan
