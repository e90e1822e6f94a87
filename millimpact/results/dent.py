"""The dent a plastic impact leaves, and the notes a plastic run prints.

Residual state: after the impact the plastic strain eps_p is frozen and the bodies unload
elastically; the static residual displacement balances the plastic strain's load,

    K u_res = -f_c = int_zone B^T C eps_p dV     (:meth:`PlasticZone.frozen_force`),

solved once with K regularised by a tiny multiple of M (s = 1e-9 of the ratio of their largest
diagonals): the free ball's rigid motions are otherwise a null space of K; the block's answer
changes by ~1e-9 relative. The dent is read off u_res along the struck face, from the contact
point outwards (along +x, the side every symmetric model keeps): the depth profile
d(r) = w(r) - w(r_far), w the displacement into the body along the contact normal and r_far =
1.5 zone radii (elastic, beyond the dent). ``residual_dent_depth_m`` = d(0); ``residual_dent_radius_m``
the radius where d first falls to 5 % of d(0) (the permanent indentation's edge).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..fem.model import FEModel
from ..fem.probes import create_probe
from ..geometry.builders import BALL_INTERFACE, BALL_REGION, BALL_ZONE, BLOCK_INTERFACE, BLOCK_REGION, BLOCK_ZONE
from ..geometry.mesh import facet_indices
from ..integration import solvers
from ..scene.plan import Plan

#: the dent's edge: where the depth falls to this share of the depth at the contact point
DENT_EDGE_SHARE = 0.05
#: samples of the depth profile from the contact point to 1.5 zone radii
PROFILE_SAMPLES = 61


def residual_displacement(model: FEModel, zone, reduced=None):
    """u_res (m, a PETSc Vec): the static residual state of the frozen plastic strain, K u = -f_p
    (the free ball held by a mass shift 1e-9 x the largest K/M diagonal ratio). ``reduced`` (a
    :class:`~millimpact.reduction.reduced_model.ReducedModel`): solved in its space instead,
    u = T (K_r + s M_r)^-1 T^T (-f_p): the reduced method's own static answer, without factoring
    the whole model (the 1.2M-DOF liner panel's factorization took the run past 23 GB).

    A finite-strain zone's residual state is the linear unloading of its plastic strain, f_p taken
    at u = 0 (``zone.unloaded_force``): first order in the residual elastic strain (~Y/E). Its
    fixed point K u = -f_c(u) is not used: a rigid rotation of the free ball (a half model's)
    turns f_c, whose moment the mass shift barely holds, and the iteration diverges."""
    dk, dm = model.K.getDiagonal(), model.M.getDiagonal()
    s = 1e-9 * dk.max()[1] / max(dm.max()[1], 1e-300)
    if reduced is None:
        A = model.K.copy()
        A.axpy(s, model.M)
        ksp = solvers.create_factored_solver(A, "impact_dent_", solvers.effective_solver_defaults(model.comm))
        owned = [ksp, A]

        def solve(f):
            u = A.createVecRight()
            solvers.solve_checked(ksp, f, u, "residual (dent) solve", 0, 0.0)
            return u
    else:
        owned = []

        def solve(f):
            rhs = reduced.restrict(f)
            x = reduced.static_solve(rhs, s, "impact_dent_", "residual (dent) solve")  # kept with the model
            u = reduced.expand(x)
            x.destroy(), rhs.destroy()
            return u

    f = zone.unloaded_force() if getattr(zone, "finite", False) else zone.frozen_force()
    f.scale(-1.0)
    u = solve(f)
    f.destroy()
    # a dropped handle would park its object on the communicator's garbage (a table's every case)
    for obj in (*owned, dk, dm):
        obj.destroy()
    return u


def dent_profile(model: FEModel, u_res, plan: Plan) -> tuple[np.ndarray, np.ndarray]:
    """(r, d(r)) in m: the residual depth below the undeformed face, from the contact point out."""
    n = np.asarray(plan.contact_normal, dtype=float)
    p = np.asarray(plan.probes.contact_point, dtype=float)  # already just inside the body
    r = np.linspace(0.0, 1.5 * plan.zone_radius, PROFILE_SAMPLES)
    pts = p[None, :] + r[:, None] * np.array([1.0, 0.0, 0.0])[None, :]
    probe = create_probe(model.V, pts, model.block_cells)
    u_fn = model.function("u_res")
    u_fn.vector.array[:] = u_res.array_r
    u_fn.x.scatter_forward()
    w = -(probe.values(u_fn.x.array) @ n)
    ok = probe.found
    return r[ok], (w - w[ok][-1])[ok]


def residual_dent(model: FEModel, zone, plan: Plan, reduced=None) -> dict[str, Any]:
    """Summary keys of the dent: depth (m), radius (m) and the profile (for the figure);
    ``reduced``: see :func:`residual_displacement`."""
    u = residual_displacement(model, zone, reduced)
    keys = dent_of(model, u, plan)
    keys["max_residual_rotation_rad"] = zone.max_rotation(u)
    u.destroy()
    return keys


#: small-strain J2 (the model's) stops being a good approximation past this equivalent plastic
#: strain (foundations.md section 10): beyond it the change of geometry under the ball and the difference
#: between stress measures reach several percent
SMALL_STRAIN_LIMIT = 0.1


def small_strain_note(
    max_plastic_strain: float, max_rotation: float, where: str = "of the residual state", finite: bool = False
) -> str:
    """One note line: the kinematics the run used, the largest equivalent plastic strain and
    rotation (rad), and (small strain) whether the model holds (a warning past SMALL_STRAIN_LIMIT)."""
    text = f"{'finite' if finite else 'small'} strain: largest equivalent plastic strain {max_plastic_strain:.3g}"
    if math.isfinite(max_rotation):  # not known when no impact state was kept at the peak force
        text += f", largest rotation {where} {max_rotation:.3g} rad"
    if finite:
        return text + " (logarithmic-strain J2: no small-strain limit)"
    if max_plastic_strain > SMALL_STRAIN_LIMIT:
        return (
            text + f"; WARNING: past {SMALL_STRAIN_LIMIT:g}, where the small-strain J2 model stops being a good "
            "approximation (no change of geometry under the ball, no finite-strain stress measure): the dent, "
            "plastic work and restitution are estimates there, a finite-strain model is needed to trust them"
        )
    return text + f"; within the small-strain model's range (plastic strain < {SMALL_STRAIN_LIMIT:g})"


def dent_of(model: FEModel, u_res, plan: Plan) -> dict[str, Any]:
    """Summary keys of the dent of a residual displacement ``u_res`` (a model vector, m): depth,
    radius (m) and the profile (module docstring)."""
    r, d = dent_profile(model, u_res, plan)
    depth = float(d[0]) if len(d) else 0.0
    radius = 0.0
    if depth > 0:
        below = np.nonzero(d <= DENT_EDGE_SHARE * depth)[0]
        if len(below):
            j = int(below[0])
            radius = float(np.interp(DENT_EDGE_SHARE * depth, [d[j], d[j - 1]], [r[j], r[j - 1]])) if j else 0.0
        else:
            radius = float(r[-1])
    return {
        "residual_dent_depth_m": depth,
        "residual_dent_radius_m": radius,
        "residual_dent_profile": {"r_m": r.tolist(), "depth_m": d.tolist()},
    }


def plastic_section(zone, plan: Plan, h_contact: float) -> dict[str, Any]:
    """The equivalent plastic strain on the section through the contact axis (the plane x = x_p,
    which holds the contact normal of the block and of every liner face, and is the symmetry
    plane of a half model): the zone's quadrature points within h_contact / 2 of it, gathered on
    rank 0 (``s_m``, ``depth_m``, ``alpha``; :meth:`PlasticZone.section`), for
    :func:`millimpact.results.plots.plot_plastic_section`."""
    s, d, alpha = zone.section(plan.impact_point, plan.contact_normal, (1.0, 0.0, 0.0), 0.5 * h_contact)
    if "z" in plan.symmetry_planes:  # a quarter model keeps z >= z_p: mirror the other half in
        s, d, alpha = np.concatenate([s, -s]), np.concatenate([d, d]), np.concatenate([alpha, alpha])
    return {
        "s_m": s,
        "depth_m": d,
        "alpha": alpha,
        "a_max_m": plan.hertz.a_max,
        "zone_radius_m": plan.zone_radius,
        "predicted_radius_m": plan.plastic_radius,
    }


#: plastic strain below this at the zone boundary counts as elastic there (round-off of the return map)
BOUNDARY_ALPHA_TOL = 1e-6


def zone_boundary_note(model: FEModel, zone, plan: Plan) -> tuple[dict[str, Any], list[str]]:
    """Whether the zone's boundary stayed elastic: summary keys and, if not, a warning note naming
    a zone radius to use (1.5x the plan's)."""
    tags = {z.cell_tag for z in zone.zones}
    # plastic in every cell: the region's cells are plastic (full), or none is left (the reduced
    # methods put a whole plastic body's region into its zone)
    values = model.meshdata.cell_tags.values
    left = {r: model.comm.allreduce(int(np.count_nonzero(values == r))) for r in (BALL_REGION, BLOCK_REGION)}
    whole = {
        "ball": BALL_REGION in tags or not left[BALL_REGION],
        "struck": BLOCK_REGION in tags or not left[BLOCK_REGION],
    }
    interfaces = [tag for tag, body in ((BALL_INTERFACE, "ball"), (BLOCK_INTERFACE, "struck")) if not whole[body]]
    alpha = zone.boundary_plastic_strain(facet_indices(model.meshdata, tuple(interfaces)))
    extents = zone.plastic_extent(plan.impact_point, BOUNDARY_ALPHA_TOL)
    ball_r = max(extents.get(BALL_ZONE, 0.0), extents.get(BALL_REGION, 0.0))
    target_r = max(extents.get(BLOCK_ZONE, 0.0), extents.get(BLOCK_REGION, 0.0))
    a = plan.hertz.a_max
    keys = {
        "zone_boundary_max_equivalent_plastic_strain": alpha,
        "zone_boundary_elastic": alpha <= BOUNDARY_ALPHA_TOL,
        "plastic_zone_radius_m": {
            "ball": ball_r,
            "struck_body": target_r,
            "predicted": plan.plastic_radius,
            "contact_zone": plan.zone_radius,
        },
    }
    extent = (
        f"plastic region: {target_r * 1e3:.3g} mm ({target_r / a:.3g} a_max) from the impact point in the struck "
        f"body, {ball_r * 1e3:.3g} mm in the ball; predicted {plan.plastic_radius * 1e3:.3g} mm "
        f"(Johnson's cavity model on Thornton's contact radius)"
    )
    keys["plastic_whole"] = [body for body, w in whole.items() if w]
    notes = [extent] + [
        f"the whole {'ball' if body == 'ball' else 'struck body'} is plastic: its predicted plastic region does not "
        "fit the contact zone (the plan's plastic_whole)"
        for body in keys["plastic_whole"]
    ]
    notes += [
        f"WARNING: the {'ball' if body == 'ball' else 'struck body'}'s predicted plastic region does not fit the "
        "contact zone, and this run keeps plasticity in the zone"
        for body in plan.plastic_whole
        if not whole[body]
    ]
    if alpha <= BOUNDARY_ALPHA_TOL:
        zoned = [body for body, w in whole.items() if not w]
        where = (
            "the contact zone"
            if len(zoned) == 2
            else f"the {'ball' if zoned[0] == 'ball' else 'struck body'}'s contact zone"
            if zoned
            else ""
        )
        return keys, notes + [
            f"plasticity stayed inside {where} (radius {plan.zone_radius * 1e3:.4g} mm): its boundary is elastic"
            if zoned
            else "no zone boundary truncates the plastic region"
        ]
    return keys, notes + [
        f"WARNING: plastic strain {alpha:.3g} at the contact zone's boundary (radius "
        f"{plan.zone_radius * 1e3:.4g} mm), where the model is linear: rerun with "
        f"--set model.zone_radius={1.5 * plan.zone_radius:.4g}",
    ]


def plastic_notes(zone, stats, sym_factor: float) -> str:
    """One note line: plastic work, the largest plastic strain, Newton's effort."""
    return (
        f"plasticity: plastic work {sym_factor * stats.plastic_work_J:.4g} J, max equivalent plastic strain "
        f"{zone.max_equivalent_plastic_strain():.3g}; {stats.n_plastic_steps} yielding steps, Newton "
        f"{stats.n_plastic_iterations} iterations (max {stats.max_plastic_iterations} a step), "
        f"{stats.n_tangent_factorizations} tangent factorizations"
    )


def plastic_report(model: FEModel, zone, plan: Plan, stats, reduced=None) -> tuple[dict[str, Any], list[str], Any]:
    """What a plastic run adds to its output: summary keys (the dent, the zone check, the plastic
    radii), note lines, and a writer of ``plastic_zone.png`` (rank 0; the section is gathered
    here, collectively). ``reduced``: the reduced model of a reduced method (the dent's static
    solve in its space)."""
    from .plots import plot_plastic_section

    notes = [plastic_notes(zone, stats, model.sym_factor)]
    keys = residual_dent(model, zone, plan, reduced)
    keys["max_equivalent_plastic_strain_final"] = zone.max_equivalent_plastic_strain()
    keys["strain"] = "finite" if getattr(zone, "finite", False) else "small"
    notes.append(
        small_strain_note(
            keys["max_equivalent_plastic_strain_final"],
            keys["max_residual_rotation_rad"],
            finite=keys["strain"] == "finite",
        )
    )
    more_keys, more = zone_boundary_note(model, zone, plan)
    keys.update(more_keys)
    section = plastic_section(zone, plan, plan.h_contact)
    rank = model.V.mesh.comm.rank

    def write(folder) -> None:
        if rank == 0:
            plot_plastic_section(section, folder / "plastic_zone.png")

    return keys, notes + more, write
