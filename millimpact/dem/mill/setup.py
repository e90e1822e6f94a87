"""A mill run's inputs: from a scene and the command's options to the JSON the Yade script reads.

:func:`check_mill_options` refuses out-of-range options (one line each, before anything is made);
:func:`plan_mill` turns a scene with a liner into a :class:`MillSetup`: the liner's profile
(:mod:`millimpact.dem.mill.geometry`), the slice, the balls and where they start, the speed, the
contact law and the clock; :meth:`MillSetup.yade_input` is the JSON of
``millimpact/dem/mill/yade_scripts/mill_slice.py``.

- Speed: omega = S omega_c, omega_c = sqrt(g / R) (n_c = 42.3 / sqrt(D) rpm; :mod:`~millimpact.dem.mill.contact`).
- Balls: ``--balls N``, or ``--fill J``, the fraction of the mill's volume the ball bed fills (the
  usual measure of a mill's load): N = J A L (1 - phi) / (4/3 pi r^3), A the open area inside the
  liner's profile, L the slice's thickness, phi = 0.4 the bed's porosity (Austin, Klimpel &
  Luckie, Process Engineering of Size Reduction: Ball Milling, 1984, the formal bed porosity of a
  ball charge). They start on a lattice at the bottom of the mill, at rest.
- Slice: L = ``--thickness`` ball diameters along the axis (2 by default), between frictionless
  walls.
- Contact: Yade's Hertz-Mindlin with the scene's elastic constants, Young's moduli times
  ``--stiffness-scale`` (0.01 by default: see :data:`DEFAULT_STIFFNESS_SCALE`), restitution e
  (``--restitution``, else :func:`~millimpact.dem.mill.contact.scene_restitution`), Coulomb
  friction mu (``--friction``, else the scene's ``contact.friction``) between balls and with the
  liner. ``--law DIR``: an exported contact law instead (:mod:`~millimpact.dem.mill.law`): its
  moduli times ``--stiffness-scale``, its friction, its e_n per ball-liner contact and its median
  damping between balls.
- Clock: dt = t_c / 25, t_c the shortest Hertz contact time at the largest speed expected, the
  shell's speed plus a fall across the mill, v_max = omega R + sqrt(4 g R); new contacts are looked
  for every t_c / 8 (none ends unseen) and take the ball's velocity from the check before
  (:mod:`~millimpact.dem.mill.log`).
"""

from __future__ import annotations

import math
import random
from dataclasses import dataclass

from ...errors import InputError
from .contact import GRAVITY, critical_omega, critical_rpm, hertz_contact_time, scene_restitution
from .geometry import MillProfile, build_profile
from .law import LAW_SCRIPT, MillLaw, check_law_ball, read_mill_law

#: allowed ranges of the options (speed fraction in (0, 2], fill in [0.05, 0.5])
SPEED_FRACTION_RANGE = (0.0, 2.0)
FILL_RANGE = (0.05, 0.5)
#: the ball bed's porosity in the fill (Austin, Klimpel & Luckie 1984)
BED_POROSITY = 0.4
#: Young's moduli are scaled by this by default: a softer contact lasts scale^(-2/5) times longer
#: (6.3x at 0.01) and the time step with it; the overlap grows as much (a 125 mm ball: 0.9 mm at
#: 10 m/s with the steel's moduli, 6 mm = 9 % of its radius at 0.01; ~ 3 % at 2 m/s). The speeds at
#: first contact (what impacts.csv logs) come from the flight before the contact; soft contacts are
#: mill-DEM practice (Mishra and Rajamani 1992; Cleary 1998 used stiffnesses far below the steel's);
#: 1 gives the steel's moduli
DEFAULT_STIFFNESS_SCALE = 0.01
#: time steps per shortest contact, and impact checks per shortest contact
STEPS_PER_CONTACT = 25
CHECKS_PER_CONTACT = 8
#: a lattice of balls: centres this many radii apart in a layer, layers this many radii apart
LATTICE_SPACING = 2.1
LAYER_SPACING = 1.75


