"""Repeated impacts at one spot: each impact starts from the previous one's residual state.

After an impact the plastic strain eps_p and the hardening variable alpha at the zone's
quadrature points are frozen and the bodies unload elastically to the static residual state

    K u_res = -f_frozen = int_zone B^T C eps_p dV     (:meth:`PlasticZone.frozen_force`),

whose stress C (eps(u_res) - eps_p) is the residual stress and whose surface is the dent
(:mod:`millimpact.results.dent`). The next impact starts there: u = u_res, v = 0 on the bodies,
the zone's committed state (eps_p, alpha) kept, and the ball launched again with its new velocity
a gap ``plan.gap`` from the DEFORMED face: the contact gaps g = g0 + B u already see the
displacement, so the ball is translated along -n by min(g0 + B u_res) - gap (the dent depth plus
the ball's own residual shape). The plastic Newmark start includes the frozen plastic force
(M a0 = -K u0 - f_c(u0) = 0 at u_res, :meth:`PlasticNewmarkScheme.initialize`).

One model for the sequence: one mesh, one reduction (``improved``, ``traditional``,
``modal-p2``: :func:`millimpact.methods.reduced.build_reduced_setup`) or one full model
(``full``), one plastic zone, whose state the impacts share; the elastic step factorization is
kept between impacts (``operator_cache``). The sequence's mesh is fixed by its slowest impact
(h_contact = a_max / 4) and its zone, modal cutoff and contact step by its fastest, as a contact
table's band (:mod:`millimpact.studies.table`), with the least symmetric model any impact needs.
Each impact runs to separation plus 0.1 t_c (:func:`millimpact.methods.reduced.impact_only_stop`,
a :class:`millimpact.integration.integrators.SeparationStop`), not the scene's 40 ms of ringing,
and records its energies as a contact table's impact-only case does: every
ENERGY_EVERY_IMPACT_ONLY-th row and the first and last (:mod:`millimpact.methods.reduced`; the
two products with M and K are ~7 ms of a ~45 ms reduced step on paper-rig-plastic). Each
impact's energy balance is checked on those rows; the others' energy columns are empty in
impact-NNN-timeseries.csv.

Offsets: impact k may land at ``offset_m`` = (dx, dy) from the scene's impact point, in the
coordinates of ``impact.point`` (x and z on the block's face y = 0). The ball keeps its meshed
place and the contact rows pair each of its nodes with the face point below the shifted node
(:func:`millimpact.fem.contact.create_contact` ``ball_offset``), so the ball meets the dented
face where the offset puts it; the zone grows by the largest offset and an offset off the x = 0
plane makes the model full (no symmetry plane through it). Small sliding: the master points stay
fixed during an impact, as for a single one.

The ball's own state (its plastic strain if it yields) is carried too: the same ball strikes
again, as in Seifried, Schiehlen & Eberhard (2005)'s repeated-impact experiment.
"""

from __future__ import annotations

import json
import logging
import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..scene.impact_direction import oblique_velocity

if TYPE_CHECKING:
    from ..fem.model import FEModel

log = logging.getLogger(__name__)

__all__ = [
    "ImpactSpec",
    "ImpactOutcome",
    "ImpactRecord",
    "run_sequence",
    "impact_velocity",
    "sequence_scene",
    "check_impacts",
    "check_sequence",
    "OUTCOME_COLUMNS",
]

#: each impact's time span: the flight over the gap plus this many Hertz contact times (the
#: separation stop ends it ~1.1 t_c after contact for a plastic impact)
IMPACT_SPAN_CONTACTS = 3.0

#: a sequence's contact zone is this many times a single impact's (capped as the plan caps it):
#: the plastic region grows under repeated impacts; measured on paper-rig-plastic at the plan's
#: sizes, 10 impacts at 3 m/s: 2.55 mm after the first, 3.06 mm after the tenth (x1.2), which
#: reached the single impact's 3.36 mm zone (plastic strain 0.0015 at its boundary). The factor
#: keeps a single impact's margin (its zone is 1.32x its plastic radius) over the grown region:
#: 4.03 mm, boundary elastic in all ten. 1.3 (4.36 mm) cost 8 % more coordinates (14,833
#: against 13,585) for the same verdict. A sequence of one impact has it too, so the first impact
#: of a sequence does not depend on its length (a ``run`` of the same impact has the single zone)
REPEAT_ZONE_FACTOR = 1.2

