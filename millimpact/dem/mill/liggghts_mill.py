"""The mill in LIGGGHTS (``millimpact mill SCENE --engine liggghts``): a slice or the whole mill, on MPI ranks.

The same mill as the Yade slice (:mod:`~millimpact.dem.mill.run`): the plan of
:func:`~millimpact.dem.mill.setup.plan_mill` (profile, balls, speed, contact law, clock) run by
LIGGGHTS 3.8 (Debian's ``liggghts``) as ``mpirun -n N liggghts -in mill.in``
(``liggghts_scripts/mill.in``; this module writes its inputs and reads what it leaves).

- Liner: the profile's segments (:mod:`~millimpact.dem.mill.geometry`) swept along the axis,
  two triangles a segment and a piece of at most :data:`MAX_PIECE_M` along z (LIGGGHTS hands a
  mesh element to the rank holding its centre: long elements would not split over ranks), as
  ``shell.stl``, a ``fix mesh/surface/stress`` turned by ``fix move/mesh rotate`` at omega about
  z. Its torque about the axis (the fix's 6th output, reference point on the axis) is averaged
  over every ``power_every`` steps: the drive's work W = sum -T_z omega Delta t, and the net power
  P = Delta W / Delta t over the logged window (:func:`~millimpact.dem.mill.power.measured_power`).
- Contacts: LIGGGHTS' ``gran model hertz tangential history`` with ``limitForce on`` (the round
  trip's convention, :mod:`millimpact.dem.export.liggghts`) and the plan's moduli (times
  ``--stiffness-scale``), restitution and friction. LIGGGHTS damps a Hertz contact as Tsuji et al.
  (1992) do, gamma_n = 2 (5/6)^(1/2) |beta| (S_n m*)^(1/2), beta = ln e / (ln^2 e + pi^2)^(1/2),
  tangentially the same with S_t: a contact's restitution is e at any speed (0.800 for 0.8 with
  limitForce on, docs/dem.md), as Yade's ``en`` gives it in the slice. Yade takes the liner's
  facet as a sphere of radius 2 r (R* = 2 r / 3), LIGGGHTS as a plane (R* = r): its ball-liner
  contacts are (3/2)^(1/2) = 1.22 times stiffer at the same overlap.
- Length: the slice of the plan (``--length`` not given), between frictionless planes as in
  Yade; or ``--length L`` (m) or ``full`` (the scene's ``liner.mill_length`` if it has one, else
  :data:`LENGTH_PER_DIAMETER` D) between end plates: steel discs of the liner's material and the
  scene's friction that turn with the shell (the end liners' lifters left out); their torque is
  part of the drive's. The charge then fills the whole length at the plan's ``--fill``.
- Ranks: ``--ranks N`` MPI processes, each a block of the box (LIGGGHTS 3.8 has no load
  balancing): a longer mill is cut along z, its charge shared evenly; a slice across x, and for
  two ranks at the centroid of Morrell's charge (:func:`charge_centre_x`: the charge leans to the
  side the liner lifts it, ~3 m off the axis in an 11 m mill), else in the middle.
- Outputs: ``torque.txt`` and ``charge.dump`` (the particles after the warm-up, 36 times a
  revolution); the toe and shoulder from them (:func:`~millimpact.dem.mill.report.charge_angles`).
  Check of the torque: averaged over whole revolutions the charge's angular momentum does not
  grow, so the liner's torque on the charge balances gravity's, T = g sum m_i x_i (x horizontal,
  positive on the side the liner lifts): the net power is also omega g M <x_cm> (M the charge's
  mass, x_cm its centre's x averaged every step like the torque: ``power_from_charge_position_W``),
  which uses the positions alone.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import shutil
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ...errors import InputError
from ..programs import find_program, run_program
from .contact import GRAVITY
from .setup import MillOptions, MillSetup, ball_count, lattice_positions, plan_mill

#: the script (millimpact/dem/mill/liggghts_scripts/)
SCRIPT = Path(__file__).resolve().parent / "liggghts_scripts" / "mill.in"
#: the liner's mesh elements are at most this long along the axis (m)
MAX_PIECE_M = 0.3
#: --length full without the scene's mill length: L = 0.5 D, the North American high-aspect SAG
#: mill (diameter about twice the length: 36 x 17 ft, 40 x 22 ft; Napier-Munn et al., Mineral
#: Comminution Circuits, JKMRC 1996, ch. 11, D/L 1.5-2.5)
LENGTH_PER_DIAMETER = 0.5
#: torque samples per snapshot interval
POWER_SAMPLES_PER_SNAPSHOT = 20
#: a mill between end plates: each ball starts with an axial speed drawn from [-v, v] (m/s), so
#: that the starting lattice's layers mix (layers more than a diameter apart would otherwise never
#: touch each other or the end plates); 1 % of the shell's speed in the built-in mills
AXIAL_SPEED = 0.05
#: the neighbour list's skin, in ball radii
SKIN_RADII = 0.25
#: what the LIGGGHTS engine does not run (one line each, exit 2)
MPI_HINT = "apt-get install openmpi-bin (the MPI the Debian liggghts is built with)"
INSTALL_HINT = "apt-get install liggghts (Debian 12: LIGGGHTS 3.8.0)"


@dataclass(frozen=True)
class LiggghtsMill:
    """A mill run in LIGGGHTS: the plan (its thickness the run's length, its positions the
    charge's), whether the ends are steel end plates, the MPI ranks and the clock in steps."""

    setup: MillSetup
    end_plates: bool
    ranks: int
    length_source: str
    warm_steps: int
    run_steps: int
    snap_every: int
    power_every: int
    axial_speed: float = 0.0
    seed: int = 0

    @property
    def length(self) -> float:
        """The run's length along the axis (m)."""
        return self.setup.thickness

    @property
    def steps_per_revolution(self) -> float:
        return self.setup.period_s / self.setup.dt


def check_engine_options(args) -> None:
    """Refuse what the LIGGGHTS engine does not run, and --ranks / --length out of range (one line)."""
    engine = getattr(args, "engine", "yade")
    if engine != "liggghts":
        for name, value in (("--ranks", getattr(args, "ranks", None)), ("--length", getattr(args, "length", None))):
            if value is not None:
                raise InputError(f"{name}: an option of --engine liggghts (Yade runs the slice on --threads)")
        return
    for name, given in (
        ("--charge sag", args.charge != "balls"),
        ("--law", args.law is not None),
        ("--law-every", args.law_every is not None),
        ("--threads", args.threads is not None),
    ):
        if given:
            raise InputError(
                f"{name}: not run by --engine liggghts (a balls-only charge with the scene's contacts, "
                "on --ranks N); give --engine yade"
            )
    if args.ranks is not None and (isinstance(args.ranks, bool) or not 1 <= args.ranks <= 256):
        raise InputError(f"--ranks {args.ranks}: must be an integer in [1, 256] (MPI processes)")
    parse_length(args.length)


def parse_length(text) -> float | str | None:
    """``--length``: None (the slice), ``"full"`` or a length in metres (0.05-100); InputError else."""
    if text is None or text == "full":
        return text
    try:
        value = float(text)
    except (TypeError, ValueError):
        raise InputError(f"--length {text!r}: must be 'full' or a length in metres") from None
    if not (math.isfinite(value) and 0.05 <= value <= 100.0):
        raise InputError(f"--length {text}: must be 'full' or a length in [0.05, 100] m")
    return value


def _run_length(scene, setup: MillSetup, length) -> tuple[float, str]:
    """The run's length (m) and where it comes from."""
    if length == "full":
        given = getattr(scene.liner, "mill_length", None)
        if given is not None:
            return float(given), "the scene's liner.mill_length"
        return LENGTH_PER_DIAMETER * setup.profile.diameter, (
            f"{LENGTH_PER_DIAMETER:g} D (the scene gives no mill length): a high-aspect SAG mill"
        )
    return float(length), "--length"


def plan_liggghts_mill(scene, opts: MillOptions, length=None, ranks: int = 1) -> LiggghtsMill:
    """The LIGGGHTS run of ``scene`` under ``opts``: the slice of :func:`plan_mill` (``length``
    None), or a length (m, or ``"full"``) between end plates filled at the plan's fill."""
    length = parse_length(length)
    setup = plan_mill(scene, opts)
    source = f"the slice, {opts.thickness:g} ball diameters"
    if length is not None:
        if opts.balls is not None:
            raise InputError("--balls with --length: give --fill (the charge fills the whole length)")
        L, source = _run_length(scene, setup, length)
        r = setup.ball_radius
        if L < 2.2 * r:
            raise InputError(f"--length {L:g} m: must hold a ball (at least {2.2 * r:.3g} m)")
        fill = opts.fill if opts.fill is not None else 0.1
        n = ball_count(setup.profile, r, L, fill)
        positions = tuple(lattice_positions(setup.profile, r, L, n, opts.seed))
        setup = dataclasses.replace(setup, thickness=L, positions=positions, fill=fill)
    dt = setup.dt
    snap = max(POWER_SAMPLES_PER_SNAPSHOT, round(setup.period_s / setup.snapshots_per_revolution / dt))
    power_every = max(1, snap // POWER_SAMPLES_PER_SNAPSHOT)
    snap = power_every * POWER_SAMPLES_PER_SNAPSHOT
    # whole snapshot intervals: the snapshots fall on the logged window's ends
    warm = snap * round(setup.warmup_s / dt / snap)
    run = max(snap, snap * round(setup.run_s / dt / snap))
    setup = dataclasses.replace(
        setup,
        warmup_s=warm * dt,
        run_s=run * dt,
        revolutions=run * dt / setup.period_s,
    )
    return LiggghtsMill(
        setup=setup,
        end_plates=length is not None,
        ranks=ranks,
        length_source=source,
        warm_steps=warm,
        run_steps=run,
        snap_every=snap,
        power_every=power_every,
        axial_speed=AXIAL_SPEED if length is not None else 0.0,
        seed=opts.seed,
    )


def _facet(fh, a, b, c) -> None:
    n = np.cross(np.subtract(b, a), np.subtract(c, a))
    n = n / (np.linalg.norm(n) or 1.0)
    fh.write(f" facet normal {n[0]:.9g} {n[1]:.9g} {n[2]:.9g}\n  outer loop\n")
    for p in (a, b, c):
        fh.write(f"   vertex {p[0]!r} {p[1]!r} {p[2]!r}\n")
    fh.write("  endloop\n endfacet\n")


def write_shell_stl(path: Path, setup: MillSetup) -> int:
    """shell.stl: the liner's profile swept from z = 0 to z = L in pieces of at most MAX_PIECE_M,
    normals pointing into the mill; the number of triangles."""
    L = setup.thickness
    nz = max(1, math.ceil(L / MAX_PIECE_M))
    zs = [L * k / nz for k in range(nz + 1)]
    count = 0
    with open(path, "w") as fh:
        fh.write("solid shell\n")
        for seg in setup.profile.segments:
            (x0, y0), (x1, y1) = seg.start, seg.end
            for z0, z1 in zip(zs, zs[1:]):
                a, b, c, d = (x0, y0, z0), (x1, y1, z0), (x1, y1, z1), (x0, y0, z1)
                # counter-clockwise walk: the inside lies to the left, (b - a) x e_z points outwards
                _facet(fh, a, c, b)
                _facet(fh, a, d, c)
                count += 2
        fh.write("endsolid shell\n")
    return count


def write_ends_stl(path: Path, radius: float, length: float, edge: float) -> int:
    """ends.stl: two discs of ``radius`` (m) at z = 0 and z = ``length``, rings ``edge`` apart
    with 6 k points on ring k (near-equilateral triangles); the number of triangles."""
    m = max(1, math.ceil(radius / edge))

    def ring(k: int) -> list[tuple[float, float]]:
        if k == 0:
            return [(0.0, 0.0)]
        rk = radius * k / m
        return [
            (rk * math.cos(2 * math.pi * j / (6 * k)), rk * math.sin(2 * math.pi * j / (6 * k))) for j in range(6 * k)
        ]

    tris = []
    for k in range(1, m + 1):
        inner, outer = ring(k - 1), ring(k)
        i = j = 0
        # walk both rings by angle: each step a triangle with one new point
        while i < len(inner) or j < len(outer):
            ai = (i + 0.5) / len(inner) if k > 1 else 2.0
            aj = (j + 0.5) / len(outer)
            if j < len(outer) and (aj <= ai or i >= len(inner)):
                tris.append((inner[i % len(inner)], outer[j], outer[(j + 1) % len(outer)]))
                j += 1
            else:
                tris.append((inner[i], outer[j % len(outer)], inner[(i + 1) % len(inner)]))
                i += 1
    with open(path, "w") as fh:
        fh.write("solid ends\n")
        for z, flip in ((0.0, False), (length, True)):
            for a, b, c in tris:
                pa, pb, pc = (*a, z), (*b, z), (*c, z)
                _facet(fh, *((pa, pc, pb) if flip else (pa, pb, pc)))
        fh.write("endsolid ends\n")
    return 2 * len(tris)


def charge_centre_x(setup: MillSetup) -> float:
    """The x (m) of the centroid of Morrell's charge: the annular sector between his toe and
    shoulder (theta_T, theta_S from the horizontal, Morrell 1996) and radii r_i and R,

        x = (2/3) (R^3 - r_i^3) / (R^2 - r_i^2) (sin theta_S - sin theta_T) / (theta_S - theta_T),

    where a slice's box is cut between two ranks. For liner-panel's balls at J = 0.1 and 75 % of
    n_c it is 3.38 m; 55 % of the balls of the Yade-checked slice lie below it (a cut at Morrell's
    mean torque arm, 2.0 m, left 34 %)."""
    from ...theory.mill_power import morrell_net_power
    from .power import model_inputs

    m = model_inputs(setup)
    mp = morrell_net_power(m["diameter_m"], 1.0, m["speed_fraction"], m["fill"], m["charge_density_kg_m3"])
    R, ri = 0.5 * m["diameter_m"], mp.inner_radius
    t0, t1 = mp.shape.toe, mp.shape.shoulder + 2.0 * math.pi
    if R - ri <= 0.0 or t1 - t0 <= 0.0:
        return 0.0
    x = 2.0 / 3.0 * (R**3 - ri**3) / (R**2 - ri**2) * (math.sin(t1) - math.sin(t0)) / (t1 - t0)
    return min(max(x, 0.0), 0.8 * setup.profile.radius)


def write_particles(
    path: Path, setup: MillSetup, margin: float, cut_x: float = 0.0, axial_speed: float = 0.0, seed: int = 0
) -> None:
    """particles.data: LIGGGHTS' data file (atom style granular: id type diameter density x y z);
    the box reaches 2 ``cut_x`` further on +x, so that its middle, where LIGGGHTS cuts it between
    two ranks, lies at x = ``cut_x`` (LIGGGHTS 3.8 has no load balancing); with ``axial_speed``,
    each ball's starting v_z drawn from [-axial_speed, axial_speed] (``seed``)."""
    R = max(math.hypot(*p) for s in setup.profile.segments for p in (s.start, s.end)) + margin
    L = setup.thickness
    rho = setup.ball_material[2]
    d = 2.0 * setup.ball_radius
    lines = [
        "LIGGGHTS data file: millimpact mill",
        "",
        f"{setup.n_balls} atoms",
        "3 atom types",
        "",
        f"{-R!r} {R + 2.0 * cut_x!r} xlo xhi",
        f"{-R!r} {R!r} ylo yhi",
        f"{-margin!r} {L + margin!r} zlo zhi",
        "",
        "Atoms",
        "",
    ]
    lines += [f"{k + 1} 1 {d!r} {rho!r} {x!r} {y!r} {z!r}" for k, (x, y, z) in enumerate(setup.positions)]
    if axial_speed > 0.0:
        vz = np.random.default_rng(seed).uniform(-axial_speed, axial_speed, setup.n_balls)
        lines += ["", "Velocities", ""] + [f"{k + 1} 0.0 0.0 {v!r} 0.0 0.0 0.0" for k, v in enumerate(vz)]
    path.write_text("\n".join(lines) + "\n")


def _walls(plan: LiggghtsMill) -> str:
    """walls.in: the shell (and the end plates) as turning meshes, or the slice's frictionless ends."""
    s = plan.setup
    turn = f"rotate origin 0. 0. 0. axis 0. 0. 1. period {s.period_s!r}"
    lines = [
        "fix shell all mesh/surface/stress file shell.stl type 2 reference_point 0.0 0.0 0.0",
        f"fix turn_shell all move/mesh mesh shell {turn}",
        "variable torque_shell equal f_shell[6]",
    ]
    if plan.end_plates:
        lines += [
            "# the end plates: steel (the liner's material, the scene's friction) turning with the shell",
            "fix ends all mesh/surface/stress file ends.stl type 2 reference_point 0.0 0.0 0.0",
            f"fix turn_ends all move/mesh mesh ends {turn}",
            "fix liner all wall/gran model hertz tangential history mesh n_meshes 2 meshes shell ends limitForce on",
            "variable torque_ends equal f_ends[6]",
        ]
    else:
        lines += [
            "fix liner all wall/gran model hertz tangential history mesh n_meshes 1 meshes shell limitForce on",
            "# the slice's ends: frictionless planes (type 3), as the Yade slice's",
            "fix end0 all wall/gran model hertz tangential history primitive type 3 zplane 0.0 limitForce on",
            f"fix end1 all wall/gran model hertz tangential history primitive type 3 zplane {s.thickness!r} "
            "limitForce on",
            "variable torque_ends equal 0.0",
        ]
    return "\n".join(lines) + "\n"


def _params(plan: LiggghtsMill) -> str:
    """params.in: the run's numbers as LIGGGHTS variables, and how the box is cut over the ranks."""
    s = plan.setup
    E_b, nu_b, _ = s.ball_material
    E_l, nu_l, _ = s.liner_material
    n = plan.ranks
    grid = f"1 1 {n}" if plan.end_plates else f"{n} 1 1"
    values = {
        "skin": SKIN_RADII * s.ball_radius,
        "E_ball": E_b,
        "nu_ball": nu_b,
        "E_liner": E_l,
        "nu_liner": nu_l,
        "e": s.restitution,
        "mu": s.friction,
        "dt": s.dt,
        "g": GRAVITY,
        "power_every": plan.power_every,
        "snap_every": plan.snap_every,
        "warm_steps": plan.warm_steps,
        "run_steps": plan.run_steps,
        "total_steps": plan.warm_steps + plan.run_steps,
        "steps_per_rev": plan.steps_per_revolution,
        "progress_every": max(plan.power_every, (plan.warm_steps + plan.run_steps) // 100),
    }
    lines = [f"processors {grid}"] + [f"variable {k} equal {v!r}" for k, v in values.items()]
    return "\n".join(lines) + "\n"


def write_inputs(work: Path, plan: LiggghtsMill) -> dict:
    """The script and its inputs in ``work``; the meshes' triangle counts."""
    s = plan.setup
    shutil.copy(SCRIPT, work / SCRIPT.name)
    counts = {"shell_triangles": write_shell_stl(work / "shell.stl", s)}
    if plan.end_plates:
        counts["end_triangles"] = write_ends_stl(work / "ends.stl", s.profile.radius, s.thickness, MAX_PIECE_M)
    cut = charge_centre_x(s) if plan.ranks == 2 and not plan.end_plates else 0.0
    write_particles(
        work / "particles.data", s, 2.0 * s.ball_radius, cut_x=cut, axial_speed=plan.axial_speed, seed=plan.seed
    )
    (work / "params.in").write_text(_params(plan))
    (work / "walls.in").write_text(_walls(plan))
    return counts


def liggghts_command(ranks: int) -> list[str]:
    """``mpirun -n N liggghts`` (``liggghts`` alone for one rank without mpirun); InputError with
    the install line when either is missing."""
    exe = find_program("liggghts", "MILLIMPACT_LIGGGHTS", INSTALL_HINT, "millimpact mill --engine liggghts")
    mpirun = shutil.which("mpirun")
    if mpirun is None:
        if ranks > 1:
            find_program("mpirun", "MILLIMPACT_MPIRUN", MPI_HINT, "--ranks > 1")
        return [exe]
    return [os.environ.get("MILLIMPACT_MPIRUN") or mpirun, "-n", str(ranks), exe]


def _mpi_env() -> dict[str, str]:
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    if hasattr(os, "geteuid") and os.geteuid() == 0:  # Open MPI refuses root without these
        env.update(OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    return env


def run_liggghts(work: Path, plan: LiggghtsMill, on_progress=None, timeout: float | None = None) -> dict:
    """Run ``mill.in`` in ``work`` on ``plan.ranks`` ranks; the wall time (s) and LIGGGHTS' loop
    times. DemCodeError with the output's last lines when it fails."""
    import time

    from ..programs import DemCodeError

    cmd = [*liggghts_command(plan.ranks), "-in", SCRIPT.name, "-log", "log.liggghts"]
    t0 = time.perf_counter()
    rc, lines = run_program(cmd, work, _mpi_env(), timeout, on_progress)
    wall = time.perf_counter() - t0
    (work / "screen.txt").write_text("".join(lines))
    if rc != 0 or any(line.startswith("ERROR") for line in lines):
        tail = "".join(lines[-15:])
        raise DemCodeError(f"liggghts exited with status {rc} in {work}:\n{tail}")
    loops = [line.split() for line in lines if line.startswith("Loop time of")]
    # "Loop time of T on P procs for S steps with A atoms"
    loop_s = sum(float(w[3]) for w in loops)
    steps = sum(int(w[8]) for w in loops)
    return {
        "command": " ".join(Path(c).name if os.path.isabs(c) else c for c in cmd),
        "ranks": plan.ranks,
        "wall_s": wall,
        "loop_s": loop_s,
        "steps": steps,
        "steps_per_s": steps / loop_s if loop_s > 0 else None,
        "runs": [{"steps": int(w[8]), "loop_s": float(w[3])} for w in loops],
        "projected_s_per_revolution": plan.steps_per_revolution * float(loops[-1][3]) / int(loops[-1][8])
        if loops and int(loops[-1][8]) > 0
        else None,
        "runs_are": "LIGGGHTS' loop times: the warm-up, then the logged revolutions (the charge in motion)",
        "particles": plan.setup.n_balls,
    }


def read_torque(work: Path, plan: LiggghtsMill) -> dict[str, np.ndarray]:
    """torque.txt as the drive's work: W_k = sum over the windows up to step k of -(T_shell +
    T_ends) omega Delta t (J), with the window ends' times (s), the two torques (N m) and the
    charge's centre's x (m), each the mean over the window that ends there."""
    data = np.loadtxt(work / "torque.txt", comments="#", ndmin=2)
    s = plan.setup
    step, t_shell, t_ends, xcm = data[:, 0], data[:, 1], data[:, 2], data[:, 3]
    dw = -(t_shell + t_ends) * s.omega * plan.power_every * s.dt
    return {
        "time_s": np.concatenate([[0.0], step * s.dt]),
        "drive_work_J": np.concatenate([[0.0], np.cumsum(dw)]),
        "torque_shell_N_m": np.concatenate([[0.0], t_shell]),
        "torque_ends_N_m": np.concatenate([[0.0], t_ends]),
        "centre_x_m": np.concatenate([[np.nan], xcm]),
    }


def read_dump(path: Path, dt: float) -> dict[str, np.ndarray]:
    """charge.dump (``id type x y z vx vy omegaz`` every snapshot) as charge_angles' snapshots."""
    blocks = []
    with open(path) as fh:
        lines = fh.read().split("\n")
    i = 0
    while i < len(lines):
        if lines[i].startswith("ITEM: TIMESTEP"):
            step = int(lines[i + 1])
            n = int(lines[i + 3])
            rows = np.loadtxt(lines[i + 9 : i + 9 + n], ndmin=2)
            blocks.append((step, rows))
            i += 9 + n
        else:
            i += 1
    cols = ("snapshot", "time_s", "particle", "x_m", "y_m", "z_m", "vx_m_s", "vy_m_s", "wz_rad_s")
    if not blocks:
        return {c: np.zeros(0) for c in cols}
    out: dict[str, list[np.ndarray]] = {c: [] for c in cols}
    for k, (step, rows) in enumerate(blocks):
        m = rows.shape[0]
        out["snapshot"].append(np.full(m, k))
        out["time_s"].append(np.full(m, step * dt))
        out["particle"].append(rows[:, 0] - 1)
        for j, c in enumerate(cols[3:]):
            out[c].append(rows[:, 2 + j])
    return {c: np.concatenate(v) for c, v in out.items()}


def charge_position_power(energy: dict[str, np.ndarray], setup: MillSetup) -> float | None:
    """omega g M <x_cm> over the logged window (W): the net power from the charge's centre of mass
    alone (module docstring); None without samples after the warm-up."""
    after = energy["time_s"] > setup.warmup_s + 0.5 * setup.dt
    if not after.any():
        return None
    mass = setup.n_balls * setup.ball_mass
    return float(setup.omega * GRAVITY * mass * energy["centre_x_m"][after].mean())


def _length_summary(plan: LiggghtsMill, counts: dict) -> dict:
    s = plan.setup
    return {
        "length_m": plan.length,
        "length_is": plan.length_source,
        "ends": "steel end plates (the liner's material, the scene's friction) turning with the shell"
        if plan.end_plates
        else "frictionless planes (a slice)",
        "processors_grid": "1 x 1 x N (cut along the axis)" if plan.end_plates else "N x 1 x 1 (cut across x)",
        "steps": plan.warm_steps + plan.run_steps,
        "warmup_steps": plan.warm_steps,
        "logged_steps": plan.run_steps,
        "steps_per_revolution": plan.steps_per_revolution,
        "power_every_steps": plan.power_every,
        "snapshot_every_steps": plan.snap_every,
        "dt_s": s.dt,
        **counts,
    }


def run_liggghts_mill(
    scene, opts: MillOptions, stage: Path, plan: LiggghtsMill, plots: bool = True, quiet: bool = False, timeout=None
) -> dict:
    """Run ``plan`` in LIGGGHTS into the folder ``stage`` (``liggghts/``: the script, its inputs
    and raw output; ``charge.png``); returns summary.json's content."""
    from .power import charge_shape_report, power_report
    from .report import charge_angles, charge_figure
    from .run import _mill_summary, _Progress

    s = plan.setup
    work = stage / "liggghts"
    work.mkdir()
    counts = write_inputs(work, plan)
    cost = run_liggghts(work, plan, on_progress=None if quiet else _Progress(), timeout=timeout)
    energy = read_torque(work, plan)
    snapshots = read_dump(work / "charge.dump", s.dt)
    angles = charge_angles(snapshots, s)
    mill_length = plan.length if plan.end_plates else getattr(scene.liner, "mill_length", None)
    power = power_report(s, energy, mill_length=mill_length)
    after = energy["time_s"] > s.warmup_s
    shell, ends = energy["torque_shell_N_m"][after], energy["torque_ends_N_m"][after]
    p_cm = charge_position_power(energy, s)
    has_share = plan.end_plates and after.any()
    power["ends_share"] = float(ends.mean() / (shell.mean() + ends.mean())) if has_share else None
    power["ends_share_is"] = "the end plates' share of the drive's torque (None: a slice's frictionless ends)"
    power["power_from_charge_position_W"] = p_cm
    power["power_from_charge_position_is"] = (
        "omega g M <x_cm> over the logged window: the torque of the charge's weight about the axis, which "
        "the liner's balances while the charge's angular momentum does not grow"
    )
    if plots:
        if snapshots["snapshot"].size:
            charge_figure(stage / "charge.png", snapshots, s, angles)

    summary = {
        "scene": s.scene_name,
        "engine": "liggghts",
        "options": dataclasses.asdict(opts),
        "mill": {**_mill_summary(s), "run_length_m": plan.length},
        "run": _length_summary(plan, counts),
        "charge": {
            "balls": s.n_balls,
            "ball_radius_m": s.ball_radius,
            "fill": s.fill,
            "charge_is": "balls alone (no rock, no slurry)",
        },
        "contact": {
            "law": "LIGGGHTS gran model hertz tangential history, limitForce on (Tsuji damping from e)",
            "restitution": s.restitution,
            "restitution_source": s.restitution_source,
            "friction": s.friction,
            "stiffness_scale": s.stiffness_scale,
        },
        "clock": {
            "dt_s": s.dt,
            "contact_time_s": s.contact_time_s,
            "warmup_revolutions": s.warmup_s / s.period_s,
            "revolutions": s.revolutions,
            "period_s": s.period_s,
        },
        "shoulder_deg": angles["shoulder_deg"],
        "toe_deg": angles["toe_deg"],
        "angles_measured": "from the vertical below the axis, positive in the direction of rotation",
        "centrifuged_fraction": angles["centrifuged_fraction"],
        "power": power,
        "charge_shape": charge_shape_report(s, angles),
        "liggghts": cost,
        "not_logged": "impacts, spectrum, abrasion and the energy balance: the Yade engine's",
    }
    json.dumps(summary)
    return summary
