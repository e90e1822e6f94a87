"""The contact zones with finite-strain J2 plasticity: large strains and rotations under the ball.

The zone's internal force becomes the total-Lagrangian one (reference volume, first Piola-Kirchhoff
stress P1 of :mod:`.finite_strain`), still written as the elastic force plus a correction on the
zone alone, so K, M and every operator built from them stay as they are:

    f_int(u) = K u + f_c(u),   f_c(u) = int_zone Grad(v) : (P1(F) - C : sym(Grad u)) dV,
    df_int/du = K + dK,        dK     = int_zone Grad(v) : (dP1/dF - C) : Grad(du) dV.

Unlike the small-strain correction, f_c is not zero where nothing yields: it carries the geometric
nonlinearity (rotations, the stress's change of configuration) wherever Grad u is not. So every
evaluation maps every zone point (no candidate cells; compiled, :mod:`.finite_strain_kernel`), each point with a
non-zero Grad u counts as a nonlinear one (the integrator iterates while any does), and the
"frozen" force of the committed state is f_c at the committed displacement (not at u = 0): the
force of the last converged step, which starts the next.

Outside the zones the bodies stay linear elastic and small-strain: there the strains are the
elastic ones (< Y/E ~ 0.5 %) and the rotations those of the bodies' vibration, so the geometric
terms, of the order of the strain times the stress, are below the elastic model's other errors
(a run reports the zone's largest rotation; the region's are smaller). The contact gap of
:mod:`millimpact.fem.contact` already takes the ball's surface nodes where they are (x + u) against the flat
face: on the deformed surface.
"""

from __future__ import annotations

import numpy as np
import ufl
from dolfinx import fem
from mpi4py import MPI

from .finite_strain import (
    finite_strain_update,
    log_strain,
    small_strain_moduli,
    small_strain_stress,
    stored_energy,
)
from .plastic_zone import PlasticZone
from .plasticity import ReturnMapResult, from_mandel

#: a point whose |Grad u| (largest component) is below this carries a geometric correction
#: below 1e-10 of its stress, beyond the Newton tolerance (1e-8): it counts as linear
GEOMETRIC_FLOOR = 1e-10


def _as_vector9(g):
    """A 3 x 3 UFL tensor as the vector of its components, row-major (the Quadrature spaces' order)."""
    return ufl.as_vector([g[i, j] for i in range(3) for j in range(3)])


