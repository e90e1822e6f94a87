"""``millimpact stability``: map where each time integrator fails.

For each integrator (``newmark-mr``, ``newmark``, ``central-penalty``) a sweep over the step size
and the impact velocity on two problems:

* ``bar``: the 1D elastic bar hitting a rigid wall (:mod:`millimpact.integration.bar`), exact solution: contact
  lasts 2L/c with the constant force rho c v0, energy conserved. Step axis: the Courant number
  dt / (h / c). Velocities 0.01 m/s (grazing: the gap closes by micrometres) to 20 m/s. The bar
  is linear, so its answers scale with v0: what changes with v0 are the solvers' absolute
  tolerances (the grazing case) and nothing else, which the map shows.
* ``sphere``: the scene's ball impact (default ``paper-rig``) on a coarse mesh (h_contact =
  a_max / 3, h_far 8 mm), run to gap / v + 1.5 t_c. Step axis: dt / (t_c / 100) (the plan's
  contact step) for the implicit methods, dt / dt_crit for the explicit one. Velocities
  0.1 to 20 m/s.

Measured per run: energy drift max|E - E0| / E0 and growth max(E - E0) / E0 (E kinetic with the
scheme's own mass + strain + penalty); penetration max(-gap) relative to the approach scale
(bar: v0 L / c, sphere: Hertz delta_max); contact status switches; pulse breaks (times the total
force drops to zero and comes back within the first pulse); force roughness
||F - median5(F)|| / ||F|| (a 5-sample median filter keeps a smooth pulse and the bar's step
edges but removes chatter); the contact duration and peak force errors (bar: exact; sphere:
the same mesh's newmark-mr run at the smallest step, so that the coarse mesh's own error against
Hertz does not hide the integrators'; the Hertz error is in the CSV's note); failure (exception,
NaN, the explicit method's divergence flag, energy growth > 50 %).

Status: ``failed`` as above; ``degraded`` if energy drift > 5 %, any pulse break, roughness > 5 %,
penetration > 5 %, or the duration (bar) / peak force (sphere) off by > 10 % / 15 %; else ``pass``
(the sweep turns the explicit method's step limit off).

Theory of the explicit critical step (central differences, lumped mass): dt_crit = 2 / omega_max.
Bar P1 with lumped mass: omega_max = 2 c / h without contact, so dt_crit = h / c (Courant 1); in
contact the penalty spring k_p = E A / h on the tip (mass rho A h / 2) raises omega_max: the
critical step in contact is 2 / sqrt(lambda_max(M_L^-1 (K + k_p e e^T))), computed here by a dense
eigensolver (numpy) on the bar's matrices, independently of the integrator's SLEPc estimate.
Sphere: dt_crit ~ h_min / c_p (P1 tetrahedra, lumped mass); the sweep's boundary is compared with
the integrator's estimate 2 / sqrt(lambda_max).

Output under ``--out``: ``stability.csv`` (a row per run, units in the header), ``map_<integrator>.png``
(pass / degraded / failed over step and velocity, a panel per problem), ``critical_step.json``
(the explicit method's measured boundary against theory).
"""

from __future__ import annotations

import argparse
import csv
import json
import logging
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypedDict

if TYPE_CHECKING:  # numpy is imported where the command computes (`millimpact --help` stays fast)
    import numpy as np

from ..console import sayer
from ..errors import InputError, MillimpactError
from ..results.output_folder import FORCE_HELP, OUT_HELP

log = logging.getLogger(__name__)

HELP = "map where each time integrator fails (step size x impact velocity, bar and sphere)"
DESCRIPTION = __doc__

INTEGRATORS = ("newmark-mr", "newmark", "central-penalty")
#: thresholds of the classification (module docstring)
DEGRADED = {"energy_drift": 0.05, "roughness": 0.05, "penetration": 0.05, "bar_duration": 0.10, "sphere_force": 0.15}
FAILED_ENERGY_GROWTH = 0.5

