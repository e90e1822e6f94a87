"""A plastic contact zone seen through a reduced model u = T q (the reduced methods' plasticity).

Plasticity lives in the contact zone (:mod:`millimpact.fem.plastic_zone`), whose dofs the reduced
model describes by the zone basis alone (u_z = G q_z; the Craig-Bampton columns touch the interior
only). So the zone's force and tangent corrections project exactly:

    f_c,r = T^T f_c(T q) = G^T f_c,     dK_r = T^T dK T = G^T dK G   (sparse, zone coordinates),

evaluated at the quadrature points of the P2 (or P1) space the NMM covers or nodal zone dofs live in:
the covers span a subspace of P2, so the strains there are the model's own. The region stays
linear and modal. So the zone's displacement is ``G q`` and its force ``G^T f_c`` (``ReducedModel.Gr``)
without the dense Craig-Bampton blocks: on the coarse liner panel the full ``T q`` / ``T^T f``
took 9 s of a 43 s run (a Psi and a Phi product per Newton iteration), and they grow with the region.
"""

from __future__ import annotations

import math

import numpy as np
from petsc4py import PETSc

from .reduced_model import ReducedModel

#: the residual state's solve regularizes the free ball's rigid motions by this shift of
#: (K_r + (2 pi f)^2 M_r): 1 Hz against a lowest elastic mode of kHz (3.2 kHz on the rig's ball)
#: changes the elastic part by (f / f_1)^2 ~ 1e-7 (the rigid part is absorbed by the free modes)
RESIDUAL_SHIFT_HZ = 1.0


class ProjectedPlasticZone:
    """:class:`millimpact.fem.plastic_zone.PlasticZone` in reduced coordinates (the integrator's
    :class:`millimpact.integration.dynamics.NonlinearZone` and the recorder's plastic view)."""

    def __init__(self, zone, red: ReducedModel):
        self.zone, self.red = zone, red
        self._u = None  # the zone's displacement G q (a Vec of the model's dofs)
        self._f = None  # the zone's force correction, assembled in place
        self._frozen: tuple[int, PETSc.Vec] | None = None  # (plastic state version, G^T f_frozen)

    def _expand(self, q: PETSc.Vec) -> PETSc.Vec:
        """u = G q: exact on the zone's dofs (all the zone's cells read); zero in the interior."""
        if self._u is None:
            self._u = self.red.model.K.createVecRight()
        self.red.Gr.mult(q, self._u)
        return self._u

    def _restrict(self, f: PETSc.Vec) -> PETSc.Vec:
        """T^T f = G^T f for a force on the zone's dofs (assembled over zone cells only)."""
        r = self.red.create_vector()
        self.red.Gr.multTranspose(f, r)
        return r

    @property
    def compiled(self) -> bool:
        """Whether the evaluations without the tangent take the compiled pass (the zone's own flag)."""
        return self.zone.compiled

    @compiled.setter
    def compiled(self, value: bool) -> None:
        self.zone.compiled = value

    @property
    def finite(self) -> bool:
        """Whether the zone is the finite-strain one (:mod:`millimpact.fem.finite_zone`)."""
        return self.zone.finite

    @property
    def time_step(self) -> float | None:
        return self.zone.time_step

    @time_step.setter
    def time_step(self, value: float | None) -> None:
        self.zone.time_step = value

    def evaluate(self, q: PETSc.Vec, tangent: bool = True, candidates_only: bool = False) -> int:
        return self.zone.evaluate(self._expand(q), tangent, candidates_only)

    def select_candidates(self, stress_fraction: float) -> int:
        return self.zone.select_candidates(stress_fraction)

    def force_correction(self) -> PETSc.Vec:
        if self._f is None:
            self._f = self.zone.force_correction()
        else:
            self.zone.force_correction(self._f)
        return self._restrict(self._f)

    def frozen_force(self) -> PETSc.Vec:
        """G^T f_frozen of the committed state (a new Vec; the projection is kept per plastic state:
        a step where nothing yields and every energy row read it)."""
        return self._frozen_force().copy()

    def _frozen_force(self) -> PETSc.Vec:
        if self._frozen is None or self._frozen[0] != self.zone.version:
            if self._frozen is not None:
                self._frozen[1].destroy()
            f = self.zone.frozen_force()
            self._frozen = (self.zone.version, self._restrict(f))
            f.destroy()
        return self._frozen[1]

    @property
    def version(self) -> int:
        """Counts the committed plastic states (changes when a step yields)."""
        return self.zone.version

    def residual_state(self) -> PETSc.Vec:
        """The static state q_s that the frozen plastic strain holds when the bodies are apart and
        at rest, K_r q_s = -f_frozen (the residual, unloaded state: its dent and residual stress).

        After separation the motion is the free vibration about q_s: M q'' + K (q - q_s) = 0
        (:mod:`millimpact.methods.free_phase`). The free ball makes K_r singular; f_frozen is
        self-equilibrated (rigid motions do no work on it), so the solve uses
        K_r + (2 pi RESIDUAL_SHIFT_HZ)^2 M_r, which fixes the rigid part near zero (any rigid
        offset is carried by the rigid free modes). Prefix ``residual_``. The factorization is the
        reduced model's, kept (:meth:`ReducedModel.static_solve`): each impact of a
        repeated-impact sequence ends at a new residual state, and a table's cases share it. A
        finite-strain zone's is the linear unloading of its plastic strain, f_frozen taken at u = 0
        (:meth:`millimpact.fem.finite_zone.FiniteStrainZone.unloaded_force`)."""
        if self.zone.finite:
            f = self.zone.unloaded_force()
            b = self._restrict(f)
            f.destroy()
        else:
            b = self.frozen_force()
        b.scale(-1.0)
        q = self.red.static_solve(
            b, (2.0 * math.pi * RESIDUAL_SHIFT_HZ) ** 2, "residual_", "residual state (K_r q_s = -f_frozen)"
        )
        b.destroy()
        return q

    def destroy(self) -> None:
        """Free the kept Vecs (the zone's displacement and force, G^T f_frozen) at a case's end
        (collective). A dropped Vec is parked on its communicator's garbage for the life of the
        process (:meth:`PlasticZone._prune_cache`): ~1.2 MB a case of a plastic table. They are
        made again if the zone is used after."""
        for name in ("_u", "_f"):
            vec = getattr(self, name)
            if vec is not None:
                vec.destroy()
                setattr(self, name, None)
        if self._frozen is not None:
            self._frozen[1].destroy()
            self._frozen = None

    def stiffness_correction(self) -> PETSc.Mat:
        dK = self.zone.stiffness_correction()
        dK_r = dK.PtAP(self.red.Gr)
        dK.destroy()
        return dK_r

    def step_plastic_work(self) -> float:
        return self.zone.step_plastic_work()

    def commit(self) -> None:
        self.zone.commit()

    def strain_energy_correction(self, q: PETSc.Vec) -> float:
        """The zone's (:meth:`PlasticZone.strain_energy_correction`) in reduced coordinates:
        (G q) . f_frozen = q . G^T f_frozen, no expansion of q (4 ms a row on the sequence model);
        a finite-strain zone's is not linear in q: evaluated at G q."""
        if self.zone.finite:
            return self.zone.strain_energy_correction(self._expand(q))
        return q.dot(self._frozen_force()) + self.zone.plastic_energy_constant()

    def plastic_strain_near(self, points: np.ndarray) -> np.ndarray:
        return self.zone.plastic_strain_near(points)

    def cell_fields(self):
        return self.zone.cell_fields()

    def max_equivalent_plastic_strain(self) -> float:
        return self.zone.max_equivalent_plastic_strain()
