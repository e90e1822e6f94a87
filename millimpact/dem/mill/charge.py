"""A SAG charge: balls and rock in the mill's slice (``millimpact mill --charge sag``).

A SAG mill's charge is mostly rock: the whole charge fills J = 25-35 % of the mill's volume, the
balls J_B = 8-15 %, at 70-80 % of the critical speed. Mill DEM models the rock as spheres with
rolling resistance standing for their shape, leaves out the fines (part of the slurry) and uses
soft contacts (B. K. Mishra, Int. J. Miner. Process. 71 (2003) 73-93; P. W. Cleary, Minerals Eng.
14 (2001) 1295-1319). Here:

- Fills: J (``--fill``, default :data:`DEFAULT_TOTAL_FILL`) and J_B (``--ball-fill``, default
  :data:`DEFAULT_BALL_FILL`) count the bed with porosity 0.4, as the balls-only charge does
  (:mod:`~millimpact.dem.mill.setup`): the balls' volume is J_B A L (1 - 0.4), the rock's
  (J - J_B) A L (1 - 0.4), A the open area inside the liner, L the slice's thickness.
- Rock sizes: the Gaudin-Schuhmann distribution by mass between the cut-off c and the top size T,
  P(d) = (d^m - c^m) / (T^m - c^m), slope m = :data:`SCHUHMANN_SLOPE` (R. Schuhmann, AIME Tech.
  Pub. 1189 (1940); the form of King, Modeling and Simulation of Mineral Processing Systems,
  2001, ch. 2; the slope is this package's choice for a broad feed). By number the density is
  proportional to d^(m - 4); diameters are drawn from it (inverse transform) until the rock's
  volume is reached. Rock finer than c belongs to the slurry: its volume is given to the modelled
  rock (J and the charge's mass are kept), and the slurry itself is left out: no fluid drag or
  lubrication in the bed, so the bed dissipates less and the charge's toe lies a little lower
  than with slurry (the docs show it).
- Rock: granite's density 2700 kg/m^3, bulk modulus 50 GPa and shear modulus 24 GPa (so E =
  9 K G / (3 K + G) = 62 GPa, nu = 0.29; R. E. Goodman, Introduction to Rock Mechanics, 2nd ed.,
  1989, tables 3 and 6 give granite 50-70 GPa, 0.2-0.3), its Young's modulus times the run's
  ``--stiffness-scale``.
- Contacts with rock (rock-rock, rock-ball, rock-liner): restitution 0.3 (Cleary's mill DEM),
  Coulomb friction 0.6 (Byerlee's rule for rock surfaces: J. Byerlee, Pure Appl. Geophys. 116
  (1978) 615-626), rolling resistance mu_r 0.2, each an option. Rolling resistance is the
  elastic-plastic spring of J. Ai, J.-F. Chen, J. M. Rotter and J. Y. Ooi, Powder Technol. 206
  (2011) 269-282 ("type C", the model DEM vendors recommend for angular particles): a bending
  moment M grows with the relative rolling rotation at stiffness k_r up to mu_r R F_n (Yade's
  ``eta`` and ``krot``), R the mean of the two radii between particles (Yade's R_mean) and the
  rock's own radius on the liner (the script sets it: Yade would take the facet as a sphere of
  twice the rock's radius), with k_r = 2.25 mu_r^2 R^2 k_n (their eq. 14) for two mean rocks at the
  peak of a 1 m/s impact. A rock rolling on the liner then stops after 7 v0^2 / (10 mu_r g).
  mu_r 0.2 is the middle of the 0.1-0.3 that mill DEM gives spheres standing for angular rock.
  Balls and the liner keep the scene's contact (no rolling resistance).
- Slurry (``--slurry-density``, default 0: dry): the bed's voids full of slurry (the C-model's wet
  charge, Morrell 1996) carried as mass, each particle's density raised by E / (1 - E) rho_p
  (E = 0.4); no drag or lubrication: a check of power and shape against wet mills. The impacts'
  energies stay the solid particle's.
- Starting positions: random, largest first, without overlaps, in the lowest part of the mill
  that holds them at a third of its volume (:func:`place_particles`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ...errors import InputError
from .geometry import MillProfile

#: the plan's SAG charge: total fill, ball fill (fractions of the mill's volume)
DEFAULT_TOTAL_FILL = 0.28
DEFAULT_BALL_FILL = 0.12
#: rock sizes (m): top size and the cut-off below which rock is slurry
DEFAULT_ROCK_TOP_SIZE = 0.20
DEFAULT_ROCK_CUTOFF = 0.10
#: Gaudin-Schuhmann slope of the rock's mass distribution
SCHUHMANN_SLOPE = 0.5
#: granite (module docstring)
ROCK_DENSITY = 2700.0
ROCK_YOUNG = 62.0e9
ROCK_POISSON = 0.29
#: contacts with rock (module docstring)
DEFAULT_ROCK_RESTITUTION = 0.3
DEFAULT_ROCK_FRICTION = 0.6
DEFAULT_ROLLING_RESISTANCE = 0.2
#: a slurry's density (kg/m^3): water to a dense ore slurry
SLURRY_DENSITY = (1000.0, 2500.0)
#: the starting region holds the particles at this fraction of its volume
START_PACKING = 1.0 / 3.0
#: the charges the command knows
CHARGES = ("balls", "sag")


@dataclass(frozen=True)
class RockSpec:
    """The rock of a SAG charge (SI units; the module docstring gives the sources)."""

    top_size: float = DEFAULT_ROCK_TOP_SIZE
    cutoff: float = DEFAULT_ROCK_CUTOFF
    slope: float = SCHUHMANN_SLOPE
    density: float = ROCK_DENSITY
    young: float = ROCK_YOUNG
    poisson: float = ROCK_POISSON
    restitution: float = DEFAULT_ROCK_RESTITUTION
    friction: float = DEFAULT_ROCK_FRICTION
    rolling_resistance: float = DEFAULT_ROLLING_RESISTANCE
    slurry_density: float = 0.0  # kg/m^3 of the slurry in the bed's voids, carried as mass; 0: dry

    def summary(self) -> dict:
        """summary.json's record of the rock and its contacts, with the sources."""
        return {
            "size_distribution": "Gaudin-Schuhmann by mass between cut-off and top size",
            "top_size_m": self.top_size,
            "cutoff_m": self.cutoff,
            "schuhmann_slope": self.slope,
            "density_kg_m3": self.density,
            "young_Pa": self.young,
            "poisson": self.poisson,
            "material_source": "granite, K 50 GPa, G 24 GPa (Goodman, Introduction to Rock Mechanics, 1989)",
            "restitution": self.restitution,
            "friction": self.friction,
            "rolling_resistance": self.rolling_resistance,
            "rolling_model": "elastic-plastic spring, M <= mu_r R F_n, R the mean radius between particles and the "
            "rock's own on the liner (Ai et al., Powder Technol. 206 (2011))",
            "contact_sources": "restitution 0.3: Cleary's mill DEM; friction 0.6: Byerlee (1978); mu_r: the "
            "0.1-0.3 of mill DEM for spheres standing for angular rock",
            "fines": "rock below the cut-off is slurry: its volume is given to the modelled rock; the slurry "
            "itself (drag, lubrication) is left out",
            "slurry_density_kg_m3": self.slurry_density,
            "slurry_is": "the bed's voids full of slurry, carried as mass on the particles (no drag, no lubrication)"
            if self.slurry_density
            else "none: a dry charge",
        }


