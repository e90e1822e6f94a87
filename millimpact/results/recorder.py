"""The recorder: turns each time step's state of an FE model into the run's time-series rows, and
the scalar results of an impact (restitution, energy balance, peak stresses) from those rows.

Columns (SI, the unit is the name's suffix): contact force (the multipliers' sum times the
symmetry factor), approach of the ball's centre of mass along the contact normal less the initial
gap, contact radius (the farthest active contact node from the contact axis), the ball's normal
velocity, the contact point's displacement / velocity / acceleration / normal and von Mises stress
(probes just inside the struck body), gauge stresses E d.eps.d, and energies (kinetic with the mass
the scheme integrates, strain 1/2 u.K u); with friction the tangential force, the ball's
tangential velocity and the cumulative friction work.

Takes the model, its contact set and the plan's :class:`millimpact.scene.plan.ProbeSpec` (where to
probe, the struck body's elastic constants, the initial gap); never the scene.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from ..fem.contact import ContactSet
from ..fem.model import FEModel
from ..fem.plasticity import from_mandel
from ..fem.probes import create_probe, patch_indicator, patch_momentum_row, stress_from_gradient, von_mises
from ..integration.integrators import product_matrix, strain_energy
from ..scene.plan import ProbeSpec
from .band_limit import gaussian_low_pass
from .timeseries import TimeSeries

if TYPE_CHECKING:
    from petsc4py import PETSc


class EnergyModel(Protocol):
    """What the rows' energies read of a model (an :class:`FEModel`, or a reduced model's view):
    the mass M and stiffness K (PETSc matrices) and the clamped dofs."""

    M: PETSc.Mat
    K: PETSc.Mat
    fixed_dofs: np.ndarray


class Recorder:
    """Observer of the time loop: turns each step's state into the run's time-series rows.

    ``probes`` says where the contact point and the gauges are probed (already inside the model's
    kept part), the struck body's material, whether it is a liner, the incoming tangential
    direction and the initial gap; ``field_times`` (s) the states kept for XDMF.
    """

    def __init__(
        self, model: FEModel, contact: ContactSet, probes: ProbeSpec, field_times: tuple[float, ...], plastic=None
    ):
        self.model: EnergyModel = model
        self.contact = contact
        #: the plastic zone (:class:`millimpact.fem.plastic_zone.PlasticZone`), None if elastic:
        #: strain energy with the plastic strain, plastic work and the largest plastic strain
        self.plastic = plastic
        self._pw_base, self._pw_last = 0.0, 0.0
        #: per recorded field time: (zone cells, equivalent plastic strain, von Mises stress) of a plastic run
        self.plastic_fields: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
        self.liner = probes.liner
        self.gauge_names = probes.gauge_names
        V = model.V
        self.u_fn = model.function("u")
        self.sym = model.sym_factor
        self.x_p, _, self.z_p = contact.point
        self.p = contact.point
        self.n = contact.normal  # e_y for the block
        # ball centre-of-mass velocity along n: c . v with c = M e_n(ball) / m_ball
        # (M has zero rows and columns on clamped and symmetry dofs, so M e ignores them)
        self.c_y = model.M.createVecLeft()
        model.M.mult(model.ball_velocity((0.0, 1.0, 0.0)), self.c_y)
        self.ball_mass_model = self.c_y.sum()
        if self.liner:
            model.M.mult(model.ball_velocity(self.n), self.c_y)
        self.c_y.scale(1.0 / self.ball_mass_model)
        # friction: the ball's tangential velocity along the incoming tangential direction t_v
        self.friction = contact.T is not None
        if self.friction:
            slide = probes.slide_direction
            assert contact.tangents is not None, "friction rows come with their tangent directions"
            self.t_v = np.array(slide) if slide is not None else contact.tangents[0]
            self.c_t = model.M.createVecLeft()
            model.M.mult(model.ball_velocity(self.t_v), self.c_t)
            self.c_t.scale(1.0 / self.ball_mass_model)
            self.t_proj = contact.tangents @ self.t_v  # components of t_v in the rows' basis (t1, t2)
            self._fw_base, self._fw_last = 0.0, 0.0
        # the contact point's velocity and acceleration (into the struck body positive): those of
        # the centre of mass of the half-ball of radius a_max under it (fem.probes.patch_momentum_row),
        # with the mass the integrator uses (rebuilt in __call__ when it is not M); radius 0: the
        # surface node's values
        self.c_patch, self._patch_mass = None, None
        self.band_limit_hz = probes.band_limit_hz
        if probes.patch_radius > 0:
            direction = -np.asarray(self.n if self.liner else (0.0, 1.0, 0.0), dtype=float)
            self._chi, self._e, self.patch_nodes, self.patch_radius = patch_indicator(
                V, model.M, model.block_dofs, np.asarray(probes.contact_point), direction, probes.patch_radius
            )
            self.c_patch, self._patch_mass = patch_momentum_row(model.M, self._chi, self._e), model.M
        self.ball_mask = model.M.createVecRight()
        self.ball_mask.set(0.0)
        self.ball_mask.array[model.ball_dofs] = 1.0
        self.tmp = model.M.createVecLeft()
        self.tmp2 = model.M.createVecLeft()
        self.gap0 = probes.gap
        # probes: contact point (surface value and just-inside gradient) and gauges
        pts = [probes.contact_point] + [g.point for g in probes.gauges]
        self.probe_point = np.array(probes.contact_point)
        self.gauge_dirs = [np.array(g.direction) for g in probes.gauges]
        self.probe = create_probe(V, np.array(pts), model.block_cells)
        if not np.all(self.probe.found):
            raise RuntimeError("a probe point (contact point or gauge) lies outside the block mesh")
        mat = probes.material
        self.mu, self.lmbda, self.E = mat.shear_modulus, mat.lame_lambda, mat.youngs_modulus
        self.rows: list[list[float]] = []
        self.field_times = sorted(field_times)
        self.fields: list[tuple[float, np.ndarray]] = []
        self._next_field = 0
        self.e0: float | None = None
        #: energies on every ``energy_every``-th row and the last (the others NaN): the two
        #: products with M and K are a quarter of a reduced contact step, and a contact table needs
        #: only the energies at the ends; 1 (every row) unless a caller sets it
        self.energy_every = 1
        #: the state of the last row recorded without energies (its index, u, v, mass), for series()
        self._skipped_row, self._skipped_u, self._skipped_v, self._skipped_mass = -1, None, None, None

    names_base = [
        "time_s",
        "contact_force_N",
        "approach_m",
        "contact_radius_m",
        "ball_velocity_m_s",
        "contact_point_displacement_m",
        "contact_point_velocity_m_s",
        "contact_point_acceleration_m_s2",
        "contact_point_stress_Pa",
        "contact_point_von_mises_Pa",
    ]

    @property
    def names(self) -> list[str]:
        return (
            self.names_base
            + [f"gauge_{name}_stress_Pa" for name in self.gauge_names]
            + ["ball_kinetic_energy_J", "kinetic_energy_J", "strain_energy_J", "total_energy_J"]
            + (
                ["tangential_force_N", "ball_tangential_velocity_m_s", "friction_dissipation_J"]
                if self.friction
                else []
            )
            + (["plastic_dissipation_J", "max_equivalent_plastic_strain"] if self.plastic is not None else [])
        )

    def _local(self, vec) -> np.ndarray:
        self.u_fn.vector.array[:] = vec.array_r
        self.u_fn.x.scatter_forward()
        return self.u_fn.x.array

    def _displacement_probe(self, st) -> tuple[np.ndarray, np.ndarray]:
        """Values (points x 3) and gradients (points x 3 x 3) of the displacement at the probes."""
        u_loc = self._local(st.u).copy()
        return self.probe.values(u_loc), self.probe.gradients(u_loc)

    def probe_columns(
        self,
        vals_u: np.ndarray,
        vals_v: np.ndarray,
        vals_a: np.ndarray,
        grads: np.ndarray,
        patch: tuple[np.ndarray, np.ndarray] | None = None,
    ) -> list[np.ndarray]:
        """The probe columns of the rows for n_t states at once: from the displacement, velocity
        and acceleration values (n_t, points, 3) and displacement gradients (n_t, points, 3, 3) at
        the probes (the contact point first, then the gauges), the contact point's displacement,
        velocity, acceleration and normal stress (along the impact direction, into the block or
        liner positive), its von Mises stress and each gauge's stress E d.eps.d, each (n_t,).
        ``patch`` (velocity, acceleration), each (n_t,): the patch's centre-of-mass values that
        replace the probe's velocity and acceleration (see ``c_patch``)."""
        s = stress_from_gradient(grads[:, 0], self.mu, self.lmbda)
        if self.plastic is not None:  # sigma = C (eps - eps_p): the contact point lies in the plastic zone
            s = s - self._plastic_stress_offset()
        eps = 0.5 * (grads[:, 1:] + np.swapaxes(grads[:, 1:], -1, -2))
        gauges = [self.E * np.einsum("i,tij,j->t", d, eps[:, k], d) for k, d in enumerate(self.gauge_dirs)]
        if not self.liner:
            normal = [-vals_u[:, 0, 1], -vals_v[:, 0, 1], -vals_a[:, 0, 1], s[:, 1, 1]]
        else:  # along the contact normal n, into the liner positive
            n = self.n
            normal = [-(vals_u[:, 0] @ n), -(vals_v[:, 0] @ n), -(vals_a[:, 0] @ n), np.einsum("i,tij,j->t", n, s, n)]
        if patch is not None:
            normal[1], normal[2] = patch
        return normal + [von_mises(s)] + gauges

    def _plastic_stress_offset(self) -> np.ndarray:
        """C eps_p (3 x 3, Pa) at the contact-point probe, from the nearest quadrature point."""
        ep = from_mandel(self.plastic.plastic_strain_near(np.array([self.probe_point]))[:, :])[0]
        return 2.0 * self.mu * ep + self.lmbda * np.trace(ep) * np.eye(3)

    def __call__(self, st) -> None:
        m = self.model
        lam = np.asarray(st.lam)
        force = self.sym * float(lam.sum()) if lam.size else 0.0
        active = lam > 0
        if np.any(active):
            pts = self.contact.points[active]
            if not self.liner:
                a = float(np.max(np.hypot(pts[:, 0] - self.x_p, pts[:, 2] - self.z_p)))
            else:  # distance from the contact axis p + s n
                d = pts - self.p
                a = float(np.max(np.linalg.norm(d - np.outer(d @ self.n, self.n), axis=1)))
        else:
            a = 0.0
        approach = -self.c_y.dot(st.u) - self.gap0
        vball = -self.c_y.dot(st.v)
        vals_u, grads = self._displacement_probe(st)
        vals_v = self.probe.values(self._local(st.v).copy())
        vals_a = self.probe.values(self._local(st.a).copy())
        patch = None
        if self.c_patch is not None:
            mass = getattr(st, "mass", None)
            if mass is not None and mass is not self._patch_mass and mass.getSize()[1] == self._chi.getSize():
                self.c_patch.destroy()  # the scheme's mass (newmark-mr: massless contact dofs)
                self.c_patch, self._patch_mass = patch_momentum_row(mass, self._chi, self._e), mass
            patch = (np.array([self.c_patch.dot(st.v)]), np.array([self.c_patch.dot(st.a)]))
        probe_cols = [
            float(c[0]) for c in self.probe_columns(vals_u[None], vals_v[None], vals_a[None], grads[None], patch)
        ]
        mass = st.mass if getattr(st, "mass", None) is not None else m.M
        if len(self.rows) % self.energy_every == 0:
            energies = self._energies(st.u, st.v, mass)
        else:  # kept for series(): the last row gets its energies there
            energies = [math.nan] * 4
            if self._skipped_u is None:
                self._skipped_u, self._skipped_v = st.u.duplicate(), st.v.duplicate()
            st.u.copy(self._skipped_u)
            st.v.copy(self._skipped_v)
            self._skipped_row, self._skipped_mass = len(self.rows), mass
        row = [st.t, force, approach, a, vball, *probe_cols, *energies]
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
        if self.plastic is not None:
            # cumulative per integrate() call, as the friction work: restarted segments continue the sum
            pw = float(getattr(st, "plastic_work", 0.0))
            if pw < self._pw_last:
                self._pw_base += self._pw_last
            self._pw_last = pw
            row += [self.sym * (self._pw_base + pw), self.plastic.max_equivalent_plastic_strain()]
        self.rows.append([float(x) for x in row])
        while self._next_field < len(self.field_times) and st.t >= self.field_times[self._next_field] - 1e-15:
            self.fields.append((st.t, st.u.array_r.copy()))
            if self.plastic is not None:  # the zone's cellwise plastic strain and von Mises stress
                self.plastic_fields.append(self.plastic.cell_fields())
            self._next_field += 1

    def _energies(self, u, v, mass) -> list[float]:
        """[ball kinetic, kinetic, strain, total] energy (J, full body): kinetic with the mass the
        scheme integrates (redistributed for newmark-mr, whose massless contact dofs carry no
        momentum), strain 1/2 u.K u (with the plastic strain: 1/2 (eps - eps_p) : C : (eps - eps_p))."""
        product_matrix(mass).mult(v, self.tmp)
        ke = 0.5 * self.tmp.dot(v)
        # the ball's part: M is block diagonal by body (the bodies share no node, and each body's
        # reduced coordinates are its own), so (mask v).M v = (mask v).M (mask v): no second product
        self.tmp2.pointwiseMult(v, self.ball_mask)
        ke_ball = 0.5 * self.tmp.dot(self.tmp2)
        se = strain_energy(product_matrix(self.model.K), u, self.model.fixed_dofs)
        if self.plastic is not None:
            se += self.plastic.strain_energy_correction(u)
        return [self.sym * ke_ball, self.sym * ke, self.sym * se, self.sym * (ke + se)]

    def _fill_last_energies(self) -> None:
        """The energies of the last row if ``energy_every`` skipped them (from its kept state)."""
        i = len(self.rows) - 1
        if i < 0 or self._skipped_row != i:
            return
        k = self.names.index("ball_kinetic_energy_J")
        self.rows[i][k : k + 4] = self._energies(self._skipped_u, self._skipped_v, self._skipped_mass)

    def series(self) -> TimeSeries:
        """The rows as a time series; with the patch (``c_patch``) the contact point's velocity and
        acceleration band-limited to ``probes.band_limit_hz`` (:mod:`.band_limit`). With
        ``energy_every`` > 1 the energy columns are NaN between their rows (never on the first
        and last)."""
        self._fill_last_energies()
        ts = TimeSeries.from_rows(self.names, self.rows)
        if self.c_patch is not None and self.band_limit_hz > 0:
            band_limit_contact_point(ts, self.band_limit_hz)
        return ts


