"""A mill run's net power draw and charge shape against the mill engineers' empirical models.

- Net power (measured): the drive's work W = int -T omega dt (T the charge's torque on the liner
  about the axis, summed in Yade every few steps: energy.csv's ``drive_work_J``) over the logged
  window, from the sample at the warm-up's end to the last, divided by that window's length:
  P = Delta W / Delta t (W). The slice is L_s thick along the axis, so the mill draws P / L_s per
  metre of its length (W/m) and P L / L_s for a mill L long. The slice's ends are frictionless
  walls that take no torque about the axis: all of T comes from the liner.
- The run's mill for the models: D = 2 R, the diameter inside the liners (the plates' inner
  circle, lifters excluded, the D of the critical speed), the slice's fraction phi of critical
  speed, and the charge's volumetric fill J = N V_b / ((1 - E) A L_s) (N balls of volume V_b, A the
  open area inside the liner's profile, E = 0.4 the bed's porosity: the C-model's E
  (:data:`millimpact.theory.mill_power.BED_POROSITY`, random loose packing), the same 0.4 the run's
  ``--fill`` used to count its balls (Austin, Klimpel & Luckie 1984)). Balls only: the ball fill
  J_B = J, no rock, no slurry.
- Morrell's C-model (:func:`~millimpact.theory.mill_power.morrell_net_power`) with the charge's
  density rho_c = (1 - E) rho_b (:func:`~millimpact.theory.mill_power.charge_density`: no rock, no
  slurry in the voids) and his toe and shoulder correlations
  (:func:`~millimpact.theory.mill_power.charge_shape`), both per metre of mill length.
- Austin's SAG equation (:func:`~millimpact.theory.mill_power.austin_power`) with J_B = J and no
  ore (ore density 0: the bed's voids hold nothing), per metre. Austin's is a drive-side (pinion)
  figure: above the shell's net power by the drive's losses (Morrell's gross/net is ~1.35 for an
  industrial mill), so a net power compares with it only through them.
- With a SAG charge: ore density the rock's; with ``--slurry-density`` rho_p the C-model's charge
  density counts the voids full of slurry (U = 1), as the run's particles carry it.

What the run measures is the power the shell gives the charge: every joule the charge turns into
heat passes through the liner's torque. The models give other things, so each is also put in
those terms (``*_shell_*`` in summary.json, the figures to judge the run by):

- Morrell: the motor draws P_0 + k P_C (:func:`~millimpact.theory.mill_power.morrell_gross_power`),
  k = 1.26 lumping what the C-model's P_C leaves out. Above the empty mill's P_0 the motor gives
  k P_C: the shell's power (the charge's heat beyond lifting and throwing inside k) plus the
  drive's load-dependent losses, a few per cent. The run is set against k P_C.
- Austin: his figure is the pinion's, which Morrell's gross power matches within 2 % on a
  10.4 m mill (:func:`~millimpact.theory.mill_power.austin_power`), so the shell's share is
  Austin's less the empty mill's P_0 (Morrell's no-load,
  :func:`~millimpact.theory.mill_power.morrell_no_load_power`, for the scene's mill length, else
  L = D / 2, a SAG mill's usual aspect; P_0 per metre goes as L^-0.18, 4 % for L 20 % off). His
  constants assume a wet charge (solids 80 % of the charge's mass, w_C): a dry run's charge is
  lighter than his by that slurry.

Relative differences are (measured - model) / model; the angles' differences are measured - model
in degrees, both angles from the vertical below the axis, positive in the direction of rotation.
"""

from __future__ import annotations

import math

import numpy as np

from ...theory.mill_power import (
    BED_POROSITY,
    MORRELL_GROSS_FACTOR,
    austin_power,
    charge_density,
    charge_shape,
    morrell_net_power,
    morrell_no_load_power,
)
from .setup import MillSetup

