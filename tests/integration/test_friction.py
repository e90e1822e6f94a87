"""Coulomb friction (millimpact.integration.friction, integrators with tangential rows) against analytical cases.

1. The dense Tresca/Coulomb problem of one step satisfies its KKT conditions and equals an
   independent convex solver (projected gradient) on random SPD compliances.
2. An elastic block (nu = 0, pre-compressed by its weight N on a rigid floor) pushed by a uniform
   tangential force F_t: with F_t = 0.3 mu N it sticks (no node slides, the centre of mass only
   rocks elastically); with F_t = 2 mu N it slides, and Coulomb's law fixes its momentum exactly:
   P_x(t) = F_t t - mu (N t + P_z(t)) (every node slides in +x: sum tau_x = -mu sum lambda), so the
   velocity approaches (F_t - mu N) t / m.
3. mu = 0 through the friction path (tangential rows present) reproduces the frictionless run.
4. Maw-Barber-Fawcett regimes of an oblique sphere impact (the liner scene's ball on a lifter face,
   coarse mesh): for a large tangential/normal ratio (tan(alpha) / mu >> 7, rigid-body sliding
   bound 7/2 (1 + e)) the ball slides throughout and the tangential impulse equals mu times the
   normal impulse; for a small ratio it sticks and the tangential force reverses during the impact
   (|J_t| < mu J_n), as MBF (1976) found.
"""
from __future__ import annotations

import numpy as np
import pytest
import ufl
from dolfinx import fem, mesh
from dolfinx.fem import petsc as fem_petsc
from mpi4py import MPI
from petsc4py import PETSc

from millimpact.fem import forms
from millimpact.integration.friction import _tresca_fista, solve_friction, solve_tresca
from millimpact.integration.integrators import LinearDynamics, TimeSchedule, integrate

MU = 0.3
SIDE = 0.05            # cube side, m
RHO, E = 7800.0, 200e9


# ------------------------------------------------------------------------------ the dense problem
def test_tresca_kkt_and_independent_solver():
    rng = np.random.default_rng(1)
    for n in (5, 16):
        X = rng.normal(size=(2 * n, 2 * n))
        S = X @ X.T / (2 * n) + 0.2 * np.eye(2 * n)
        c = rng.normal(size=2 * n)
        b = np.abs(rng.normal(size=n)) * 0.6
        tau, slip, ok = solve_tresca(S, c, b)
        assert ok
        ds = c + S @ tau
        T, D = np.stack([tau[:n], tau[n:]], 1), np.stack([ds[:n], ds[n:]], 1)
        # KKT to round-off: sticking nodes do not slip, sliding ones carry mu lambda against the slip
        assert np.abs(D[~slip]).max(initial=0.0) < 1e-12 * np.abs(c).max()
        assert np.allclose(np.linalg.norm(T[slip], axis=1), b[slip], rtol=1e-10)
        cosines = -np.sum(T[slip] * D[slip], 1) / (np.linalg.norm(T[slip], axis=1) * np.linalg.norm(D[slip], axis=1))
        assert np.all(cosines > 1 - 1e-10)
        assert np.all(np.linalg.norm(T[~slip], axis=1) <= b[~slip] * (1 + 1e-10))
        # the same minimiser from the (independent) projected gradient, to its tolerance
        perm = np.ravel(np.column_stack([np.arange(n), n + np.arange(n)]))
        xf = _tresca_fista(S[np.ix_(perm, perm)], c[perm], b, np.zeros(2 * n), np.ones(2 * n, bool), 50000)
        tf = np.zeros(2 * n)
        tf[perm] = xf
        assert np.abs(tf - tau).max() < 1e-6 * b.max()


def test_warm_start_gives_the_same_forces():
    """Starting the normal/tangential alternation and the Tresca Newton from other forces (the last
    step's, as the integrator does) changes the iterations, not the answer: random compliances with
    a weak normal-tangential coupling (as for like materials), one solution each. Tolerance: the
    fixed point stops at 1e-8 of the largest lambda; measured differences ~1e-10."""
    rng = np.random.default_rng(7)
    checked = 0
    for n in (4, 12, 30):
        X = rng.normal(size=(3 * n, 3 * n))
        S = X @ X.T / (3 * n) + 0.5 * np.eye(3 * n)
        S[:n, n:] *= 0.05
        S[n:, :n] *= 0.05
        q_n = rng.normal(size=n) * 0.5
        q_t = rng.normal(size=2 * n)
        cold = solve_friction(S, q_n, q_t, MU)
        for tau0 in (cold.tau * 1.3 + 0.1, rng.normal(size=2 * n) * 5.0, np.zeros(2 * n)):
            warm = solve_friction(S, q_n, q_t, MU, tau0=tau0)
            scale = np.abs(cold.lam).max()
            assert np.abs(warm.lam - cold.lam).max() <= 1e-7 * scale
            assert np.abs(warm.tau - cold.tau).max() <= 1e-7 * scale
            checked += 1
        assert (cold.slip.any() and (cold.lam > 0).any()) or n < 12   # friction really acts
    assert checked == 9