BAR_COURANT = (0.25, 0.5, 0.8, 0.9, 0.91, 0.92, 0.95, 1.0, 1.1, 1.5, 2.0, 4.0)
BAR_VELOCITIES = (0.01, 0.1, 1.0, 5.0, 20.0)
SPHERE_DT = (0.5, 1.0, 2.0, 4.0, 8.0)  # x t_c / 100
SPHERE_DT_EXPLICIT = (0.5, 0.7, 0.8, 0.9, 1.1)  # x dt_crit
SPHERE_VELOCITIES = (0.1, 3.0, 20.0)


class SweepSettings(TypedDict, total=False):
    """Settings of a sweep that differ from the full one's (the module constants)."""

    bar_courant: tuple[float, ...]
    bar_velocities: tuple[float, ...]
    bar_n_el: int
    sphere_dt: tuple[float, ...]
    sphere_dt_explicit: tuple[float, ...]
    sphere_velocities: tuple[float, ...]


QUICK: SweepSettings = {
    "bar_courant": (0.5, 0.9, 1.1, 2.0),
    "bar_velocities": (0.01, 1.0, 20.0),
    "bar_n_el": 50,
    "sphere_dt": (1.0, 4.0),
    "sphere_dt_explicit": (0.7, 1.1),
    "sphere_velocities": (3.0,),
}


@dataclass
class Case:
    """One run of the sweep and what it measured (SI units; ``*_rel`` relative)."""

    problem: str
    integrator: str
    velocity_m_s: float
    dt_s: float
    dt_rel: float  #: bar: Courant; sphere: dt / (t_c/100) or dt / dt_crit (explicit)
    dt_axis: str
    status: str = "pass"
    reason: str = ""
    energy_drift_rel: float = math.nan
    energy_growth_rel: float = math.nan
    penetration_rel: float = math.nan
    status_switches: int = 0
    pulse_breaks: int = 0
    force_roughness_rel: float = math.nan
    duration_rel_error: float = math.nan
    peak_force_rel_error: float = math.nan
    dt_critical_s: float = math.nan
    steps: int = 0
    wall_s: float = 0.0
    extra: dict = field(default_factory=dict)


# --- measures --------------------------------------------------------------------------------------
def force_measures(force: np.ndarray) -> tuple[int, float]:
    """(pulse breaks, roughness) of a force history on a uniform step: breaks are returns to zero
    between the first and last positive samples; roughness ||F - median5(F)|| / ||F||."""
    import numpy as np
    from scipy.ndimage import median_filter

    pos = np.flatnonzero(force > 0)
    if pos.size == 0:
        return 0, 0.0
    seg = force[pos[0] : pos[-1] + 1] > 0
    breaks = int(np.count_nonzero(seg[1:] & ~seg[:-1]))
    f = np.asarray(force, float)
    dev = f - median_filter(f, size=5, mode="nearest")
    return breaks, float(np.linalg.norm(dev) / max(float(np.linalg.norm(f)), 1e-300))


def classify(c: Case) -> None:
    """Set ``c.status`` and ``c.reason`` from its measures (thresholds: :data:`DEGRADED`)."""
    if c.status == "failed":
        return
    vals = [c.energy_drift_rel, c.energy_growth_rel]
    if not all(math.isfinite(v) for v in vals):
        c.status, c.reason = "failed", "non-finite energy"
        return
    if c.energy_growth_rel > FAILED_ENERGY_GROWTH:
        c.status, c.reason = "failed", f"energy growth {100 * c.energy_growth_rel:.3g} %"
        return
    why = []
    if c.energy_drift_rel > DEGRADED["energy_drift"]:
        why.append(f"energy drift {100 * c.energy_drift_rel:.2g} %")
    if c.pulse_breaks > 0:
        why.append(f"chatter ({c.pulse_breaks} pulse breaks)")
    if c.force_roughness_rel > DEGRADED["roughness"]:
        why.append(f"rough force {100 * c.force_roughness_rel:.2g} %")
    if c.penetration_rel > DEGRADED["penetration"]:
        why.append(f"penetration {100 * c.penetration_rel:.2g} %")
    if c.problem == "bar" and abs(c.duration_rel_error) > DEGRADED["bar_duration"]:
        why.append(f"duration {100 * c.duration_rel_error:+.2g} %")
    if c.problem == "sphere" and abs(c.peak_force_rel_error) > DEGRADED["sphere_force"]:
        why.append(f"F_max {100 * c.peak_force_rel_error:+.2g} % vs newmark-mr at the smallest step")
    c.status, c.reason = ("degraded", "; ".join(why)) if why else ("pass", "")


