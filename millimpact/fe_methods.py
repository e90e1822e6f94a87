"""Finite-element methods as named run methods (``--method full``).

``full``: the unreduced reference. Both bodies elastic (P1 or P2), the block clamped, the ball free
with its arrival velocity a small gap before contact; node-to-surface Lagrange-multiplier contact
(:mod:`millimpact.contact`), time integration by :mod:`millimpact.integrators` (default Newmark
with mass redistribution), linear solves by PETSc (:mod:`millimpact.solvers`).
"""
from __future__ import annotations

import logging
import time
from pathlib import Path
from typing import Any, Optional

import numpy as np
from mpi4py import MPI

from . import integrators
from .contact import ContactSet, create_contact
from .errors import InputError
from .mesh import create_mesh
from .model import BLOCK_CELLS, FEModel, _cells_of, create_fe_model, create_probe, stress_from_gradient, von_mises
from .plan import Plan
from .results import TimeSeries
from .runner import RunOutput, register_method
from .scene import Scene

log = logging.getLogger(__name__)


def _mirror_into_model(point: np.ndarray, direction: np.ndarray, plan: Plan, scene: Scene):
    """Map a point (and a direction) on the full body into the kept part of a symmetric model."""
    x_p, _, z_p = scene.impact_point
    p, d = np.array(point, float), np.array(direction, float)
    if "x" in plan.symmetry_planes and p[0] < x_p:
        p[0], d[0] = 2 * x_p - p[0], -d[0]
    if "z" in plan.symmetry_planes and p[2] < z_p:
        p[2], d[2] = 2 * z_p - p[2], -d[2]
    return p, d


def _inward(point: np.ndarray, plan: Plan, scene: Scene) -> np.ndarray:
    """A point nudged just inside the block (and off the symmetry planes) so one cell holds it."""
    eps = 1e-6 * plan.h_contact
    p = np.array(point, float)
    if scene.liner is not None:   # the liner's contact point: along -n into the lifter
        p = p - eps * np.asarray(scene.contact_normal)
        if "x" in plan.symmetry_planes:
            p[0] = max(p[0], scene.impact_point[0] + eps)
        return p
    blk = scene.block
    p[1] = min(p[1], -eps)
    p[1] = max(p[1], -blk.thickness + eps)
    p[0] = np.clip(p[0], -blk.length / 2 + eps, blk.length / 2 - eps)
    p[2] = np.clip(p[2], eps, blk.height - eps)
    x_p, _, z_p = scene.impact_point
    if "x" in plan.symmetry_planes:
        p[0] = max(p[0], x_p + eps)
    if "z" in plan.symmetry_planes:
        p[2] = max(p[2], z_p + eps)
    return p