#: the columns of impacts.csv, in order (ImpactOutcome's fields)
OUTCOME_COLUMNS = (
    "impact",
    "restitution_normal",
    "restitution_tangential",
    "peak_normal_force_N",
    "contact_duration_s",
    "plastic_dissipation_J",
    "residual_dent_depth_m",
    "residual_dent_radius_m",
    "max_equivalent_plastic_strain",
    "surface_flow_stress_Pa",
)

#: Brinell hardness (kgf/mm^2) per Pa of flow stress: HB ~ 3 sigma_y (Tabor, The Hardness of Metals,
#: Oxford 1951: the mean pressure of a fully plastic indentation ~ 3 Y), over g = 9.807 m/s^2 and
#: 1e6 Pa per MPa
HB_PER_PA = 3.0 / 9.807e6


@dataclass(frozen=True)
class ImpactSpec:
    """One impact of a sequence: speed (m/s), angle from the face normal (deg, in the plane of the
    scene's tangential direction, as a contact table's), and the offset (m) of its impact point
    from the scene's on the face (the coordinates of ``impact.point``)."""

    speed_m_s: float
    angle_deg: float = 0.0
    offset_m: tuple[float, float] = (0.0, 0.0)


@dataclass(frozen=True)
class ImpactOutcome:
    """What one impact of a sequence gave (SI). The dent is the residual state's after this
    impact (cumulative), measured at the scene's impact point; the plastic work is this impact's
    alone; the largest plastic strain is the state's after it."""

    impact: int
    restitution_normal: float
    restitution_tangential: float
    peak_normal_force_N: float
    contact_duration_s: float
    plastic_dissipation_J: float
    residual_dent_depth_m: float
    residual_dent_radius_m: float
    max_equivalent_plastic_strain: float
    #: the struck body's flow stress sigma_y(alpha) at the impact point (the zone's quadrature point
    #: nearest it, just under the face) after this impact, Pa; NaN for an elastic target
    surface_flow_stress_Pa: float = math.nan


@dataclass
class ImpactRecord:
    """More of an impact than its outcome: its time series (force, approach, energies), the
    energy balance over the impact, the largest rotation (rad) at the peak force, the ball's
    launch shift (m) onto the deformed face, the wall time (s), the dent profile."""

    outcome: ImpactOutcome
    spec: ImpactSpec
    series: Any = None
    details: dict = field(default_factory=dict)


# --- input ------------------------------------------------------------------------------------
def impact_velocity(scene, spec: ImpactSpec) -> list[float]:
    """v = V (-cos(angle) n + sin(angle) t), m/s (:func:`millimpact.scene.impact_direction.oblique_velocity`)."""
    return oblique_velocity(scene, spec.speed_m_s, spec.angle_deg)


def offset_vector(scene, offset) -> np.ndarray:
    """The 3D shift (m) of a face offset (dx, dy): (dx, 0, dy) on the block's face y = 0."""
    return np.array([float(offset[0]), 0.0, float(offset[1])])


def check_impacts(scene, impacts: Sequence[ImpactSpec]) -> None:
    """One :class:`InputError` line for a sequence that cannot run: no impact, a speed or angle
    out of range, an offset whose point leaves the face (or any offset on a liner)."""
    from ..errors import InputError

    if len(impacts) < 1:
        raise InputError(f"--impacts {len(impacts)}: must be at least 1")
    p = scene.impact.point if scene.impact.point is not None else None
    for k, s in enumerate(impacts, 1):
        if not (math.isfinite(s.speed_m_s) and 0.0 < s.speed_m_s <= 100.0):
            raise InputError(f"impact {k}: speed {s.speed_m_s:g} m/s is outside (0, 100] m/s")
        if not (math.isfinite(s.angle_deg) and 0.0 <= s.angle_deg < 90.0):
            raise InputError(f"impact {k}: angle {s.angle_deg:g} deg is outside [0, 90) deg")
        dx, dy = (float(c) for c in s.offset_m)
        if dx == 0.0 and dy == 0.0:
            continue
        if scene.liner is not None:
            raise InputError(
                f"--offset {dx:g},{dy:g}: offsets are for block scenes (the face y = 0); {scene.name} strikes a liner"
            )
        x0, z0 = p if p is not None else (scene.impact_point[0], scene.impact_point[2])
        try:
            scene.with_value("impact.point", (x0 + dx, z0 + dy))
        except InputError as exc:
            raise InputError(f"--offset {dx:g},{dy:g} (impact {k}): the point leaves the face ({exc})") from None


