"""Figures (matplotlib, Agg): contact force with the Hertz curve, the paper's four contact-point
panels, gauge stresses and the energy balance. Called by rank 0 after a run; never by solvers."""
from __future__ import annotations

from pathlib import Path
from typing import Optional

import numpy as np

from ..theory.hertz import HertzHistory
from .timeseries import TimeSeries


def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _contact_window(ts: TimeSeries, pad: float = 0.5) -> tuple[float, float]:
    """Time window (s) around the contact pulse, padded by ``pad`` x its length."""
    t, f = ts.time, ts["contact_force_N"]
    on = np.nonzero(f > 1e-3 * max(f.max(), 1e-30))[0]
    if len(on) == 0:
        return float(t[0]), float(t[-1])
    t0, t1 = t[on[0]], t[on[-1]]
    d = max(t1 - t0, 1e-12)
    return float(max(t[0], t0 - pad * d)), float(min(t[-1], t1 + pad * d))


def plot_force(ts: TimeSeries, path: Path, hertz: Optional[HertzHistory] = None, title: str = "") -> None:
    """Contact force against time (us), with the Hertz history shifted to the same first contact."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(7, 4.2), constrained_layout=True)
    t, f = ts.time, ts["contact_force_N"]
    lo, hi = _contact_window(ts)
    sel = (t >= lo) & (t <= hi)
    ax.plot(t[sel] * 1e6, f[sel] / 1e3, lw=2, label="simulation")
    if hertz is not None:
        on = np.nonzero(f > 1e-3 * max(f.max(), 1e-30))[0]
        t0 = t[on[0] - 1] if len(on) and on[0] > 0 else 0.0
        ax.plot((hertz.time + t0) * 1e6, hertz.force / 1e3, "k--", lw=1.3, label="Hertz (quasi-static)")
    ax.set_xlabel("time [us]")
    ax.set_ylabel("contact force [kN]")
    ax.set_title(title or "Contact force")
    ax.grid(alpha=0.3)
    ax.legend()
    fig.savefig(path, dpi=130)
    plt.close(fig)


CONTACT_POINT_PANELS = [
    ("contact_point_displacement_m", 1e6, "displacement [um]"),
    ("contact_point_velocity_m_s", 1.0, "velocity [m/s]"),
    ("contact_point_acceleration_m_s2", 1e-3, "acceleration [km/s^2]"),
    ("contact_point_stress_Pa", 1e-9, "normal stress [GPa]"),
]


def plot_contact_point(series: dict[str, TimeSeries], path: Path, title: str = "",
                       window: Optional[tuple[float, float]] = None) -> None:
    """The paper's four panels (displacement, velocity, acceleration, stress of the liner's contact
    point, along the face normal) against time; one line per labelled series."""
    plt = _plt()
    fig, axes = plt.subplots(2, 2, figsize=(10, 7), constrained_layout=True)
    for label, ts in series.items():
        lo, hi = window or _contact_window(ts, pad=1.0)
        t = ts.time
        sel = (t >= lo) & (t <= hi)
        for ax, (col, scale, ylabel) in zip(axes.flat, CONTACT_POINT_PANELS):
            if col in ts:
                ax.plot(t[sel] * 1e6, ts[col][sel] * scale, label=label)
            ax.set_ylabel(ylabel)
    for ax, letter in zip(axes.flat, "abcd"):
        ax.set_xlabel("time [us]")
        ax.grid(alpha=0.3)
        ax.set_title(f"({letter})", loc="left")
    if len(series) > 1:
        axes.flat[0].legend()
    fig.suptitle(title or "Contact point of the liner (normal components)")
    fig.savefig(path, dpi=130)
    plt.close(fig)


def plot_gauges(ts: TimeSeries, path: Path, title: str = "") -> bool:
    """Gauge stresses (MPa) against time (ms); returns False when the series has no gauge."""
    cols = [c for c in ts.columns if c.startswith("gauge_") and c.endswith("_Pa")]
    if not cols:
        return False
    plt = _plt()
    fig, (ax0, ax1) = plt.subplots(1, 2, figsize=(11, 4), constrained_layout=True)
    lo, hi = _contact_window(ts, pad=3.0)
    t = ts.time
    for c in cols:
        name = c[len("gauge_"):-len("_stress_Pa")]
        ax0.plot(t * 1e3, ts[c] / 1e6, lw=0.8, label=name)
        sel = (t >= lo) & (t <= hi)
        ax1.plot(t[sel] * 1e6, ts[c][sel] / 1e6, label=name)
    ax0.set_xlabel("time [ms]")
    ax1.set_xlabel("time [us]")
    ax0.set_title("whole run")
    ax1.set_title("around the impact")
    for ax in (ax0, ax1):
        ax.set_ylabel("gauge stress sigma = E eps [MPa]")
        ax.grid(alpha=0.3)
        ax.legend()
    fig.suptitle(title or "Strain-gauge stresses")
    fig.savefig(path, dpi=130)
    plt.close(fig)
    return True


def plot_energy(ts: TimeSeries, path: Path, title: str = "") -> bool:
    """Kinetic, strain and total energy (J) against time; False when the series has none."""
    if "total_energy_J" not in ts:
        return False
    plt = _plt()
    fig, ax = plt.subplots(figsize=(7, 4.2), constrained_layout=True)
    t = ts.time
    scale, unit = (1e3, "ms") if t[-1] > 2e-3 else (1e6, "us")
    for col, label in (("kinetic_energy_J", "kinetic"), ("strain_energy_J", "strain"),
                       ("total_energy_J", "total"), ("ball_kinetic_energy_J", "ball kinetic")):
        if col in ts:
            ax.plot(t * scale, ts[col], label=label, lw=2 if col == "total_energy_J" else 1.2)
    ax.set_xlabel(f"time [{unit}]")
    ax.set_ylabel("energy [J]")
    ax.set_title(title or "Energy balance")
    ax.grid(alpha=0.3)
    ax.legend()
    fig.savefig(path, dpi=130)
    plt.close(fig)
    return True


def plot_friction(ts: TimeSeries, path: Path, mu: float, title: str = "") -> None:
    """Friction of an oblique impact: normal and tangential contact forces with the Coulomb bounds
    +-mu F_n (kN), and the ball's tangential velocity (m/s), against time (us)."""
    plt = _plt()
    fig, (ax, bx) = plt.subplots(2, 1, figsize=(7, 6), sharex=True, constrained_layout=True)
    t, fn, ft = ts.time, ts["contact_force_N"], ts["tangential_force_N"]
    lo, hi = _contact_window(ts)
    sel = (t >= lo) & (t <= hi)
    us = t[sel] * 1e6
    ax.plot(us, fn[sel] / 1e3, lw=2, label="normal force")
    ax.plot(us, ft[sel] / 1e3, lw=2, label="tangential force (along the incoming tangential velocity)")
    ax.fill_between(us, -mu * fn[sel] / 1e3, mu * fn[sel] / 1e3, color="0.85", label=f"Coulomb cone |F_t| <= {mu:g} F_n")
    ax.set_ylabel("force on the ball [kN]")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    bx.plot(us, ts["ball_tangential_velocity_m_s"][sel], lw=2, color="C2")
    bx.set_xlabel("time [us]")
    bx.set_ylabel("ball tangential velocity [m/s]")
    bx.grid(alpha=0.3)
    fig.suptitle(title or "Friction")
    fig.savefig(path, dpi=130)
    plt.close(fig)