class Recorder:
    """Observer of the time loop: turns each step's state into the run's time-series rows."""

    def __init__(self, model: FEModel, contact: ContactSet, field_times: tuple[float, ...]):
        scene, plan = model.scene, model.plan
        self.model, self.contact = model, contact
        V = model.V
        self.u_fn = model.function("u")
        self.sym = model.sym_factor
        self.x_p, _, self.z_p = scene.impact_point
        self.p = np.array(scene.impact_point)
        self.n = np.array(scene.contact_normal)     # e_y for the block
        # ball centre-of-mass velocity along n: c . v with c = M e_n(ball) / m_ball
        # (M has zero rows and columns on clamped and symmetry dofs, so M e ignores them)
        self.c_y = model.M.createVecLeft()
        model.M.mult(model.ball_velocity((0.0, 1.0, 0.0)), self.c_y)
        self.ball_mass_model = self.c_y.sum()
        if scene.liner is not None:
            model.M.mult(model.ball_velocity(self.n), self.c_y)
        self.c_y.scale(1.0 / self.ball_mass_model)
        # friction: the ball's tangential velocity along the incoming tangential direction t_v
        self.friction = contact.T is not None
        if self.friction:
            v = np.array(scene.impact.velocity)
            vt = v - (v @ self.n) * self.n
            self.t_v = vt / np.linalg.norm(vt) if np.linalg.norm(vt) > 1e-12 * np.linalg.norm(v) else contact.tangents[0]
            self.c_t = model.M.createVecLeft()
            model.M.mult(model.ball_velocity(self.t_v), self.c_t)
            self.c_t.scale(1.0 / self.ball_mass_model)
            self.t_proj = contact.tangents @ self.t_v    # components of t_v in the rows' basis (t1, t2)
            self._fw_base, self._fw_last = 0.0, 0.0
        self.ball_mask = model.M.createVecRight()
        self.ball_mask.set(0.0)
        self.ball_mask.array[model.ball_dofs] = 1.0
        self.tmp = model.M.createVecLeft()
        self.tmp2 = model.M.createVecLeft()
        self.gap0 = plan.gap
        # probes: contact point (surface value and just-inside gradient) and gauges
        blk_cells = _cells_of(model.meshdata, BLOCK_CELLS)
        cp = _inward(np.array(scene.impact_point), plan, scene)
        pts = [cp]
        self.gauge_dirs = []
        for g in scene.gauges:
            p, d = _mirror_into_model(np.array(g.position), np.array(g.direction), plan, scene)
            pts.append(_inward(p, plan, scene))
            self.gauge_dirs.append(d / np.linalg.norm(d))
        self.probe = create_probe(V, np.array(pts), blk_cells)
        if not np.all(self.probe.found):
            raise RuntimeError("a probe point (contact point or gauge) lies outside the block mesh")
        mat = scene.target_material
        self.mu, self.lmbda, self.E = mat.shear_modulus, mat.lame_lambda, mat.youngs_modulus
        self.rows: list[list[float]] = []
        self.field_times = sorted(field_times)
        self.fields: list[tuple[float, np.ndarray]] = []
        self._next_field = 0
        self.e0: Optional[float] = None

    names_base = ["time_s", "contact_force_N", "approach_m", "contact_radius_m", "ball_velocity_m_s",
                  "contact_point_displacement_m", "contact_point_velocity_m_s", "contact_point_acceleration_m_s2",
                  "contact_point_stress_Pa", "contact_point_von_mises_Pa"]

    @property
    def names(self) -> list[str]:
        return (self.names_base + [f"gauge_{g.name}_stress_Pa" for g in self.model.scene.gauges]
                + ["ball_kinetic_energy_J", "kinetic_energy_J", "strain_energy_J", "total_energy_J"]
                + (["tangential_force_N", "ball_tangential_velocity_m_s", "friction_dissipation_J"]
                   if self.friction else []))

    def _local(self, vec) -> np.ndarray:
        self.u_fn.vector.array[:] = vec.array_r
        self.u_fn.x.scatter_forward()
        return self.u_fn.x.array

    def _displacement_probe(self, st) -> tuple[np.ndarray, np.ndarray]:
        """Values (points x 3) and gradients (points x 3 x 3) of the displacement at the probes."""
        u_loc = self._local(st.u).copy()
        return self.probe.values(u_loc), self.probe.gradients(u_loc)

    def probe_columns(self, vals_u: np.ndarray, vals_v: np.ndarray, vals_a: np.ndarray,
                      grads: np.ndarray) -> list[np.ndarray]:
        """The probe columns of the rows for n_t states at once: from the displacement, velocity
        and acceleration values (n_t, points, 3) and displacement gradients (n_t, points, 3, 3) at
        the probes (the contact point first, then the gauges), the contact point's displacement,
        velocity, acceleration and normal stress (along the impact direction, into the block or
        liner positive), its von Mises stress and each gauge's stress E d.eps.d, each (n_t,)."""
        s = stress_from_gradient(grads[:, 0], self.mu, self.lmbda)
        eps = 0.5 * (grads[:, 1:] + np.swapaxes(grads[:, 1:], -1, -2))
        gauges = [self.E * np.einsum("i,tij,j->t", d, eps[:, k], d) for k, d in enumerate(self.gauge_dirs)]
        if self.model.scene.liner is None:
            normal = [-vals_u[:, 0, 1], -vals_v[:, 0, 1], -vals_a[:, 0, 1], s[:, 1, 1]]
        else:   # along the contact normal n, into the liner positive
            n = self.n
            normal = [-(vals_u[:, 0] @ n), -(vals_v[:, 0] @ n), -(vals_a[:, 0] @ n), np.einsum("i,tij,j->t", n, s, n)]
        return normal + [von_mises(s)] + gauges

    def __call__(self, st) -> None:
        m = self.model
        lam = np.asarray(st.lam)
        force = self.sym * float(lam.sum()) if lam.size else 0.0
        active = lam > 0
        if np.any(active):
            pts = self.contact.points[active]
            if self.model.scene.liner is None:
                a = float(np.max(np.hypot(pts[:, 0] - self.x_p, pts[:, 2] - self.z_p)))
            else:   # distance from the contact axis p + s n
                d = pts - self.p
                a = float(np.max(np.linalg.norm(d - np.outer(d @ self.n, self.n), axis=1)))
        else:
            a = 0.0
        approach = -self.c_y.dot(st.u) - self.gap0
        vball = -self.c_y.dot(st.v)
        vals_u, grads = self._displacement_probe(st)
        vals_v = self.probe.values(self._local(st.v).copy())
        vals_a = self.probe.values(self._local(st.a).copy())
        probe_cols = [float(c[0]) for c in self.probe_columns(vals_u[None], vals_v[None], vals_a[None], grads[None])]
        # energies: kinetic with the mass the scheme integrates (st.mass: redistributed for
        # newmark-mr, whose massless contact dofs carry no momentum), strain 1/2 u.K u
        mass = st.mass if getattr(st, "mass", None) is not None else m.M
        mass.mult(st.v, self.tmp)
        ke = 0.5 * self.tmp.dot(st.v)
        self.tmp2.pointwiseMult(st.v, self.ball_mask)
        mass.mult(self.tmp2, self.tmp)
        ke_ball = 0.5 * self.tmp.dot(self.tmp2)
        se = integrators.strain_energy(m.K, st.u, m.fixed_dofs)
        row = [st.t, force, approach, a, vball, *probe_cols, self.sym * ke_ball, self.sym * ke, self.sym * se,
               self.sym * (ke + se)]
        if self.friction:
            # tangential force on the ball along t_v (N, full body: the half model's mirror adds
            # only the in-plane component, which is t_v's when the plane of incidence is the cut)
            tau = np.asarray(st.tau) if getattr(st, "tau", None) is not None else np.zeros(2 * lam.size)
            nc = lam.size
            ft = self.sym * float(self.t_proj[0] * tau[:nc].sum() + self.t_proj[1] * tau[nc:].sum())
            # friction work is cumulative per integrate() call: restarted segments (reduced
            # methods) and modal free phases (no friction) continue the sum
            fw = float(getattr(st, "friction_work", 0.0))
            if fw < self._fw_last:
                self._fw_base += self._fw_last
            self._fw_last = fw
            row += [ft, self.c_t.dot(st.v), self.sym * (self._fw_base + fw)]
        self.rows.append([float(x) for x in row])
        while self._next_field < len(self.field_times) and st.t >= self.field_times[self._next_field] - 1e-15:
            self.fields.append((st.t, st.u.array_r.copy()))
            self._next_field += 1

    def series(self) -> TimeSeries:
        return TimeSeries.from_rows(self.names, self.rows)