def sequence_scene(scene, impacts: Sequence[ImpactSpec], method: str):
    """The scene whose mesh serves every impact (module docstring): h_contact and gap of the
    slowest normal speed, cutoff and contact step of the fastest, the least symmetric model, the
    zone of the fastest (REPEAT_ZONE_FACTOR times it, whatever the number of impacts: a
    sequence's first impact is the same for one impact or several) grown by the largest offset."""
    from ..scene.plan import (
        ELEMENTS_ACROSS_CONTACT,
        F_CUT_FACTOR,
        GAP_FACTOR,
        STEPS_PER_CONTACT,
        make_plan,
        scene_hertz,
    )

    # one scene per distinct impact (a long sequence repeats a few): its plan decides the symmetry
    distinct = list(dict.fromkeys(ImpactSpec(i.speed_m_s, i.angle_deg) for i in impacts))
    scenes = [scene.with_value("impact.velocity", impact_velocity(scene, s)) for s in distinct]
    slow = min(scenes, key=lambda s: s.normal_speed)
    fast = max(scenes, key=lambda s: s.normal_speed)
    hs, hf = scene_hertz(slow), scene_hertz(fast)
    sets = {
        "model.h_contact": scene.model.h_contact or hs.a_max / ELEMENTS_ACROSS_CONTACT,
        "impact.gap": scene.impact.gap or GAP_FACTOR * hs.delta_max,
        "model.f_cut": scene.model.f_cut or F_CUT_FACTOR / hf.contact_time,
        "time.dt_contact": scene.time.dt_contact or hf.contact_time / STEPS_PER_CONTACT,
    }
    planes = set(make_plan(fast).symmetry_planes)
    for s in scenes:
        planes &= set(make_plan(s).symmetry_planes)
    if any(i.offset_m[0] != 0.0 for i in impacts):
        planes.discard("x")
    if any(i.offset_m[1] != 0.0 for i in impacts):
        planes.discard("z")
    sets["model.symmetry"] = {frozenset(): "full", frozenset({"x"}): "half", frozenset({"x", "z"}): "quarter"}.get(
        frozenset(planes), "full"
    )
    design = fast
    for k, v in sets.items():
        design = design.with_value(k, v)
    if scene.model.zone_radius is None:
        plan = make_plan(design)
        zone = plan.zone_radius
        if method != "full":
            from ..methods.reduced import reduced_plan

            zone = reduced_plan(design, plan)[1].zone_radius
        single = zone
        # every sequence, one impact too: its first impact does not depend on how many follow
        from ..scene.plan import PLASTIC_ZONE_CAP, zone_radius_limit

        zone = max(zone, min(REPEAT_ZONE_FACTOR * zone, PLASTIC_ZONE_CAP * zone_radius_limit(design)))
        zone += max(math.hypot(*i.offset_m) for i in impacts)
        design = design.with_value("model.zone_radius", zone)
        if zone > single and scene.model.ball_zone_radius is None:
            # the ball keeps a single impact's zone: it is struck at the same point of its own
            # (offsets move the face point, not the ball), and its plastic region (1.1 mm on
            # paper-rig-plastic) stays far inside that zone (3.36 mm)
            ball = make_plan(design.with_value("model.zone_radius", single)).ball_zone
            design = design.with_value("model.ball_zone_radius", ball)
    return design


def check_sequence(scene, impacts: Sequence[ImpactSpec], method: str):
    """The sequence's scene (:func:`sequence_scene`) and its plan, made as the engines make them:
    an :class:`InputError` / :class:`SceneError` line for settings the plan refuses (a time.end
    below the contact step, an h_contact too large for the zone) before any folder is touched."""
    from ..scene.plan import make_plan

    check_impacts(scene, impacts)
    design = sequence_scene(scene, impacts, method)
    plan = make_plan(design)
    if method != "full":
        from ..methods.reduced import reduced_plan

        reduced_plan(design, plan)
    return design