#: where the porosity of the fill comes from (summary.json states it)
POROSITY_SOURCE = (
    "0.4: the C-model's E (random loose packing of spheres, G. D. Scott, Nature 188 (1960) 908), the "
    "bed porosity the run's --fill counts its balls with (Austin, Klimpel & Luckie 1984)"
)


def measured_power(
    energy: dict[str, np.ndarray],
    start_s: float,
    thickness: float,
    mill_length: float | None = None,
    tolerance_s: float = 0.0,
) -> dict:
    """The drive's mean power over the samples from the first at or after ``start_s`` (less
    ``tolerance_s``) to the last: P = Delta W / Delta t (W), P / L_s (W per metre of mill length, the
    slice ``thickness`` L_s m thick) and, given the mill's length L (m), P L / L_s (W). None where
    the window holds fewer than two samples."""
    t, w = np.asarray(energy["time_s"], float), np.asarray(energy["drive_work_J"], float)
    inside = np.flatnonzero(t >= start_s - tolerance_s)
    out: dict = {
        "net_W": None,
        "net_per_metre_W_m": None,
        "mill_length_m": mill_length,
        "net_mill_W": None,
        "window_s": [None, None],
        "drive_work_J": None,
    }
    if inside.size < 2 or t[-1] <= t[inside[0]]:
        return out
    k0 = int(inside[0])
    work, span = float(w[-1] - w[k0]), float(t[-1] - t[k0])
    p = work / span
    out.update(
        net_W=p,
        net_per_metre_W_m=p / thickness,
        net_mill_W=None if mill_length is None else p * mill_length / thickness,
        window_s=[float(t[k0]), float(t[-1])],
        drive_work_J=work,
    )
    return out


def volumetric_fill(setup: MillSetup, porosity: float = BED_POROSITY, balls_only: bool = False) -> float:
    """J = V_p / ((1 - E) A L_s): the fraction of the mill's volume inside the liner's profile the
    charge's bed fills, V_p the particles' volume (the balls' alone: J_B) (module docstring)."""
    v = setup.n_balls * 4.0 / 3.0 * math.pi * setup.ball_radius**3
    if not balls_only:
        v += sum(4.0 / 3.0 * math.pi * r**3 for r in setup.rock_radii)
    return v / ((1.0 - porosity) * setup.profile.open_area() * setup.thickness)


def _relative(measured: float | None, model: float) -> float | None:
    return None if measured is None or model == 0.0 else (measured - model) / model


def _difference(measured: float | None, model: float) -> float | None:
    return None if measured is None else measured - model


def model_inputs(setup: MillSetup) -> dict:
    """The run's mill as the models take it (SI; module docstring)."""
    fill = volumetric_fill(setup)
    ball_fill = volumetric_fill(setup, balls_only=True)
    rho_b = setup.ball_material[2]
    rho_o = setup.rock_material[2] if setup.n_rocks else 0.0
    rho_p = setup.rock.slurry_density if setup.rock is not None else 0.0
    charge = "balls and rock" if setup.n_rocks else "balls alone: J_B = J, no rock"
    return {
        "diameter_m": setup.profile.diameter,
        "speed_fraction": setup.speed_fraction,
        "fill": fill,
        "ball_fill": ball_fill,
        "bed_porosity": BED_POROSITY,
        "bed_porosity_source": POROSITY_SOURCE,
        "ball_density_kg_m3": rho_b,
        "ore_density_kg_m3": rho_o,
        "slurry_density_kg_m3": rho_p,
        "charge_density_kg_m3": charge_density(fill, ball_fill, rho_o, rho_b, rho_p, 1.0, BED_POROSITY),
        "charge_is": charge + (f", voids full of slurry of {rho_p:g} kg/m^3" if rho_p else ", no slurry"),
    }


def shell_power(diameter: float, speed: float, morrell: float, austin: float, length: float) -> tuple:
    """The models put at the shell (module docstring), per metre (W/m): Morrell's k P_C, Austin's
    pinion figure less the empty mill's P_0, and P_0 itself, for a mill ``length`` m long, from
    Morrell's net P_C and Austin's figure per metre."""
    no_load = morrell_no_load_power(diameter, length, speed) / length
    return MORRELL_GROSS_FACTOR * morrell, austin - no_load, no_load


