"""A plastic contact zone seen through a reduced model u = T q (the reduced methods' plasticity).

Plasticity lives in the contact zone (:mod:`millimpact.fem.plastic_zone`), whose dofs the reduced
model describes by the zone basis alone (u_z = G q_z; the Craig-Bampton columns touch the interior
only). So the zone's force and tangent corrections project exactly:

    f_c,r = T^T f_c(T q) = G^T f_c,     dK_r = T^T dK T = G^T dK G   (sparse, zone coordinates),

evaluated at the quadrature points of the P2 (or P1) space the NMM covers or nodal zone dofs live in:
the covers span a subspace of P2, so the strains there are the model's own. The region stays
linear and modal.
"""
from __future__ import annotations

import numpy as np
from petsc4py import PETSc

from .reduced_model import ReducedModel


class ProjectedPlasticZone:
    """:class:`millimpact.fem.plastic_zone.PlasticZone` in reduced coordinates (the integrator's
    :class:`millimpact.integration.dynamics.NonlinearZone` and the recorder's plastic view)."""

    def __init__(self, zone, red: ReducedModel):
        self.zone, self.red = zone, red
        self._u = red.model.K.createVecRight()

    def _expand(self, q: PETSc.Vec) -> PETSc.Vec:
        return self.red.expand(q, self._u)

    def evaluate(self, q: PETSc.Vec) -> int:
        return self.zone.evaluate(self._expand(q))

    def force_correction(self) -> PETSc.Vec:
        f = self.zone.force_correction()
        r = self.red.restrict(f)
        f.destroy()
        return r

    def frozen_force(self) -> PETSc.Vec:
        f = self.zone.frozen_force()
        r = self.red.restrict(f)
        f.destroy()
        return r

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
        return self.zone.strain_energy_correction(self._expand(q))

    def plastic_strain_near(self, points: np.ndarray) -> np.ndarray:
        return self.zone.plastic_strain_near(points)

    def cell_fields(self):
        return self.zone.cell_fields()

    def max_equivalent_plastic_strain(self) -> float:
        return self.zone.max_equivalent_plastic_strain()
