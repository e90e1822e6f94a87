"""``hertz-modal``: a Hertz contact spring driving the block's modal model (a light method).

The ball is rigid (mass m, the scene's); the block is its finite-element model (P1, clamped base,
symmetry planes as planned) reduced to its lowest modes with the clamp as the only support
(:func:`millimpact.reduction.compute_modes`, SLEPc, modes up to ``f_cut``). The two meet in one
nonlinear spring, Hertz's (Johnson 11.4)::

    m x''          = -F,                        F = k max(delta, 0)^(3/2),  k = 4/3 E* sqrt(R)
    eta_j'' + w_j^2 eta_j = s_j F / n_sym,      delta = x - gap - w,        w = sum_j s_j eta_j

``x`` is the ball's travel along the impact normal, ``s_j`` the normal displacement of mode j
(M-orthonormal) at the contact point, ``w`` the block's modal displacement there, ``n_sym`` the
symmetry factor (the modes belong to the kept part of the block, which carries F / n_sym).

Why this split does not count the local compliance twice: Hertz's delta is the local indentation
of both bodies as half-spaces; the modes up to f_cut (default the plan's 4 / t_c) are smooth on
the contact scale, so their point displacement is the block's structural (global) motion, which
Hertz leaves out. The block mesh only has to resolve the modes and the gauges' static field, so
by default the contact mesh is coarsened to a_max / 2 (``options["h_contact"]`` or
``model.h_contact`` set in the scene win). Cost: meshing, one factorization and the eigensolve; the time loop is an ODE
of 2 + 2 n_modes unknowns (scipy DOP853 while in contact; closed form in free vibration).

Time series: contact force, approach (ball travel less the gap), Hertz contact radius
sqrt(R delta), ball velocity, the contact point's displacement / velocity / acceleration (the
block's modal motion plus its Hertz share of delta, ``(1 - nu2^2)/E2 * E*``), the Hertz pressure
as contact-point stress, gauges from the modes' strains (sigma = E d.eps.d) plus the static response of the modes left out
(mode-acceleration method), energies (ball,
modal, Hertz spring). Options: ``f_cut`` (Hz), ``modes`` (count, wins), ``h_contact`` (m),
``t_end`` (s), ``rtol`` (ODE).
"""

from __future__ import annotations

import logging
import math
import time
from typing import Any

import numpy as np
from mpi4py import MPI
from petsc4py import PETSc
from scipy import integrate as sci

from ..errors import InputError
from ..fem.model import create_fe_model
from ..fem.probes import create_probe
from ..geometry.mesh import create_mesh
from ..integration.solvers import create_factored_solver
from ..reduction.eigen import compute_modes, default_solver_options
from ..results.output import RunOutput
from ..results.timeseries import TimeSeries
from ..scene.plan import Plan, make_plan
from ..scene.schema import Scene
from ..theory.hertz import FallingZeroEvent
from .options import float_option, take
from .reduced import refuse_plastic

log = logging.getLogger(__name__)

DESCRIPTION = (
    "Hertz contact spring (rigid ball) on the block's modal model (modes up to f_cut): "
    "a light model of the block's structural response"
)

#: default contact mesh size of the block model, in units of a_max (the plan's is a_max / 4)
COARSE_H_CONTACT = 0.5
#: ODE samples per step of the plan's contact step (dense output)
SAMPLES_PER_STEP = 1


class BlockModes:
    """The block's modes as seen by the contact and the gauges (replicated on every rank).

    ``omega`` (rad/s), ``s`` normal displacement at the contact point per unit modal coordinate,
    ``gauge`` gauge stress (Pa) per unit modal coordinate (n_gauges x n_modes), ``gauge_static``
    gauge stress (Pa/N) of the left-out modes' static response to a unit contact force, ``n_fe`` the FE
    model's dofs, ``timings`` s.
    """

    def __init__(self, omega, s, gauge, gauge_static, n_fe, info):
        self.omega, self.s, self.gauge, self.n_fe, self.info = omega, s, gauge, n_fe, info
        self.gauge_static = gauge_static