def check_sag_options(total: float, balls: float, rock: RockSpec, mill_radius: float, thickness: float) -> None:
    """Refuse fills that do not add up and rock sizes out of order or too large (InputError, one
    line naming the option and its allowed range)."""
    if not 0.05 <= total <= 0.5:
        raise InputError(
            f"--fill {total:g}: must lie in [0.05, 0.5] (the whole charge's fraction of the mill's volume)"
        )
    if not 0.0 < balls <= total:
        raise InputError(
            f"--ball-fill {balls:g}: must lie in (0, --fill = {total:g}] (the balls are part of the charge)"
        )
    if not 0.0 < rock.cutoff < rock.top_size:
        raise InputError(
            f"--rock-cutoff {rock.cutoff:g} m: must lie in (0, --rock-top-size = {rock.top_size:g} m) "
            "(rock finer than the cut-off is slurry)"
        )
    if rock.top_size >= 0.5 * mill_radius:
        raise InputError(
            f"--rock-top-size {rock.top_size:g} m: must be below half the mill's radius ({0.5 * mill_radius:g} m)"
        )
    if rock.top_size * 1.05 > thickness:
        raise InputError(
            f"--rock-top-size {rock.top_size:g} m: must be at most the slice's thickness / 1.05 "
            f"({thickness / 1.05:.4g} m); give a smaller top size or a larger --thickness"
        )
    for name, x, lo, hi in (
        ("--rock-restitution", rock.restitution, 0.0, 1.0),
        ("--rock-friction", rock.friction, 0.0, 2.0),
        ("--rolling-resistance", rock.rolling_resistance, 0.0, 1.0),
    ):
        if not lo <= x <= hi or (name == "--rock-restitution" and x == 0.0):
            low = "(0" if name == "--rock-restitution" else "[0"
            raise InputError(f"{name} {x:g}: must lie in {low}, {hi:g}]")
    if rock.slurry_density != 0.0 and not SLURRY_DENSITY[0] <= rock.slurry_density <= SLURRY_DENSITY[1]:
        raise InputError(
            f"--slurry-density {rock.slurry_density:g} kg/m^3: must be 0 (a dry charge) or lie in "
            f"[{SLURRY_DENSITY[0]:g}, {SLURRY_DENSITY[1]:g}] (water to a dense slurry)"
        )


