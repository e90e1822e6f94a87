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

import numpy as np

from ...errors import InputError
from .charge import (
    CHARGES,
    DEFAULT_BALL_FILL,
    DEFAULT_TOTAL_FILL,
    RockSpec,
    check_sag_options,
    place_particles,
    rock_diameters,
)
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
#: the rock's rolling moments' work is sampled every this many checks (one in ten: a sample costs a
#: pass over every contact in Yade's Python, which at every check doubled the SAG slice's CPU time;
#: a sample at fixed steps is unbiased, and the bed's rolling contacts last many samples)
ROLLING_EVERY_CHECKS = 10
#: the contacts between particles are visited every this many checks (their new ones counted,
#: ball-ball contacts freed of rolling resistance): a pass over every contact in Yade's Python is
#: most of a check's cost; 2 checks (6 steps) stay well inside the shortest contact (25 steps)
PAIR_EVERY_CHECKS = 2
#: abrasion.csv's bins of surface position (m): 10 mm, a twentieth of a lifter's height
ABRASION_BIN = 0.01
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
    charge: str = "balls"
    ball_fill: float | None = None
    rock_top_size: float | None = None
    rock_cutoff: float | None = None
    rock_restitution: float | None = None
    rock_friction: float | None = None
    rolling_resistance: float | None = None
    slurry_density: float | None = None

    @property
    def rock_options(self) -> dict[str, float]:
        """The rock options given (option name -> value)."""
        names = (
            "ball_fill",
            "rock_top_size",
            "rock_cutoff",
            "rock_restitution",
            "rock_friction",
            "rolling_resistance",
            "slurry_density",
        )
        return {"--" + n.replace("_", "-"): getattr(self, n) for n in names if getattr(self, n) is not None}

    def rock(self) -> RockSpec:
        """The rock of a SAG charge: the options given, the defaults of :mod:`.charge` otherwise."""
        given = {
            "top_size": self.rock_top_size,
            "cutoff": self.rock_cutoff,
            "restitution": self.rock_restitution,
            "friction": self.rock_friction,
            "rolling_resistance": self.rolling_resistance,
            "slurry_density": self.slurry_density,
        }
        return RockSpec(**{k: float(v) for k, v in given.items() if v is not None})


def _check_charge_options(opts: MillOptions) -> None:
    """The charge's options: a known charge; rock options only with a SAG charge; --balls only
    without one; every rock option a finite number."""
    if opts.charge not in CHARGES:
        raise InputError(f"--charge {opts.charge!r}: must be one of {', '.join(CHARGES)}")
    for name, x in opts.rock_options.items():
        if isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(x):
            raise InputError(f"{name} {x!r}: must be a finite number")
        if opts.charge != "sag":
            raise InputError(f"{name}: a rock option; give --charge sag (a charge of balls and rock)")
    if opts.charge == "sag" and opts.law is not None:
        raise InputError(
            "--law with --charge sag: an exported law sets the balls' contacts with the liner only; "
            "a SAG charge runs with the scene's contacts and the rock's (give one of them)"
        )
    if opts.charge == "sag" and opts.balls is not None:
        raise InputError("--balls: with --charge sag give --fill and --ball-fill (fractions of the mill's volume)")