def band_limit_contact_point(ts: TimeSeries, f_half: float) -> None:
    """Band-limit the contact point's velocity and acceleration of ``ts`` (in place) to ``f_half``
    (Hz), keeping the samples before the first contact (contact force > 0) as they are: the struck
    body is at rest there and the zero-phase filter would smear the impact back into it
    (:mod:`.band_limit`)."""
    touching = np.nonzero(ts["contact_force_N"] > 0)[0]
    first = float(ts.time[touching[0]]) if len(touching) else None
    for name in ("contact_point_velocity_m_s", "contact_point_acceleration_m_s2"):
        if name in ts:
            ts.columns[name] = gaussian_low_pass(ts.time, ts[name], f_half, rest_until=first)


def impact_results(
    ts: TimeSeries, normal_speed: float, gauge_names: Sequence[str], stats, integrator: str
) -> dict[str, Any]:
    """Scalar results of an FE run (full or reduced): restitution from the ball's centre-of-mass
    velocity just after the first contact (over the arrival ``normal_speed``, m/s), energy balance
    (kinetic + elastic strain + friction and plastic dissipation), peak stresses (of the gauges
    ``gauge_names``), plastic work and strain, integrator statistics."""
    f = ts["contact_force_N"]
    after = np.nonzero(f > 0)[0]
    if len(after):
        last = after[-1] if not np.any(np.diff(after) > 1) else after[np.argmax(np.diff(after) > 1)]
        i_out = min(last + 2, len(f) - 1)
        restitution = -ts["ball_velocity_m_s"][i_out] / normal_speed
    else:
        i_out = len(f) - 1
        restitution = float("nan")
    # energy balance: kinetic + elastic + what friction and plasticity dissipated stays constant
    dissipated = sum(ts[c] for c in ("friction_dissipation_J", "plastic_dissipation_J") if c in ts)
    e = ts["total_energy_J"] + dissipated
    e_in = e[0]
    e_dev = np.abs(e - e_in)
    e_dev[~np.isfinite(e)] = 0.0  # rows without energies (Recorder.energy_every)
    i_peak = int(np.argmax(f))
    plastic = {}
    if "plastic_dissipation_J" in ts:
        plastic = {
            "plastic_dissipation_J": float(ts["plastic_dissipation_J"][-1]),
            "plastic_dissipation_share": float(ts["plastic_dissipation_J"][-1] / e_in),
            "max_equivalent_plastic_strain": float(ts["max_equivalent_plastic_strain"][-1]),
        }
    return {
        **plastic,
        "restitution": restitution,
        "energy_initial_J": float(e_in),
        "energy_final_J": float(e[-1]),
        "energy_drift_max_rel": float(np.max(e_dev) / e_in),
        "energy_drift_over_impact_rel": float(np.max(e_dev[: i_out + 1]) / e_in),
        "ball_kinetic_energy_after_J": float(ts["ball_kinetic_energy_J"][-1]),
        "vibration_energy_share_end": float(1.0 - ts["ball_kinetic_energy_J"][-1] / e_in),
        "peak_contact_point_stress_Pa": float(np.min(ts["contact_point_stress_Pa"])),
        "peak_contact_point_von_mises_Pa": float(np.max(ts["contact_point_von_mises_Pa"])),
        "peak_gauge_stress_Pa": {name: _signed_peak(ts[f"gauge_{name}_stress_Pa"]) for name in gauge_names},
        "time_of_peak_force_s": float(ts.time[i_peak]),
        "integrator": integrator,
        "integration": stats._asdict() if hasattr(stats, "_asdict") else stats,
    }


def _signed_peak(x: np.ndarray) -> float:
    """The value of largest magnitude, with its sign."""
    return float(x[np.argmax(np.abs(x))])
