"""A model's plastic zone, small or finite strain: the plan's choice made into a zone.

:class:`.plastic_zone.PlasticZone` is small-strain J2 in the contact zones,
:class:`.finite_zone.FiniteStrainZone` its finite-strain (logarithmic strain) sibling; the plan's
``strain`` chooses (:func:`millimpact.scene.plan.choose_strain`).
"""

from __future__ import annotations

from .finite_zone import FiniteStrainZone
from .hardening import tabulated
from .plastic_zone import PlasticZone, ZoneMaterial
from .plasticity import J2Material, flow_curve_from_fields


def create_plastic_zone(model, zone_materials, strain: str = "small") -> PlasticZone | None:
    """The plastic zone of a model: ``zone_materials`` pairs (cell tag of a body's contact zone or
    region, its scene material); bodies whose material is elastic are left out; None if none yields.
    ``strain``: ``small`` (:class:`PlasticZone`) or ``finite`` (:class:`FiniteStrainZone`)."""
    zones = []
    for tag, mat in zone_materials:
        flow = flow_curve_from_fields(mat.initial_yield_stress, mat.hardening_modulus, tabulated(mat))
        if flow is not None:
            jc = mat.johnson_cook_rate
            rate = None if jc is None else (float(jc[0]), float(jc[1]))
            zones.append(ZoneMaterial(tag, J2Material(mat.youngs_modulus, mat.poisson, flow, rate)))
    if not zones:
        return None
    kind = FiniteStrainZone if strain == "finite" else PlasticZone
    return kind(model.V, model.meshdata.cell_tags, zones, model.bcs)