@dataclass(frozen=True)
class MillOptions:
    """The command's options (revolutions and warm-up in revolutions, thickness in ball diameters)."""

    revolutions: float
    balls: int | None = None
    fill: float | None = None
    speed_fraction: float = 0.75
    restitution: float | None = None
    friction: float | None = None
    stiffness_scale: float = DEFAULT_STIFFNESS_SCALE
    warmup: float = 1.0
    thickness: float = 2.0
    seed: int = 0
    law: str | None = None
    law_every: int | None = None


def check_mill_options(opts: MillOptions) -> None:
    """Refuse an option outside its range with one line naming it (InputError)."""

    def finite(name: str, x) -> float:
        if isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(x):
            raise InputError(f"{name} {x!r}: must be a finite number")
        return float(x)

    s = finite("--speed-fraction", opts.speed_fraction)
    if not SPEED_FRACTION_RANGE[0] < s <= SPEED_FRACTION_RANGE[1]:
        raise InputError(
            f"--speed-fraction {s:g}: must lie in (0, 2] (a fraction of the critical speed "
            "n_c = 42.3 / sqrt(D) rpm; mills run at 0.65-0.85)"
        )
    if opts.balls is not None and opts.fill is not None:
        raise InputError(
            "--balls and --fill: give one of them (the number of balls, or the fraction of the "
            "mill's volume the ball bed fills)"
        )
    if opts.fill is not None:
        f = finite("--fill", opts.fill)
        if not FILL_RANGE[0] <= f <= FILL_RANGE[1]:
            raise InputError(
                f"--fill {f:g}: must lie in [0.05, 0.5] (the fraction of the mill's volume the ball bed fills)"
            )
    if opts.balls is not None and (isinstance(opts.balls, bool) or not isinstance(opts.balls, int) or opts.balls < 1):
        raise InputError(f"--balls {opts.balls!r}: must be an integer >= 1")
    r = finite("--revolutions", opts.revolutions)
    if not 0.0 < r <= 1000.0:
        raise InputError(f"--revolutions {r:g}: must lie in (0, 1000]")
    w = finite("--warmup", opts.warmup)
    if not 0.0 <= w <= 100.0:
        raise InputError(f"--warmup {w:g}: must lie in [0, 100] revolutions")
    if opts.restitution is not None:
        e = finite("--restitution", opts.restitution)
        if not 0.0 < e <= 1.0:
            raise InputError(f"--restitution {e:g}: must lie in (0, 1]")
    if opts.law is not None and opts.restitution is not None:
        raise InputError("--law and --restitution: give one of them (the exported law sets each contact's restitution)")
    if opts.law is not None and opts.friction is not None:
        raise InputError("--law and --friction: give one of them (the exported law carries the table's friction)")
    if opts.law_every is not None and (
        isinstance(opts.law_every, bool) or not isinstance(opts.law_every, int) or not 1 <= opts.law_every <= 1000
    ):
        raise InputError(f"--law-every {opts.law_every!r}: must be an integer in [1, 1000] (steps)")
    if opts.friction is not None:
        mu = finite("--friction", opts.friction)
        if not 0.0 <= mu <= 2.0:
            raise InputError(f"--friction {mu:g}: must lie in [0, 2] (Coulomb coefficient)")
    k = finite("--stiffness-scale", opts.stiffness_scale)
    if not 1e-5 <= k <= 1.0:
        raise InputError(f"--stiffness-scale {k:g}: must lie in [1e-05, 1] (the factor on Young's moduli)")
    t = finite("--thickness", opts.thickness)
    if not 1.05 <= t <= 50.0:
        raise InputError(f"--thickness {t:g}: must lie in [1.05, 50] ball diameters")


