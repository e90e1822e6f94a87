"""What a mill run reports: the impact-energy spectrum, impacts per revolution by place, the charge's
shoulder and toe, the centrifuged share and the energy balance.

- Spectrum: for each energy E, the number of impacts per revolution with an energy >= E (the
  cumulative spectrum of the mill-DEM literature, e.g. P. W. Cleary, Int. J. Miner. Process. 63
  (2001) 79-114; M. S. Powell et al., Minerals Eng. 24 (2011) 1222-1232), drawn with the energy
  against the cumulative number on log scales, one curve per place and all together.
- Shoulder and toe: angles psi in the mill's cross-section from the vertical below the axis,
  positive in the direction of rotation. The balls whose centres lie within one diameter of the
  lifters' tips (rho >= R - h - 2 r) are counted in 5 degree sectors over the snapshots after the
  warm-up; the charge's foot on the shell is the run of sectors (round the circle) holding at least
  half the fullest sector's count, around that sector: the toe is its start, the shoulder its end.
  A run that goes all the way round, or a charge mostly centrifuged, has neither.
- Centrifuged share: the balls that stay in that band in every snapshot of the last revolution and
  turn with the liner, their mean angular speed about the axis over those snapshots at least
  0.9 omega (a centrifuged ball may still roll across its pocket between two lifters).
- Energy balance (from t = 0): the drive's work W = int -T omega dt (T the charge's torque on the
  liner about the axis) against the change of the balls' kinetic + potential energy, the energy
  dissipated in the contacts (normal and tangential damping, sliding friction) and the change of
  the energy stored in them.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..impacts import KINDS, PLACES, Impact
from .setup import MillSetup

#: sector width (deg) of the shoulder and toe count
SECTOR_DEG = 5.0


def spectrum(
    impacts: list[Impact], revolutions: float, place: str | None = None, kind: str | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """(energies in decreasing order (J), impacts per revolution with at least that energy), of
    one place and one kind of particle when given."""
    e = np.sort(
        [i.impact_energy_J for i in impacts if (place is None or i.place == place) and (kind is None or i.kind == kind)]
    )[::-1]
    return e, np.arange(1, e.size + 1) / revolutions


def place_table(impacts: list[Impact], revolutions: float, kind: str | None = None) -> list[dict]:
    """Per place and all together: impacts per revolution, energy per revolution (J), mean energy
    (J), mean normal and tangential speed (m/s); of one kind of particle only, given ``kind``."""
    rows = []
    impacts = [i for i in impacts if kind is None or i.kind == kind]
    for place in (*PLACES, "all"):
        sel = [i for i in impacts if place == "all" or i.place == place]
        n = len(sel)
        e = sum(i.impact_energy_J for i in sel)
        rows.append(
            {
                "place": place,
                "impacts_per_revolution": n / revolutions,
                "energy_per_revolution_J": e / revolutions,
                "mean_impact_energy_J": e / n if n else 0.0,
                "mean_normal_speed_m_s": sum(i.normal_speed_m_s for i in sel) / n if n else 0.0,
                "mean_tangential_speed_m_s": sum(i.tangential_speed_m_s for i in sel) / n if n else 0.0,
            }
        )
    return rows


def charge_angles(snapshots: dict[str, np.ndarray], setup: MillSetup) -> dict:
    """Shoulder and toe angles (deg, see the module docstring; None for a ring) and the centrifuged
    share of the balls over the last revolution."""
    p = setup.profile
    x, y = snapshots["x_m"], snapshots["y_m"]
    rho = np.hypot(x, y)
    band = rho >= p.radius - p.lifter_height - 2.0 * setup.ball_radius
    psi = np.degrees(np.arctan2(x, -y))
    n_snap = int(snapshots["snapshot"].max()) + 1 if snapshots["snapshot"].size else 0
    out: dict = {"shoulder_deg": None, "toe_deg": None, "snapshots": n_snap}
    if n_snap == 0:
        out["centrifuged_fraction"] = None
        return out
    nbins = int(round(360.0 / SECTOR_DEG))
    counts = np.bincount(((psi[band] + 180.0) // SECTOR_DEG).astype(int) % nbins, minlength=nbins) / n_snap
    stuck = _centrifuged(snapshots, setup, band, rho)
    out["centrifuged_fraction"] = float(stuck.mean())
    full = counts >= 0.5 * counts.max() if counts.max() > 0 else np.zeros(nbins, bool)
    if counts.max() > 0 and not full.all() and stuck.mean() < 0.5:
        k0 = int(np.argmax(counts))
        lo = k0
        while full[(lo - 1) % nbins]:
            lo -= 1
        hi = k0
        while full[(hi + 1) % nbins]:
            hi += 1
        out["toe_deg"] = -180.0 + lo * SECTOR_DEG
        out["shoulder_deg"] = -180.0 + (hi + 1) * SECTOR_DEG
    return out


def _centrifuged(snapshots: dict[str, np.ndarray], setup: MillSetup, band: np.ndarray, rho: np.ndarray) -> np.ndarray:
    """Per particle: in the band in every snapshot of the last revolution, turning with the liner."""
    x, y = snapshots["x_m"], snapshots["y_m"]
    t = snapshots["time_s"]
    last = t >= t.max() - setup.period_s * (1.0 - 0.5 / setup.snapshots_per_revolution)
    ang = (x * snapshots["vy_m_s"] - y * snapshots["vx_m_s"]) / np.maximum(rho**2, 1e-300)
    balls = snapshots["particle"].astype(int)
    stuck = np.ones(setup.n_particles, bool)
    for b in range(setup.n_particles):
        sel = last & (balls == b)
        stuck[b] = bool(sel.any() and band[sel].all() and ang[sel].mean() >= 0.9 * setup.omega)
    return stuck


def energy_balance(energy: dict[str, np.ndarray]) -> dict:
    """The drive's work against where it went, from the first to the last energy sample (J): the
    particles' kinetic and potential energy, the contacts' stored energy, and the dissipation by
    kind (impact damping, friction at the liner and in the bed, and the rock's rolling resistance:
    the bending moments' work less their stored energy, which ``elastic_shear_J`` holds)."""
    d = {k: float(v[-1] - v[0]) for k, v in energy.items()}
    mech = d["kinetic_J"] + d["potential_J"]
    rolling = d.get("rolling_J", 0.0)
    dissipated = d["damping_normal_J"] + d["damping_shear_J"] + d["friction_J"] + rolling
    stored = d["elastic_normal_J"] + d["elastic_shear_J"]
    w = d["drive_work_J"]
    liner = d.get("liner_friction_J")
    out: dict = {
        "drive_work_J": w,
        "mechanical_change_J": mech,
        "dissipated_J": dissipated,
        "stored_change_J": stored,
        "relative_error": (w - mech - dissipated - stored) / w if w else None,
        "mean_power_W": w / d["time_s"] if d["time_s"] > 0 else None,
    }
    if liner is not None:
        out["dissipated_by_kind_J"] = {
            "impact_damping": d["damping_normal_J"] + d["damping_shear_J"],
            "friction_at_liner": liner,
            "friction_in_bed": d["friction_J"] - liner,
        }
        if rolling:
            out["dissipated_by_kind_J"]["rolling_resistance"] = rolling
    return out


def write_spectrum_csv(path: Path, impacts: list[Impact], revolutions: float) -> None:
    """spectrum.csv: each impact's energy and the impacts per revolution at or above it (all places)."""
    with open(path, "w") as fh:
        fh.write("impact_energy_J,impacts_per_revolution_at_or_above,place,kind\n")
        for kind in KINDS:
            mine = [i for i in impacts if i.kind == kind]
            e, n = spectrum(mine, revolutions)
            places = [i.place for i in sorted(mine, key=lambda i: -i.impact_energy_J)]
            for ek, nk, pk in zip(e, n, places):
                fh.write(f"{ek!r},{nk!r},{pk},{kind}\n")


def plot_spectrum(path: Path, impacts: list[Impact], revolutions: float, title: str) -> None:
    """spectrum.png: impact energy (J) against the cumulative number of impacts per revolution, log-log."""
    from ...results.plots import pyplot

    plt = pyplot()

    fig, ax = plt.subplots(figsize=(6.4, 4.6))
    rock = any(i.kind == "rock" for i in impacts)
    for place, style in ((None, "k-"), ("lifter_face", "C0--"), ("lifter_top", "C1-."), ("plate", "C2:")):
        e, n = spectrum(impacts, revolutions, place, kind="ball")
        keep = e > 0
        if keep.any():
            ax.loglog(n[keep], e[keep], style, label=(place or "all places") + (" (balls)" if rock else ""))
    if rock:
        e, n = spectrum(impacts, revolutions, kind="rock")
        keep = e > 0
        if keep.any():
            ax.loglog(n[keep], e[keep], "-", color="C5", label="all places (rock)")
    ax.set_xlabel("cumulative number of impacts per revolution (-)")
    ax.set_ylabel("impact energy (J)")
    ax.set_title(title, fontsize=9)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def charge_figure(path: Path, snapshots: dict[str, np.ndarray], setup: MillSetup, angles: dict) -> None:
    """charge.png: the particles of the last snapshot in the mill's cross-section, the liner's profile at
    that time, and the shoulder and toe."""
    from ...results.plots import pyplot

    plt = pyplot()

    fig, ax = plt.subplots(figsize=(5.2, 5.2))
    last = snapshots["snapshot"] == snapshots["snapshot"].max()
    th = setup.omega * float(snapshots["time_s"][last][0])
    c, s = math.cos(th), math.sin(th)
    for seg in setup.profile.segments:
        (x0, y0), (x1, y1) = seg.start, seg.end
        ax.plot([c * x0 - s * y0, c * x1 - s * y1], [s * x0 + c * y0, s * x1 + c * y1], "k-", lw=0.6)
    k = snapshots["particle"][last].astype(int)
    x, y = snapshots["x_m"][last], snapshots["y_m"][last]
    ball = k < setup.n_balls
    ax.scatter(x[ball], y[ball], s=4, c="C0", label="balls" if setup.n_rocks else None)
    if setup.n_rocks:
        ax.scatter(x[~ball], y[~ball], s=4, c="C5", label="rock")
    R = setup.profile.radius
    for key, colour in (("shoulder_deg", "C3"), ("toe_deg", "C2")):
        if angles.get(key) is not None:
            a = math.radians(angles[key])
            ax.plot(
                [0, R * math.sin(a)],
                [0, -R * math.cos(a)],
                "-",
                color=colour,
                lw=1,
                label=f"{key[:-4]} {angles[key]:.0f} deg",
            )
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    if ax.get_legend_handles_labels()[1]:  # a centrifuging charge has no shoulder or toe to label
        ax.legend(fontsize=8, loc="upper left")
    else:
        ax.text(0.02, 0.98, "no shoulder or toe: the charge centrifuges", transform=ax.transAxes, va="top", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