def _scatter_add():
    from dolfinx import la

    return la.ScatterMode.add


def compute_block_modes(
    scene: Scene, plan: Plan, f_cut: float | None, n_modes: int | None, comm: MPI.Comm = MPI.COMM_WORLD
) -> BlockModes:
    """Mesh the scene, assemble P1 and compute the block's clamped modes (collective)."""
    t0 = time.perf_counter()
    md = create_mesh(scene, plan, comm)
    model = create_fe_model(md, plan, 1)
    t_model = time.perf_counter() - t0
    K, M = model.K, model.M
    free = np.ones(K.getLocalSize()[0], dtype=bool)
    free[model.fixed_dofs] = False
    blk = np.zeros_like(free)
    blk[model.block_dofs] = True
    idx = np.nonzero(free & blk)[0]
    r0 = K.getOwnershipRange()[0]
    I = PETSc.IS().createGeneral((r0 + idx).astype(np.int32), comm=comm)
    K_bb, M_bb = K.createSubMatrix(I, I), M.createSubMatrix(I, I)
    prefix = "impact_hertzmodal_"
    opts = default_solver_options(comm.size)
    ksp = create_factored_solver(K_bb, prefix, opts)
    # probes: the contact point and the gauges, just inside the block (the plan's places)
    pts = [plan.probes.contact_point] + [g.point for g in plan.probes.gauges]
    dirs = [np.array(g.direction) for g in plan.probes.gauges]
    probe = create_probe(model.V, np.array(pts), model.block_cells)
    if not np.all(probe.found):
        raise InputError("hertz-modal: a probe point (contact point or gauge) lies outside the block mesh")
    E = scene.block.material.youngs_modulus
    u_fn = model.function("mode")
    full = K.createVecRight()

    def observe(v: PETSc.Vec) -> tuple[float, np.ndarray]:
        """(normal displacement at the contact point, gauge stresses) of a block vector."""
        full.set(0.0)
        full.isaxpy(I, 1.0, v)
        u_fn.vector.array[:] = full.array_r
        u_fn.x.scatter_forward()
        vals = probe.values(u_fn.x.array)
        grads = probe.gradients(u_fn.x.array)
        g = np.array([E * d @ (0.5 * (gr + gr.T)) @ d for d, gr in zip(dirs, grads[1:])])
        return -vals[0, 1], g  # into the block (-y) positive

    # (solved before the eigensolver takes the factorization over as its spectral transform)
    f_fn = model.function("unit_force")
    f_fn.x.array[:] = -np.asarray(probe.P_val[1].todense()).ravel() if probe.P_val.shape[0] else 0.0
    f_fn.x.scatter_reverse(_scatter_add())
    fI = f_fn.vector.getSubVector(I)
    x_st = fI.duplicate()
    ksp.solve(fI, x_st)
    f_fn.vector.restoreSubVector(I, fI)
    t1 = time.perf_counter()
    freq, vecs, nxt = compute_modes(K_bb, M_bb, ksp, f_cut, n_modes, prefix, opts)
    t_modes = time.perf_counter() - t1

    s = np.zeros(len(vecs))
    gauge = np.zeros((len(dirs), len(vecs)))
    for j, v in enumerate(vecs):
        s[j], gauge[:, j] = observe(v)
    # mode-acceleration correction of the gauges: the static response of the modes left out,
    # (K^-1 - sum_j phi_j phi_j^T / w_j^2) f for a unit point force f at the contact point (into
    # the block), seen at the gauges. Gauges lie outside the contact patch, where this local
    # quasi-static field (Boussinesq) is finite; the contact point's own displacement does not
    # get it (Hertz's delta already holds the local compliance).
    omega2 = (2 * math.pi * np.asarray(freq)) ** 2
    for j, v in enumerate(vecs):
        x_st.axpy(-s[j] / omega2[j], v)
    _, gauge_res = observe(x_st)
    for v in vecs:
        v.destroy()
    for o in (full, ksp, K_bb, M_bb, I, x_st):
        o.destroy()
    omega = 2 * math.pi * np.asarray(freq)
    info = {
        "fe_dofs": model.n_dofs_global,
        "block_dofs": comm.allreduce(len(idx)),
        "modes": len(freq),
        "lowest_frequency_Hz": float(freq[0]) if len(freq) else None,
        "highest_frequency_Hz": float(freq[-1]) if len(freq) else None,
        "next_frequency_Hz": nxt,
        "f_cut_Hz": f_cut,
        "symmetry_factor": model.sym_factor,
        "timings_s": {"mesh_and_model": t_model, "modes": t_modes},
    }
    return BlockModes(omega, s, gauge, gauge_res, model.n_dofs_global, info)


