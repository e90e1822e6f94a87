"""The 1D elastic bar hitting a rigid wall, as a :class:`millimpact.integration.integrators.LinearDynamics`.

A bar of length ``L`` (unit cross-section, Young's modulus ``E``, density ``rho``) occupies
``x in [0, L]`` and moves rigidly with velocity ``+v0`` towards a rigid wall at ``x = L + gap``.
The only constraint is ``gap(t) = gap - u(L, t) >= 0``: ``B`` is one row with ``-1`` at the tip dof.

Exact solution (foundations.md section 3): contact starts at ``t0 = gap / v0`` and lasts ``2 L / c``
with ``c = sqrt(E / rho)``; during contact the wall force (per unit area, here equal to the
stress) is the constant ``rho c v0``; afterwards the bar is unstressed and moves rigidly with
``-v0``; the energy ``rho L v0^2 / 2`` is conserved.

Importable by the tests and by the stability sweeps (:mod:`millimpact.studies.stability`);
``python -m millimpact.integration.bar --method newmark-mr`` (also under ``mpirun``) runs one case and prints
its summary and force history as JSON on rank 0.
"""

from __future__ import annotations

import argparse
import json
import math
from dataclasses import dataclass

import numpy as np
import ufl
from dolfinx import fem, mesh
from dolfinx.fem import petsc as fem_petsc
from mpi4py import MPI
from petsc4py import PETSc

from .integrators import (
    IntegrationStats,
    LinearDynamics,
    StepState,
    TimeSchedule,
    integrate,
    kinetic_energy,
    strain_energy,
)


@dataclass(frozen=True)
class BarCase:
    """Parameters of the bar problem (SI units)."""

    L: float = 0.1  #: bar length, m
    E: float = 200e9  #: Young's modulus, Pa
    rho: float = 7800.0  #: density, kg/m^3
    v0: float = 1.0  #: initial velocity towards the wall, m/s
    n_el: int = 100  #: number of P1 elements
    gap_steps: float = 3.37  #: initial gap in units of v0 * (h / c): contact starts mid-step

    @property
    def c(self) -> float:
        """Wave speed sqrt(E / rho), m/s."""
        return math.sqrt(self.E / self.rho)

    @property
    def h(self) -> float:
        """Element size, m."""
        return self.L / self.n_el

    @property
    def gap(self) -> float:
        """Initial gap between the tip and the wall, m."""
        return self.gap_steps * self.v0 * self.h / self.c

    @property
    def t_contact_start(self) -> float:
        """Exact time of first contact, s."""
        return self.gap / self.v0

    @property
    def duration(self) -> float:
        """Exact contact duration 2 L / c, s."""
        return 2.0 * self.L / self.c

    @property
    def force(self) -> float:
        """Exact contact force during contact, rho c v0 (N, per unit area), N."""
        return self.rho * self.c * self.v0

    @property
    def energy(self) -> float:
        """Exact (conserved) energy rho L v0^2 / 2, J (per unit area)."""
        return 0.5 * self.rho * self.L * self.v0**2


def build_bar(case: BarCase, comm: MPI.Comm = MPI.COMM_WORLD) -> tuple[LinearDynamics, PETSc.Vec, PETSc.Vec]:
    """Assemble the bar: returns (system, u0, v0) with u0 = 0 and v0 = +case.v0 everywhere."""
    msh = mesh.create_interval(comm, case.n_el, [0.0, case.L])
    V = fem.FunctionSpace(msh, ("Lagrange", 1))
    u, w = ufl.TrialFunction(V), ufl.TestFunction(V)
    E, rho = fem.Constant(msh, PETSc.ScalarType(case.E)), fem.Constant(msh, PETSc.ScalarType(case.rho))
    M = fem_petsc.assemble_matrix(fem.form(rho * u * w * ufl.dx))
    M.assemble()
    K = fem_petsc.assemble_matrix(fem.form(E * u.dx(0) * w.dx(0) * ufl.dx))
    K.assemble()

    imap = V.dofmap.index_map
    n_owned = imap.size_local
    tip = fem.locate_dofs_geometrical(V, lambda x: np.isclose(x[0], case.L))
    tip = tip[tip < n_owned].astype(np.int32)  # owned by exactly one rank
    rstart = imap.local_range[0]

    # B: one row (owned by rank 0), -1 at the tip dof; the tip's owner inserts it (off-process rows
    # are stashed and communicated by assemble()).
    n_rows_local = 1 if comm.rank == 0 else 0
    B = PETSc.Mat().createAIJ(((n_rows_local, 1), (n_owned, imap.size_global)), nnz=(1, 1), comm=comm)
    B.setOption(PETSc.Mat.Option.NEW_NONZERO_ALLOCATION_ERR, False)
    for d in tip:
        B.setValue(0, rstart + int(d), -1.0)
    B.assemble()

    system = LinearDynamics(M=M, K=K, B=B, g0=np.array([case.gap]), fixed_dofs=np.zeros(0, np.int32), contact_dofs=tip)
    u0 = M.createVecRight()
    u0.set(0.0)
    v0 = M.createVecRight()
    v0.set(case.v0)
    return system, u0, v0


