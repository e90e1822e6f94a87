"""Reading what a Yade mill run leaves (``mill_slice.py``): impacts, charge snapshots, energies,
traces, the sliding at the liner (:mod:`~millimpact.dem.mill.abrasion` reports it).

Each row of ``impacts_raw.csv`` is a particle-liner contact (a ball's or a rock's: its mass and
radius from the particle's number, balls first) found at a check (every ``check_every``
steps, ``age`` steps after it began) with a part of the liner the ball was not touching at the
previous check, with the ball's velocity v before the contact (its velocity at the previous check
plus gravity's pull since: exact for a ball landing from a flight; a ball in the bed may also have
been pushed by other balls in those few steps), the contact point c and the liner's normal n (into
the ball) when found. In the liner's moving frame the ball's velocity relative to the liner's
surface there is

    v_rel = v - omega e_z x c,

its normal part v_n = -v_rel . n (approaching: > 0; a ball rolling onto a part can give 0) and
tangential part v_t = |v_rel - (v_rel . n) n| (the ball's centre along the liner; its spin is not
counted); the impact energy is (1/2) m (v_n^2 + v_t^2). (The velocity when the contact is found
is no substitute: Yade's Tsuji damping, proportional to delta^(1/4), takes ~ 10 % of the normal
speed in the first steps of a contact.) The impact's arc position is its contact point turned back
by the liner's angle omega t (the liner starts at angle 0 at t = 0), measured by
:meth:`~millimpact.dem.mill.geometry.MillProfile.arc_position`.
"""

from __future__ import annotations

import csv
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..impacts import Impact
from .setup import MillSetup


@dataclass(frozen=True)
class MillRun:
    """A finished Yade mill run: the logged impacts (after the warm-up; times from its end), the
    charge snapshots (time, ball, x, y, vx, vy: arrays over rows), the energy samples (column ->
    array), the traced balls' rows and Yade's run record."""

    impacts: list[Impact]
    snapshots: dict[str, np.ndarray]
    energy: dict[str, np.ndarray]
    trace: dict[str, np.ndarray]
    info: dict
    abrasion: dict[str, np.ndarray]


def _read_columns(path: Path) -> dict[str, np.ndarray]:
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    header, body = rows[0], rows[1:]
    if not body:
        return {h: np.zeros(0) for h in header}
    data = np.array(body, dtype=float)
    return {h: data[:, j] for j, h in enumerate(header)}


def impacts_from_raw(raw: dict[str, np.ndarray], setup: MillSetup) -> list[Impact]:
    """The :class:`~millimpact.dem.impacts.Impact` rows of the raw log after the warm-up (module
    docstring), times counted from the warm-up's end."""
    if raw["time_s"].size == 0:
        return []
    w = setup.omega
    t = raw["time_s"]
    v = np.stack([raw["vx"], raw["vy"], raw["vz"]], axis=1)
    c = np.stack([raw["cx"], raw["cy"], raw["cz"]], axis=1)
    n = np.stack([raw["nx"], raw["ny"], raw["nz"]], axis=1)
    n /= np.linalg.norm(n, axis=1)[:, None]
    v_liner = np.stack([-w * c[:, 1], w * c[:, 0], np.zeros_like(t)], axis=1)
    v_rel = v - v_liner
    vn_signed = np.einsum("ij,ij->i", v_rel, n)
    v_t = np.linalg.norm(v_rel - vn_signed[:, None] * n, axis=1)
    k_part = raw["particle"].astype(int)
    m = np.array([setup.particle_mass(k) for k in k_part])
    radius = np.array([setup.particle_radius(k) for k in k_part])
    v_n0 = np.maximum(-vn_signed, 0.0)
    energy = 0.5 * m * (v_n0**2 + v_t**2)
    # the contact point in the liner's frame: turned back by the liner's angle omega t
    th = -w * t
    xl = np.cos(th) * c[:, 0] - np.sin(th) * c[:, 1]
    yl = np.sin(th) * c[:, 0] + np.cos(th) * c[:, 1]
    place_of = {s.part: s.place for s in setup.profile.segments}
    out = []
    keep = t >= setup.warmup_s
    for k in np.flatnonzero(keep):
        out.append(
            Impact(
                time_s=float(t[k] - setup.warmup_s),
                ball_radius_m=float(radius[k]),
                normal_speed_m_s=float(v_n0[k]),
                tangential_speed_m_s=float(v_t[k]),
                impact_energy_J=float(energy[k]),
                place=place_of[int(raw["part"][k])],
                arc_position_m=float(setup.profile.arc_position(xl[k], yl[k])),
                kind="ball" if k_part[k] < setup.n_balls else "rock",
                mass_kg=float(m[k]),
                surface_position_m=float(setup.profile.surface_position(xl[k], yl[k], int(raw["part"][k]))),
            )
        )
    return out


def read_mill_run(folder: Path, setup: MillSetup) -> MillRun:
    """The files ``mill_slice.py`` wrote in ``folder``."""
    folder = Path(folder)
    raw = _read_columns(folder / "impacts_raw.csv")
    return MillRun(
        impacts=impacts_from_raw(raw, setup),
        snapshots=_read_columns(folder / "charge.csv"),
        energy=_read_columns(folder / "energy.csv"),
        trace=_read_columns(folder / "trace.csv"),
        info=json.loads((folder / "run.json").read_text()),
        abrasion=_read_columns(folder / "abrasion_raw.csv"),
    )