def rock_diameters(volume: float, rock: RockSpec, rng: np.random.Generator) -> np.ndarray:
    """Rock diameters (m) drawn from the number density ~ d^(m - 4) between cut-off and top size
    until their volume reaches ``volume`` (m^3); the last is kept when that lands nearer it."""
    k = rock.slope - 4.0 + 1.0  # the exponent of the number CDF, d^k
    lo, hi = rock.cutoff**k, rock.top_size**k
    out: list[float] = []
    total = 0.0
    while total < volume:
        d = float((lo + rng.random() * (hi - lo)) ** (1.0 / k))
        v = math.pi / 6.0 * d**3
        if total + v > volume and (total + v - volume) > (volume - total):
            break
        out.append(d)
        total += v
    return np.array(out)


def _segment_area(a: float, y: float) -> float:
    """Area of the part of a disc of radius a below the line at height y (m^2)."""
    y = min(max(y, -a), a)
    return a * a * math.acos(-y / a) + y * math.sqrt(a * a - y * y) if y > -a else 0.0


def place_particles(
    profile: MillProfile, radii: np.ndarray, thickness: float, rng: np.random.Generator, tries: int = 400
) -> np.ndarray:
    """Centres (n x 3, m) of particles of ``radii`` (placed largest first; returned in the input's
    order): random points inside the lifters' tips, in the lowest part of the mill whose volume is
    the particles' over START_PACKING (raised by a tenth of the radius when a particle finds no
    place in ``tries`` draws), none overlapping another or the slice's ends."""
    a = profile.radius - profile.lifter_height
    need = float(np.sum(4.0 / 3.0 * math.pi * radii**3)) / START_PACKING / thickness
    lo_y, hi_y = -a, a
    for _ in range(60):
        mid = 0.5 * (lo_y + hi_y)
        lo_y, hi_y = (mid, hi_y) if _segment_area(a, mid) < need else (lo_y, mid)
    top = hi_y
    order = np.argsort(-radii, kind="stable")
    centres = np.zeros((radii.size, 3))
    placed = np.zeros((radii.size, 3))
    placed_r = np.zeros(radii.size)
    n = 0
    for idx in order:
        r = radii[idx]
        while True:
            inner = a - 1.05 * r
            ys = rng.uniform(-inner, min(top - r, inner), tries)
            half = np.sqrt(np.maximum(inner**2 - ys**2, 0.0))
            xs = rng.uniform(-1.0, 1.0, tries) * half
            zs = rng.uniform(1.01 * r, thickness - 1.01 * r, tries)
            ok = None
            for x, y, z in zip(xs, ys, zs):
                if n == 0 or np.all(np.sum((placed[:n] - (x, y, z)) ** 2, axis=1) > (1.01 * (placed_r[:n] + r)) ** 2):
                    ok = (x, y, z)
                    break
            if ok is not None:
                break
            if top >= a:
                raise InputError(
                    f"--fill: {radii.size} particles do not fit the mill's slice at its start; give a smaller fill"
                )
            top = min(a, top + 0.1 * a)
        centres[idx] = placed[n] = ok
        placed_r[n] = r
        n += 1
    return centres