def test_mu_zero_is_the_lcp():
    rng = np.random.default_rng(2)
    n = 12
    X = rng.normal(size=(3 * n, 3 * n))
    S = X @ X.T / (3 * n) + 0.5 * np.eye(3 * n)
    q = rng.normal(size=n)
    from millimpact.integration.lcp import solve_lcp

    res = solve_friction(S, q, rng.normal(size=2 * n), 0.0)
    assert np.array_equal(res.tau, np.zeros(2 * n))
    assert np.allclose(res.lam, solve_lcp(S[:n, :n], q).lam, rtol=0, atol=1e-14 * np.abs(res.lam).max())


# ------------------------------------------------------------------------------ block on a floor
def _block(comm, n_el: int = 3):
    """The cube [0, SIDE]^3 (nu = 0), floor z = 0 under its bottom nodes: M, K, B (u_z rows), T (u_x, u_y rows)."""
    msh = mesh.create_box(comm, [np.zeros(3), np.full(3, SIDE)], [n_el] * 3, mesh.CellType.tetrahedron)
    V = fem.VectorFunctionSpace(msh, ("Lagrange", 1))
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    mu_l, lam_l = E / 2.0, 0.0          # nu = 0: no lateral expansion under the weight
    K = fem_petsc.assemble_matrix(fem.form(forms.elastic_stiffness(u, v, fem.Constant(msh, mu_l),
                                                                   fem.Constant(msh, lam_l), ufl.dx)))
    K.assemble()
    M = fem_petsc.assemble_matrix(fem.form(forms.mass(u, v, fem.Constant(msh, RHO), ufl.dx)))
    M.assemble()
    bottom = fem.locate_dofs_geometrical(V, lambda x: np.isclose(x[2], 0.0))
    imap = V.dofmap.index_map
    bottom = bottom[bottom < imap.size_local]
    gl = imap.local_to_global(bottom.astype(np.int32))
    counts = comm.allgather(len(gl))
    off = sum(counts[:comm.rank])
    n_c = sum(counts)
    n_loc, n = imap.size_local * 3, imap.size_global * 3

    def rows(nr):
        A = PETSc.Mat().createAIJ(((PETSc.DECIDE, nr), (n_loc, n)), comm=comm)
        A.setPreallocationNNZ((3, 3))
        return A
    B, T = rows(n_c), rows(2 * n_c)
    for i, g in enumerate(gl):
        B.setValue(off + i, int(g) * 3 + 2, 1.0)
        T.setValue(off + i, int(g) * 3 + 0, 1.0)
        T.setValue(n_c + off + i, int(g) * 3 + 1, 1.0)
    B.assemble()
    T.assemble()
    contact_dofs = np.sort((bottom[:, None] * 3 + np.arange(3)).ravel()).astype(np.int32)
    return V, M, K, B, T, n_c, contact_dofs


def _force(V, fx: float, fz: float) -> PETSc.Vec:
    """Uniform body force with resultant (fx, 0, fz) N on the cube."""
    v = ufl.TestFunction(V)
    vol = SIDE**3
    b = fem.Constant(V.mesh, np.array([fx / vol, 0.0, fz / vol]))
    f = fem_petsc.assemble_vector(fem.form(ufl.inner(b, v) * ufl.dx))
    f.ghostUpdate(addv=PETSc.InsertMode.ADD, mode=PETSc.ScatterMode.REVERSE)
    return f


def _static_precompression(V, K, B, f):
    """u0: the static state under the weight with the bottom nodes held (u = 0 there). With nu = 0
    the held nodes need no tangential reaction, so it is the frictionless equilibrium too."""
    bottom = fem.locate_dofs_geometrical(V, lambda x: np.isclose(x[2], 0.0))
    bc = fem.dirichletbc(np.zeros(3, dtype=PETSc.ScalarType), bottom, V)
    u, v = ufl.TrialFunction(V), ufl.TestFunction(V)
    Kb = fem_petsc.assemble_matrix(fem.form(forms.elastic_stiffness(u, v, fem.Constant(V.mesh, E / 2.0),
                                                                    fem.Constant(V.mesh, 0.0), ufl.dx)), bcs=[bc])
    Kb.assemble()
    rhs = f.copy()
    fem_petsc.set_bc(rhs, [bc])
    ksp = PETSc.KSP().create(V.mesh.comm)
    ksp.setOperators(Kb)
    ksp.setType("preonly")
    ksp.getPC().setType("lu")
    ksp.getPC().setFactorSolverType("mumps")
    u0 = rhs.duplicate()
    ksp.solve(rhs, u0)
    return u0