# --- the bar ---------------------------------------------------------------------------------------
def bar_critical_step_theory(n_el: int = 100, penalty_factor: float = 1.0) -> dict[str, float]:
    """Critical steps of central differences on the lumped P1 bar, in units of h / c: free
    (exactly 1) and with the tip's penalty spring k_p = penalty_factor * E/h (dense eigenvalues of
    M_L^-1 (K + k_p e e^T), unit E, rho, h)."""
    import numpy as np

    n = n_el + 1
    K = np.zeros((n, n))
    for e in range(n_el):
        K[e : e + 2, e : e + 2] += np.array([[1.0, -1.0], [-1.0, 1.0]])
    m = np.full(n, 1.0)
    m[0] = m[-1] = 0.5
    d = 1.0 / np.sqrt(m)

    def dt_of(Kx: np.ndarray) -> float:
        lam = np.linalg.eigvalsh(d[:, None] * Kx * d[None, :]).max()
        return 2.0 / math.sqrt(lam)

    Kc = K.copy()
    Kc[-1, -1] += penalty_factor * 1.0
    return {"free": dt_of(K), "contact": dt_of(Kc)}


def run_bar_case(integrator: str, courant: float, v0: float, n_el: int = 100) -> Case:
    """One bar run: ``courant`` = dt / (h / c), ``v0`` m/s; the explicit method's step limit off."""
    import numpy as np

    from ..integration.bar import BarCase, run_bar, summarize

    case = BarCase(v0=v0, n_el=n_el)
    hc = case.h / case.c
    dt = courant * hc
    c = Case("bar", integrator, v0, dt, courant, "dt / (h/c)")
    opts = {"limit_step": False} if integrator == "central-penalty" else {}
    t_end = case.t_contact_start + 1.5 * case.duration
    t0 = time.perf_counter()
    try:
        res = run_bar(case, integrator, dt_contact=dt, dt_free=dt, t_end=t_end, options=opts)
    except Exception as exc:  # a sweep looks for failures: record them, don't stop
        c.status, c.reason = "failed", f"{type(exc).__name__}: {str(exc).splitlines()[0][:120]}"
        c.wall_s = time.perf_counter() - t0
        return c
    c.wall_s = time.perf_counter() - t0
    s = summarize(case, res)
    e0 = res.energy[0]
    c.energy_drift_rel = float(np.max(np.abs(res.energy - e0)) / e0)
    c.energy_growth_rel = float(np.max(res.energy - e0) / e0)
    c.penetration_rel = float(max(0.0, -np.min(res.gap)) / (v0 * case.L / case.c))
    c.status_switches = int(s["status_switches"])
    c.pulse_breaks, c.force_roughness_rel = force_measures(res.force)
    c.duration_rel_error = float(s["duration_rel_error"])
    c.peak_force_rel_error = float((np.max(res.force) - case.force) / case.force)
    c.steps = int(res.stats.n_steps)
    c.dt_critical_s = float(getattr(res.stats, "dt_critical", math.nan))
    if getattr(res.stats, "diverged", False):
        c.status, c.reason = "failed", f"diverged at t = {res.stats.diverged_at:.3g} s"
    classify(c)
    return c


