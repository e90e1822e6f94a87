"""What mill engineers check a tumbling mill against: power draw and charge shape, closed forms.

SI in and out: lengths m, densities kg/m^3, power W, angles rad; the speed is the fraction of
critical speed phi = N / N_c, N_c = sqrt(2 g / D) / (2 pi) rev/s (42.3 / sqrt(D) rpm), D the
diameter inside the liners. The fills J (total) and J_B (balls) are fractions of the mill's volume,
bed voids included. (The models were written for t/m^3 and kW; their constants are rescaled here.)

Angles (Morrell's convention): theta is measured at the mill's axis from the horizontal on the side
where the charge rises, counter-clockwise with the mill turning counter-clockwise: the shoulder
theta_S lies above that horizontal (0 < theta_S < pi/2), the toe theta_T below the opposite one
(pi < theta_T < 3 pi/2), bottom dead centre is 3 pi/2. :func:`angle_from_bottom_deg` converts to the
angle the mill runs report: degrees from the vertical below the axis, positive in the direction of
rotation (shoulder ~ +135, toe ~ -40).

Sources (the 1993 thesis and the 1996 papers themselves were not at hand; what was read is named):

- S. Morrell, "Power draw of wet tumbling mills and its relationship to charge dynamics", Trans.
  IMM C105 (1996) 43-53 (Part 1, the continuum "C-model") and 54-62 (Part 2, the toe and shoulder
  correlations). Read: the Met Dynamics wiki ("Tumbling Mill (Power, Morrell Continuum)": the
  model's terms, symbols and k = 1.26) and two public reimplementations, one in Python with
  Morrell's equation numbers, one in TypeScript; the power integrals are re-derived here.
- A. S. Erdem, S. L. Ergun, A. H. Benzer, Physicochem. Probl. Miner. Process. 38 (2004) 221-230:
  the C-model applied to a two-chamber cement mill (its first page read; its no-load, net and
  gross powers as quoted in the TypeScript reimplementation's tests).
- L. G. Austin, "A mill power equation for SAG mills", Miner. Metall. Process. 7 (1990) 57-62.
  Read: the SAGMILLING.COM wiki ("Austin SAG model", A. Doll) and the XXXI IMPC 2024 proceedings
  (p. 3685), which agree on K = 10.6, A = 0.937, eps_B = 0.3, w_C = 0.8.

Where the sources disagree or only one was read, the function's docstring says so.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

#: gravity, m/s^2
G = 9.81
#: Morrell's net-to-gross factor k: gross = no-load + k net (Met Dynamics wiki; Erdem et al. 2004)
MORRELL_GROSS_FACTOR = 1.26
#: voids of a bed of spheres, the C-model's E: random loose packing (solid fraction ~0.60,
#: G. D. Scott, Nature 188 (1960) 908) and the value the C-model reimplementations use
BED_POROSITY = 0.4
#: Austin's constants (wiki and IMPC 2024): K (kW per m^3.5 per t/m^3), A, bed porosity, solids mass fraction
AUSTIN_K, AUSTIN_A, AUSTIN_POROSITY, AUSTIN_SOLIDS = 10.6, 0.937, 0.3, 0.8


def critical_speed(diameter: float) -> float:
    """N_c (rev/s) of a mill of inside diameter D (m): a particle at the shell just centrifuges."""
    return math.sqrt(2.0 * G / diameter) / (2.0 * math.pi)


def angle_from_bottom_deg(theta: float) -> float:
    """Morrell's angle theta (rad, module docstring) as degrees from the vertical below the axis,
    positive in the direction of rotation, in (-180, 180]."""
    psi = math.degrees(theta - 1.5 * math.pi) % 360.0
    return psi - 360.0 if psi > 180.0 else psi


def centrifuging_speed(fill: float) -> float:
    """phi_c = 0.35 (3.364 - J): Morrell's fraction of critical speed at which centrifuging is fully
    established (Morrell 1996 Part 2; above 1 for J < 0.507: a charge needs more than the single
    particle's critical speed to centrifuge whole)."""
    return 0.35 * (3.364 - fill)


@dataclass(frozen=True)
class ChargeShape:
    """Toe and shoulder of the charge at the shell (rad, Morrell's convention) and phi_c."""

    toe: float  #: theta_T, rad
    shoulder: float  #: theta_S, rad
    centrifuging_speed: float  #: phi_c, fraction of critical speed

    @property
    def toe_deg(self) -> float:
        """The toe in degrees from the vertical below the axis, positive with the rotation."""
        return angle_from_bottom_deg(self.toe)

    @property
    def shoulder_deg(self) -> float:
        """The shoulder in degrees from the vertical below the axis, positive with the rotation."""
        return angle_from_bottom_deg(self.shoulder)


def charge_shape(speed: float, fill: float) -> ChargeShape:
    """Morrell's empirical toe and shoulder (Morrell 1996 Part 2) at fraction of critical speed phi
    and fill J (both restatements read):

        theta_T = 2.5307 (1.2796 - J) (1 - exp(-19.42 (phi_c - phi))) + pi/2
        theta_S = pi/2 - (theta_T - pi/2) [(0.3386 + 0.1041 phi) + (1.54 - 2.5673 phi) J]

    As phi rises to phi_c both ends climb to the top (theta_T = theta_S = pi/2, the whole charge
    on the shell); at and above phi_c that limit is returned. For J > 0.39 the bracket turns
    negative before phi_c and the shoulder passes the top (theta_S > pi/2): outside the mills'
    range (phi <= 0.9 avoids it up to J = 0.45). The restatements read agree on the
    constants; the TypeScript one puts phi_c for phi in theta_S, the Python one (with Morrell's
    equation numbers) has phi, used here. Neither gives the clamp at phi_c: it is the correlation's
    own limit (past phi_c its exponential would put the toe above the shoulder)."""
    phi_c = centrifuging_speed(fill)
    if speed >= phi_c:
        return ChargeShape(0.5 * math.pi, 0.5 * math.pi, phi_c)
    toe = 2.5307 * (1.2796 - fill) * (1.0 - math.exp(-19.42 * (phi_c - speed))) + 0.5 * math.pi
    lift = (0.3386 + 0.1041 * speed) + (1.54 - 2.5673 * speed) * fill
    return ChargeShape(toe, 0.5 * math.pi - (toe - 0.5 * math.pi) * lift, phi_c)


def charge_density(
    fill: float,
    ball_fill: float,
    ore_density: float,
    ball_density: float,
    slurry_density: float,
    slurry_filling: float = 1.0,
    porosity: float = BED_POROSITY,
) -> float:
    """rho_c (kg/m^3), the C-model's charge density: rock and balls filling 1 - E of the bed, a
    fraction U (slurry_filling) of the voids E filled with slurry of density rho_p:

        rho_c = [(J - J_B)(1 - E) rho_o + J_B (1 - E) rho_b + J E U rho_p] / J

    The Python reimplementation writes it with the slurry's solids volume fraction S, rho_p =
    S rho_o + (1 - S) 1000: [J rho_o (1 - E + E U S) + J_B (rho_b - rho_o)(1 - E) + J E U (1 - S)
    1000] / J, the same."""
    solids = (fill - ball_fill) * (1.0 - porosity) * ore_density + ball_fill * (1.0 - porosity) * ball_density
    return (solids + fill * porosity * slurry_filling * slurry_density) / fill


@dataclass(frozen=True)
class MorrellPower:
    """Morrell's C-model net power (W) and the geometry behind it."""

    cylinder: float  #: net power of the cylindrical section (potential + kinetic), W
    potential: float  #: its lifting part, W
    kinetic: float  #: its kinetic part, W
    cone: float  #: of the two cone ends (0 without cones), W
    inner_radius: float  #: r_i, the charge's inner surface, m
    z: float  #: (1 - J)^0.4532: the charge's speed is zero at radius z r_i
    shape: ChargeShape

    @property
    def net(self) -> float:
        """Net power of the charge, W: cylinder + cones."""
        return self.cylinder + self.cone


def morrell_net_power(
    diameter: float,
    length: float,
    speed: float,
    fill: float,
    charge_density: float,
    slurry_density: float = 0.0,
    slurry_toe: float | None = None,
    cone_length: float = 0.0,
    trunnion_diameter: float = 0.0,
) -> MorrellPower:
    """Morrell's C-model (Morrell 1996 Part 1): the rate at which the shell lifts the charge from
    toe to shoulder and gives it kinetic energy, the charge's tangential speed falling linearly
    from the shell's V_m = 2 pi N_m r_m to zero at radius z r_i (N_m = phi N_c, rev/s)::

        P_cyl = pi g L N_m r_m / (3 (r_m - z r_i)) [2 r_m^3 - 3 z r_m^2 r_i + r_i^3 (3 z - 2)]
                x [rho_c (sin theta_S - sin theta_T) + rho_p (sin theta_T - sin theta_TO)]
              + L rho_c (pi N_m r_m / (r_m - z r_i))^3 [(r_m - z r_i)^4 - r_i^4 (z - 1)^4]

    z = (1 - J)^0.4532; r_i = r_m [1 - 2 pi beta J / (2 pi + theta_S - theta_T)]^(1/2), beta =
    t_c / (t_f + t_c) the share of its cycle a particle spends in the charge rather than in flight:
    t_c = (2 pi + theta_S - theta_T) / (2 pi N_m / 2), t_f = [2 r_bar (sin theta_S - sin theta_T)
    / g]^(1/2), r_bar = r_m / 2 [1 + (1 - 2 pi J / (2 pi + theta_S - theta_T))^(1/2)].
    beta's three lines are the Python reimplementation's only (one source: the wiki's variable
    list names r_i without its formula; the TypeScript one drops beta, i.e. beta = 1). The two
    integrals are reproduced from that velocity profile (tests/theory/test_mill_power.py). The
    kinetic factor is pi^3, not (2 pi)^3 as one reimplementation once had: it is the integral of
    rho L v^3 / 2 over r.

    The slurry pool (rho_p, its toe theta_TO, rad) only enters through that bracket; theta_TO
    defaults to theta_T (a grate-discharge mill: no pool, the term is zero). Cones (optional, each
    end of axial length L_d from the shell to a trunnion of radius r_t) turn as a rigid body:

        P_cones = pi g L_d N_m / (3 (r_m - r_t)) (r_m^4 - 4 r_m r_i^3 + 3 r_i^4) [same bracket]
                + 2 pi^3 N_m^3 L_d rho_c / (5 (r_m - r_t)) (r_m^5 - 5 r_m r_i^4 + 4 r_i^5)

    (derived here for both ends under that assumption; the wiki's own cone formula was not legible,
    the TypeScript reimplementation has the same kinetic part and no pi in the lifting part: one
    source, unverified). Fitted below phi_c: at phi_c the lifting term vanishes, the kinetic one
    does not."""
    shape = charge_shape(speed, fill)
    r_m, n_m = 0.5 * diameter, speed * critical_speed(diameter)
    span = 2.0 * math.pi + shape.shoulder - shape.toe
    lift = math.sin(shape.shoulder) - math.sin(shape.toe)
    r_bar = 0.5 * r_m * (1.0 + math.sqrt(max(0.0, 1.0 - 2.0 * math.pi * fill / span)))
    t_f = math.sqrt(2.0 * r_bar * lift / G)
    t_c = span / (math.pi * n_m)
    beta = t_c / (t_f + t_c)
    r_i = r_m * math.sqrt(max(0.0, 1.0 - 2.0 * math.pi * beta * fill / span))
    z = (1.0 - fill) ** 0.4532
    theta_to = shape.toe if slurry_toe is None else slurry_toe
    bracket = charge_density * lift + slurry_density * (math.sin(shape.toe) - math.sin(theta_to))
    d = r_m - z * r_i
    potential = (
        math.pi
        * G
        * length
        * n_m
        * r_m
        / (3.0 * d)
        * (2.0 * r_m**3 - 3.0 * z * r_m**2 * r_i + r_i**3 * (3.0 * z - 2.0))
        * bracket
    )
    kinetic = length * charge_density * (math.pi * n_m * r_m / d) ** 3 * (d**4 - r_i**4 * (z - 1.0) ** 4)
    cone = 0.0
    if cone_length > 0.0:
        r_t = 0.5 * trunnion_diameter
        cone = math.pi * G * cone_length * n_m / (3.0 * (r_m - r_t)) * (
            r_m**4 - 4.0 * r_m * r_i**3 + 3.0 * r_i**4
        ) * bracket + 2.0 * math.pi**3 * n_m**3 * cone_length * charge_density / (5.0 * (r_m - r_t)) * (
            r_m**5 - 5.0 * r_m * r_i**4 + 4.0 * r_i**5
        )
    return MorrellPower(potential + kinetic, potential, kinetic, cone, r_i, z, shape)


def morrell_no_load_power(diameter: float, length: float, speed: float, cone_length: float = 0.0) -> float:
    """The empty mill's draw (W) in Morrell's model, P_0 = 1.68 D^2.05 [phi (0.667 L_d + L)]^0.82
    kW (D, L, L_d in m; the TypeScript reimplementation's form, which reproduces Erdem et al.
    2004's 41.94 and 72.35 kW to their four digits, a second source by its numbers).
    Bearing, gear and motor losses: not part of the shell's net power."""
    return 1.68e3 * diameter**2.05 * (speed * (0.667 * cone_length + length)) ** 0.82


def morrell_gross_power(net: float, no_load: float, k: float = MORRELL_GROSS_FACTOR) -> float:
    """Motor input (W) = P_0 + k P_net, k = 1.26 for industrial mills (Met Dynamics wiki; Erdem et
    al. 2004's 1365.04 kW = 41.94 + 72.35 + 1.26 (341.97 + 650.69))."""
    return no_load + k * net


def austin_power(
    diameter: float,
    length: float,
    speed: float,
    fill: float,
    ball_fill: float,
    ore_density: float,
    ball_density: float,
    porosity: float = AUSTIN_POROSITY,
    solids_fraction: float = AUSTIN_SOLIDS,
) -> float:
    """Austin's SAG-mill power (W), at the pinion per the IMPC 2024 restatement:

        P = K D^2.5 L (1 - A J) [(1 - eps_B) (rho_s / w_C) J + 0.6 J_B (rho_b - rho_s / w_C)]
            x phi (1 - 0.1 / 2^(9 - 10 phi))

    K = 10.6 (kW with D, L in m and densities in t/m^3: the same number gives W with kg/m^3),
    A = 0.937, eps_B the bed porosity (0.3) and w_C the charge's solids mass fraction (0.8): Doll's
    values, both restatements. Cylinder only (Austin's cone-end factor is not used); the speed
    factor and A are Bond's ball-mill ones. A drive-side figure: for the 10.36 x 4.27 m mill of
    the tests (J 0.28, J_B 0.12, phi 0.75) it gives 8.24 MW where Morrell gives 5.97 MW net and
    8.05 MW gross, so a shell (net) power compares with it only through the drive's losses."""
    rho_rock = ore_density / solids_fraction
    bed = (1.0 - porosity) * rho_rock * fill + 0.6 * ball_fill * (ball_density - rho_rock)
    return (
        AUSTIN_K
        * diameter**2.5
        * length
        * (1.0 - AUSTIN_A * fill)
        * bed
        * speed
        * (1.0 - 0.1 / 2.0 ** (9.0 - 10.0 * speed))
    )
