"""Static Hertz contact: the ball pressed on the block, the FE solver's check against Hertz (1882).

The ball's top cap (the surface within ``CAP_HALF_ANGLE`` of the pole opposite the contact) is
pushed towards the block by a prescribed displacement; the block is supported as in the scene.
The frictionless contact is the same node-to-surface set as the impact solver's
(:mod:`millimpact.fem.contact`), solved exactly:

    K u = f(cap) + B^T lam,   g = g0 + B u >= 0,   lam >= 0,   lam . g = 0,

with the multipliers from the small dense LCP ``q + S lam`` (``S = B K^-1 B^T``, ``q`` the gaps
of the contact-free solution), as in each time step of the impact solver.

Measured, for the full body (symmetric models scaled back):

- ``force``: the contact resultant F = sum(lam) (N);
- ``contact_radius``: from the second moment of the nodal forces about the axis. For the Hertz
  pressure p0 sqrt(1 - r^2/a^2), int r^2 p dA / int p dA = (2/5) a^2 exactly, so
  a = sqrt(5/2 sum(lam r^2) / sum(lam)) uses every node instead of the outermost one (whose radius
  is quantised by the contact element size);
- ``approach``: the travel of the ball's centre less the initial gap (the "distant point" of the
  ball; the block's distant points are clamped), Hertz's delta;
- ``block_indentation``: the block surface's displacement under the contact point, Hertz's share
  delta (1 - nu2^2)/E2 / (1/E*) of the approach for the block treated as a half-space.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import ufl
from dolfinx import fem
from dolfinx.fem import petsc as fem_petsc
from mpi4py import MPI
from petsc4py import PETSc

from ..fem import forms
from ..fem.contact import create_contact
from ..fem.model import create_fe_model
from ..fem.plastic_zone import PlasticZone, ZoneMaterial
from ..fem.plasticity import FlowCurve, J2Material
from ..fem.plasticity import von_mises as von_mises_mandel
from ..fem.probes import create_probe
from ..geometry import builders as G
from ..geometry.mesh import facet_indices
from ..integration.contact_operator import compute_contact_operator
from ..integration.lcp import solve_lcp
from ..integration.solvers import create_effective_solver
from ..scene.plan import Plan
from ..scene.schema import Scene
from ..theory.hertz import effective_modulus

#: the loaded cap: ball surface within this angle (rad) of the pole opposite the contact point
CAP_HALF_ANGLE = np.radians(30.0)


@dataclass
class StaticHertzResult:
    """Static contact of the ball pressed on the block (SI units, full body)."""

    cap_displacement: float
    force: float
    contact_radius: float
    approach: float
    block_indentation: float
    n_active: int
    n_dofs: int
    lcp_iterations: int
    max_von_mises: float = float("nan")  #: largest von Mises stress in the block's zone (quadrature points), Pa
    max_von_mises_depth: float = float("nan")  #: its depth below the struck face, m
    max_von_mises_offset: float = float("nan")  #: its distance from the contact axis, m

    def hertz(self, scene: Scene) -> dict[str, float]:
        """Hertz's contact radius, approach and block indentation at the measured force."""
        R = scene.ball.radius
        e_star = effective_modulus(scene.ball.material, scene.block.material)
        a = (3.0 * self.force * R / (4.0 * e_star)) ** (1.0 / 3.0)
        delta = a * a / R
        mk = scene.block.material
        share = (1.0 - mk.poisson**2) / mk.youngs_modulus * e_star
        return {"contact_radius": a, "approach": delta, "block_indentation": share * delta}