@dataclass(frozen=True)
class MillSetup:
    """Everything a mill run needs (SI units; angles in rad)."""

    scene_name: str
    profile: MillProfile
    ball_radius: float
    ball_mass: float
    ball_material: tuple[float, float, float]  # Young's modulus (Pa, scaled), Poisson, density
    liner_material: tuple[float, float, float]
    thickness: float
    positions: tuple[tuple[float, float, float], ...]
    speed_fraction: float
    omega: float
    critical_rpm: float
    restitution: float
    restitution_source: str
    friction: float
    stiffness_scale: float
    dt: float
    check_every: int
    power_every: int
    warmup_s: float
    run_s: float
    revolutions: float
    fill: float | None
    contact_time_s: float
    v_max: float
    snapshots_per_revolution: int = 36
    energy_samples: int = 50
    trace_balls: tuple[int, ...] = ()
    trace_every: int = 0
    law: MillLaw | None = None
    law_every: int = 0

    @property
    def n_balls(self) -> int:
        return len(self.positions)

    @property
    def period_s(self) -> float:
        """One revolution (s)."""
        return 2.0 * math.pi / self.omega

    def yade_input(self) -> dict:
        """The JSON of ``mill_slice.py``."""
        E_b, nu_b, rho_b = self.ball_material
        E_l, nu_l, rho_l = self.liner_material
        return {
            "thickness_m": self.thickness,
            "gravity_m_s2": GRAVITY,
            "omega_rad_s": self.omega,
            "ball": {"radius_m": self.ball_radius, "young_Pa": E_b, "poisson": nu_b, "density_kg_m3": rho_b},
            "liner": {"young_Pa": E_l, "poisson": nu_l, "density_kg_m3": rho_l},
            "friction": self.friction,
            "en_yade": self.restitution,
            "segments": [[*s.start, *s.end, s.part] for s in self.profile.segments],
            "ball_positions": [list(p) for p in self.positions],
            "dt_s": self.dt,
            "check_every": self.check_every,
            "power_every": self.power_every,
            "warmup_s": self.warmup_s,
            "run_s": self.run_s,
            "snapshot_every_s": self.period_s / self.snapshots_per_revolution,
            "energy_samples": self.energy_samples,
            "trace_balls": list(self.trace_balls),
            "trace_every": self.trace_every,
            "law": None
            if self.law is None
            else {"file": LAW_SCRIPT, "every": self.law_every, "stiffness_scale": self.stiffness_scale},
        }


def ball_count(profile: MillProfile, ball_radius: float, thickness: float, fill: float) -> int:
    """N = J A L (1 - phi) / (4/3 pi r^3) (see the module docstring), at least 1."""
    v_ball = 4.0 / 3.0 * math.pi * ball_radius**3
    return max(1, round(fill * profile.open_area() * thickness * (1.0 - BED_POROSITY) / v_ball))


def lattice_positions(profile: MillProfile, r: float, thickness: float, n: int, seed: int = 0) -> list:
    """The lowest ``n`` points of a lattice of ball centres inside the lifters' tips (hexagonal
    layers LATTICE_SPACING r apart, layers LAYER_SPACING r apart and shifted to the hollows of the
    layer below, a random shift of 1 % of r each), m; InputError when fewer fit."""
    rng = random.Random(seed)
    a = LATTICE_SPACING * r
    inner = profile.radius - profile.lifter_height - 1.1 * r
    nz = max(1, int((thickness - 2.02 * r) / (LAYER_SPACING * r)) + 1)
    zs = [thickness / 2] if nz == 1 else [1.01 * r + k * (thickness - 2.02 * r) / (nz - 1) for k in range(nz)]
    dy = a * math.sqrt(3.0) / 2.0
    pts = []
    for k, z in enumerate(zs):
        x0, y0 = (0.5 * a, a / (2.0 * math.sqrt(3.0))) if k % 2 else (0.0, 0.0)
        rows = int(inner / dy) + 2
        for j in range(-rows, rows + 1):
            y = y0 + j * dy
            xoff = x0 + (0.5 * a if j % 2 else 0.0)
            cols = int(inner / a) + 2
            for i in range(-cols, cols + 1):
                x = xoff + i * a
                if math.hypot(x, y) < inner:
                    pts.append((y, abs(x), x, z))
    if len(pts) < n:
        raise InputError(
            f"--balls/--fill: {n} balls do not fit the starting lattice of this mill (at most {len(pts)}); give fewer"
        )
    pts.sort()
    jitter = 0.01 * r
    return [(x + rng.uniform(-jitter, jitter), y + rng.uniform(-jitter, jitter), z) for y, _, x, z in pts[:n]]