# --- the sphere ------------------------------------------------------------------------------------
def sphere_scene(scene, v: float):
    """The scene at normal speed ``v`` (m/s) on a coarse mesh (h_contact a_max / 3, h_far 8 mm)."""
    from ..scene.plan import scene_hertz

    sc = scene.with_value("impact.velocity", [0.0, -float(v), 0.0])
    a_max = scene_hertz(sc).a_max
    sc = sc.with_value("model.h_contact", a_max / 3.0)
    far = min(8e-3, sc.ball.radius / 2)
    # the plan's zone (4 a_max) outgrows the ball at high speed (a_max ~ v^0.4): cap it below the
    # plan's limit (0.45 x the smallest body size); the contact candidates (2.5 a_max) stay inside
    smallest = min(sc.ball.radius, sc.block.length, sc.block.height, sc.block.thickness)
    sc = sc.with_value("model.zone_radius", min(4.0 * a_max, 0.44 * smallest))
    return sc.with_value("model.h_far", far)


class _SphereSetup:
    """Mesh, model and contact rows of a sphere case (built once per velocity)."""

    def __init__(self, scene, v: float):
        from mpi4py import MPI

        from ..fem.contact import create_contact
        from ..fem.model import create_fe_model
        from ..geometry.mesh import create_mesh
        from ..scene.plan import make_plan

        self.scene = sphere_scene(scene, v)
        self.plan = make_plan(self.scene)
        md = create_mesh(self.scene, self.plan, MPI.COMM_WORLD)
        self.model = create_fe_model(md, self.plan, 1)
        self.contact = create_contact(self.model, self.plan)
        self.t_end = self.plan.gap / self.plan.hertz.speed + 1.5 * self.plan.hertz.contact_time

    def run(self, integrator: str, dt: float, options: dict) -> dict[str, Any]:
        """One run with a fixed step ``dt``; returns histories (force N, energy J, min gap m)."""
        import numpy as np

        from ..integration import integrators as I

        m = self.model
        system = I.LinearDynamics(
            M=m.M,
            K=m.K,
            B=self.contact.B,
            g0=self.contact.g0,
            fixed_dofs=m.fixed_dofs,
            contact_dofs=self.contact.contact_dofs,
        )
        u0 = m.M.createVecRight()
        u0.set(0.0)
        v0 = m.ball_velocity(self.scene.impact.velocity)
        rows = []

        def observe(st) -> None:
            e = I.kinetic_energy(st.mass, st.v) + I.strain_energy(m.K, st.u, m.fixed_dofs) + st.penalty_energy
            rows.append(
                (
                    st.t,
                    m.sym_factor * float(np.sum(st.lam)),
                    m.sym_factor * e,
                    float(np.min(st.gap)) if len(st.gap) else math.inf,
                )
            )

        stats = I.integrate(
            system, u0, v0, I.TimeSchedule(self.t_end, dt, dt), method=integrator, observer=observe, options=options
        )
        a = np.array(rows)
        return {"t": a[:, 0], "force": a[:, 1], "energy": a[:, 2], "gap": a[:, 3], "stats": stats}


