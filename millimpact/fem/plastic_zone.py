"""J2 plasticity in the contact zones: stresses at quadrature points, internal force and tangent.

Outside their contact zones the bodies stay linear elastic (the plan sizes the zones to hold the
plastic region, and a run checks that the zone boundary stayed elastic). Inside, the stress follows
small-strain J2 plasticity with isotropic hardening (:func:`millimpact.fem.plasticity.return_map`:
radial return and its consistent tangent; Simo & Hughes, Computational Inelasticity, 1998, ch. 3)
at the quadrature points of the zone cells. The internal force is the elastic one plus a correction
that lives on the zone alone:

    f_int(u) = K u + f_c(u),    f_c(u) = int_zone B^T (sigma(eps(u); state) - C eps(u)) dV
    df_int/du = K + dK(u),      dK     = int_zone B^T (C_t - C) B dV

with C the elastic and C_t the consistent tangent matrix (Mandel notation, 6 x 6). So the elastic
K, M and every operator built from them stay as they are; a step's Newton iteration adds dK to the
effective matrix and f_c to the residual, and the reduced methods project both with their
transform (f_c,r = T^T f_c, dK_r = T^T dK T: the zone's NMM covers span a subspace of the P2
space these quadrature points belong to, so the projection is exact).

Plastic state per quadrature point: plastic strain (Mandel, 6) and equivalent plastic strain
alpha. :meth:`PlasticZone.evaluate` computes the trial state of a displacement without changing
the committed one; :meth:`PlasticZone.commit` accepts it at the end of a converged step. Units SI.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Literal

import basix
import numpy as np
import ufl
from dolfinx import fem
from dolfinx import mesh as dmesh
from dolfinx.fem import petsc as fem_petsc
from mpi4py import MPI
from petsc4py import PETSc

from .plasticity import J2Material, ReturnMapResult, return_map

if TYPE_CHECKING:
    from .return_map_kernel import CompiledPass

_S2 = float(np.sqrt(2.0))


def mandel_strain(u) -> ufl.core.expr.Expr:
    """The small strain sym(grad u) as a Mandel vector [xx, yy, zz, sqrt2 yz, sqrt2 xz, sqrt2 xy]."""
    e = ufl.sym(ufl.grad(u))
    return ufl.as_vector([e[0, 0], e[1, 1], e[2, 2], _S2 * e[1, 2], _S2 * e[0, 2], _S2 * e[0, 1]])


@dataclass(frozen=True)
class ZoneMaterial:
    """A body's contact zone (its cell tag) and the J2 material that fills it."""

    cell_tag: int
    material: J2Material