# --- the sequence -----------------------------------------------------------------------------
def run_sequence(
    scene,
    impacts: Sequence[ImpactSpec],
    method: str = "improved",
    petsc_options: Mapping | None = None,
    comm=None,
    progress=None,
    *,
    store_dir: Path | None = None,
    records: list | None = None,
) -> list[ImpactOutcome]:
    """Run ``impacts`` one after the other on ``scene`` (a Scene, a built-in name or a TOML
    file) with ``method`` (improved, traditional, modal-p2 or full), each from the previous one's
    residual state (module docstring); returns one :class:`ImpactOutcome` per impact.

    ``petsc_options``: the method's options (as ``millimpact run``'s, keys without ``-impact_``).
    ``progress``: called with one line per finished impact (rank 0); True prints them
    (:func:`millimpact.console.say`). ``store_dir``: each finished
    impact's outcome and plastic state are kept there (``impact-NNN.json``, ``impact-NNN.rankR.npz``);
    a rerun with the same scene, method, options and rank count takes the finished ones and
    continues from the last state. ``records``: a list that gets an :class:`ImpactRecord` per
    impact computed now (time series, energy balance, rotation)."""
    from mpi4py import MPI

    from ..scene.builtin import resolve_scene

    if isinstance(scene, (str, Path)):
        scene = resolve_scene(str(scene))
    impacts = [i if isinstance(i, ImpactSpec) else ImpactSpec(*i) for i in impacts]
    if progress is True:
        from ..console import say as progress
    elif not callable(progress):
        progress = None
    check_impacts(scene, impacts)
    comm = comm or MPI.COMM_WORLD
    options = dict(petsc_options or {})
    design = sequence_scene(scene, impacts, method)
    key = sequence_key(design, method, options, comm.size)
    done, state = load_finished(store_dir, key, impacts, comm) if store_dir is not None else ([], None)
    if len(done) == len(impacts):
        return done
    engine = (_FullEngine if method == "full" else _ReducedEngine)(design, method, options, comm)
    # the time loop's own progress inside each impact (a line per 10 % of its span, or a terminal bar)
    engine.progress = progress is not None and comm.rank == 0
    if state is not None and engine.zone is not None:
        engine.zone.set_state(state)
    outcomes = list(done)
    for k in range(len(done), len(impacts)):
        spec = impacts[k]
        t0 = time.perf_counter()
        record = engine.impact(k + 1, spec, scene)
        record.details["wall_time_s"] = time.perf_counter() - t0
        engine.release()
        outcomes.append(record.outcome)
        if store_dir is not None:
            store_finished(store_dir, key, k + 1, record, engine, comm)
        if records is not None:
            records.append(record)
        if progress is not None and comm.rank == 0:
            o = record.outcome
            progress(
                f"  [{k + 1}/{len(impacts)}] v = {spec.speed_m_s:g} m/s, angle {spec.angle_deg:g} deg"
                + (
                    f", offset ({spec.offset_m[0] * 1e3:g}, {spec.offset_m[1] * 1e3:g}) mm"
                    if any(spec.offset_m)
                    else ""
                )
                + f": e_n {o.restitution_normal:.4f}, F_max {o.peak_normal_force_N / 1e3:.4g} kN, plastic work "
                f"{o.plastic_dissipation_J:.4g} J, dent {o.residual_dent_depth_m * 1e6:.4g} um, "
                f"{record.details['wall_time_s']:.1f} s"
            )
    return outcomes


def sequence_key(design, method: str, options: Mapping, ranks: int) -> str:
    """A hash of what a stored state belongs to: the sequence's scene, method, options, ranks."""
    from .. import __version__
    from ..commandkit.store import piece_key
    from ..scene.toml_io import dump_scene

    return piece_key(
        {
            "scene": dump_scene(design),
            "method": method,
            "options": sorted(options.items()),
            "ranks": ranks,
            "version": __version__,
        }
    )


def _spec_json(spec: ImpactSpec) -> dict:
    return {"speed_m_s": spec.speed_m_s, "angle_deg": spec.angle_deg, "offset_m": list(spec.offset_m)}


def load_finished(folder: Path, key: str, impacts: Sequence[ImpactSpec], comm) -> tuple[list[ImpactOutcome], Any]:
    """The finished impacts stored in ``folder`` for this sequence (the longest prefix whose key
    and impact match) and the plastic state after the last of them (this rank's), or ([], None)."""
    folder = Path(folder)
    done: list[ImpactOutcome] = []
    for k, spec in enumerate(impacts, 1):
        f = folder / f"impact-{k:03d}.json"
        npz = folder / f"impact-{k:03d}.rank{comm.rank}.npz"
        ok = False
        try:
            data = json.loads(f.read_text())
            ok = data.get("key") == key and data.get("spec") == _spec_json(spec) and npz.is_file()
        except (OSError, ValueError):
            pass
        if not comm.allreduce(ok, op=_land()):
            break
        done.append(ImpactOutcome(**data["outcome"]))
    if not done:
        return [], None
    with np.load(folder / f"impact-{len(done):03d}.rank{comm.rank}.npz") as z:
        state = {k: z[k] for k in z.files}
    return done, state


def _land():
    from mpi4py import MPI

    return MPI.LAND