def run_sphere_case(
    setup: _SphereSetup, integrator: str, dt: float, dt_rel: float, axis: str, options: dict | None = None
) -> Case:
    """One sphere run with a fixed step ``dt`` (s)."""
    import numpy as np

    from ..results.timeseries import TimeSeries, contact_metrics

    h = setup.plan.hertz
    c = Case("sphere", integrator, h.speed, dt, dt_rel, axis)
    t0 = time.perf_counter()
    try:
        r = setup.run(integrator, dt, dict(options or {}))
    except Exception as exc:  # a sweep looks for failures: record them, don't stop
        c.status, c.reason = "failed", f"{type(exc).__name__}: {str(exc).splitlines()[0][:120]}"
        c.wall_s = time.perf_counter() - t0
        return c
    c.wall_s = time.perf_counter() - t0
    e, f = r["energy"], r["force"]
    e0 = e[0]
    with np.errstate(invalid="ignore", over="ignore"):
        c.energy_drift_rel = float(np.max(np.abs(e - e0)) / e0)
        c.energy_growth_rel = float(np.max(e - e0) / e0)
    c.penetration_rel = float(max(0.0, -np.nanmin(r["gap"])) / h.delta_max)
    st = r["stats"]
    c.status_switches = int(st.n_switches)
    c.pulse_breaks, c.force_roughness_rel = force_measures(np.nan_to_num(f))
    if np.all(np.isfinite(f)):
        m = contact_metrics(TimeSeries({"time_s": r["t"], "contact_force_N": f}))
        c.duration_rel_error = m["contact_duration_s"] / h.contact_time - 1.0
        c.peak_force_rel_error = m["peak_contact_force_N"] / h.force_max - 1.0
        c.extra.update(
            F_max_N=m["peak_contact_force_N"], t_c_s=m["contact_duration_s"], F_max_vs_hertz=c.peak_force_rel_error
        )
    c.steps = int(st.n_steps)
    c.dt_critical_s = float(st.dt_critical)
    c.extra.update(max_active=int(st.max_active), dofs=int(setup.model.n_dofs_global))
    if st.diverged:
        c.status, c.reason = "failed", f"diverged at t = {st.diverged_at:.3g} s"
        c.extra["hard_fail"] = True
    classify(c)
    return c


def rescore_sphere(cases: list[Case]) -> None:
    """Score the sphere runs of one velocity against the same mesh's newmark-mr run at the
    smallest step (the coarse mesh's own error against Hertz, e.g. +46 % on F_max at 0.1 m/s
    where h_far / h_contact is 80, would otherwise mask the integrators' differences): F_max and
    t_c relative to that run; then classify again."""
    refs = sorted((c for c in cases if c.integrator == "newmark-mr" and "F_max_N" in c.extra), key=lambda c: c.dt_rel)
    if not refs:
        return
    ref = refs[0]
    for c in cases:
        if "F_max_N" not in c.extra:
            continue
        c.peak_force_rel_error = c.extra["F_max_N"] / ref.extra["F_max_N"] - 1.0
        c.duration_rel_error = c.extra["t_c_s"] / ref.extra["t_c_s"] - 1.0
        if not c.extra.get("hard_fail"):
            c.status, c.reason = "pass", ""
            classify(c)


# --- the sweep -------------------------------------------------------------------------------------
def sweep(
    integrators=INTEGRATORS, problems=("bar", "sphere"), quick: bool = False, scene=None, say=print
) -> list[Case]:
    """Run the sweep; returns the cases in order."""
    cfg: SweepSettings = QUICK if quick else {}
    cases: list[Case] = []
    if "bar" in problems:
        courants = cfg.get("bar_courant", BAR_COURANT)
        vels = cfg.get("bar_velocities", BAR_VELOCITIES)
        n_el = cfg.get("bar_n_el", 100)
        for integ in integrators:
            for v in vels:
                for cr in courants:
                    c = run_bar_case(integ, cr, v, n_el)
                    c.extra["n_el"] = n_el
                    cases.append(c)
                say(
                    f"  bar {integ:16s} v {v:6g} m/s: "
                    + " ".join(f"{x.dt_rel:g}:{x.status[0].upper()}" for x in cases[-len(courants) :])
                )
    if "sphere" in problems:
        from ..scene.builtin import resolve_scene

        scene = scene if scene is not None else resolve_scene(None)
        for v in cfg.get("sphere_velocities", SPHERE_VELOCITIES):
            try:
                setup = _SphereSetup(scene, v)
            except MillimpactError as exc:
                # a velocity the scene cannot model (e.g. the contact patch outgrows the ball):
                # recorded as failed set-ups, the sweep goes on
                for integ in integrators:
                    cases.append(
                        Case("sphere", integ, v, math.nan, math.nan, "-", "failed", f"set-up: {str(exc)[:120]}")
                    )
                say(f"  sphere v {v:g} m/s: set-up failed: {exc}")
                continue
            dt_c = setup.plan.dt_contact
            crit = None
            n_v = len(cases)
            for integ in integrators:
                n0 = len(cases)
                if integ == "central-penalty":
                    if crit is None:
                        crit = _sphere_dt_crit(setup)
                    for fac in cfg.get("sphere_dt_explicit", SPHERE_DT_EXPLICIT):
                        cases.append(
                            run_sphere_case(setup, integ, fac * crit, fac, "dt / dt_crit", {"limit_step": False})
                        )
                else:
                    for fac in cfg.get("sphere_dt", SPHERE_DT):
                        cases.append(run_sphere_case(setup, integ, fac * dt_c, fac, "dt / (t_c/100)"))
                for c in cases[n0:]:
                    c.extra["dofs"] = int(setup.model.n_dofs_global)
            rescore_sphere(cases[n_v:])
            for integ in integrators:
                cs = [x for x in cases[n_v:] if x.integrator == integ]
                say(
                    f"  sphere {integ:16s} v {v:6g} m/s: " + " ".join(f"{x.dt_rel:g}:{x.status[0].upper()}" for x in cs)
                )
    return cases


