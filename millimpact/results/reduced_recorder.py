"""The recorder of a reduced model: the full method's rows from reduced maps.

A reduced run (:mod:`millimpact.methods.reduced`) integrates the coordinates q of a Galerkin
projection u = T q (:class:`millimpact.reduction.reduced_model.ReducedModel`) and, between
impacts, the modal coordinates eta of its free vibration, u = T Phi eta
(:class:`millimpact.reduction.free_modes.ModalProjection`). :class:`ReducedRecorder` gives the
same time-series columns as :class:`millimpact.results.recorder.Recorder` from rows precomputed
once per projection (probe rows P T, the ball's centre-of-mass row T^T c), energies as
``q . M_r q / 2`` and ``q . K_r q / 2``; u = T q is expanded only for the XDMF fields. Probe
displacements and gradients in the non-contact region (the gauges) are recovered by mode
acceleration (``recovery``: mode-acceleration, the default, or modal: u = T q alone):
``P T q + C q''`` with the rows C of :meth:`ReducedModel.mode_acceleration_rows`.
:meth:`ReducedRecorder.record_free` records a closed-form free phase's thousands of rows at once.

Takes the reduced model, the full model's contact set and the plan's probe spec; gives rows.
"""

from __future__ import annotations

import dataclasses
import math
from types import SimpleNamespace

import numpy as np
import scipy.sparse as sp
from mpi4py import MPI
from petsc4py import PETSc

from ..fem.contact import ContactSet
from ..fem.probes import PointProbe
from ..reduction.distributed import gather_aij_dense, local_rows_to_aij
from ..reduction.free_modes import ModalProjection
from ..reduction.reduced_model import ReducedModel
from ..scene.plan import ProbeSpec
from .recorder import Recorder


def project_probe(probe: PointProbe, red: ReducedModel) -> PointProbe:
    """The probe's rows P T, restricted on each rank to its owned reduced columns (so that
    ``values(q_owned)`` sums the ranks' parts exactly as :class:`PointProbe` does)."""
    q0, q1 = red.M.getOwnershipRange()
    mats = []
    for P in (probe.P_val, probe.P_grad):
        PT = red.project_rows(local_rows_to_aij(P, red.model.V))
        r0, r1 = PT.getOwnershipRange()
        indptr, indices, data = PT.getValuesCSR()
        local = sp.csr_matrix((data, indices, indptr), shape=(r1 - r0, red.n_global))
        full = sp.vstack(red.comm.allgather(local)).tocsc()
        mats.append(full[:, q0:q1].tocsr())
    return PointProbe(probe.comm, probe.n_points, mats[0], mats[1], probe.found)


@dataclasses.dataclass
class ProjectedModel:
    """A projection's operators in the place of the full model's for the rows' energies: reduced
    (or modal) mass M and stiffness K; no fixed coordinates (T is zero on clamped dofs)."""

    M: PETSc.Mat
    K: PETSc.Mat
    fixed_dofs: np.ndarray
    sym_factor: float