def _simulate(
    bm: BlockModes,
    m: float,
    k: float,
    v0: float,
    gap: float,
    n_sym: float,
    t_end: float,
    dt_contact: float,
    dt_free: float,
    rtol: float,
) -> dict[str, np.ndarray]:
    """Integrate the ball + modes system over [0, t_end]; returns sampled states."""
    w2, s = bm.omega**2, bm.s
    n = len(s)
    omega = bm.omega

    def rhs(_t, y):
        x, xd, eta, etad = y[0], y[1], y[2 : 2 + n], y[2 + n :]
        d = x - gap - s @ eta
        f = k * d**1.5 if d > 0 else 0.0
        return np.concatenate([[xd, -f / m], etad, -w2 * eta + s * (f / n_sym)])

    released = FallingZeroEvent(lambda _t, y: y[0] - gap - s @ y[2 : 2 + n])

    smax = max(float(np.max(np.abs(s))), 1e-300) if n else 1.0
    d_scale = (m * v0**2 / k) ** 0.4  # ~ delta_max
    atol = np.concatenate(
        [[1e-9 * d_scale, 1e-9 * v0], np.full(n, 1e-9 * d_scale / smax), np.full(n, 1e-9 * v0 / smax)]
    )
    times, states = [np.array([0.0])], [np.concatenate([[0.0, v0], np.zeros(2 * n)])[:, None]]
    t, y = 0.0, states[0][:, 0].copy()
    # flight over the gap (exact), then alternate contact (ODE) and free vibration (closed form)
    t_touch = min(gap / v0, t_end)
    tf = np.arange(1, 5) * t_touch / 4
    states.append(np.vstack([v0 * tf, np.full_like(tf, v0), np.zeros((2 * n, len(tf)))]))
    times.append(tf)
    t, y = t_touch, states[-1][:, -1].copy()
    y[0] = gap  # exactly touching
    n_ode = 0
    plain = False
    while t < t_end * (1 - 1e-12):
        # contact: ODE until the spring releases (or a chunk ends); after a free phase that closed
        # within one free step, one free step of plain ODE (no release event) to get past it
        t_stop = min(t_end, t + (dt_free if plain else 40 * 100 * dt_contact))
        sol = sci.solve_ivp(
            rhs,
            (t, t_stop),
            y,
            method="DOP853",
            rtol=rtol,
            atol=atol,
            events=None if plain else released,
            dense_output=True,
            first_step=dt_contact / 100,
            max_step=dt_contact,
        )
        plain = False
        if sol.status < 0:
            raise RuntimeError(f"hertz-modal: ODE failed at t = {sol.t[-1]:.6g} s: {sol.message}")
        n_ode += sol.t.size
        t1 = float(sol.t[-1])
        tt = np.arange(t + dt_contact, t1, dt_contact)
        tt = np.append(tt, t1) if (not len(tt) or tt[-1] < t1 - 1e-3 * dt_contact) else tt
        times.append(tt)
        states.append(sol.sol(tt))
        t, y = t1, sol.sol(t1)
        if t >= t_end * (1 - 1e-12):
            break
        # free: closed form until t_end or until delta > 0 on the free grid
        x0, xd0, eta0, etad0 = y[0], y[1], y[2 : 2 + n], y[2 + n :]
        tau = np.arange(1, int(math.ceil((t_end - t) / dt_free)) + 1) * dt_free
        tau[-1] = min(tau[-1], t_end - t)
        c, sn = np.cos(np.outer(omega, tau)), np.sin(np.outer(omega, tau))
        eta = eta0[:, None] * c + (etad0 / omega)[:, None] * sn
        etad = -(eta0 * omega)[:, None] * sn + etad0[:, None] * c
        x = x0 + xd0 * tau
        d = x - gap - s @ eta
        hit = np.nonzero(d > 0)[0]
        k_end = len(tau) if not len(hit) else max(int(hit[0]), 1)
        if len(hit) and hit[0] == 0:
            # touching again within one free step: go on with the ODE from here
            plain = True
            continue
        st = np.vstack([x[:k_end], np.full(k_end, xd0), eta[:, :k_end], etad[:, :k_end]])
        times.append(t + tau[:k_end])
        states.append(st)
        t, y = float(t + tau[k_end - 1]), st[:, -1].copy()
    T = np.concatenate(times)
    Y = np.concatenate(states, axis=1)
    return {"t": T, "x": Y[0], "xd": Y[1], "eta": Y[2 : 2 + n], "etad": Y[2 + n :], "n_ode_steps": n_ode}