@dataclass
class BarResult:
    """Time series of one bar run (rank-independent numpy arrays) and the integrator's stats."""

    t: np.ndarray
    dt: np.ndarray
    force: np.ndarray  #: wall force lambda, N (per unit area)
    gap: np.ndarray  #: gap, m
    energy: np.ndarray  #: kinetic + strain (+ penalty) energy, J
    momentum: np.ndarray  #: sum(M v), kg m/s
    v_mean: np.ndarray  #: momentum / mass, m/s
    n_active: np.ndarray
    stats: IntegrationStats

    def contact_mask(self) -> np.ndarray:
        """Steps at whose end the contact force is positive."""
        return self.force > 0.0

    def contact_duration(self) -> float:
        """Contact duration (s): from the start of the first step that ends with a positive force
        to the end of the last one (a chattering contact counts as one contact).

        Steps are counted whole: the discretisation cannot tell where inside a step the gap closed
        or opened, so the resolution is one step at each end.
        """
        idx = np.flatnonzero(self.contact_mask())
        if idx.size == 0:
            return 0.0
        return float(self.t[idx[-1]] - self.t[idx[0]] + self.dt[idx[0]])

    def time_in_contact(self) -> float:
        """Sum of the step sizes of the steps ending with a positive force (s): shorter than
        :meth:`contact_duration` when the contact chatters."""
        return float(np.sum(self.dt[self.contact_mask()]))

    def impulse(self) -> float:
        """Trapezoidal impulse of the wall force, N s (exact for Newmark's momentum balance)."""
        return float(np.sum(0.5 * (self.force[1:] + self.force[:-1]) * self.dt[1:]))

    def n_status_switches(self) -> int:
        """Number of open <-> closed changes of the constraint along the run."""
        active = self.n_active > 0
        return int(np.count_nonzero(active[1:] != active[:-1]))


def run_bar(
    case: BarCase,
    method: str = "newmark-mr",
    dt_contact: float | None = None,
    dt_free: float | None = None,
    t_end: float | None = None,
    options: dict | None = None,
    comm: MPI.Comm = MPI.COMM_WORLD,
    operator_cache: dict | None = None,
) -> BarResult:
    """Run one bar case; default steps: dt_contact = h / c (Courant 1), dt_free = 4 h / c.
    ``operator_cache``: a dict the implicit schemes keep their step operators in (a table's)."""
    system, u0, v0 = build_bar(case, comm)
    system.operator_cache = operator_cache
    hc = case.h / case.c
    dt_contact = hc if dt_contact is None else dt_contact
    dt_free = 4.0 * hc if dt_free is None else dt_free
    t_end = case.t_contact_start + 1.5 * case.duration if t_end is None else t_end
    sched = TimeSchedule(t_end, dt_contact, dt_free)
    rows: list[tuple] = []
    ones = system.M.createVecRight()
    ones.set(1.0)
    mass_vec = system.M.createVecRight()

    def observer(s: StepState) -> None:
        Ek = kinetic_energy(s.mass, s.v)
        Es = strain_energy(system.K, s.u, system.fixed_dofs)
        s.mass.mult(ones, mass_vec)
        total_mass = mass_vec.sum()
        p = mass_vec.dot(s.v)
        rows.append(
            (s.t, s.dt, float(s.lam[0]), float(s.gap[0]), Ek + Es + s.penalty_energy, p, p / total_mass, s.n_active)
        )

    stats = integrate(system, u0, v0, sched, method=method, observer=observer, options=options)
    a = np.array(rows, dtype=float)
    return BarResult(
        t=a[:, 0],
        dt=a[:, 1],
        force=a[:, 2],
        gap=a[:, 3],
        energy=a[:, 4],
        momentum=a[:, 5],
        v_mean=a[:, 6],
        n_active=a[:, 7].astype(int),
        stats=stats,
    )


def summarize(case: BarCase, res: BarResult) -> dict:
    """Errors against the exact solution (relative unless stated)."""
    dur = res.contact_duration()
    e0 = res.energy[0]
    mask = res.contact_mask()
    return {
        "duration": dur,
        "duration_rel_error": (dur - case.duration) / case.duration,
        "time_in_contact_rel_error": (res.time_in_contact() - case.duration) / case.duration,
        "mean_force_rel_error": (res.impulse() / dur - case.force) / case.force if dur > 0 else float("nan"),
        "impulse_rel_error": (res.impulse() - 2 * case.rho * case.L * case.v0) / (2 * case.rho * case.L * case.v0),
        "rebound_velocity_rel_error": (res.v_mean[-1] + case.v0) / case.v0,
        "energy_max_rel_error": float(np.max(np.abs(res.energy - e0)) / e0),
        "energy_final_rel_error": float((res.energy[-1] - e0) / e0),
        "median_force_rel_error": (
            float((np.median(res.force[mask]) - case.force) / case.force) if mask.any() else float("nan")
        ),
        "status_switches": res.n_status_switches(),
        "steps": res.stats.n_steps,
    }


def main(argv: list[str] | None = None) -> None:
    """Command line: run one case, print JSON (summary, force history) on rank 0."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--method", default="newmark-mr")
    p.add_argument("--n-el", type=int, default=100)
    p.add_argument("--courant", type=float, default=1.0, help="dt_contact in units of h / c")
    p.add_argument("--option", action="append", default=[], help="KEY=VALUE, relative to -impact_")
    a = p.parse_args(argv)
    case = BarCase(n_el=a.n_el)
    opts = dict(kv.split("=", 1) for kv in a.option)
    res = run_bar(case, a.method, dt_contact=a.courant * case.h / case.c, options=opts)
    if MPI.COMM_WORLD.rank == 0:
        print(json.dumps({"summary": summarize(case, res), "t": res.t.tolist(), "force": res.force.tolist()}))


if __name__ == "__main__":
    main()