class PlasticZone:
    """J2 plasticity at the quadrature points of the contact-zone cells of one or more bodies.

    ``V`` the vector P1/P2 space of the model, ``cell_tags`` its cell tags, ``zones`` the zone tags
    with their materials, ``bcs`` the model's Dirichlet conditions (their rows of f_c and dK are
    zero). The quadrature degree is 2 (p - 1) (at least 1): exact for the elastic stiffness.
    """

    #: the committed stress per zone (None for an empty zone), set by commit() and set_state()
    _stress: list[np.ndarray | None]
    #: small strain here; :class:`.finite_zone.FiniteStrainZone` is the finite-strain zone
    finite = False

    def __init__(self, V: fem.FunctionSpace, cell_tags, zones: Sequence[ZoneMaterial], bcs: Sequence = ()):
        mesh = V.mesh
        self.V, self.bcs, self.zones = V, list(bcs), list(zones)
        self.comm = mesh.comm
        p = V.ufl_element().degree()
        self.q_degree = max(1, 2 * (p - 1))
        points, _ = basix.make_quadrature(basix.CellType.tetrahedron, self.q_degree)
        self.n_q = points.shape[0]
        n_owned = mesh.topology.index_map(mesh.topology.dim).size_local
        self.cells = [
            np.sort(cell_tags.find(z.cell_tag)[cell_tags.find(z.cell_tag) < n_owned]).astype(np.int32)
            for z in self.zones
        ]
        self.u = fem.Function(V)
        cell = mesh.ufl_cell()
        quad = {"quadrature_degree": self.q_degree, "quadrature_scheme": "default"}
        Q1 = fem.FunctionSpace(mesh, ufl.FiniteElement("Quadrature", cell, self.q_degree, quad_scheme="default"))
        self.density = fem.Function(Q1)  # a scalar density to integrate over the zones
        dx = ufl.Measure("dx", domain=mesh, subdomain_data=cell_tags, metadata=quad)
        dxz = dx(tuple(z.cell_tag for z in self.zones))
        self._v = ufl.TestFunction(V)
        self._quad = quad
        self._define_forms(points, dxz)
        # select_candidates(): per zone the positions (in its cell list) of the candidate cells
        self._candidates: list[np.ndarray] | None = None
        self._candidate_form: fem.FormMetaClass | None = None
        self._restricted = False
        self._int_form = fem.form(self.density * dxz)
        # committed and trial state per zone: plastic strain (n, 6), alpha (n,)
        n = [len(c) * self.n_q for c in self.cells]
        self.plastic_strain = [np.zeros((k, 6)) for k in n]
        self.alpha = [np.zeros(k) for k in n]
        self._trial: list[ReturnMapResult | None] | None = None
        self._elastic = [z.material.elastic_matrix() for z in self.zones]
        self._slots = [self._points_of(c) for c in self.cells]  # each zone's quadrature slots
        # (version, per zone (eps_p, alpha, slots) of the candidates)
        self._picked: tuple[int, list[tuple[np.ndarray, np.ndarray, np.ndarray]]] | None = None
        self.version = 0  #: bumped by commit() when the plastic state changed
        self._cache: dict = {}
        #: evaluations without the tangent by the compiled pass (:mod:`.return_map_kernel`); False: numpy
        self.compiled = True
        #: the time step (s) the integrator is taking: a strain-rate factor's dg / dt (None: none)
        self.time_step: float | None = None
        self._kernel: CompiledPass | Literal[False] | None = None  # False: tried, none here
        self._compiled_force: np.ndarray | None = None

    def _define_forms(self, points: np.ndarray, dxz) -> None:
        """The small-strain corrections (Mandel: sigma - C eps per point, C_t - C) and their forms:
        f_c = int B^T (sigma - C eps) dV and dK's integrand B^T (C_t - C) B."""
        mesh, cell = self.V.mesh, self.V.mesh.ufl_cell()
        self._strain = fem.Expression(mandel_strain(self.u), points)
        Q6 = fem.FunctionSpace(mesh, ufl.VectorElement("Quadrature", cell, self.q_degree, dim=6, quad_scheme="default"))
        Q66 = fem.FunctionSpace(
            mesh, ufl.TensorElement("Quadrature", cell, self.q_degree, shape=(6, 6), quad_scheme="default")
        )
        self.stress_correction = fem.Function(Q6)  # sigma - C eps, Pa
        self.tangent_correction = fem.Function(Q66)  # C_t - C, Pa
        du = ufl.TrialFunction(self.V)
        self._f_form = fem.form(ufl.inner(self.stress_correction, mandel_strain(self._v)) * dxz)
        self._k_integrand = ufl.inner(ufl.dot(self.tangent_correction, mandel_strain(du)), mandel_strain(self._v))

    # --- state --------------------------------------------------------------------------------
    def _set_displacement(self, u_vec) -> None:
        self.u.vector.array[:] = u_vec.array_r
        self.u.x.scatter_forward()

    def quadrature_slots(self, k: int) -> np.ndarray:
        """Indices (cell-major, point-minor) of zone k's quadrature points in the Quadrature spaces."""
        return self._slots[k]

    def _points_of(self, cells: np.ndarray) -> np.ndarray:
        """The point indices (cell-major, point-minor) of ``cells``: mesh cells give the slots in the
        Quadrature spaces, positions in a zone's cell list give its rows of the plastic state."""
        return (np.asarray(cells)[:, None] * self.n_q + np.arange(self.n_q)[None, :]).ravel()

    def evaluate(self, u_vec, tangent: bool = True, candidates_only: bool = False) -> int:
        """Return-map the strains of displacement ``u_vec`` (PETSc Vec of V) from the committed
        state: fills the stress and (with ``tangent``) the tangent corrections and keeps the trial
        state. Returns the number of yielding quadrature points (this rank).

        ``candidates_only``: only the cells of :meth:`select_candidates` (the others are taken to
        stay elastic: their f_c is the frozen plastic strain's). Such an evaluation gives
        :meth:`force_correction` but no trial state to commit: a full evaluation confirms it."""
        candidates = self._candidates if candidates_only else None
        restricted = candidates is not None
        if not tangent and self._compiled() is not None:
            return self._evaluate_compiled(u_vec, restricted)
        self._compiled_force = None
        if restricted:
            self._frozen_force()  # kept before the stress correction is written below
        self._set_displacement(u_vec)
        sc = self.stress_correction.x.array.reshape(-1, 6)
        tc = self.tangent_correction.x.array.reshape(-1, 6, 6)
        # only the zones' slots are ever written (the Quadrature spaces span the whole mesh: zeroing
        # all of C_t - C was 8 ms of a 19 ms evaluation on the plastic rig)
        trial: list[ReturnMapResult | None] = []
        n_yield, yielding_cells = 0, []
        picked = self._candidate_state() if restricted else []
        for k, zone in enumerate(self.zones):
            pos = candidates[k] if candidates is not None else None
            cells = self.cells[k] if pos is None else self.cells[k][pos]
            if not len(cells):
                trial.append(None)
                continue
            eps = self._strain.eval(cells).reshape(-1, 6)
            if pos is None:
                eps_p, alpha, slots = self.plastic_strain[k], self.alpha[k], self._slots[k]
            else:
                eps_p, alpha, slots = picked[k]
            res = return_map(zone.material, eps, eps_p, alpha, tangent, self.time_step)
            if pos is None:
                # sigma - C eps = -C eps_p,n+1 (sigma = C (eps - eps_p,n+1)): the frozen force's
                # own expression where a point stays elastic
                sc[slots] = -zone.material.elastic_stress(res.plastic_strain)
            else:
                # restricted: the correction beyond the frozen one, sigma - C (eps - eps_p,n)
                # = -C d eps_p, zero where the point stays elastic
                y = np.flatnonzero(res.yielding)
                sc[slots] = 0.0
                sc[slots[y]] = -zone.material.elastic_stress(res.plastic_increment[y])
            if tangent:
                tc[slots] = res.tangent - self._elastic[k][None, :, :]
            trial.append(res)
            n_yield += int(np.count_nonzero(res.yielding))
            if tangent:
                yielding_cells.append(cells[res.yielding.reshape(len(cells), self.n_q).any(axis=1)])
        self.stress_correction.x.scatter_forward()
        if tangent:
            self.tangent_correction.x.scatter_forward()
        self._trial = None if restricted else trial
        self._restricted = restricted
        # without the tangent, stiffness_correction() is zero (no stale C_t - C is assembled)
        self._yielding_cells = np.unique(np.concatenate(yielding_cells)) if yielding_cells else np.zeros(0, np.int32)
        return n_yield

    def _compiled(self):
        """The compiled pass (:class:`.return_map_kernel.CompiledPass`), built on first use; None
        where it is off (``compiled = False``), cannot be built or the space is not one it handles."""
        if self._kernel is None:
            self._kernel = (self._build_pass() if self.compiled else None) or False
        return self._kernel or None

    def _build_pass(self):
        from .return_map_kernel import CompiledPass

        return CompiledPass.build(self.V, self.cells, [z.material for z in self.zones], self.q_degree)

    def _evaluate_compiled(self, u_vec, restricted: bool) -> int:
        """:meth:`evaluate` without the tangent by the compiled pass: strains, return map and the
        force correction beyond the frozen one (the yielding points' -int B^T C d eps_p dV) in one
        loop, kept for :meth:`force_correction`; the stress correction is not written. Over the
        candidates (``restricted``: no trial state kept) or every zone cell (the trial state kept,
        as numpy's :func:`return_map` gives it)."""
        self._frozen_force()  # assembled (if not kept) before this evaluation marks itself restricted
        self._set_displacement(u_vec)
        u = self.u.x.array
        f = self._compiled_force
        if f is None or f.size != u.size:
            f = np.zeros_like(u)
        else:
            f[:] = 0.0
        positions = self._candidates if restricted else [np.arange(len(c)) for c in self.cells]
        n_yield, trial = self._compiled().evaluate(
            u, positions, self.plastic_strain, self.alpha, f, keep_state=not restricted, dt=self.time_step
        )
        self._compiled_force = f
        self._trial = None if restricted else trial
        self._restricted = restricted
        self._yielding_cells = np.zeros(0, np.int32)
        return n_yield

    def _candidate_state(self) -> list[tuple[np.ndarray, np.ndarray, np.ndarray]]:
        """Per zone, the committed (eps_p, alpha) of the candidates' points and their quadrature
        slots: gathered once per selection and plastic state, not every iteration."""
        assert self._candidates is not None, "called after select_candidates()"
        if self._picked is None or self._picked[0] != self.version:
            picked = []
            for k, pos in enumerate(self._candidates):
                points = self._points_of(pos)
                picked.append(
                    (self.plastic_strain[k][points], self.alpha[k][points], self._points_of(self.cells[k][pos]))
                )
            self._picked = (self.version, picked)
        return self._picked[1]

    def select_candidates(self, stress_fraction: float) -> int:
        """Make the cells of the last full evaluation with a point at or above ``stress_fraction``
        of its flow stress (von Mises of the trial state against sigma_y(alpha)), or yielding, the
        candidates of ``evaluate(candidates_only=True)``; returns their number (this rank).

        Outside them f_c(u) is the frozen f_c of the committed plastic strain, so only these cells
        are return-mapped and assembled: f_c = f_frozen + int_cand B^T (sigma - C (eps - eps_p,n)) dV."""
        if self._trial is None:
            raise RuntimeError("select_candidates needs a full evaluation first")
        from .plasticity import von_mises

        picked, mesh_cells = [], []
        for k, res in enumerate(self._trial):
            if res is None:
                picked.append(np.zeros(0, np.int64))
                continue
            hot = res.yielding | (
                von_mises(res.stress) >= stress_fraction * self.zones[k].material.flow.flow_stress(res.alpha)
            )
            pos = np.flatnonzero(hot.reshape(len(self.cells[k]), self.n_q).any(axis=1))
            picked.append(pos)
            mesh_cells.append(self.cells[k][pos])
        self._candidates = picked
        self._picked = None
        cells = np.unique(np.concatenate(mesh_cells)).astype(np.int32) if mesh_cells else np.zeros(0, np.int32)
        self._candidate_cells, self._candidate_form = cells, None  # the form when numpy's path asks
        return len(cells)

    def _candidates_form(self):
        """The force form over the candidate cells (numpy's restricted path), built on first use
        after a selection (2.5 ms on the plastic rig; the compiled path needs none)."""
        if self._candidate_form is None:
            mesh, cells = self.V.mesh, self._candidate_cells
            tags = dmesh.meshtags(mesh, mesh.topology.dim, cells, np.ones(len(cells), dtype=np.int32))
            dxc = ufl.Measure("dx", domain=mesh, subdomain_data=tags, metadata=self._quad)(1)
            self._candidate_form = fem.form(ufl.inner(self.stress_correction, mandel_strain(self._v)) * dxc)
        return self._candidate_form

    def commit(self) -> None:
        """Accept the last evaluated state (end of a converged step)."""
        if self._restricted:
            raise RuntimeError("a candidates-only evaluation cannot be committed: evaluate fully first")
        if self._trial is None:
            return
        changed = False
        self._stress = [res.stress.copy() if res is not None else None for res in self._trial]
        for k, res in enumerate(self._trial):
            if res is not None:
                changed |= bool(res.yielding.any())
                self.plastic_strain[k] = res.plastic_strain.copy()
                self.alpha[k] = res.alpha.copy()
        self._trial = None
        # the state's version (global): outputs of an unchanged plastic state are cached
        if self.comm.allreduce(changed, op=MPI.LOR):
            self.version += 1
            self._prune_cache()

    def _prune_cache(self) -> None:
        """Drop the outputs cached for older plastic states, destroying their PETSc Vecs (f_frozen of
        each state). Dropped alone, a Vec is parked on the garbage of its index map's communicator,
        which no cleanup reaches: a plastic case of paper-rig-plastic kept ~50 MB (73 yielding steps
        of 70,641 dofs) for the life of the process, ~3 GB a rank over a 100-case table."""
        for key in [k for k in self._cache if k[1] != self.version]:
            value = self._cache.pop(key)
            if isinstance(value, PETSc.Vec):
                value.destroy()

    def get_state(self) -> dict[str, np.ndarray]:
        """The committed plastic state of this rank: ``plastic_strain_<k>`` (n, 6, Mandel) and
        ``alpha_<k>`` (n,) per zone k, copies (a repeated impact's stored state,
        :mod:`millimpact.repeat.sequence`)."""
        out = {}
        for k in range(len(self.zones)):
            out[f"plastic_strain_{k}"] = self.plastic_strain[k].copy()
            out[f"alpha_{k}"] = self.alpha[k].copy()
        return out

    def set_state(self, state) -> None:
        """Make ``state`` (of :meth:`get_state`, on the same mesh and ranks) the committed state;
        the outputs cached for the old state are dropped (collective: the version is bumped)."""
        for k in range(len(self.zones)):
            ep, a = np.asarray(state[f"plastic_strain_{k}"], float), np.asarray(state[f"alpha_{k}"], float)
            if ep.shape != self.plastic_strain[k].shape or a.shape != self.alpha[k].shape:
                raise ValueError(
                    f"plastic state of zone {k}: shapes {ep.shape}, {a.shape} do not fit the zone's "
                    f"{self.plastic_strain[k].shape}, {self.alpha[k].shape} (another mesh or rank count)"
                )
            self.plastic_strain[k], self.alpha[k] = ep.copy(), a.copy()
        self._trial = None
        self._restricted = False
        self._candidates = self._candidate_form = None  # another state: chosen again
        self._stress = [None] * len(self.zones)
        self.version += 1
        self._prune_cache()

    # --- operators ----------------------------------------------------------------------------
    def force_correction(self, out=None):
        """f_c = int_zone B^T (sigma - C eps) dV (N, a PETSc Vec of V; zero on Dirichlet rows); after a
        candidates-only evaluation f_frozen plus the candidate cells' part (:meth:`select_candidates`).
        ``out``: a Vec of V to assemble into (overwritten, and returned), else a new one (a ghosted
        Vec's creation was a third of the assembly's cost, once an iteration)."""
        if self._compiled_force is not None:
            b = self._vector_of(self._compiled_force, out)
            b.axpy(1.0, self._frozen_force())
            return b
        form = self._candidates_form() if self._restricted else self._f_form
        if out is None:
            b = fem_petsc.assemble_vector(form)
        else:
            b = out
            with b.localForm() as local:
                local.set(0.0)
            fem_petsc.assemble_vector(b, form)
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        fem_petsc.set_bc(b, self.bcs, scale=0.0)
        if self._restricted:
            b.axpy(1.0, self._frozen_force())
        return b

    def _vector_of(self, local_force: np.ndarray, out=None):
        """The Vec of V (``out``, else a new one) of a force the compiled pass added up per rank
        (local array, ghosts included): the ghosts' parts summed into their owners, zero on
        Dirichlet rows."""
        b = out if out is not None else fem_petsc.create_vector(self._f_form)
        with b.localForm() as local:
            local.array[:] = local_force
        b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
        fem_petsc.set_bc(b, self.bcs, scale=0.0)
        return b

    def frozen_force(self):
        """f_c of the committed plastic strain alone, -int_zone B^T C eps_p dV (N): the load that
        the residual (unloaded, elastic) state balances, and f_c(u) at any u where no point yields;
        a new PETSc Vec of V (assembled once per plastic state)."""
        return self._frozen_force().copy()

    def _frozen_force(self):
        """The kept f_frozen of the committed state (not a copy: read only)."""
        key = ("frozen", self.version)
        if key not in self._cache:
            self._cache[key] = self._assemble_frozen_force()
        return self._cache[key]

    def _assemble_frozen_force(self):
        sc = self.stress_correction.x.array.reshape(-1, 6)
        sc[:] = 0.0
        for k in range(len(self.zones)):
            if len(self.cells[k]):
                sc[self.quadrature_slots(k)] = -self.zones[k].material.elastic_stress(self.plastic_strain[k])
        self.stress_correction.x.scatter_forward()
        self._trial = None
        self._restricted, self._compiled_force = False, None  # the form over every zone cell
        return self.force_correction()

    def stiffness_correction(self):
        """dK = int_zone B^T (C_t - C) B dV (N/m, a PETSc Mat on V; zero Dirichlet rows and
        columns, so K + dK keeps K's unit diagonal there) of the last evaluated state. C_t = C
        where a point does not yield, so the integral runs over the cells with a yielding point
        only: the matrix has their dofs' pattern (a few % of the zone's at first yield), which
        keeps its assembly and its projection (PtAP) small."""
        mesh = self.V.mesh
        cells = np.asarray(getattr(self, "_yielding_cells", np.zeros(0, np.int32)), dtype=np.int32)
        tags = dmesh.meshtags(mesh, mesh.topology.dim, cells, np.ones(len(cells), dtype=np.int32))
        dxy = ufl.Measure("dx", domain=mesh, subdomain_data=tags, metadata=self._quad)(1)
        A = fem_petsc.assemble_matrix(fem.form(self._k_integrand * dxy), bcs=self.bcs, diagonal=0.0)
        A.assemble()
        return A

    def integrate(self, values: Sequence[np.ndarray]) -> float:
        """int_zone d dV of a density given per zone at its quadrature points (global sum)."""
        arr = self.density.x.array
        arr[:] = 0.0
        for k, val in enumerate(values):
            if len(self.cells[k]):
                arr[self.quadrature_slots(k)] = val
        self.density.x.scatter_forward()
        return self.comm.allreduce(fem.assemble_scalar(self._int_form), op=MPI.SUM)

    def strain_energy_correction(self, u_vec) -> float:
        """E_el - 1/2 u.K u (J): the elastic strain energy with the committed plastic strain is
        1/2 int (eps - eps_p) : C : (eps - eps_p) dV = 1/2 u.K u + int_zone (-eps : C : eps_p
        + 1/2 eps_p : C : eps_p) dV (global sum). The first integral is linear in u,
        u . f_frozen with f_frozen = -int B^T C eps_p (:meth:`frozen_force`): both terms are kept per
        plastic state, so a row costs a dot product while the state does not change."""
        return u_vec.dot(self._frozen_force()) + self.plastic_energy_constant()

    def plastic_energy_constant(self) -> float:
        """1/2 int_zone eps_p : C : eps_p dV (J, global) of the committed state: the part of
        :meth:`strain_energy_correction` that does not depend on u (kept per plastic state)."""
        key = ("energy", self.version)
        if key not in self._cache:
            const = self.integrate(
                [0.5 * np.einsum("pi,pi->p", ep, ep @ C) for ep, C in zip(self.plastic_strain, self._elastic)]
            )
            self._cache[key] = const
        return self._cache[key]

    def step_plastic_work(self) -> float:
        """The plastic work of the evaluated (trial) state over the step, int_zone sigma : d eps_p dV
        (J, global; the model's, not scaled by symmetry)."""
        if self._trial is None:
            return 0.0
        return self.integrate([r.dissipation_increment if r is not None else np.zeros(0) for r in self._trial])

    # --- outputs ------------------------------------------------------------------------------
    def trial(self):
        """The last evaluated return-mapping results per zone (None for an empty zone)."""
        return self._trial

    def quadrature_points(self) -> list[np.ndarray]:
        """The physical coordinates (m) of each zone's quadrature points on this rank, (n, 3) arrays
        in the order of :meth:`trial`'s values."""
        if not hasattr(self, "_qp_xyz"):
            X = fem.Expression(
                ufl.SpatialCoordinate(self.V.mesh), basix.make_quadrature(basix.CellType.tetrahedron, self.q_degree)[0]
            )
            self._qp_xyz = [X.eval(c).reshape(-1, 3) if len(c) else np.zeros((0, 3)) for c in self.cells]
        return self._qp_xyz

    def _state_near(
        self, points: np.ndarray, zone_tag: int | None = None
    ) -> list[tuple[np.ndarray, float, float] | None]:
        """Per point, (plastic strain (Mandel, 6), alpha, flow stress sigma_y(alpha) in Pa) of the
        committed state at the quadrature point nearest it of the zones (or of the zone with cell
        tag ``zone_tag``), over all ranks (None where no such zone has a point)."""
        key = ("near", self.version, zone_tag, np.asarray(points, dtype=float).tobytes())
        if key in self._cache:
            return self._cache[key]
        qps = self.quadrature_points()
        out: list[tuple[np.ndarray, float, float] | None] = []
        for x in np.asarray(points, dtype=float):
            best = (np.inf, -1, -1)
            for k, xyz in enumerate(qps):
                if len(xyz) and zone_tag in (None, self.zones[k].cell_tag):
                    d = np.linalg.norm(xyz - x, axis=1)
                    j = int(np.argmin(d))
                    best = min(best, (float(d[j]), k, j))
            dist = self.comm.allgather(best[0])
            owner = int(np.argmin(dist))
            value = None
            if self.comm.rank == owner and best[1] >= 0:
                k, j = best[1], best[2]
                a = float(self.alpha[k][j])
                value = (
                    self.plastic_strain[k][j].copy(),
                    a,
                    float(self.zones[k].material.flow.flow_stress(np.array(a))),
                )
            out.append(self.comm.bcast(value, root=owner))
        self._cache[key] = out
        return out

    def plastic_strain_near(self, points: np.ndarray) -> np.ndarray:
        """The committed plastic strain (Mandel, (n_points, 6)) at the zone's quadrature point
        nearest each point (global over ranks; zeros where no zone has a point)."""
        return np.array([np.zeros(6) if v is None else v[0] for v in self._state_near(points)]).reshape(-1, 6)

    def flow_stress_near(self, points: np.ndarray, zone_tag: int | None = None) -> np.ndarray:
        """The committed flow stress sigma_y(alpha) (Pa; the rate-independent curve, a hardness
        test's) at the quadrature point nearest each point of the zones (or of the zone with cell
        tag ``zone_tag``; NaN where none has a point)."""
        return np.array([np.nan if v is None else v[2] for v in self._state_near(points, zone_tag)])

    def boundary_plastic_strain(self, interface_facets: np.ndarray) -> float:
        """The largest committed alpha in the zone cells that touch the zone/region interface
        (``interface_facets``, local facet indices): > 0 means the plastic region reached the zone's
        boundary, where the model turns linear (global over ranks)."""
        mesh = self.V.mesh
        tdim = mesh.topology.dim
        mesh.topology.create_connectivity(tdim - 1, tdim)
        f2c = mesh.topology.connectivity(tdim - 1, tdim)
        touching: set[int] = set()
        for f in np.asarray(interface_facets, dtype=np.int32):
            touching.update(int(c) for c in f2c.links(f))
        local = 0.0
        for k, cells in enumerate(self.cells):
            mask = np.isin(cells, np.fromiter(touching, dtype=np.int32, count=len(touching)))
            if mask.any():
                local = max(local, float(self.alpha[k].reshape(len(cells), self.n_q)[mask].max()))
        return self.comm.allreduce(local, op=MPI.MAX)

    def plastic_extent(self, point, tol: float) -> dict[int, float]:
        """Per zone (keyed by its cell tag), the largest distance (m) from ``point`` of a quadrature
        point whose committed alpha exceeds ``tol`` (0 where none does; global over ranks): the
        measured radius of the plastic region about the first contact point."""
        qps = self.quadrature_points()
        out = {}
        for k in range(len(self.cells)):
            local = 0.0
            if len(self.cells[k]):
                hot = self.alpha[k] > tol
                if hot.any():
                    local = float(np.linalg.norm(qps[k][hot] - np.asarray(point, dtype=float), axis=1).max())
            out[self.zones[k].cell_tag] = self.comm.allreduce(local, op=MPI.MAX)
        return out

    def section(self, point, normal, plane_normal, half_width: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The committed alpha on a section: the quadrature points within ``half_width`` (m) of the
        plane through ``point`` with unit normal ``plane_normal``, as (s, depth, alpha) gathered on
        rank 0 (empty on the others): s (m) along ``plane_normal x normal`` in the plane, depth (m)
        along ``-normal`` (into the struck body positive, the ball at negative depth)."""
        p, n, m = (np.asarray(v, dtype=float) for v in (point, normal, plane_normal))
        t = np.cross(m, n)
        qps = self.quadrature_points()
        parts = []
        for k in range(len(self.cells)):
            if len(self.cells[k]):
                d = qps[k] - p
                near = np.abs(d @ m) <= half_width
                parts.append(np.column_stack([d[near] @ t, -(d[near] @ n), self.alpha[k][near]]))
        local = np.concatenate(parts) if parts else np.zeros((0, 3))
        every = self.comm.gather(local, root=0)
        if self.comm.rank != 0:
            return np.zeros(0), np.zeros(0), np.zeros(0)
        data = np.concatenate(every)
        return data[:, 0], data[:, 1], data[:, 2]

    def cell_fields(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(local zone cells, their largest committed equivalent plastic strain, their largest von
        Mises stress of the last committed step (Pa)): the cellwise fields written to XDMF."""
        from .plasticity import von_mises as vm_of

        cells, alpha, vm = [], [], []
        for k, c in enumerate(self.cells):
            if not len(c):
                continue
            cells.append(c)
            alpha.append(self.alpha[k].reshape(len(c), self.n_q).max(axis=1))
            stress = getattr(self, "_stress", [None] * len(self.cells))[k]
            vm.append(vm_of(stress).reshape(len(c), self.n_q).max(axis=1) if stress is not None else np.zeros(len(c)))
        if not cells:
            return np.zeros(0, np.int32), np.zeros(0), np.zeros(0)
        return np.concatenate(cells), np.concatenate(alpha), np.concatenate(vm)

    def max_rotation(self, u_vec) -> float:
        """The largest infinitesimal rotation |w| (rad), w the axial vector of the skew part of
        grad u, over the zone's quadrature points for the displacement ``u_vec`` (global): the
        small-strain model needs it well below 1 (foundations.md section 10)."""
        if not hasattr(self, "_rotation"):
            g = ufl.grad(self.u)
            w = ufl.as_vector([g[2, 1] - g[1, 2], g[0, 2] - g[2, 0], g[1, 0] - g[0, 1]]) * 0.5
            self._rotation = fem.Expression(w, basix.make_quadrature(basix.CellType.tetrahedron, self.q_degree)[0])
        self._set_displacement(u_vec)
        local = 0.0
        for c in self.cells:
            if len(c):
                local = max(local, float(np.linalg.norm(self._rotation.eval(c).reshape(-1, 3), axis=1).max()))
        return self.comm.allreduce(local, op=MPI.MAX)

    def max_equivalent_plastic_strain(self) -> float:
        """Largest committed alpha over all zones and ranks."""
        key = ("max_alpha", self.version)
        if key not in self._cache:
            local = max((float(a.max()) for a in self.alpha if a.size), default=0.0)
            self._cache[key] = self.comm.allreduce(local, op=MPI.MAX)
        return self._cache[key]