class FiniteStrainZone(PlasticZone):
    """:class:`.plastic_zone.PlasticZone` with the finite-strain J2 law of :mod:`.finite_strain`
    (the module docstring); its protocol and outputs are the small-strain zone's."""

    finite = True

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self._moduli = [small_strain_moduli(z.material) for z in self.zones]
        self._committed_sc: np.ndarray | None = None  # the committed P1 - C eps per point (numpy path)
        self._trial_sc: np.ndarray | None = None
        # the compiled pass's force of the trial and the committed state (local arrays): kept in
        # place of the point corrections, which that pass does not write
        self._trial_f: np.ndarray | None = None
        self._committed_f: np.ndarray | None = None

    def _define_forms(self, points: np.ndarray, dxz) -> None:
        mesh, cell = self.V.mesh, self.V.mesh.ufl_cell()
        self._grad = fem.Expression(ufl.grad(self.u), points)
        Q9 = fem.FunctionSpace(
            mesh, ufl.TensorElement("Quadrature", cell, self.q_degree, shape=(3, 3), quad_scheme="default")
        )
        Q99 = fem.FunctionSpace(
            mesh, ufl.TensorElement("Quadrature", cell, self.q_degree, shape=(9, 9), quad_scheme="default")
        )
        self.stress_correction = fem.Function(Q9)  # P1 - C : sym(Grad u), Pa
        self.tangent_correction = fem.Function(Q99)  # dP1/dF - C, Pa
        du = ufl.TrialFunction(self.V)
        self._f_form = fem.form(ufl.inner(self.stress_correction, ufl.grad(self._v)) * dxz)
        self._k_integrand = ufl.inner(
            ufl.dot(self.tangent_correction, _as_vector9(ufl.grad(du))), _as_vector9(ufl.grad(self._v))
        )

    def _grad_u(self, k: int) -> np.ndarray:
        """Grad u (n, 3, 3) at zone k's quadrature points for the displacement in ``self.u``."""
        return self._grad.eval(self.cells[k]).reshape(-1, 3, 3)

    def _build_pass(self):
        from .finite_strain_kernel import FiniteStrainPass

        return FiniteStrainPass.build(self.V, self.cells, [z.material for z in self.zones], self.q_degree)

    def evaluate(self, u_vec, tangent: bool = True, candidates_only: bool = False) -> int:
        """The finite-strain update of displacement ``u_vec`` from the committed state: the
        correction's force (compiled, :mod:`.finite_strain_kernel`, without the tangent) or the
        corrections P1 - C eps and (``tangent``) dP1/dF - C at the points (numpy); keeps the trial
        state; returns the number of nonlinear points (this rank): those that yield or whose
        Grad u passes GEOMETRIC_FLOOR."""
        if candidates_only:
            raise RuntimeError("a finite-strain zone evaluates every cell (no candidates)")
        if not tangent and self._compiled() is not None:
            return self._evaluate_finite_pass(u_vec)
        self._compiled_force = self._trial_f = None
        self._set_displacement(u_vec)
        sc = self.stress_correction.x.array.reshape(-1, 9)
        tc = self.tangent_correction.x.array.reshape(-1, 81)
        trial: list[ReturnMapResult | None] = []
        n_active, active_cells = 0, []
        for k, zone in enumerate(self.zones):
            cells = self.cells[k]
            if not len(cells):
                trial.append(None)
                continue
            G = self._grad_u(k)
            upd = finite_strain_update(
                zone.material, np.eye(3) + G, self.plastic_strain[k], self.alpha[k], tangent, self.time_step
            )
            slots = self._slots[k]
            sc[slots] = (upd.first_pk - small_strain_stress(zone.material, G)).reshape(-1, 9)
            if tangent:
                tc[slots] = (upd.tangent - self._moduli[k][None]).reshape(-1, 81)
            trial.append(upd.state)
            active = upd.state.yielding | (np.abs(G).reshape(-1, 9).max(axis=1) > GEOMETRIC_FLOOR)
            n_active += int(np.count_nonzero(active))
            active_cells.append(cells[active.reshape(len(cells), self.n_q).any(axis=1)])
        self.stress_correction.x.scatter_forward()
        if tangent:
            self.tangent_correction.x.scatter_forward()
        self._trial, self._restricted = trial, False
        self._yielding_cells = np.unique(np.concatenate(active_cells)) if active_cells else np.zeros(0, np.int32)
        self._trial_sc = self.stress_correction.x.array.copy()
        return n_active

    def _evaluate_finite_pass(self, u_vec) -> int:
        """The compiled pass over every zone point: the force correction of ``u_vec`` (kept for
        :meth:`force_correction`, and as the committed force once committed) and the trial state."""
        self._set_displacement(u_vec)
        u = self.u.x.array
        f = self._compiled_force
        # a new buffer where the last one became the committed force (commit keeps it, uncopied)
        f = np.zeros_like(u) if f is None or f.size != u.size or f is self._committed_f else f
        f[:] = 0.0
        n_active, trial = self._compiled().evaluate_finite(
            u, self.plastic_strain, self.alpha, f, GEOMETRIC_FLOOR, self.time_step
        )
        self._compiled_force, self._trial, self._restricted = f, trial, False
        self._yielding_cells = np.zeros(0, np.int32)
        self._trial_sc, self._trial_f = None, f
        return n_active

    def force_correction(self, out=None):
        """f_c of the last evaluation (N, a PETSc Vec of V): the compiled pass's whole force (no
        frozen part is added: it is the correction at u itself), else the assembled one."""
        if self._compiled_force is None:
            return super().force_correction(out)
        return self._vector_of(self._compiled_force, out)

    def select_candidates(self, stress_fraction: float) -> int:
        raise RuntimeError("a finite-strain zone evaluates every cell (no candidates)")

    def commit(self) -> None:
        """Accept the last evaluated state and its force (end of a converged step); the
        version is bumped every time (the committed force moves with the displacement)."""
        if self._trial is None:
            return
        self._stress = [res.stress.copy() if res is not None else None for res in self._trial]
        for k, res in enumerate(self._trial):
            if res is not None:
                self.plastic_strain[k] = res.plastic_strain.copy()
                self.alpha[k] = res.alpha.copy()
        self._committed_sc, self._committed_f = self._trial_sc, self._trial_f
        self._trial = None
        self.version += 1  # collective: every rank commits every step
        self._prune_cache()

    def set_state(self, state) -> None:
        """The committed plastic state of :meth:`get_state`, at zero displacement."""
        super().set_state(state)
        self._committed_sc = self._committed_f = None

    def _assemble_frozen_force(self):
        """f_c at the committed displacement (before the first commit, at u = 0)."""
        if self._committed_f is not None:
            return self._vector_of(self._committed_f)
        if self._committed_sc is None:
            return self._assemble_unloaded_force()
        self.stress_correction.x.array[:] = self._committed_sc
        return self._assembled_correction()

    def unloaded_force(self):
        """f_c of the committed plastic strain at u = 0, -int_zone Grad(v) : C E_p dV (N, a new Vec):
        the load of the linear unloading (the residual state of :mod:`millimpact.results.dent` and
        the reduced free phase). Its stress is symmetric, so its moment vanishes in the reference
        configuration, as a free body's static load must."""
        return self._assemble_unloaded_force()

    def _assemble_unloaded_force(self):
        sc = self.stress_correction.x.array.reshape(-1, 9)
        sc[:] = 0.0
        for k, zone in enumerate(self.zones):
            if len(self.cells[k]):
                # F = I: E = 0, S = T = C (0 - E_p) (no return map: the unloading is elastic)
                stress = from_mandel(-zone.material.elastic_stress(self.plastic_strain[k]))
                sc[self._slots[k]] = stress.reshape(-1, 9)
        return self._assembled_correction()

    def _assembled_correction(self):
        self.stress_correction.x.scatter_forward()
        self._trial = None
        self._restricted, self._compiled_force = False, None
        return self.force_correction()

    def strain_energy_correction(self, u_vec) -> float:
        """E_el - 1/2 u.K u (J): int_zone (psi(E - E_p) - 1/2 eps : C : eps) dV of the committed
        plastic strain at ``u_vec`` (Hencky's energy, :func:`.finite_strain.stored_energy`; by the
        compiled pass where there is one)."""
        self._set_displacement(u_vec)
        if self._compiled() is not None:
            return self.comm.allreduce(self._compiled().energy(self.u.x.array, self.plastic_strain), op=MPI.SUM)
        values = []
        for k, zone in enumerate(self.zones):
            if not len(self.cells[k]):
                values.append(np.zeros(0))
                continue
            G = self._grad_u(k)
            E = log_strain(np.eye(3) + G)[0]
            linear = 0.5 * np.einsum("pij,pij->p", small_strain_stress(zone.material, G), G)
            values.append(stored_energy(zone.material, E, self.plastic_strain[k]) - linear)
        return self.integrate(values)

    def plastic_energy_constant(self) -> float:
        raise RuntimeError("a finite-strain zone's energy is not split: strain_energy_correction(u)")
