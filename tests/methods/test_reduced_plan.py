"""The reduced methods' zone sizing (methods/reduced.py reduced_plan) with a user's fine radius."""
import pytest

from millimpact.methods.reduced import (REDUCED_CANDIDATE_FACTOR, REDUCED_ZONE_FACTOR, boundary_element_size,
                                        reduced_plan)
from millimpact.scene.builtin import builtin_scene
from millimpact.scene.plan import make_plan


def test_the_reduced_zone_reads_a_user_fine_radius():
    """The zone holds the candidates (1.75 a_max) plus one element of the size the mesh has at its
    boundary. The rig at 0.1 m/s needs ~4.8 a_max by default because the size grows from h_contact
    beyond 1.5 a_max. With model.fine_radius = F the mesh is h_contact out to F
    (geometry/builders.py), so the boundary element is h_contact, and the zone is F itself: the
    plan keeps the fine region inside the zone. Before, the sizing ignored F and the plan refused
    the smaller zone's fine radius."""
    rig = builtin_scene("paper-rig").with_value("impact.velocity", [0.0, -0.1, 0.0])
    plan = make_plan(rig)
    a, h_c = plan.hertz.a_max, plan.h_contact
    _, default, _, _ = reduced_plan(rig, plan)
    floor = max(REDUCED_ZONE_FACTOR * a, REDUCED_CANDIDATE_FACTOR * a + 3.0 * h_c)
    fine = 0.5 * (floor + default.zone_radius)          # between the floor and the default zone
    assert boundary_element_size(plan, fine) > h_c                        # the default grows there
    assert boundary_element_size(plan, fine, fine) == pytest.approx(h_c)  # a user's fine radius does not
    _, user, _, _ = reduced_plan(rig.with_value("model.fine_radius", fine), plan)
    assert user.zone_radius == pytest.approx(fine) and user.fine_radius == pytest.approx(fine)
    assert user.zone_radius < default.zone_radius