def store_finished(folder: Path, key: str, k: int, record: ImpactRecord, engine, comm) -> None:
    """Keep impact k: each rank's plastic state (``impact-NNN.rankR.npz``), then on rank 0 its
    outcome and details (``impact-NNN.json``, written last: its presence marks the impact done).
    Each file is written to a temporary name and renamed."""
    folder = Path(folder)
    if comm.rank == 0:
        folder.mkdir(parents=True, exist_ok=True)
    comm.barrier()
    from ..commandkit.store import write_atomic

    state = engine.zone.get_state() if engine.zone is not None else {}

    def save_state(tmp: Path) -> None:
        with open(tmp, "wb") as f:  # a file, not a name: np.savez would add ".npz" to the temporary one
            np.savez(f, **state)

    write_atomic(folder / f"impact-{k:03d}.rank{comm.rank}.npz", save_state)
    comm.barrier()
    if comm.rank == 0:
        data = {
            "key": key,
            "impact": k,
            "spec": _spec_json(record.spec),
            "outcome": asdict(record.outcome),
            "details": {n: v for n, v in record.details.items() if n != "dent_profile"},
        }
        write_atomic(folder / f"impact-{k:03d}.json", json.dumps(data, indent=1, default=float))
        if record.series is not None:
            record.series.write_csv(folder / f"impact-{k:03d}-timeseries.csv")
    comm.barrier()


# --- engines: one model, its plastic zone, one impact at a time --------------------------------
def small_strain_plan(plan):
    """``plan`` with small strain and plasticity in the contact zones: a sequence carries the plastic
    state through residual states solved linearly, which a finite-strain zone does not have."""
    from dataclasses import replace

    reasons = dict(plan.reasons)
    if plan.strain != "small" or plan.plastic_whole:
        reasons["strain"] = "repeated impacts: small-strain J2 in the contact zones (residual states solved linearly)"
    return replace(plan, strain="small", plastic_whole=(), reasons=tuple(reasons.items()))