def check_mill_options(opts: MillOptions) -> None:
    """Refuse an option outside its range with one line naming it (InputError)."""

    _check_charge_options(opts)

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
    rock: RockSpec | None = None
    rock_radii: tuple[float, ...] = ()  # the rock's radii (m); its centres follow the balls' in positions
    rock_material: tuple[float, float, float] = (0.0, 0.0, 0.0)  # Young's modulus (Pa, scaled), Poisson, density
    rolling_stiffness: float = 0.0  # k_r (N m / rad) of the rock's rolling resistance
    ball_fill: float | None = None
    abrasion_bin_m: float = ABRASION_BIN

    @property
    def n_particles(self) -> int:
        return len(self.positions)

    @property
    def n_balls(self) -> int:
        return len(self.positions) - len(self.rock_radii)

    @property
    def n_rocks(self) -> int:
        return len(self.rock_radii)

    def particle_radius(self, k: int) -> float:
        """Radius (m) of particle k (balls first, then rock)."""
        return self.ball_radius if k < self.n_balls else self.rock_radii[k - self.n_balls]

    def particle_mass(self, k: int) -> float:
        """Mass (kg) of particle k."""
        if k < self.n_balls:
            return self.ball_mass
        return 4.0 / 3.0 * math.pi * self.rock_radii[k - self.n_balls] ** 3 * self.rock_material[2]

    def _rock_input(self) -> dict | None:
        if self.rock is None:
            return None
        E, nu, rho = self.rock_material
        rho += self.slurry_mass_density
        return {
            "positions": [list(p) for p in self.positions[self.n_balls :]],
            "radii": list(self.rock_radii),
            "young_Pa": E,
            "poisson": nu,
            "density_kg_m3": rho,
            "en_yade": self.rock.restitution,
            "friction": self.rock.friction,
            "eta": self.rock.rolling_resistance,
            "krot": self.rolling_stiffness,
        }

    @property
    def period_s(self) -> float:
        """One revolution (s)."""
        return 2.0 * math.pi / self.omega

    @property
    def slurry_mass_density(self) -> float:
        """The slurry carried with each particle per unit of its volume, E / (1 - E) rho_p (kg/m^3):
        the bed's voids full of slurry (:mod:`.charge`); 0 for a dry charge."""
        rho_p = self.rock.slurry_density if self.rock is not None else 0.0
        return BED_POROSITY / (1.0 - BED_POROSITY) * rho_p

    def yade_input(self) -> dict:
        """The JSON of ``mill_slice.py``."""
        E_b, nu_b, rho_b = self.ball_material
        rho_b += self.slurry_mass_density
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
            "ball_positions": [list(p) for p in self.positions[: self.n_balls]],
            "rock": self._rock_input(),
            "v_max_m_s": self.v_max,
            "arc": {
                "lifter_height_m": self.profile.lifter_height,
                "radius_m": self.profile.radius,
                "bin_m": self.abrasion_bin_m,
                "segment_s0_m": self.profile.unit_starts()[0],
            },
            "dt_s": self.dt,
            "check_every": self.check_every,
            "power_every": self.power_every,
            "rolling_every": ROLLING_EVERY_CHECKS,
            "pair_every": PAIR_EVERY_CHECKS,
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


def plan_mill(
    scene, opts: MillOptions, restitution_source: str | None = None, profile: MillProfile | None = None
) -> MillSetup:
    """The :class:`MillSetup` of ``scene`` (which must have a liner) under ``opts``; ``profile``:
    a worn liner's instead of the scene's new one."""
    check_mill_options(opts)
    if scene.liner is None:
        raise InputError(
            f"scene '{scene.name}': has no liner; a mill run builds the mill from the scene's [liner] "
            "(e.g. the built-in scenes liner-segment, liner-panel)"
        )
    ball, liner = scene.ball, scene.liner
    r = ball.radius
    profile = build_profile(liner, r) if profile is None else profile
    R = profile.radius
    thickness = opts.thickness * 2.0 * r
    sag = _sag_charge(profile, r, thickness, opts) if opts.charge == "sag" else None
    positions: tuple[tuple[float, float, float], ...] | list
    if sag is not None:
        positions = sag.positions
    elif opts.balls is not None:
        positions = lattice_positions(profile, r, thickness, opts.balls, opts.seed)
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
    rock_material, krot = (0.0, 0.0, 0.0), 0.0
    if sag is not None:
        rock_material = (sag.rock.young * k, sag.rock.poisson, sag.rock.density)
        t_c = min(t_c, _rock_contact_time(sag, rock_material, (E_b, nu_b, bm.density), (E_l, nu_l), r, v_max))
        krot = _rolling_stiffness(sag, rock_material)
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
        fill=(sag.total_fill if sag else opts.fill) if opts.balls is None else None,
        ball_fill=sag.ball_fill if sag else None,
        rock=sag.rock if sag else None,
        rock_radii=sag.rock_radii if sag else (),
        rock_material=rock_material,
        rolling_stiffness=krot,
        contact_time_s=t_c,
        v_max=v_max,
        law=law,
        law_every=0 if law is None else (opts.law_every or check_every),
    )