def _push(ft_over_mu_n: float, mu: float, with_rows: bool = True, t_end: float = 2e-4):
    comm = MPI.COMM_WORLD
    V, M, K, B, T, n_c, cdofs = _block(comm)
    m = RHO * SIDE**3
    N = m * 2000.0                       # a 200 g weight: 4 kN on the 2.5 cm^2 floor of the cube
    u0 = _static_precompression(V, K, B, _force(V, 0.0, -N))
    f = _force(V, ft_over_mu_n * mu * N, -N)
    system = LinearDynamics(M=M, K=K, B=B, g0=np.zeros(n_c), fixed_dofs=np.zeros(0, np.int32),
                            contact_dofs=cdofs, f_ext=f, T=T if with_rows else None, friction=mu)
    v0 = u0.duplicate()
    v0.set(0.0)
    rows = []
    ex = M.createVecRight()
    ez = M.createVecRight()

    def observe(st):
        r0 = ex.getOwnershipRange()[0]
        comp = (np.arange(ex.getLocalSize()) + r0) % 3
        ex.array[:] = comp == 0
        ez.array[:] = comp == 2
        Mv = st.mass.createVecLeft()
        st.mass.mult(st.v, Mv)
        Mu = st.mass.createVecLeft()
        M.mult(st.u, Mu)
        tau = np.zeros(2 * n_c) if st.tau is None else st.tau
        rows.append((st.t, Mv.dot(ex), Mv.dot(ez), Mu.dot(ex) / m, float(np.sum(st.lam)),
                     float(np.sum(tau[:n_c])), float(np.sum(np.hypot(tau[:n_c], tau[n_c:])))))
    c = np.sqrt(E / RHO)
    dt = SIDE / 3 / c                    # one element crossing of the bar wave per step
    stats = integrate(system, u0, v0, TimeSchedule(t_end, dt), observer=observe)
    return np.array(rows), stats, m, N


def test_block_sticks_below_mu_n():
    rows, stats, m, N = _push(0.3, MU)
    assert stats.max_sliding_nodes == 0            # |tau_i| < mu lambda_i at every node and step
    # it only rocks elastically: the static shear deflection F_t / (G * SIDE) ~ 1e-8 m; dynamic
    # overshoot at most 2x; a slide at (F_t - mu N)/m would cover ~1e-4 m here
    x = rows[:, 3]
    static = 0.3 * MU * N / (E / 2 * SIDE)
    assert np.abs(x).max() < 2.5 * static
    # the floor's tangential reaction balances the push on average (rocking about it)
    assert np.mean(rows[len(rows) // 2:, 5]) == pytest.approx(-0.3 * MU * N, rel=0.1)


def test_block_slides_above_mu_n():
    rows, stats, m, N = _push(2.0, MU)
    t, px, pz = rows[:, 0], rows[:, 1], rows[:, 2]
    ft = 2.0 * MU * N
    assert stats.max_sliding_nodes > 0
    # every node in contact slides: |tau_i| = mu lambda_i, so sum |tau_i| = mu sum lambda_i exactly
    # from the time the shear wave has crossed the cube (SIDE / c_s = 16 us) on
    on = rows[:, 4] > 0.5 * N
    assert on[1:].all()
    slides = np.isclose(rows[:, 6], MU * rows[:, 4], rtol=1e-9) & on
    k0 = int(np.argmax(slides))
    assert slides[k0:].all() and rows[k0, 0] <= 1.2 * SIDE / np.sqrt(E / 2 / RHO)
    on[:k0] = False
    # the slip is along +x up to the small elastic y-slip of the floor nodes (measured: the x share
    # sum tau_x / sum |tau_i| stays above 0.999), so the floor's tangential force is -mu N_floor
    assert np.allclose(rows[on, 5] / rows[on, 4], -MU, rtol=1e-3)
    # Newmark's trapezoidal momentum balance with sum tau_x = -mu sum lambda:
    # P_x = F_t t - mu (N t + P_z) from the first step on (step 0's reaction is not in a_0)
    err = px - (ft * t - MU * (N * t + pz))
    assert np.max(np.abs(err[k0:] - err[k0])) < 1e-3 * np.max(np.abs(px))
    # and the block accelerates at (F_t - mu N) / m up to the elastic rocking (P_z oscillates about 0)
    assert px[-1] / m == pytest.approx((ft - MU * N) * t[-1] / m, rel=0.03)


def test_mu_zero_friction_path_equals_frictionless():
    a, sa, m, N = _push(0.0, 0.0, with_rows=True, t_end=1e-4)
    b, sb, _, _ = _push(0.0, 0.0, with_rows=False, t_end=1e-4)
    assert sa.contact_solve == "schur" and sb.contact_solve == "fieldsplit"   # two different code paths
    # same trajectory to solver round-off (two different solves of the same contact problem)
    assert np.max(np.abs(a[:, 2] - b[:, 2])) < 1e-8 * max(np.abs(b[:, 2]).max(), m * 1e-3)
    assert np.max(np.abs(a[:, 4] - b[:, 4])) < 1e-8 * N
