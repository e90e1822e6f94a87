"""The liner through time: wear a step, move the profile, run the mill on it, and again.

Each cycle takes a mill run on the current profile (the user's on the new liner first; then
``millimpact mill``'s own run with the first run's options on the worn profile), its wear rates
(:func:`~millimpact.life.wear.depth_rates`) over a step of ``hours / cycles``, and moves the profile
(:func:`~millimpact.life.profile.worn_profile`). The steps should be short enough that a step's wear
is small against the lifter's height (each step's largest depth is reported) and long enough that
the charge changes between runs. With ``max_step_share`` F a step is also short enough that no bin
of any surface loses more than F of the lifter's current height above the plate,

    dt = min(hours / cycles, F h / d_max),   d_max the largest depth rate of the bins (m/h),

but at least MIN_STEP_SHARE of hours / cycles: a worn lifter's faces meet at its top, where the
corner bins wear 5-10 times the face's mean, and equal steps would carry a bin past the lifter in
one step. It stops at the relining criterion: the lifters' height above the plate or the plate's
thickness at their limits, or, with ``stop_height`` (a calibration on the life's own height curve,
:func:`~millimpact.life.calibration.through_life`), where the lifters' height reaches it. Then the
steps are ``cycles`` equal falls of the height instead of equal hours: the wear constants are
provisional until the end (a factor rescales the hours), so a step's hours follow from the rates,
found where the profile update's height crosses the step's (regula falsi: the height falls
linearly in the hours until the chamfers meet on the top).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path

from ..commandkit.timing import StageClock
from ..errors import InputError
from .profile import LifterProfile, worn_profile
from .wear import MillRecord, WearLaw, depth_rates, place_rates, read_mill_record, surface_depths

#: a step limited by ``max_step_share`` is at least this share of hours / cycles (the mill runs of a
#: life are at most cycles / MIN_STEP_SHARE)
MIN_STEP_SHARE = 0.25
#: with ``stop_height`` the steps run to the height; more than this many times ``hours`` is refused
STOP_BOUND = 10.0


@dataclass
class LifeStep:
    """One row of profiles.csv: the profile at ``hours``, and the mill run on it."""

    hours: float
    profile: LifterProfile
    mill: dict = field(default_factory=dict)  # net power, toe, shoulder of the run on this profile
    largest_step_depth_mm: float = math.nan


def mill_state(rec: MillRecord) -> dict:
    """The mill run's power, toe and shoulder, and its balls' impacts per revolution."""
    s = rec.summary
    p = s["power"]["measured"]["net_per_metre_W_m"]
    return {
        "net_power_kW_m": None if p is None else p / 1e3,
        "toe_deg": s.get("toe_deg"),
        "shoulder_deg": s.get("shoulder_deg"),
        "ball_impacts_per_rev": s["impacts_per_revolution"]["all"],
        "ball_energy_J_per_rev": s["energy_per_revolution_J"]["all"],
    }


def relined(lp: LifterProfile, reline_height_mm: float, reline_plate_mm: float) -> str | None:
    """Why the liner is relined now ('lifter height', 'plate thickness'), or None."""
    if 1e3 * lp.height_above_plate <= reline_height_mm:
        return "lifter height"
    if 1e3 * lp.plate_left <= reline_plate_mm:
        return "plate thickness"
    return None


def run_life(
    lp: LifterProfile,
    first: MillRecord,
    law: WearLaw,
    hours: float,
    cycles: int,
    reline: tuple[float, float],
    run_mill_on: Callable[[LifterProfile, int], Path] | None,
    ball_radius: float,
    say: Callable[[str], None] = lambda s: None,
    clock: StageClock | None = None,
    max_step_share: float | None = None,
    stop_height: float | None = None,
) -> tuple[list[LifeStep], list[dict], str | None]:
    """The steps (the profile at 0, hours/cycles, ...; shorter ones with ``max_step_share``, the
    module docstring), the per-surface rates of each cycle's mill run, and the relining reason if
    reached. With ``stop_height`` (m, the lifters' height above the plate) the steps go on past
    ``hours`` until that height, the last one cut where it is reached (InputError beyond
    STOP_BOUND x ``hours``). ``run_mill_on(profile, cycle)`` runs the mill on a worn profile and returns its folder
    (None: one cycle only). ``clock`` gets a lap of ``wear_and_profile`` per cycle, of
    ``mill_reruns`` per re-run and of ``read`` per re-run read."""
    clock = StageClock() if clock is None else clock
    nominal = hours / cycles
    steps = [LifeStep(0.0, lp, mill_state(first))]
    rates_per_cycle = []
    rec, why = first, None
    k, reached = 0, False
    end = hours if stop_height is None else STOP_BOUND * hours
    while steps[-1].hours < end * (1.0 - 1e-9):
        with clock.stage("wear_and_profile"):
            rates = depth_rates(rec, law)
            rates_per_cycle.append(place_rates(rec, rates))
            if stop_height is None:
                dt = step_hours(rec, rates, lp, nominal, end - steps[-1].hours, max_step_share)
                depths = surface_depths(rec, rates, dt)
                worn = worn_profile(lp, depths, rec.bin_m)
            else:  # equal falls of the height, cycles of them to stop_height
                h0 = steps[0].profile.height_above_plate
                target = (
                    stop_height if k + 1 >= cycles else max(stop_height, h0 - (k + 1) * (h0 - stop_height) / cycles)
                )
                dt = _hours_below(lp, rec, rates, target, nominal, end - steps[-1].hours)
                depths = surface_depths(rec, rates, dt)
                worn = worn_profile(lp, depths, rec.bin_m)
                if worn.height_above_plate <= target:  # else out of reach: the loop ends at its bound
                    dt, depths, worn = _cut_at_height(lp, rec, rates, dt, target)
                    reached = target <= stop_height * (1.0 + 1e-12)
            lp = worn
        largest = max((float(d.max()) for _, d in depths.values() if d.size), default=0.0)
        steps[-1].largest_step_depth_mm = 1e3 * largest
        say(
            f"  life: {steps[-1].hours + dt:.0f} h: lifter {1e3 * lp.height_above_plate:.1f} mm high, faces "
            f"{lp.trailing_angle_deg:.1f} / {lp.leading_angle_deg:.1f} deg (trailing / leading), plate "
            f"{1e3 * lp.plate_left:.1f} mm"
        )
        why = relined(lp, *reline)
        last = steps[-1].hours + dt >= end * (1.0 - 1e-9) or why is not None or reached
        k += 1
        if not last and run_mill_on is not None:
            with clock.stage("mill_reruns"):
                folder = run_mill_on(lp, k)
            with clock.stage("read"):
                rec = read_mill_record(folder, lp.mill_profile(ball_radius))
        steps.append(LifeStep(steps[-1].hours + dt, lp, {} if last or run_mill_on is None else mill_state(rec)))
        if why is not None or reached:
            break
    if stop_height is not None and not reached:
        if why is not None:
            raise InputError(
                f"the liner reaches its relining limit ({why}) before the lifters are {1e3 * stop_height:g} mm "
                "high: lower --reline-height or --reline-plate to calibrate on that height"
            )
        raise InputError(
            f"the lifters stay above {1e3 * stop_height:g} mm for {end:g} h at the first run's constants "
            f"({1e3 * lp.height_above_plate:.1f} mm then): the figure cannot be reached"
        )
    return steps, rates_per_cycle, why


def _hours_below(lp: LifterProfile, rec: MillRecord, rates: dict, height: float, hours: float, bound: float) -> float:
    """Hours (``hours`` doubled until then, at most ``bound``) after which the lifter is below
    ``height`` (m) at these rates (``bound`` when it never gets there)."""
    t = min(hours, bound)
    while worn_profile(lp, surface_depths(rec, rates, t), rec.bin_m).height_above_plate > height and t < bound:
        t = min(2.0 * t, bound)
    return t


def _cut_at_height(lp: LifterProfile, rec: MillRecord, rates: dict, dt: float, height: float):
    """(hours, depths, profile) of the step of at most ``dt`` hours that ends with the lifter
    ``height`` high (m): the height falls linearly in the hours, unless the chamfers meet on the
    top (:func:`~millimpact.life.profile.worn_profile`), so the linear cut is refined by regula
    falsi (Illinois) in [0, dt] to 1e-12 of the height."""
    h0 = lp.height_above_plate

    def at(t):
        depths = surface_depths(rec, rates, t)
        worn = worn_profile(lp, depths, rec.bin_m)
        return worn.height_above_plate - height, depths, worn

    lo, f_lo, hi = 0.0, h0 - height, dt
    f_hi, depths, worn = at(hi)
    t = hi * f_lo / (f_lo - f_hi)
    side = 0
    for _ in range(100):
        f, depths, worn = at(t)
        if abs(f) <= 1e-12 * height:
            break
        if f > 0:
            lo, f_lo = t, f
            f_hi = 0.5 * f_hi if side == 1 else f_hi
            side = 1
        else:
            hi, f_hi = t, f
            f_lo = 0.5 * f_lo if side == -1 else f_lo
            side = -1
        t = (lo * f_hi - hi * f_lo) / (f_hi - f_lo)
    return t, depths, worn


def rescaled(steps: list[LifeStep], rates_per_cycle: list[dict], factor: float) -> tuple[list, list]:
    """The life with every wear constant times ``factor``: the same profiles at the hours over
    ``factor`` (the depths are the rates times the hours, the rates linear in the constants), the
    rates (mm and kg per 1000 h) times ``factor``."""
    steps = [replace(s, hours=s.hours / factor) for s in steps]
    per_1000h = ("mean_mm_per_1000h", "largest_mm_per_1000h", "mass_kg_per_1000h_per_metre")
    rates = [
        {surf: {k: (v * factor if k in per_1000h else v) for k, v in r.items()} for surf, r in cyc.items()}
        for cyc in rates_per_cycle
    ]
    return steps, rates


def step_hours(
    rec: MillRecord, rates, lp: LifterProfile, nominal: float, left: float, max_step_share: float | None
) -> float:
    """The next step (h): ``nominal`` (hours / cycles) or what is ``left``, and with
    ``max_step_share`` F at most F h / d_max (h the lifter's height above the plate, d_max the
    largest bin's depth rate), but not below MIN_STEP_SHARE x nominal (the module docstring)."""
    dt = min(nominal, left)
    if max_step_share is not None:
        per_hour = max((float(d.max()) for _, d in surface_depths(rec, rates, 1.0).values() if d.size), default=0.0)
        if per_hour > 0.0:
            dt = min(dt, max(max_step_share * lp.height_above_plate / per_hour, MIN_STEP_SHARE * nominal))
    return dt


def hours_to_reline(lp: LifterProfile, rates: dict, reline: tuple[float, float], factor: float = 1.0) -> dict:
    """Hours (from the profile ``lp``) until each criterion at the surfaces' mean rates (mm per
    1000 h) times ``factor``: the lifter's height above the plate falls at the top's rate less the
    plate's (the top's corners included: they wear first, and the top falls once they meet); the
    plate thins at the plate's."""
    top, plate = rates["top"]["mean_mm_per_1000h"] * factor, rates["plate"]["mean_mm_per_1000h"] * factor
    h_rate = top - plate
    out: dict = {
        "lifter_height_h": 1000.0 * (1e3 * lp.height_above_plate - reline[0]) / h_rate if h_rate > 0 else math.inf,
        "plate_thickness_h": 1000.0 * (1e3 * lp.plate_left - reline[1]) / plate if plate > 0 else math.inf,
    }
    out["first"] = min(("lifter_height_h", "plate_thickness_h"), key=lambda k: out[k])
    return out