@dataclass(frozen=True)
class _SagCharge:
    total_fill: float
    ball_fill: float
    rock: RockSpec
    rock_radii: tuple[float, ...]
    positions: tuple[tuple[float, float, float], ...]  # balls first, then rock


def _sag_charge(profile: MillProfile, r: float, thickness: float, opts: MillOptions) -> _SagCharge:
    """Balls and rock of a SAG charge (:mod:`.charge`): counts from the fills, rock sizes drawn,
    all placed at random in the bottom of the mill."""
    total = float(opts.fill) if opts.fill is not None else DEFAULT_TOTAL_FILL
    jb = float(opts.ball_fill) if opts.ball_fill is not None else DEFAULT_BALL_FILL
    rock = opts.rock()
    check_sag_options(total, jb, rock, profile.radius, thickness)
    n_balls = ball_count(profile, r, thickness, jb)
    rng = np.random.default_rng(opts.seed)
    v_rock = (total - jb) * profile.open_area() * thickness * (1.0 - BED_POROSITY)
    rock_r = 0.5 * rock_diameters(v_rock, rock, rng)
    radii = np.concatenate([np.full(n_balls, r), rock_r])
    centres = place_particles(profile, radii, thickness, rng)
    return _SagCharge(
        total_fill=total,
        ball_fill=jb,
        rock=rock,
        rock_radii=tuple(float(x) for x in rock_r),
        positions=tuple((float(x), float(y), float(z)) for x, y, z in centres),
    )


def _rock_contact_time(sag: _SagCharge, rock_mat, ball_mat, liner_mat, r_ball: float, v_max: float) -> float:
    """The shortest Hertz contact time (s) of the smallest rock at v_max against rock, a ball and
    the liner (Yade's facet: a sphere of radius 2 r, R* = 2 r / 3)."""
    E_r, nu_r, rho_r = rock_mat
    E_b, nu_b, rho_b = ball_mat
    E_l, nu_l = liner_mat
    r = min(sag.rock_radii) if sag.rock_radii else 0.5 * sag.rock.cutoff
    m = 4.0 / 3.0 * math.pi * r**3 * rho_r
    m_b = 4.0 / 3.0 * math.pi * r_ball**3 * rho_b

    def e_star(E1, n1, E2, n2):
        return 1.0 / ((1.0 - n1**2) / E1 + (1.0 - n2**2) / E2)

    return min(
        hertz_contact_time(0.5 * m, 0.5 * r, e_star(E_r, nu_r, E_r, nu_r), v_max),
        hertz_contact_time(m * m_b / (m + m_b), r * r_ball / (r + r_ball), e_star(E_r, nu_r, E_b, nu_b), v_max),
        hertz_contact_time(m, 2.0 * r / 3.0, e_star(E_r, nu_r, E_l, nu_l), v_max),
    )


def _rolling_stiffness(sag: _SagCharge, rock_mat) -> float:
    """k_r = 2.25 mu_r^2 R^2 k_n (Ai et al. 2011, eq. 14; :mod:`.charge`) for two rocks of the mean
    radius R at the peak of a 1 m/s impact: R = R_mean / 2 their effective radius, k_n = 3/2 k_no
    delta^(1/2) at delta = (15 m* v^2 / (16 E* sqrt(R)))^(2/5)."""
    E_r, nu_r, rho_r = rock_mat
    mu_r = sag.rock.rolling_resistance
    if mu_r == 0.0 or not sag.rock_radii:
        return 0.0
    r_mean = float(np.mean(sag.rock_radii))
    R = 0.5 * r_mean
    m_star = 0.5 * 4.0 / 3.0 * math.pi * r_mean**3 * rho_r
    e_star = E_r / (2.0 * (1.0 - nu_r**2))
    delta = (15.0 * m_star * 1.0**2 / (16.0 * e_star * math.sqrt(R))) ** 0.4
    k_n = 1.5 * (4.0 / 3.0) * e_star * math.sqrt(R) * math.sqrt(delta)
    return 2.25 * mu_r**2 * R**2 * k_n