def run_hertz_modal(scene: Scene, plan: Plan, options: dict[str, Any], progress: bool) -> RunOutput:
    """The ``hertz-modal`` run of a scene (see the module docstring)."""
    comm = MPI.COMM_WORLD
    options = dict(options)
    refuse_plastic("hertz-modal", plan)
    t_wall = time.perf_counter()
    take(options, "degree")
    take(options, "integrator")

    t_end = float_option(options, "t_end", scene.time.end)
    f_cut = float_option(options, "f_cut", plan.f_cut)
    n_modes = float_option(options, "modes", scene.model.modes)
    n_modes = int(n_modes) if n_modes is not None else None
    rtol = float_option(options, "rtol", 1e-8)
    h_c = float_option(options, "h_contact", None)
    if h_c is None and scene.model.h_contact is None:
        # the modes need no contact mesh, but the gauges' static correction sees the 1/r^2
        # Boussinesq field near the impact: a_max / 2 (coarser, a_max-sized elements, flipped the
        # sign of gauge C's static stress on paper-rig)
        h_c = COARSE_H_CONTACT * plan.hertz.a_max
    mscene = scene.with_value("model.h_contact", h_c) if h_c is not None else scene
    mplan = make_plan(mscene)
    if not (f_cut > 0):
        raise InputError(f"option f_cut = {f_cut!r}: must be > 0 Hz")
    bm = compute_block_modes(mscene, mplan, f_cut, n_modes, comm)
    h = plan.hertz
    n_sym = bm.info["symmetry_factor"]
    t_modes = time.perf_counter() - t_wall
    sim = _simulate(
        bm,
        scene.ball.mass,
        h.k,
        h.speed,
        plan.gap,
        n_sym,
        t_end,
        plan.dt_contact / SAMPLES_PER_STEP,
        plan.dt_free,
        rtol,
    )
    t, x, xd, eta, etad = sim["t"], sim["x"], sim["xd"], sim["eta"], sim["etad"]
    s = bm.s
    w, wd = s @ eta, s @ etad
    d = np.maximum(x - plan.gap - w, 0.0)
    f = h.k * d**1.5
    wdd = s @ (-(bm.omega**2)[:, None] * eta + s[:, None] * (f / n_sym))
    xdd = -f / scene.ball.mass
    blk = scene.block.material
    share = (1 - blk.poisson**2) / blk.youngs_modulus * h.e_star
    in_c = d > 0
    dd = np.where(in_c, xd - wd, 0.0)
    a = np.sqrt(h.radius * d)
    with np.errstate(divide="ignore", invalid="ignore"):
        p = np.where(a > 0, 3 * f / (2 * np.pi * a * a), 0.0)
    ke_ball = 0.5 * scene.ball.mass * xd**2
    ke_modes = n_sym * 0.5 * np.sum(etad**2, axis=0)
    se = 0.4 * h.k * d**2.5 + n_sym * 0.5 * np.sum((bm.omega**2)[:, None] * eta**2, axis=0)
    cols = {
        "time_s": t,
        "contact_force_N": f,
        "approach_m": x - plan.gap,
        "contact_radius_m": a,
        "ball_velocity_m_s": xd,
        "contact_point_displacement_m": w + share * d,
        "contact_point_velocity_m_s": wd + share * dd,
        "contact_point_acceleration_m_s2": wdd + np.where(in_c, share * (xdd - wdd), 0.0),
        "contact_point_stress_Pa": -p,
    }
    for i, g in enumerate(scene.gauges):
        cols[f"gauge_{g.name}_stress_Pa"] = bm.gauge[i] @ eta + bm.gauge_static[i] * f / n_sym
    cols.update(
        {
            "ball_kinetic_energy_J": ke_ball,
            "kinetic_energy_J": ke_ball + ke_modes,
            "strain_energy_J": se,
            "total_energy_J": ke_ball + ke_modes + se,
        }
    )
    ts = TimeSeries(cols)
    e = cols["total_energy_J"]
    on = np.nonzero(f > 0)[0]
    if len(on):
        gaps = np.nonzero(np.diff(on) > 1)[0]
        last = on[gaps[0]] if len(gaps) else on[-1]
        restitution = -xd[min(last + 1, len(xd) - 1)] / h.speed
    else:
        restitution = float("nan")
    wall = time.perf_counter() - t_wall
    results = {
        "restitution": float(restitution),
        "energy_initial_J": float(e[0]),
        "energy_drift_max_rel": float(np.max(np.abs(e - e[0])) / e[0]),
        "vibration_energy_share_end": float(1.0 - ke_ball[-1] / e[0]),
        "peak_contact_stress_Pa": float(p.max()),
        "peak_gauge_stress_Pa": {
            g.name: float(cols[f"gauge_{g.name}_stress_Pa"][np.argmax(np.abs(cols[f"gauge_{g.name}_stress_Pa"]))])
            for g in scene.gauges
        },
        "timings_s": {**bm.info["timings_s"], "integrate": wall - t_modes},
        "ode_steps": int(sim["n_ode_steps"]),
    }
    model = {
        "method": "hertz-modal",
        "dofs": 1 + len(s),
        "modes": len(s),
        "fe_dofs": bm.n_fe,
        "block": bm.info,
        "h_contact_m": mplan.h_contact,
        "description": DESCRIPTION,
    }
    notes = [
        f"hertz-modal: rigid ball + Hertz spring on {len(s)} block modes up to "
        f"{(bm.info['highest_frequency_Hz'] or 0) / 1e3:.4g} kHz (f_cut {f_cut / 1e3:.4g} kHz), "
        f"P1 block mesh {bm.n_fe} dofs (h_contact {mplan.h_contact * 1e3:.3g} mm)",
        "normal impact component only; no ball vibration; modes above f_cut and the local "
        "wave radiation beyond Hertz are left out",
    ]
    return RunOutput("hertz-modal", ts, results, model, notes=notes)


def run(scene: Scene, plan: Plan, options: dict[str, Any], progress: bool) -> RunOutput:
    """``--method hertz-modal`` (the registry's entry point)."""
    return run_hertz_modal(scene, plan, dict(options), progress)