def write_fields(model: FEModel, fields: list[tuple[float, np.ndarray]], path: Path) -> None:
    """XDMF of the displacement (m) at the recorded times, with cell tags (collective)."""
    from dolfinx.io import XDMFFile

    mesh = model.V.mesh
    u = model.function("displacement_m")
    # XDMF in DOLFINx 0.5 writes P1 geometry: interpolate P2 fields to P1
    from dolfinx import fem

    out_fn = u
    if model.degree != 1:
        V1 = fem.VectorFunctionSpace(mesh, ("Lagrange", 1))
        out_fn = fem.Function(V1)
        out_fn.name = "displacement_m"
    with XDMFFile(mesh.comm, str(path), "w") as xdmf:
        xdmf.write_mesh(mesh)
        xdmf.write_meshtags(model.meshdata.cell_tags)
        for t, arr in fields:
            u.vector.array[:] = arr
            u.x.scatter_forward()
            if out_fn is not u:
                out_fn.interpolate(u)
            xdmf.write_function(out_fn, t)


def impact_results(ts: TimeSeries, scene: Scene, stats, integrator: str) -> dict[str, Any]:
    """Scalar results of an FE run (full or reduced): restitution from the ball's centre-of-mass
    velocity just after the first contact, energy balance, peak stresses, integrator statistics."""
    f = ts["contact_force_N"]
    after = np.nonzero(f > 0)[0]
    if len(after):
        last = after[-1] if not np.any(np.diff(after) > 1) else after[np.argmax(np.diff(after) > 1)]
        i_out = min(last + 2, len(f) - 1)
        restitution = -ts["ball_velocity_m_s"][i_out] / scene.normal_speed
    else:
        i_out = len(f) - 1
        restitution = float("nan")
    e = ts["total_energy_J"]
    e_in = e[0]
    i_peak = int(np.argmax(f))
    return {
        "restitution": restitution,
        "energy_initial_J": float(e_in),
        "energy_final_J": float(e[-1]),
        "energy_drift_max_rel": float(np.max(np.abs(e - e_in)) / e_in),
        "energy_drift_over_impact_rel": float(np.max(np.abs(e[: i_out + 1] - e_in)) / e_in),
        "ball_kinetic_energy_after_J": float(ts["ball_kinetic_energy_J"][-1]),
        "vibration_energy_share_end": float(1.0 - ts["ball_kinetic_energy_J"][-1] / e_in),
        "peak_contact_point_stress_Pa": float(np.min(ts["contact_point_stress_Pa"])),
        "peak_contact_point_von_mises_Pa": float(np.max(ts["contact_point_von_mises_Pa"])),
        "peak_gauge_stress_Pa": {g.name: _signed_peak(ts[f"gauge_{g.name}_stress_Pa"]) for g in scene.gauges},
        "time_of_peak_force_s": float(ts.time[i_peak]),
        "integrator": integrator,
        "integration": stats._asdict() if hasattr(stats, "_asdict") else stats,
    }