class _Engine:
    """What the two engines share: the per-impact scene and plan, the contact rows per offset,
    the launch onto the deformed face and the outcome."""

    zone = None  #: the model's PlasticZone (None when nothing yields)
    #: the sequence's full model and its contact candidates' radius (m; None: the plan's), set by
    #: each engine once it has built them
    model: FEModel
    cand_radius: float | None
    progress = False  #: the time loop's progress inside an impact (rank 0)

    def __init__(self, design, method: str, options: dict, comm):
        from ..scene.plan import make_plan

        if design.model.strain == "finite":
            from ..errors import SceneError

            raise SceneError(
                "model.strain",
                "finite",
                "must be auto or small for repeated impacts (each impact starts from "
                "the last one's residual state, a linear solve)",
            )
        self.design, self.method, self.options, self.comm = design, method, dict(options), comm
        self.plan = small_strain_plan(make_plan(design))
        self.contacts: dict[tuple, Any] = {}
        self.systems: dict[tuple, Any] = {}
        self.u_res = None  #: the residual state's vector (model or reduced), None before the first impact

    def release(self) -> None:
        """Free what the impact dropped (collective): petsc4py 3.18 parks the objects whose
        handles are gone (the impact's tangent factorizations, its contact operators) until a
        garbage cleanup of their communicator, and glibc keeps freed memory in the heap."""
        from ..integration.solvers import release_petsc_garbage, return_freed_memory

        release_petsc_garbage(self.model.V.mesh.comm)
        release_petsc_garbage(self.comm)
        return_freed_memory()

    def impact_scene(self, scene, spec: ImpactSpec):
        """The impact's scene on the sequence's mesh (its own velocity) and its plan."""
        from ..scene.plan import make_plan

        s = self.design.with_value("impact.velocity", impact_velocity(scene, spec))
        return s, small_strain_plan(make_plan(s))

    def contact_for(self, spec: ImpactSpec):
        from ..fem.contact import create_contact

        key = tuple(float(c) for c in spec.offset_m)
        if key not in self.contacts:
            shift = offset_vector(self.design, key) if any(key) else None
            self.contacts[key] = create_contact(self.model, self.plan, radius=self.cand_radius, ball_offset=shift)
        return key, self.contacts[key]

    def launch_shift(self, system, gap0: np.ndarray, u0) -> float:
        """How far (m) the ball moves towards the face so that the smallest gap of the state
        ``u0`` (the residual state) is the plan's gap: min(g0 + B u0) - gap."""
        if u0 is None:
            return 0.0
        b = system.B.createVecLeft()
        system.B.mult(u0, b)
        g = gap0 + np.concatenate(self.comm.allgather(b.array_r.copy()))
        b.destroy()
        return float(g.min() - self.plan.gap)

    def outcome(self, k: int, plan, ts, results: dict, dent: dict) -> tuple[ImpactOutcome, dict]:
        from ..results.timeseries import contact_metrics

        metrics = contact_metrics(ts)
        t, fn = ts.time, ts["contact_force_N"]
        ft = ts["tangential_force_N"] if "tangential_force_N" in ts else np.zeros_like(t)
        m = plan.ball.mass
        n = np.asarray(plan.contact_normal, float)
        v = np.asarray(plan.velocity, float)
        v_n, v_t = float(-(v @ n)), float(np.linalg.norm(v - (v @ n) * n))
        j_t = float(np.trapz(ft, t))
        # the contact point's tangential velocity ratio (Maw, Barber & Fawcett 1976), as a table's
        e_t = (v_t + 3.5 * j_t / m) / v_t if v_t > 1e-9 * max(v_n, 1e-300) else math.nan
        w_p = float(ts["plastic_dissipation_J"][-1]) if "plastic_dissipation_J" in ts else 0.0
        eps = float(ts["max_equivalent_plastic_strain"][-1]) if "max_equivalent_plastic_strain" in ts else 0.0
        o = ImpactOutcome(
            k,
            float(results.get("restitution", math.nan)),
            float(e_t),
            float(fn.max()),
            float(metrics["contact_duration_s"]),
            w_p,
            float(dent["residual_dent_depth_m"]),
            float(dent["residual_dent_radius_m"]),
            eps,
            self.surface_flow_stress(),
        )
        details = {
            "energy_drift_over_impact_rel": float(results["energy_drift_over_impact_rel"]),
            "energy_initial_J": float(results["energy_initial_J"]),
            "impact_energy_J": float(plan.hertz.energy) if hasattr(plan.hertz, "energy") else math.nan,
            "max_approach_m": float(metrics.get("max_approach_m", math.nan)),
            "contact_ended": bool(fn[-1] <= 1e-6 * max(float(fn.max()), 1e-300)),
            "dent_profile": dent.get("residual_dent_profile"),
        }
        return o, details

    def surface_flow_stress(self) -> float:
        """The struck body's committed flow stress (Pa) at its zone's quadrature point nearest the
        impact point (just under the face): a hardness test's flow stress there, NaN when it is
        elastic."""
        from ..geometry.builders import BLOCK_ZONE

        if self.zone is None:
            return math.nan
        return float(self.zone.flow_stress_near(np.array([self.plan.impact_point]), BLOCK_ZONE)[0])

    def boundary(self) -> dict:
        """Whether the plastic region stayed inside the contact zone (the model is linear beyond
        it): :func:`millimpact.results.dent.zone_boundary_note`'s strain at the boundary."""
        if self.zone is None:
            return {}
        from ..results.dent import zone_boundary_note

        keys, notes = zone_boundary_note(self.model, self.zone, self.plan)
        return {
            "zone_boundary_max_equivalent_plastic_strain": keys["zone_boundary_max_equivalent_plastic_strain"],
            "zone_boundary_elastic": bool(keys["zone_boundary_elastic"]),
            "plastic_zone_radius_m": keys["plastic_zone_radius_m"]["struck_body"],
        }

    def dent(self, u_full) -> dict:
        """Depth and radius (m) of the dent of the residual displacement ``u_full`` (a model
        vector) at the scene's impact point (:func:`millimpact.results.dent.dent_of`)."""
        from ..results.dent import dent_of

        return dent_of(self.model, u_full, self.plan)