def plan_mill(scene, opts: MillOptions, restitution_source: str | None = None) -> MillSetup:
    """The :class:`MillSetup` of ``scene`` (which must have a liner) under ``opts``."""
    check_mill_options(opts)
    if scene.liner is None:
        raise InputError(
            f"scene '{scene.name}': has no liner; a mill run builds the mill from the scene's [liner] "
            "(e.g. the built-in scenes liner-segment, liner-panel)"
        )
    ball, liner = scene.ball, scene.liner
    r = ball.radius
    profile = build_profile(liner, r)
    R = profile.radius
    thickness = opts.thickness * 2.0 * r
    if opts.balls is not None:
        n = opts.balls
    else:
        n = ball_count(profile, r, thickness, opts.fill if opts.fill is not None else 0.1)
    positions = lattice_positions(profile, r, thickness, n, opts.seed)
    omega = opts.speed_fraction * critical_omega(R)
    k = float(opts.stiffness_scale)
    bm, lm = ball.material, liner.material
    law = None
    if opts.law is not None:
        law = read_mill_law(opts.law)
        check_law_ball(law, r)
        lo, hi = law.restitution_range
        e, src = (
            0.5 * (lo + hi),
            (
                f"the exported law {law.folder}: e_n {lo:.3g}-{hi:.3g} per ball-liner contact "
                f"from its impact speed ({min(law.speeds):g}-{max(law.speeds):g} m/s) and "
                "angle, the table's median damping between balls"
            ),
        )
        mu = law.friction
        E_b = E_l = law.young * k
        nu_b = nu_l = law.poisson
        # the runtime's k_no = (4/3) E* r^(1/2): a flat liner, R* = r
        e_bl, r_bl = law.e_star_max * k, r
    else:
        if opts.restitution is not None:
            e, src = float(opts.restitution), restitution_source or "--restitution"
        else:
            e, src = scene_restitution(scene, omega * R)
        mu = float(opts.friction) if opts.friction is not None else float(scene.contact.friction)
        E_b, E_l = bm.youngs_modulus * k, lm.youngs_modulus * k
        nu_b, nu_l = bm.poisson, lm.poisson
        e_bl = 1.0 / ((1.0 - nu_b**2) / E_b + (1.0 - nu_l**2) / E_l)
        # Yade's facet contact takes the facet as a sphere of radius 2 r: R* = 2 r / 3
        r_bl = 2.0 * r / 3.0
    e_bb = 1.0 / (2.0 * (1.0 - nu_b**2) / E_b)
    v_max = omega * R + math.sqrt(4.0 * GRAVITY * R)
    m = ball.mass
    t_c = min(hertz_contact_time(0.5 * m, 0.5 * r, e_bb, v_max), hertz_contact_time(m, r_bl, e_bl, v_max))
    dt = t_c / STEPS_PER_CONTACT
    check_every = max(1, round(STEPS_PER_CONTACT / CHECKS_PER_CONTACT))
    period = 2.0 * math.pi / omega
    return MillSetup(
        scene_name=scene.name,
        profile=profile,
        ball_radius=r,
        ball_mass=m,
        ball_material=(E_b, nu_b, bm.density),
        liner_material=(E_l, nu_l, lm.density),
        thickness=thickness,
        positions=tuple(positions),
        speed_fraction=opts.speed_fraction,
        omega=omega,
        critical_rpm=critical_rpm(2.0 * R),
        restitution=e,
        restitution_source=src,
        friction=mu,
        stiffness_scale=k,
        dt=dt,
        check_every=check_every,
        power_every=check_every,
        warmup_s=opts.warmup * period,
        run_s=opts.revolutions * period,
        revolutions=opts.revolutions,
        fill=opts.fill if opts.balls is None else None,
        contact_time_s=t_c,
        v_max=v_max,
        law=law,
        law_every=0 if law is None else (opts.law_every or check_every),
    )
