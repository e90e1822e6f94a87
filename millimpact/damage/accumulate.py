"""Accumulation: the bins' responses combined with the impact rates, per place and per revolution.

Per impact i of a bin (ball mass m_i from its radius and the scene ball's density; v_n, v_t its
normal and tangential speeds; e_n, e_t the bin's normal and tangential restitutions from the
table row, e_t of the contact point's tangential velocity with a rigid ball's spin):

    energy absorbed   W_a = (1 - e_n^2) m v_n^2 / 2 + (1 - e_t^2) m v_t^2 / 7

(the ball's loss of translational and rotational kinetic energy: a sphere's tangential impact with
spin omega = -5 J_t / (2 m R) keeps (m/2)(v_t + J_t/m)^2 + (m R^2/5) omega^2 of (m/2) v_t^2, and
with u_out = e_t v_t = v_t + 7 J_t / (2 m) the loss is (1 - e_t^2) m v_t^2 / 7; Maw, Barber &
Fawcett, Wear 38 (1976) 101-114). A bin whose representative is normal (v_t = 0, e_t undefined)
takes the tangential term from its tangential impulse: -7 J_t^2 / (4 m), the energy a curved or
asymmetric surface turns into the ball's sliding and spin. The absorbed energy is spent as plastic
work, friction and the liner's vibration.

    plastic work      W_p = (W_p,bin / T_bin) T_i

the bin's plastic work as a fraction of its representative kinetic energy T_bin times the
impact's kinetic energy T_i (the representative is the bin's root-mean-square speeds, so a bin's
W_p sums to its count times W_p,bin). A bin at or below the yield-onset speed V_y (Thornton 1997)
adds no plastic work (W_p = 0: the table's plastic work there, round-off of a zone that does not
yield, is reported per bin).

Per revolution: the sums over a place's impacts divided by the revolutions the log covers (and by
the lifters it folds onto one lifter's profile).

Dent growth (the place's dominant bin: the largest plastic work per revolution, else the largest
absorbed energy): the repeated-impact sequence at its representative impact gives the dent depth
d_k and the largest equivalent plastic strain eps_k after impact k. The impacts spread over the
place; a spot the size of the first dent, pi r_d^2, is struck N_spot = N_place pi r_d^2 / A_place
times a revolution (A_place: the place's extent along the profile times the slice's axial length).
The dent grows at (d_n - d_n-1) N_spot a revolution at the sequence's end (0 after shakedown), and
eps_p reaches the small-strain limit EPS_SMALL_STRAIN after (0.1 - eps_n) / (eps_n - eps_n-1) more
impacts at the end's increment (inf when it does not grow).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..dem.impacts import PLACES, Impact, impact_column
from .bins import Bin
from .responses import finite

#: the largest equivalent plastic strain small-strain J2 plasticity describes (foundations.md section 10)
EPS_SMALL_STRAIN = 0.1


@dataclass(frozen=True)
class ImpactDamage:
    """One impact's share: energy absorbed and plastic work (J)."""

    energy_absorbed_J: float
    plastic_work_J: float


def impact_damage(imp: Impact, row: dict, below_yield: bool, density: float, scene_ball_mass: float) -> ImpactDamage:
    """An impact's absorbed energy and plastic work from its bin's table ``row`` (module docstring)."""
    a, p = impacts_damage(
        np.array([imp.ball_radius_m]),
        np.array([imp.normal_speed_m_s]),
        np.array([imp.tangential_speed_m_s]),
        row,
        below_yield,
        density,
        scene_ball_mass,
    )
    return ImpactDamage(float(a[0]), float(p[0]))