def _sphere_dt_crit(setup: _SphereSetup) -> float:
    """The integrator's own critical step for the sphere model (s), from one explicit step."""
    from ..integration import integrators as I

    m = setup.model
    system = I.LinearDynamics(
        M=m.M,
        K=m.K,
        B=setup.contact.B,
        g0=setup.contact.g0,
        fixed_dofs=m.fixed_dofs,
        contact_dofs=setup.contact.contact_dofs,
    )
    u0 = m.M.createVecRight()
    u0.set(0.0)
    stats = I.integrate(system, u0, u0.copy(), I.TimeSchedule(1e-12, 1e-12), method="central-penalty")
    return float(stats.dt_critical)


def critical_step_report(cases: list[Case], n_el: int) -> dict[str, Any]:
    """The explicit method's measured stability boundary on the bar (largest passing and smallest
    failing Courant number over all velocities) against theory, and on the sphere against the
    integrator's estimate."""
    import numpy as np

    th = bar_critical_step_theory(n_el)
    out: dict[str, Any] = {
        "bar_theory_courant": th,
        "theory": "lumped P1 bar: dt_crit = h/c free; with the tip penalty k_p = E/h "
        "2/sqrt(lambda_max(M_L^-1 (K + k_p e e^T))) (dense eigenvalues)",
    }
    bar = [c for c in cases if c.problem == "bar" and c.integrator == "central-penalty"]
    if bar:
        ok = [c.dt_rel for c in bar if c.status != "failed"]
        bad = [c.dt_rel for c in bar if c.status == "failed"]
        stable = max([x for x in ok if not bad or x < min(bad)], default=math.nan)
        out["bar_measured_courant"] = {"largest_stable": stable, "smallest_failed": min(bad, default=math.nan)}
        ests = [c.dt_critical_s / (c.dt_s / c.dt_rel) for c in bar if math.isfinite(c.dt_critical_s)]
        out["bar_integrator_estimate_courant"] = float(np.median(ests)) if ests else math.nan
    sph = [c for c in cases if c.problem == "sphere" and c.integrator == "central-penalty"]
    if sph:
        rows = {}
        for v in sorted({c.velocity_m_s for c in sph}):
            cs = [c for c in sph if c.velocity_m_s == v]
            ok = [c.dt_rel for c in cs if c.status != "failed"]
            bad = [c.dt_rel for c in cs if c.status == "failed"]
            rows[f"{v:g}"] = {
                "dt_crit_estimate_s": cs[0].dt_s / cs[0].dt_rel,
                "largest_stable_rel": max(ok, default=math.nan),
                "smallest_failed_rel": min(bad, default=math.nan),
            }
        out["sphere"] = rows
    return out