class _ReducedEngine(_Engine):
    """The reduced methods: one reduction for the sequence (the plastic state lives in the zone)."""

    def __init__(self, design, method, options, comm):
        super().__init__(design, method, options, comm)
        from ..fem.plastic_zones import create_plastic_zone
        from ..geometry.builders import BALL_ZONE, BLOCK_ZONE
        from ..methods.reduced import build_reduced_setup
        from ..reduction.plastic_projection import ProjectedPlasticZone

        self.setup = build_reduced_setup(design, self.plan, self.options, method, comm)
        self.design, self.plan = self.setup.scene, self.setup.plan
        self.model, self.red, self.cand_radius = self.setup.model, self.setup.red, self.setup.cand_radius
        self.contacts[(0.0, 0.0)] = self.setup.contact
        self.zone = create_plastic_zone(
            self.model, [(BALL_ZONE, self.plan.ball.material), (BLOCK_ZONE, self.plan.target)]
        )
        self.plastic = ProjectedPlasticZone(self.zone, self.red) if self.zone is not None else None

    def system_for(self, spec):
        from ..methods.reduced import reduced_system

        key, contact = self.contact_for(spec)
        if key not in self.systems:
            system = reduced_system(self.red, contact, self.plan.friction)
            system.operator_cache = {}  # the elastic step factorization, kept between impacts
            system.plastic = self.plastic
            self.systems[key] = system
        return self.systems[key], contact

    def impact(self, k: int, spec: ImpactSpec, scene) -> ImpactRecord:
        from ..methods.free_phase import integrate_reduced
        from ..methods.reduced import ENERGY_EVERY_IMPACT_ONLY, impact_only_stop
        from ..results.recorder import impact_results

        scene_k, plan = self.impact_scene(scene, spec)
        opt = self.setup.opt
        system, contact = self.system_for(spec)
        q_res = self.residual_q()
        shift = self.launch_shift(system, contact.g0, q_res)
        q0 = self.red.create_vector()
        if q_res is not None:
            q0.axpy(1.0, q_res)
        if shift != 0.0:
            q0.axpy(1.0, self._ball_field(-shift * np.asarray(plan.contact_normal, float)))
        qd0 = self._ball_field(plan.velocity)
        rec = _peak_recorder(self.red, contact, plan, opt.recovery, self.plastic)
        rec.energy_every = ENERGY_EVERY_IMPACT_ONLY
        t_end = impact_t_end(plan)
        stop = impact_only_stop(plan)
        run = integrate_reduced(
            self.red,
            system,
            q0,
            qd0,
            contact,
            plan,
            t_end,
            rec,
            integrator=opt.integrator,
            options=dict(self.options),
            progress=self.progress,
            free_phase=opt.free_phase,
            f_free=opt.free_factor * plan.f_cut,
            min_span=opt.min_span,
            stop=stop,
        )
        ts = rec.series()
        results = impact_results(ts, plan.normal_speed, plan.probes.gauge_names, run["stats"], opt.integrator)
        rotation = self._rotation(rec.q_peak)
        self._q_res = None  # the state changed: a new residual state
        q_new = self.residual_q()
        u_full = self.red.expand(q_new) if q_new is not None else self.red.model.K.createVecRight()
        dent = self.dent(u_full)
        u_full.destroy()
        outcome, details = self.outcome(k, plan, ts, results, dent)
        details.update(
            {
                "launch_shift_m": shift,
                "max_rotation_at_peak_rad": rotation,
                **solver_counts(run["stats"].get),
                **self.boundary(),
            }
        )
        return ImpactRecord(outcome, spec, ts, details)

    _q_res = None

    def residual_q(self):
        """q_s with K_r q_s = -f_frozen (the zone's committed state), None while nothing yielded."""
        if self.plastic is None or self.zone.max_equivalent_plastic_strain() <= 0.0:
            return None
        if self._q_res is None or self._q_res[0] != self.zone.version:
            self._q_res = (self.zone.version, self.plastic.residual_state())
        return self._q_res[1]

    def _ball_field(self, vector):
        v = self.model.ball_velocity(vector)
        q = self.red.project_state(v)
        v.destroy()
        return q

    def _rotation(self, q_peak) -> float:
        if q_peak is None or self.zone is None:
            return math.nan
        return self.zone.max_rotation(self.plastic._expand(q_peak))