def impacts_damage(
    radius: np.ndarray,
    v_n: np.ndarray,
    v_t: np.ndarray,
    row: dict,
    below_yield: bool,
    density: float,
    scene_ball_mass: float,
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`impact_damage` of a bin's impacts at once, from their ball radii (m) and normal and
    tangential speeds (m/s): (energy absorbed, plastic work) per impact (J)."""
    m = 4.0 / 3.0 * math.pi * radius**3 * density
    e_n = finite(row.get("restitution_normal"))
    e_t = finite(row.get("restitution_tangential"))
    vn, vt = finite(row.get("normal_velocity_in_m_s")), finite(row.get("tangential_velocity_in_m_s"))
    vt = 0.0 if math.isnan(vt) else vt
    t_n = 0.5 * m * v_n**2
    t_t = 0.5 * m * v_t**2
    if not math.isnan(e_t):
        tangential = (1.0 - e_t**2) * 2.0 / 7.0 * t_t
    else:
        # a normal representative (v_t = 0): the tangential impulse J_t it still takes (a curved or
        # asymmetric surface) gives the ball m v_t'^2/2 + I omega^2/2 = 7 J_t^2 / (4 m), a negative
        # loss, scaled with the impact's normal kinetic energy
        j_t = finite(row.get("tangential_impulse_N_s"))
        gain = 0.0 if math.isnan(j_t) else 7.0 * j_t**2 / (4.0 * scene_ball_mass)
        t_n_rep = 0.5 * scene_ball_mass * vn**2
        tangential = -gain * t_n / t_n_rep if t_n_rep > 0 else 0.0 * t_n
    absorbed = (1.0 - e_n**2) * t_n + tangential
    if below_yield:
        return absorbed, np.zeros_like(absorbed)
    t_rep = 0.5 * scene_ball_mass * (vn**2 + vt**2)
    w_p = finite(row.get("plastic_dissipation_J"))
    frac = w_p / t_rep if t_rep > 0 and not math.isnan(w_p) else 0.0
    return absorbed, frac * (t_n + t_t)


def place_extent(liner, place: str) -> float:
    """The extent (m) of a place along the liner's profile per lifter: a face's slant length, the
    top's width, or the plate between two lifters' feet (lifter spacing minus the base width)."""
    if place == "lifter_face":
        return liner.lifter_height / math.cos(math.radians(liner.lifter_face_angle))
    if place == "lifter_top":
        return liner.lifter_top_width
    return max(liner.lifter_spacing - liner.lifter_base_width, 1e-9)


def dent_trend(repeat: dict | None, impacts_per_rev: float, extent_m: float, slice_length_m: float) -> dict:
    """Dent growth and plastic strain trend of a place from its repeated-impact sequence (module
    docstring); NaN when there is no sequence."""
    nan = math.nan
    out = {
        "repeat_verdict": "not computed",
        "impacts_to_shakedown": nan,
        "repeat_impacts": 0,
        "dent_depth_first_m": nan,
        "dent_depth_last_m": nan,
        "dent_growth_per_impact_m": nan,
        "spot_impacts_per_rev": nan,
        "dent_growth_m_per_rev": nan,
        "revolutions_to_shakedown": nan,
        "max_eq_plastic_strain_first": nan,
        "max_eq_plastic_strain_last": nan,
        "max_eq_plastic_strain_growth_per_impact": nan,
        "revolutions_to_small_strain_limit": nan,
    }
    if not repeat or not repeat.get("outcomes"):
        return out
    oc = repeat["outcomes"]
    d = np.array([finite(o.get("residual_dent_depth_m")) for o in oc])
    eps = np.array([finite(o.get("max_equivalent_plastic_strain")) for o in oc])
    r_d = finite(oc[0].get("residual_dent_radius_m"))
    verdict = repeat.get("verdict", {})
    kind = str(verdict.get("kind", "undecided"))
    n_sd = verdict.get("impacts_to_shakedown")
    shaken = "shakedown" in kind
    spot = impacts_per_rev * math.pi * r_d**2 / (extent_m * slice_length_m) if r_d > 0 else nan
    growth = 0.0 if shaken else (float(d[-1] - d[-2]) if len(d) >= 2 else nan)
    deps = 0.0 if shaken else (float(eps[-1] - eps[-2]) if len(eps) >= 2 else nan)
    if eps[-1] >= EPS_SMALL_STRAIN:
        to_limit = 0.0
    elif deps > 0 and spot > 0:
        to_limit = ((EPS_SMALL_STRAIN - eps[-1]) / deps + len(eps)) / spot
    else:
        to_limit = math.inf
    out.update(
        {
            "repeat_verdict": kind,
            "impacts_to_shakedown": float(n_sd) if n_sd is not None else nan,
            "repeat_impacts": len(oc),
            "dent_depth_first_m": float(d[0]),
            "dent_depth_last_m": float(d[-1]),
            "dent_growth_per_impact_m": growth,
            "spot_impacts_per_rev": spot,
            "dent_growth_m_per_rev": growth * spot if spot == spot else nan,
            "revolutions_to_shakedown": (float(n_sd) / spot if n_sd is not None and spot > 0 else nan),
            "max_eq_plastic_strain_first": float(eps[0]),
            "max_eq_plastic_strain_last": float(eps[-1]),
            "max_eq_plastic_strain_growth_per_impact": deps,
            "revolutions_to_small_strain_limit": to_limit,
        }
    )
    return out


def dominant_bin(bins: Sequence[Bin], per_bin: dict[int, dict], place: str) -> int | None:
    """The bin of ``place`` with the largest plastic work per revolution (else the largest absorbed
    energy) among the computed ones, or None."""
    cand = [b for b in bins if b.place == place and b.index in per_bin]
    if not cand:
        return None
    return max(
        cand, key=lambda b: (per_bin[b.index]["plastic_work_J_per_rev"], per_bin[b.index]["energy_absorbed_J_per_rev"])
    ).index


def accumulate(
    impacts: Sequence[Impact],
    bins: Sequence[Bin],
    rows: dict[int, dict],
    density: float,
    scene_ball_mass: float,
    revolutions: float,
    lifters: int = 1,
) -> tuple[dict[int, dict], dict]:
    """Per-bin sums per revolution (bin index -> numbers) and each impact's share: arrays
    ``energy_absorbed_J`` and ``plastic_work_J`` over the impacts (NaN for an impact of a bin
    without a response)."""
    per_rev = 1.0 / (revolutions * lifters)
    radius, v_n, v_t, energy = (
        impact_column(impacts, c)
        for c in ("ball_radius_m", "normal_speed_m_s", "tangential_speed_m_s", "impact_energy_J")
    )
    shares = {"energy_absorbed_J": np.full(len(impacts), math.nan), "plastic_work_J": np.full(len(impacts), math.nan)}
    per_bin = {}
    for b in bins:
        if b.index not in rows or not str(rows[b.index].get("status", "ok")).startswith("ok"):
            continue
        i = np.asarray(b.impacts, dtype=np.int64)
        a, p = impacts_damage(radius[i], v_n[i], v_t[i], rows[b.index], b.below_yield, density, scene_ball_mass)
        shares["energy_absorbed_J"][i] = a
        shares["plastic_work_J"][i] = p
        per_bin[b.index] = {
            "impacts_per_rev": len(b.impacts) * per_rev,
            "impact_energy_J_per_rev": float(energy[i].sum()) * per_rev,
            "energy_absorbed_J_per_rev": float(a.sum()) * per_rev,
            "plastic_work_J_per_rev": float(p.sum()) * per_rev,
        }
    return per_bin, shares


def place_totals(
    impacts: Sequence[Impact], bins: Sequence[Bin], per_bin: dict[int, dict], revolutions: float, lifters: int = 1
) -> dict[str, dict]:
    """Per place: impacts, impact energy, energy absorbed and plastic work per revolution, and the
    impacts left out (their bins refused or failed)."""
    per_rev = 1.0 / (revolutions * lifters)
    energy = impact_column(impacts, "impact_energy_J")
    out = {}
    for p in PLACES:
        mine = [b for b in bins if b.place == p]
        if not mine:
            continue
        done = [b for b in mine if b.index in per_bin]
        n_all = sum(len(b.impacts) for b in mine)
        out[p] = {
            "impacts_per_rev": n_all * per_rev,
            "impact_energy_J_per_rev": sum(float(energy[np.asarray(b.impacts, dtype=np.int64)].sum()) for b in mine)
            * per_rev,
            "energy_absorbed_J_per_rev": sum(per_bin[b.index]["energy_absorbed_J_per_rev"] for b in done),
            "plastic_work_J_per_rev": sum(per_bin[b.index]["plastic_work_J_per_rev"] for b in done),
            "impacts_left_out_per_rev": (n_all - sum(len(b.impacts) for b in done)) * per_rev,
            "bins": len(mine),
            "bins_computed": len(done),
        }
    return out


def profile_rates(
    impacts: Sequence[Impact], shares: dict, cell_m: float, revolutions: float, lifters: int = 1
) -> dict[str, dict]:
    """Per place, arc cells ``cell_m`` wide: the plastic work and the absorbed energy per revolution
    per metre of arc (J/(rev m)) at each cell's centre (``shares``: :func:`accumulate`'s)."""
    per_rev = 1.0 / (revolutions * lifters)
    place, arc = impact_column(impacts, "place"), impact_column(impacts, "arc_position_m")
    absorbed, plastic = shares["energy_absorbed_J"], shares["plastic_work_J"]
    out = {}
    for p in PLACES:
        idx = np.flatnonzero((place == p) & ~np.isnan(absorbed))
        if not idx.size:
            continue
        s = arc[idx]
        lo = math.floor(s.min() / cell_m) * cell_m
        n = max(1, int(math.ceil((s.max() - lo) / cell_m + 1e-9)))
        k = np.clip(((s - lo) / cell_m).astype(int), 0, n - 1)
        wp = np.bincount(k, plastic[idx], n) * per_rev / cell_m
        wa = np.bincount(k, absorbed[idx], n) * per_rev / cell_m
        out[p] = {
            "arc_m": (lo + cell_m * (np.arange(n) + 0.5)).tolist(),
            "plastic_work_J_per_rev_m": wp.tolist(),
            "energy_absorbed_J_per_rev_m": wa.tolist(),
        }
    return out