def static_hertz(
    scene: Scene, plan: Plan, md, cap_displacement: float, degree: int | None = None, options: dict | None = None
) -> StaticHertzResult:
    """Press the ball on the block by moving its top cap ``cap_displacement`` (m) towards the block
    and solve the frictionless contact exactly (collective over the mesh's communicator)."""
    model = create_fe_model(md, plan, degree)
    V, comm = model.V, model.comm
    mesh = V.mesh
    fdim = mesh.topology.dim - 1
    x_p, _, z_p = scene.impact_point
    centre = np.array(scene.ball_centre(plan.gap), dtype=float)

    # the top cap: ball-surface facets whose midpoint lies within CAP_HALF_ANGLE of the top pole
    surface = facet_indices(md, G.BALL_SURFACE)
    mid = _facet_midpoints(mesh, surface)
    cosang = (mid[:, 1] - centre[1]) / np.linalg.norm(mid - centre, axis=1)
    cap = surface[cosang > np.cos(CAP_HALF_ANGLE)]
    n_cap = comm.allreduce(len(cap), op=MPI.SUM)
    if n_cap == 0:
        raise RuntimeError("static Hertz: no ball-surface facets in the top cap")
    Vy, _ = V.sub(1).collapse()
    push = fem.Function(Vy)
    push.x.array[:] = -abs(cap_displacement)
    cap_dofs = fem.locate_dofs_topological((V.sub(1), Vy), fdim, cap)
    bcs = list(model.bcs) + [fem.dirichletbc(push, cap_dofs, V.sub(1))]

    u_, v_ = ufl.TrialFunction(V), ufl.TestFunction(V)
    dx = ufl.Measure("dx", domain=mesh)
    a_k = fem.form(forms.elastic_stiffness(u_, v_, model.mu, model.lmbda, dx))
    K = fem_petsc.assemble_matrix(a_k, bcs=bcs, diagonal=1.0)
    K.assemble()
    zero = fem.Constant(mesh, PETSc.ScalarType((0.0, 0.0, 0.0)))
    L = fem.form(ufl.inner(zero, v_) * dx)
    b = fem_petsc.assemble_vector(L)
    fem_petsc.apply_lifting(b, [a_k], bcs=[bcs])
    b.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    fem_petsc.set_bc(b, bcs)

    ksp = create_effective_solver(K, options)
    u0 = K.createVecRight()
    ksp.solve(b, u0)

    contact = create_contact(model, plan)
    op = compute_contact_operator(ksp, contact.B)
    q = contact.g0 + _gather_rows(contact.B, u0)
    lcp = solve_lcp(op.S, q)
    lam_vec = contact.B.createVecLeft()
    r0, r1 = lam_vec.getOwnershipRange()
    lam_vec.array[:] = lcp.lam[r0:r1]
    du = K.createVecRight()
    op.W.mult(lam_vec, du)
    u = u0 + du

    uf = model.function()
    uf.x.array[: len(u.array_r)] = u.array_r
    uf.x.scatter_forward()
    probe = create_probe(V, np.array([centre, [x_p, 0.0, z_p]]), np.concatenate([model.ball_cells, model.block_cells]))
    # the centre lies in the ball, the surface point on the block's face (found in the block cells:
    # the probe takes the best-containing cell, and the ball does not reach y = 0 at that point)
    disp = probe.values(uf.x.array)
    lam = lcp.lam
    r2 = (contact.points[:, 0] - x_p) ** 2 + (contact.points[:, 2] - z_p) ** 2
    F = float(lam.sum())
    a = float(np.sqrt(2.5 * (lam @ r2) / F)) if F > 0 else 0.0
    approach = float(-disp[0, 1] - plan.gap)
    vm, depth, offset = _block_von_mises_peak(model, u, np.array([x_p, 0.0, z_p]))
    result = StaticHertzResult(
        cap_displacement=abs(cap_displacement),
        force=model.sym_factor * F,
        contact_radius=a,
        approach=approach,
        block_indentation=float(-disp[1, 1]),
        n_active=int(np.count_nonzero(lam > 0)),
        n_dofs=model.n_dofs_global,
        lcp_iterations=lcp.iterations,
        max_von_mises=vm,
        max_von_mises_depth=depth,
        max_von_mises_offset=offset,
    )
    for obj in (ksp, K, b, u0, du, u, lam_vec, op.W, contact.B):
        obj.destroy()
    return result


def _block_von_mises_peak(model, u: PETSc.Vec, point: np.ndarray) -> tuple[float, float, float]:
    """The largest von Mises stress (Pa) at the quadrature points of the block's contact zone, its
    depth below the face y = 0 and its distance from the contact axis (m), global over ranks:
    where a Hertz contact first yields (Johnson 6.2: on the axis at 0.48 a, 0.62 p0 for nu = 0.3)."""
    mat = model.target_material
    elastic = J2Material(mat.youngs_modulus, mat.poisson, FlowCurve(1e300))  # never yields: the elastic stress
    zone = PlasticZone(model.V, model.meshdata.cell_tags, [ZoneMaterial(G.BLOCK_ZONE, elastic)])
    zone.evaluate(u)
    best = (-1.0, float("nan"), float("nan"))
    for res, xyz in zip(zone.trial(), zone.quadrature_points()):
        if res is None or not len(xyz):
            continue
        vm = von_mises_mandel(res.stress)
        i = int(np.argmax(vm))
        d = xyz[i] - point
        best = max(best, (float(vm[i]), float(-d[1]), float(np.hypot(d[0], d[2]))))
    every = model.comm.allgather(best)
    return max(every)


def _facet_midpoints(mesh, facets: np.ndarray) -> np.ndarray:
    from dolfinx.mesh import compute_midpoints

    if len(facets) == 0:
        return np.zeros((0, 3))
    return compute_midpoints(mesh, mesh.topology.dim - 1, facets.astype(np.int32))


def _gather_rows(B: PETSc.Mat, u: PETSc.Vec) -> np.ndarray:
    """B u replicated on every rank."""
    g = B.createVecLeft()
    B.mult(u, g)
    out = np.concatenate(B.getComm().tompi4py().allgather(g.array_r.copy()))
    g.destroy()
    return out