class _FullEngine(_Engine):
    """``full``: the unreduced model (the check of the reduced methods' carried state)."""

    def __init__(self, design, method, options, comm):
        super().__init__(design, method, options, comm)
        from ..fem.model import create_fe_model
        from ..fem.plastic_zones import create_plastic_zone
        from ..geometry.builders import BALL_ZONE, BLOCK_ZONE
        from ..geometry.mesh import create_mesh
        from ..methods.options import take
        from ..methods.reduced import REDUCED_CANDIDATE_FACTOR

        self.degree = int(take(self.options, "degree") or 2)
        self.integrator = take(self.options, "integrator") or "newmark-mr"
        a = self.plan.hertz.a_max
        # the reduced methods' candidates (methods/reduced.py reduced_plan): the same model as improved's
        self.cand_radius = min(
            REDUCED_CANDIDATE_FACTOR * a, min(self.plan.zone_radius, self.plan.ball_zone) - 2.0 * self.plan.h_contact
        )
        md = create_mesh(design, self.plan, comm)
        self.model = create_fe_model(md, self.plan, self.degree)
        self.zone = create_plastic_zone(
            self.model, [(BALL_ZONE, self.plan.ball.material), (BLOCK_ZONE, self.plan.target)]
        )

    def system_for(self, spec):
        from ..integration import integrators

        key, c = self.contact_for(spec)
        if key not in self.systems:
            s = integrators.LinearDynamics(
                M=self.model.M,
                K=self.model.K,
                B=c.B,
                g0=c.g0,
                fixed_dofs=self.model.fixed_dofs,
                contact_dofs=c.contact_dofs,
                T=c.T,
                friction=self.plan.friction,
                plastic=self.zone,
            )
            s.operator_cache = {}
            self.systems[key] = s
        return self.systems[key], c

    _u_res = None

    def residual_u(self):
        from ..results.dent import residual_displacement

        if self.zone is None or self.zone.max_equivalent_plastic_strain() <= 0.0:
            return None
        if self._u_res is None or self._u_res[0] != self.zone.version:
            self._u_res = (self.zone.version, residual_displacement(self.model, self.zone))
        return self._u_res[1]

    def impact(self, k: int, spec: ImpactSpec, scene) -> ImpactRecord:
        from ..integration import integrators
        from ..methods.reduced import ENERGY_EVERY_IMPACT_ONLY, impact_only_stop
        from ..results.recorder import Recorder, impact_results

        scene_k, plan = self.impact_scene(scene, spec)
        system, contact = self.system_for(spec)
        u_res = self.residual_u()
        shift = self.launch_shift(system, contact.g0, u_res)
        u0 = self.model.M.createVecRight()
        u0.set(0.0)
        if u_res is not None:
            u0.axpy(1.0, u_res)
        if shift != 0.0:
            d = self.model.ball_velocity(-shift * np.asarray(plan.contact_normal, float))
            u0.axpy(1.0, d)
            d.destroy()
        v0 = self.model.ball_velocity(plan.velocity)
        rec = _PeakMixin.wrap(Recorder)(self.model, contact, plan.probes, (), self.zone)
        rec.energy_every = ENERGY_EVERY_IMPACT_ONLY
        t_end = impact_t_end(plan)
        stop = impact_only_stop(plan)
        sched = integrators.TimeSchedule(t_end, plan.dt_contact, plan.dt_contact)
        stats = integrators.integrate(
            system,
            u0,
            v0,
            sched,
            method=self.integrator,
            observer=rec,
            options=dict(self.options),
            progress=self.progress,
            stop=stop,
        )
        ts = rec.series()
        results = impact_results(ts, plan.normal_speed, plan.probes.gauge_names, stats, self.integrator)
        rotation = (
            self.zone.max_rotation(rec.q_peak) if (self.zone is not None and rec.q_peak is not None) else math.nan
        )
        u_new = self.residual_u()
        if u_new is None:
            u_new = self.model.K.createVecRight()
        dent = self.dent(u_new)
        outcome, details = self.outcome(k, plan, ts, results, dent)
        details.update(
            {
                "launch_shift_m": shift,
                "max_rotation_at_peak_rad": rotation,
                **solver_counts(lambda k, d: getattr(stats, k, d)),
                **self.boundary(),
            }
        )
        return ImpactRecord(outcome, spec, ts, details)


def solver_counts(get) -> dict:
    """What an impact's time loop cost in solver work, from its integration statistics (``get(key,
    default)``): steps that yielded, their plastic iterations, effective-matrix solves, tangent
    factorizations."""
    return {
        "plastic_steps": int(get("n_plastic_steps", 0)),
        "plastic_iterations": int(get("n_plastic_iterations", 0)),
        "solves": int(get("n_solves", 0)),
        "tangent_factorizations": int(get("n_tangent_factorizations", 0)),
    }


def impact_t_end(plan) -> float:
    """An impact's span (s): the flight over the gap plus IMPACT_SPAN_CONTACTS Hertz contact
    times, whole contact steps (the separation stop ends it earlier)."""
    t = plan.gap / plan.normal_speed + IMPACT_SPAN_CONTACTS * plan.hertz.contact_time
    return max(1, math.floor(t / plan.dt_contact * (1 + 1e-12))) * plan.dt_contact


class _PeakMixin:
    """A recorder that also keeps the state at the largest contact force (the rotation there)."""

    @staticmethod
    def wrap(base):
        class PeakRecorder(base):
            q_peak, f_peak = None, -1.0

            def __call__(self, st):
                super().__call__(st)
                f = float(np.sum(st.lam[: len(self.contact.g0)])) if len(st.lam) else 0.0
                if f > self.f_peak:
                    self.f_peak = f
                    if self.q_peak is not None:
                        self.q_peak.destroy()
                    self.q_peak = st.u.copy()

        return PeakRecorder


def _peak_recorder(red, contact, plan, recovery, plastic):
    from ..results.reduced_recorder import ReducedRecorder

    return _PeakMixin.wrap(ReducedRecorder)(red, contact, plan.probes, (), recovery, plastic)