def _signed_peak(x: np.ndarray) -> float:
    """The value of largest magnitude, with its sign."""
    return float(x[np.argmax(np.abs(x))])


def run_fe(scene: Scene, plan: Plan, options: dict[str, Any], progress: bool, method: str = "full") -> RunOutput:
    """The full FE model of a scene, integrated over the scene's time span.

    ``options["candidate_radius"]`` (m, default the contact module's 2.5 a_max): contact candidates
    within this distance of the contact axis; a reduced run's (``candidate_radius_m`` of its model
    info) makes this run the very model that run reduces (same massless contact nodes)."""
    comm = MPI.COMM_WORLD
    t0 = time.perf_counter()
    degree = int(options.pop("degree", None) or plan.degree)
    integrator = options.pop("integrator", None) or "newmark-mr"
    t_end = float(options.pop("t_end", None) or scene.time.end)
    radius = options.pop("candidate_radius", None)
    try:
        radius = float(radius) if radius not in (None, "") else None
    except (TypeError, ValueError):
        raise InputError(f"option candidate_radius = {radius!r}: must be a length in m") from None
    if radius is not None and not radius > 0:
        raise InputError(f"option candidate_radius = {radius!r}: must be > 0 m")
    md = create_mesh(scene, plan, comm)
    t_mesh = time.perf_counter() - t0
    model = create_fe_model(scene, plan, md, degree)
    contact = create_contact(model, radius=radius)
    t_assemble = time.perf_counter() - t0 - t_mesh
    system = integrators.LinearDynamics(M=model.M, K=model.K, B=contact.B, g0=contact.g0,
                                        fixed_dofs=model.fixed_dofs, contact_dofs=contact.contact_dofs,
                                        T=contact.T, friction=scene.contact.friction)
    u0 = model.M.createVecRight()
    u0.set(0.0)
    v0 = model.ball_velocity(scene.impact.velocity)
    rec = Recorder(model, contact, scene.outputs.field_times if scene.outputs.xdmf else ())
    schedule = integrators.TimeSchedule(t_end, plan.dt_contact, plan.dt_free)
    stats = integrators.integrate(system, u0, v0, schedule, method=integrator, observer=rec,
                                  options=options, progress=progress)
    ts = rec.series()
    wall = time.perf_counter() - t0

    results = impact_results(ts, scene, stats, integrator)
    results["timings_s"] = {"mesh": t_mesh, "assemble": t_assemble, "integrate": wall - t_mesh - t_assemble}
    info = md.info
    model_info = {
        "method": method, "degree": degree, "dofs": model.n_dofs_global, "contact_candidates": contact.n,
        "symmetry": plan.symmetry, "symmetry_factor": model.sym_factor,
        "ball_mass_model_kg": model.sym_factor * rec.ball_mass_model, "ball_mass_exact_kg": scene.ball.mass,
        "ball_density_scale": model.extra["ball_density_scale"],
        "mesh": info.__dict__ if hasattr(info, "__dict__") else str(info),
        "mpi_ranks": comm.size,
    }
    notes = [f"full FE, P{degree}, {model.n_dofs_global} dofs, {plan.symmetry} model, integrator {integrator}"]
    fields = rec.fields
    writers = []
    if fields:
        writers.append(lambda folder: write_fields(model, fields, folder / "fields.xdmf"))
    return RunOutput(method, ts, results, model_info, extra_writers=writers, notes=notes)


register_method("full", "unreduced finite elements of ball and block (P1/P2), Lagrange-multiplier contact: "
                "the reference", lambda scene, plan, options, progress: run_fe(scene, plan, dict(options), progress))


from . import reduced_methods  # noqa: E402,F401  (registers traditional, improved, modal-p2)
from . import hertz_modal  # noqa: E402,F401  (registers hertz-modal)