# --- output ----------------------------------------------------------------------------------------
CSV_FIELDS = [
    ("problem", ""),
    ("integrator", ""),
    ("velocity_m_s", "m/s"),
    ("dt_s", "s"),
    ("dt_rel", ""),
    ("dt_axis", ""),
    ("status", ""),
    ("reason", ""),
    ("energy_drift_rel", ""),
    ("energy_growth_rel", ""),
    ("penetration_rel", ""),
    ("status_switches", ""),
    ("pulse_breaks", ""),
    ("force_roughness_rel", ""),
    ("duration_rel_error", ""),
    ("peak_force_rel_error", ""),
    ("dt_critical_s", "s"),
    ("steps", ""),
    ("wall_s", "s"),
    ("F_max_vs_hertz", ""),
]


def write_csv(cases: list[Case], path: Path) -> None:
    """One row per run; the header names carry their units (SI)."""
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow([k for k, _ in CSV_FIELDS])
        for c in cases:
            vals = [getattr(c, k, c.extra.get(k, "")) for k, _ in CSV_FIELDS]
            w.writerow([f"{v:.6g}" if isinstance(v, float) else v for v in vals])


def read_csv(path: Path) -> list[dict[str, str]]:
    """The rows of a ``stability.csv``."""
    with open(path) as fh:
        return list(csv.DictReader(fh))


STATUS_COLOURS = {"pass": "#4caf50", "degraded": "#ffb300", "failed": "#e53935"}


def plot_maps(cases: list[Case], folder: Path, crit: dict[str, Any]) -> list[str]:
    """One figure per integrator: pass / degraded / failed over (step, velocity), a panel per
    problem; cells are labelled with the energy drift (%)."""
    import numpy as np

    from ..results.plots import pyplot

    plt = pyplot()
    from matplotlib.patches import Patch

    names = []
    for integ in sorted({c.integrator for c in cases}, key=INTEGRATORS.index):
        probs = [p for p in ("bar", "sphere") if any(c.problem == p and c.integrator == integ for c in cases)]
        fig, axes = plt.subplots(1, len(probs), figsize=(max(7.5, 6.2 * len(probs)), 4.8), squeeze=False)
        for ax, prob in zip(axes[0], probs):
            cs = [c for c in cases if c.problem == prob and c.integrator == integ]
            xs = sorted({c.dt_rel for c in cs})
            vs = sorted({c.velocity_m_s for c in cs})
            for c in cs:
                i, j = xs.index(c.dt_rel), vs.index(c.velocity_m_s)
                ax.add_patch(plt.Rectangle((i - 0.5, j - 0.5), 1, 1, color=STATUS_COLOURS[c.status], ec="white"))
                label = (
                    "NaN"
                    if not math.isfinite(c.energy_drift_rel)
                    else (f"{100 * c.energy_drift_rel:.2g}" if c.energy_drift_rel < 10 else ">1e3")
                )
                ax.text(i, j, label, ha="center", va="center", fontsize=7)
            ax.set_xlim(-0.5, len(xs) - 0.5)
            ax.set_ylim(-0.5, len(vs) - 0.5)
            ax.set_xticks(range(len(xs)), [f"{x:g}" for x in xs], rotation=45)
            ax.set_yticks(range(len(vs)), [f"{v:g}" for v in vs])
            ax.set_xlabel(cs[0].dt_axis + (" (Courant number)" if prob == "bar" else ""))
            ax.set_ylabel("impact velocity (m/s)")
            title = {"bar": "1D bar on a rigid wall (exact solution)", "sphere": "sphere impact (coarse mesh)"}[prob]
            if integ == "central-penalty" and prob == "bar":
                th = crit.get("bar_theory_courant", {})
                for key, ls in (("free", "--"), ("contact", ":")):
                    if key in th:
                        xpos = np.interp(th[key], xs, range(len(xs)))
                        ax.axvline(xpos, color="k", ls=ls, lw=1)
                title += f"\ntheory dt_crit: h/c free (--), {th.get('contact', math.nan):.3f} h/c in contact (:)"
            ax.set_title(title, fontsize=9)
        handles = [Patch(color=v, label=k) for k, v in STATUS_COLOURS.items()]
        fig.legend(handles=handles, loc="lower center", ncol=3, fontsize=8)
        fig.suptitle(f"{integ}: stability map (cell labels: energy drift, % of the impact energy)", fontsize=10)
        fig.tight_layout(rect=(0, 0.05, 1, 0.95))
        name = f"map_{integ}.png"
        fig.savefig(folder / name, dpi=110)
        plt.close(fig)
        names.append(name)
    return names