class ReducedRecorder(Recorder):
    """The full method's :class:`Recorder` on a reduced model: same rows, from reduced maps.

    Replaces the recorder's full-space maps by their images under the current projection (a
    :class:`ReducedModel` ``u = T q`` or a :class:`ModalProjection` ``u = T Phi eta``, switched
    with :meth:`set_projection`): the ball's centre-of-mass row ``c`` by ``T^T c``, the probes
    by ``P T``, the ball mask by the ball's coordinates, the energies' M and K by the projected
    ones (no fixed coordinates: T is zero on clamped dofs). ``time_offset`` (s) is added to the
    states' times (restarted integrations). XDMF states are expanded to model vectors at once.
    """

    def __init__(
        self,
        red: ReducedModel,
        contact: ContactSet,
        probes: ProbeSpec,
        field_times: tuple[float, ...],
        recovery: str = "mode-acceleration",
        plastic=None,
    ):
        super().__init__(red.model, contact, probes, field_times, plastic)
        self._c_full = self.c_y
        self._probe_full = self.probe
        # mode-acceleration rows of the probes (ReducedModel.mode_acceleration_rows): displacement
        # values and gradients get C q'' added; replicated dense (rows x reduced coordinates)
        self._ma = self._md = None
        if recovery == "mode-acceleration":
            P_val = self._probe_full.P_val
            rows = local_rows_to_aij(sp.vstack([P_val, self._probe_full.P_grad]).tocsr(), red.model.V)
            C = red.mode_acceleration_rows(rows)
            self._ma = (C[: P_val.shape[0]], C[P_val.shape[0] :])
            # bodies reduced with zone-interface patterns: a displacement part too (added to P T)
            D = red.displacement_recovery_rows(rows)
            if D is not None:
                self._md = (D[: P_val.shape[0]], D[P_val.shape[0] :])
        self.time_offset = 0.0
        self.proj: ReducedModel | ModalProjection = red
        # per projection (its id): (T^T c, ball mask, two work vectors, probe P T, energy view)
        self._maps: dict[int, tuple[PETSc.Vec, PETSc.Vec, PETSc.Vec, PETSc.Vec, PointProbe, ProjectedModel]] = {}
        self._ma_maps: dict[int, PointProbe | None] = {}  # per projection: mode-acceleration rows
        self._dense: dict[int, SimpleNamespace] = {}  # per modal projection: _dense_maps()
        self._offsets: dict[tuple[int, int], SimpleNamespace] = {}  # per plastic state: _offset_terms()
        self._ct_full = getattr(self, "c_t", None)  # friction: the ball's tangential row
        self._ct_maps: dict[int, object] = {}
        self._patch_full = self.c_patch  # the contact point's patch row
        self._patch_maps: dict[int, object] = {}
        self.set_projection(red)

    def set_projection(self, proj) -> None:
        """Observe states of ``proj`` (a ReducedModel or a ModalProjection) from now on."""
        self.proj = proj
        key = id(proj)
        if key not in self._maps:
            mask = proj.create_vector()
            mask.array[proj.ball_coords] = 1.0
            view = ProjectedModel(
                M=proj.M, K=proj.K, fixed_dofs=np.zeros(0, dtype=np.int32), sym_factor=proj.model.sym_factor
            )
            probe = project_probe(self._probe_full, proj)
            if self._md is not None:
                d = self._rows_probe(self._md, proj)
                probe = PointProbe(
                    probe.comm, probe.n_points, probe.P_val + d.P_val, probe.P_grad + d.P_grad, probe.found
                )
            self._maps[key] = (
                proj.restrict(self._c_full),
                mask,
                proj.create_vector(),
                proj.create_vector(),
                probe,
                view,
            )
            self._ma_maps[key] = self._ma_probe(proj)
        self.c_y, self.ball_mask, self.tmp, self.tmp2, self.probe, self.model = self._maps[key]
        self.ma_probe = self._ma_maps[key]
        if self._ct_full is not None:
            if key not in self._ct_maps:
                self._ct_maps[key] = proj.restrict(self._ct_full)
            self.c_t = self._ct_maps[key]
        if self._patch_full is not None:
            if key not in self._patch_maps:
                self._patch_maps[key] = proj.restrict(self._patch_full)
            self.c_patch = self._patch_maps[key]

    def _local(self, vec) -> np.ndarray:
        return vec.array_r

    def _ma_probe(self, proj) -> PointProbe | None:
        """The mode-acceleration rows for states of ``proj`` as a probe acting on accelerations
        (owned columns of proj's coordinates): C for the reduced model, C Phi for a modal one."""
        return None if self._ma is None else self._rows_probe(self._ma, proj, quasi_static=True)

    def _rows_probe(self, rows: tuple[np.ndarray, np.ndarray], proj, quasi_static: bool = False) -> PointProbe:
        """Replicated dense recovery rows (values, gradients; k x reduced coordinates) as a probe on
        ``proj``'s coordinates (owned columns): C itself for the reduced model, C Phi for a modal
        one; ``quasi_static``: a modal one's columns above the lowest mode not kept dropped."""
        comm = proj.comm
        mats = []
        for C in rows:
            if isinstance(proj, ModalProjection):
                r0, r1 = proj.red.M.getOwnershipRange()
                C = comm.allreduce(C[:, r0:r1] @ proj.Phi.getDenseArray(), op=MPI.SUM)
                # quasi-static only below the lowest fixed-interface mode not kept: a free mode
                # above it drives the truncated modes near or past resonance
                nxt = [
                    b.next_frequency_hz for b in proj.red.bodies if b.n_interior and np.isfinite(b.next_frequency_hz)
                ]
                if nxt and quasi_static:
                    C = C * (np.sqrt(proj.omega2) < 2 * math.pi * min(nxt))[None, :]
            lo, hi = proj.M.getOwnershipRange()
            mats.append(sp.csr_matrix(C[:, lo:hi]))
        return PointProbe(comm, self._probe_full.n_points, mats[0], mats[1], self._probe_full.found)

    def _displacement_probe(self, st) -> tuple[np.ndarray, np.ndarray]:
        vals, grads = super()._displacement_probe(st)
        if self.ma_probe is not None:
            a = st.a.array_r
            vals = vals + self.ma_probe.values(a)
            grads = grads + self.ma_probe.gradients(a)
        return vals, grads

    def _dense_maps(self, modal: ModalProjection) -> SimpleNamespace:
        """Replicated dense maps of a modal projection (m modal coordinates, a few dozen): the
        ball's rows c and c_t, the probe rows (values, gradients), the scheme's mass, K_r and the
        ball mask, all m-column; built once per projection."""
        key = id(modal)
        if key not in self._dense:
            comm = modal.comm

            def vec(v) -> np.ndarray:
                return np.concatenate(comm.allgather(v.array_r.copy()))

            c_y, mask, _, _, probe, _ = self._maps[id(modal)]
            ma = self._ma_maps[id(modal)]
            cols = lambda P: sp.hstack(comm.allgather(P)).toarray()  # noqa: E731 (local columns)
            self._dense[key] = SimpleNamespace(
                c=vec(c_y),
                ct=vec(self._ct_maps[id(modal)]) if self._ct_full is not None else None,
                cp=vec(self._patch_maps[id(modal)]) if self._patch_full is not None else None,
                mask=vec(mask),
                Pv=cols(probe.P_val),
                Pg=cols(probe.P_grad),
                n_points=probe.n_points,
                Cv=cols(ma.P_val) if ma is not None else None,
                Cg=cols(ma.P_grad) if ma is not None else None,
                M=gather_aij_dense(modal.M_scheme, comm),
                K=gather_aij_dense(modal.K, comm),
            )
        return self._dense[key]

    def _offset_terms(self, red, offset) -> SimpleNamespace:
        """What the residual state q_s of a plastic run (``offset``: :func:`millimpact.methods.
        free_phase.residual_offset`) adds to every free-phase row: the ball's displacement row
        c.q_s, the probes' values and gradients (a static state: no mode-acceleration term), its
        elastic strain energy 1/2 q_s.K_r.q_s + the plastic correction (the motion about q_s adds
        1/2 eta.Lambda.eta: the cross term is eta.Phi^T (K_r q_s + f_frozen) = 0), and the model
        vector T q_s for the fields; cached per plastic state."""
        key = (offset.version, id(offset.q))
        if key not in self._offsets:
            c_y, _, _, _, probe, _ = self._maps[id(red)]
            arr = offset.q.array_r
            Kq = red.K.createVecLeft()
            red.K.mult(offset.q, Kq)
            se = 0.5 * Kq.dot(offset.q) + self.plastic.strain_energy_correction(offset.q)
            Kq.destroy()
            self._offsets[key] = SimpleNamespace(
                c=c_y.dot(offset.q), vals=probe.values(arr), grads=probe.gradients(arr), se=se, u=red.expand(offset.q)
            )
        return self._offsets[key]

    def record_free(
        self,
        modal: ModalProjection,
        times: np.ndarray,
        eta: np.ndarray,
        etad: np.ndarray,
        etadd: np.ndarray,
        offset=None,
    ) -> None:
        """Rows of a closed-form free phase at ``times`` from the replicated modal states (m x n_t),
        all at once: the rows :meth:`__call__` would give for each (no contact force, zero
        multipliers; the same formulas on m-column maps), plus the XDMF fields at their times.
        With a plastic run's residual state ``offset`` the modal states are the motion about it
        (:meth:`_offset_terms`); the plastic work and strain stay at their values (frozen)."""
        off = self._offset_terms(modal.red, offset) if offset is not None else None
        self.set_projection(modal)
        d = self._dense_maps(modal)
        n_t = len(times)
        approach = -(d.c @ eta) - self.gap0
        vball = -(d.c @ etad)
        np_ = d.n_points
        u_v, u_g = d.Pv @ eta, d.Pg @ eta
        if d.Cv is not None:  # mode-acceleration recovery
            u_v, u_g = u_v + d.Cv @ etadd, u_g + d.Cg @ etadd
        vals_u, vals_v, vals_a = (np.moveaxis(x.reshape(np_, 3, n_t), -1, 0) for x in (u_v, d.Pv @ etad, d.Pv @ etadd))
        grads = np.moveaxis(u_g.reshape(np_, 3, 3, n_t), -1, 0)  # (n_t, points, 3, 3)
        ke = 0.5 * np.einsum("it,it->t", etad, d.M @ etad)
        vb = d.mask[:, None] * etad
        ke_ball = 0.5 * np.einsum("it,it->t", vb, d.M @ vb)
        se = 0.5 * np.einsum("it,it->t", eta, d.K @ eta)
        if off is not None:
            approach = approach - off.c
            vals_u = vals_u + off.vals[None]
            grads = grads + off.grads[None]
            se = se + off.se
        zero = np.zeros(n_t)
        patch = (d.cp @ etad, d.cp @ etadd) if d.cp is not None else None
        cols = [
            times,
            zero,
            approach,
            zero,
            vball,
            *self.probe_columns(vals_u, vals_v, vals_a, grads, patch),
            self.sym * ke_ball,
            self.sym * ke,
            self.sym * se,
            self.sym * (ke + se),
        ]
        if self.friction:
            # no friction while apart: the cumulative work stays at its value (see __call__)
            self._fw_base += self._fw_last
            self._fw_last = 0.0
            cols += [zero, d.ct @ etad, np.full(n_t, self.sym * self._fw_base)]
        if self.plastic is not None:
            # the plastic strain is frozen while apart: the work and the strain keep their values
            self._pw_base += self._pw_last
            self._pw_last = 0.0
            cols += [np.full(n_t, self.sym * self._pw_base), np.full(n_t, self.plastic.max_equivalent_plastic_strain())]
        self.rows.extend(np.column_stack(cols).tolist())
        lo, hi = modal.Phi.getOwnershipRangeColumn()
        while self._next_field < len(self.field_times):
            k = int(np.searchsorted(times, self.field_times[self._next_field] - 1e-15))
            if k >= n_t:
                break
            x = modal.create_vector()
            x.array[:] = eta[lo:hi, k]
            u = modal.expand(x)
            if off is not None:
                u.axpy(1.0, off.u)
            self.fields.append((float(times[k]), u.array_r.copy()))
            if self.plastic is not None:
                self.plastic_fields.append(self.plastic.cell_fields())
            u.destroy()
            x.destroy()
            self._next_field += 1

    def __call__(self, st) -> None:
        if self.time_offset:
            st = dataclasses.replace(st, t=st.t + self.time_offset)
        n = len(self.fields)
        super().__call__(st)
        for i in range(n, len(self.fields)):
            t, arr = self.fields[i]
            x = self.proj.create_vector()
            x.array[:] = arr
            u = self.proj.expand(x)
            self.fields[i] = (t, u.array_r.copy())
            u.destroy()
            x.destroy()