def power_report(setup: MillSetup, energy: dict[str, np.ndarray], mill_length: float | None = None) -> dict:
    """summary.json's "power": the measured net power (W, W/m, and W for the scene's mill length if
    it has one) beside Morrell's net and Austin's pinion power per metre, with relative differences."""
    measured = measured_power(
        energy, setup.warmup_s, setup.thickness, mill_length, tolerance_s=setup.power_every * setup.dt
    )
    m = model_inputs(setup)
    d, phi, j = m["diameter_m"], m["speed_fraction"], m["fill"]
    morrell = morrell_net_power(d, 1.0, phi, j, m["charge_density_kg_m3"]).net
    austin = austin_power(d, 1.0, phi, j, m["ball_fill"], m["ore_density_kg_m3"], m["ball_density_kg_m3"])
    length = mill_length if mill_length is not None else 0.5 * d
    morrell_shell, austin_shell, no_load = shell_power(d, phi, morrell, austin, length)
    per_m = measured["net_per_metre_W_m"]
    return {
        "measured": measured,
        "measured_is": "the drive's work (charge's torque on the liner x omega) over the logged window, "
        "after the warm-up",
        "scaled_to": "the scene's mill length"
        if mill_length is not None
        else "per metre (the scene gives no mill length)",
        "model_inputs": m,
        "morrell_net_per_metre_W_m": morrell,
        "morrell_relative_difference": _relative(per_m, morrell),
        "morrell_source": "Morrell 1996 C-model, net power at the shell (millimpact.theory.mill_power)",
        "austin_per_metre_W_m": austin,
        "austin_relative_difference": _relative(per_m, austin),
        "austin_source": "Austin 1990 SAG equation (millimpact.theory.mill_power)",
        "austin_is": "a drive-side (pinion) figure: above the shell's net power by the drive's losses",
        "morrell_shell_per_metre_W_m": morrell_shell,
        "morrell_shell_relative_difference": _relative(per_m, morrell_shell),
        "morrell_shell_is": f"k P_C, k = {MORRELL_GROSS_FACTOR}: the motor's draw above the empty mill's in "
        "Morrell's model, the shell's power less the drive's load-dependent losses",
        "no_load_per_metre_W_m": no_load,
        "no_load_is": f"Morrell's empty-mill draw P_0 per metre for a {length:g} m mill"
        + ("" if mill_length is not None else " (L = D / 2: the scene gives no mill length)"),
        "austin_shell_per_metre_W_m": austin_shell,
        "austin_shell_relative_difference": _relative(per_m, austin_shell),
        "austin_shell_is": "Austin's pinion power less the empty mill's P_0",
        "units": "W, W/m (per metre of mill length), s, J; relative differences (measured - model) / model",
    }


def charge_shape_report(setup: MillSetup, angles: dict) -> dict:
    """summary.json's "charge_shape": the measured toe and shoulder (deg) beside Morrell's
    correlations for the run's speed fraction and fill, and the differences (deg)."""
    j = volumetric_fill(setup)
    shape = charge_shape(setup.speed_fraction, j)
    return {
        "toe_deg": angles.get("toe_deg"),
        "shoulder_deg": angles.get("shoulder_deg"),
        "morrell_toe_deg": shape.toe_deg,
        "morrell_shoulder_deg": shape.shoulder_deg,
        "toe_difference_deg": _difference(angles.get("toe_deg"), shape.toe_deg),
        "shoulder_difference_deg": _difference(angles.get("shoulder_deg"), shape.shoulder_deg),
        "fill": j,
        "speed_fraction": setup.speed_fraction,
        "morrell_source": "Morrell 1996 Part 2 toe and shoulder correlations (millimpact.theory.mill_power)",
        "units": "deg from the vertical below the axis, positive in the direction of rotation; "
        "differences measured - model",
    }