# --- command line ----------------------------------------------------------------------------------
def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("scene", nargs="?", help="scene of the sphere sweep (default paper-rig)")
    p.add_argument("--out", help=OUT_HELP.format(default="out/stability"))
    p.add_argument("--force", action="store_true", help=FORCE_HELP)
    p.add_argument("--quick", action="store_true", help="tiny sweep (tests): fewer steps and velocities")
    p.add_argument(
        "--integrators", default=",".join(INTEGRATORS), help=f"comma-separated subset of {', '.join(INTEGRATORS)}"
    )
    p.add_argument("--problems", default="bar,sphere", help="comma-separated subset of bar, sphere")


def main(args: argparse.Namespace) -> int:
    from mpi4py import MPI

    from ..results.output_folder import claim_output
    from ..scene.builtin import resolve_scene

    integ = [x.strip() for x in args.integrators.split(",") if x.strip()]
    bad = [x for x in integ if x not in INTEGRATORS]
    if bad or not integ:
        raise InputError(f"--integrators {args.integrators!r}: choose from {', '.join(INTEGRATORS)}")
    probs = [x.strip() for x in args.problems.split(",") if x.strip()]
    if not probs or any(x not in ("bar", "sphere") for x in probs):
        raise InputError(f"--problems {args.problems!r}: choose from bar, sphere")
    scene = resolve_scene(args.scene) if "sphere" in probs else None
    comm = MPI.COMM_WORLD
    say = sayer(comm=comm)
    target = claim_output(
        args.out if args.out is not None else "out/stability", "stability", force=args.force, comm=comm
    )  # before the sweep
    out = target.shown
    say(
        f"stability sweep: integrators {', '.join(integ)}; problems {', '.join(probs)}"
        + (" (quick)" if args.quick else "")
        + f" -> {out}/  (letters: P pass, D degraded, F failed)"
    )
    t0 = time.perf_counter()
    cases = sweep(integ, probs, args.quick, scene, say)
    n_el = QUICK["bar_n_el"] if args.quick else 100
    crit = critical_step_report(cases, n_el)
    with target.staged() as stage:
        if comm.rank == 0:
            write_csv(cases, stage / "stability.csv")
            plot_maps(cases, stage, crit)
            (stage / "critical_step.json").write_text(json.dumps(crit, indent=2, default=float))
    counts = {s: sum(c.status == s for c in cases) for s in STATUS_COLOURS}
    say(f"{len(cases)} runs in {time.perf_counter() - t0:.0f} s: " + ", ".join(f"{v} {k}" for k, v in counts.items()))
    if "bar_measured_courant" in crit:
        m, th = crit["bar_measured_courant"], crit["bar_theory_courant"]
        say(
            f"explicit critical step on the bar: stable up to Courant {m['largest_stable']:g}, failed from "
            f"{m['smallest_failed']:g}; theory {th['free']:.3f} (free), {th['contact']:.3f} (in contact, penalty)"
        )
    say(f"results in {out}/ (stability.csv, critical_step.json, map_*.png)" + target.replaced_note())
    return 0
