"""Figures of a parameter study (matplotlib, Agg): all cases overlaid.

``contact_point.png`` the paper's four contact-point panels around the impact, ``contact_point_run.png``
the same over the whole run, ``contact_force.png`` the contact force of each case with its Hertz curve,
``trends.png`` the peaks against the parameter (log-log) beside Hertz's scaling laws,
``restitution.png`` (a speed sweep) the restitution against the impact speed beside Thornton's
elastic-plastic curve and the elastic line.
Called by rank 0 after the cases are computed.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..results.plots import CONTACT_POINT_PANELS, pyplot
from ..results.timeseries import TimeSeries
from ..theory.hertz import HertzHistory

#: the "whole run" figure shows the first RUN_WINDOW seconds: the impact and the block's first
#: vibration periods (the undamped ringing then repeats to the end of the run)
RUN_WINDOW = 2e-3


def _case_window(
    series: Sequence[TimeSeries], t_starts: Sequence[float], t_cs: Sequence[float], pad: float = 0.6
) -> tuple[float, float]:
    """A window (s, relative to each case's first contact) that holds every case's pulse, padded."""
    longest = max(t_cs) if len(t_cs) else 1e-4
    return -0.1 * longest, (1.0 + pad) * longest


def plot_study_contact_point(
    cases: Sequence[tuple[str, TimeSeries, float, float]], path: Path, title: str, whole_run: bool = False
) -> None:
    """The paper's four panels (liner contact point: normal displacement, velocity, acceleration,
    normal stress) with one line per case.

    ``cases``: (label, series, first-contact time s, contact duration s). Around the impact the time
    axis is the time since each case's first contact (us), so the pulses line up; with
    ``whole_run`` it is the simulated time (ms) up to :data:`RUN_WINDOW`.
    """
    plt = pyplot()
    fig, axes = plt.subplots(2, 2, figsize=(11, 7.5), constrained_layout=True)
    lo, hi = _case_window([c[1] for c in cases], [c[2] for c in cases], [c[3] for c in cases])
    smooth_peak = raw_peak = 0.0
    for label, ts, t0, tc in cases:
        t = ts.time
        if whole_run:
            sel = t <= min(t[-1], RUN_WINDOW)
            x = t[sel] * 1e3
        else:
            rel = t - t0
            sel = (rel >= lo) & (rel <= hi)
            x = rel[sel] * 1e6
        for i, (ax, (col, scale, ylabel)) in enumerate(zip(axes.flat, CONTACT_POINT_PANELS)):
            if col in ts:
                thin = whole_run or i == 2  # the raw acceleration is noisy: keep it behind its smooth part
                (line,) = ax.plot(
                    x,
                    ts[col][sel] * scale,
                    lw=0.8 if thin else 1.4,
                    alpha=0.5 if i == 2 and not whole_run else (0.85 if whole_run else 1.0),
                    label=label,
                )
                if i == 2 and not whole_run and tc > 0 and "contact_point_velocity_m_s" in ts:
                    # the smooth part: the velocity's slope over windows of t_c / 8, 10-90 % of the pulse
                    w = tc / 8.0
                    tt = np.linspace(t0 + 0.1 * tc, t0 + 0.9 * tc, 60)
                    v = ts["contact_point_velocity_m_s"]
                    a_w = (np.interp(tt + w / 2, t, v) - np.interp(tt - w / 2, t, v)) / w
                    ax.plot((tt - t0) * 1e6, a_w * scale, "--", color=line.get_color(), lw=2.4, zorder=5)
                    smooth_peak = max(smooth_peak, float(np.max(np.abs(a_w))) * scale)
                    raw_peak = max(raw_peak, float(np.max(np.abs(ts[col][sel]))) * scale)
            ax.set_ylabel(ylabel)
    if not whole_run and smooth_peak > 0:
        ax = axes.flat[2]
        ax.plot([], [], "k--", lw=2.2, label="velocity slope over t_c/8")
        if raw_peak > 5 * smooth_peak:
            # the one-step jumps at first contact and release (a resolution value) would flatten the rest
            ax.set_ylim(-5 * smooth_peak, 5 * smooth_peak)
            ax.text(
                0.02,
                0.03,
                f"clipped: one-step spikes at first contact / release up to {raw_peak:.3g} km/s^2",
                transform=ax.transAxes,
                fontsize=7,
                color="0.3",
            )
    for ax, letter, (col, _, _) in zip(axes.flat, "abcd", CONTACT_POINT_PANELS):
        ax.set_xlabel("time [ms]" if whole_run else "time since first contact [us]")
        ax.grid(alpha=0.3)
        name = col.replace("contact_point_", "").rsplit("_", 1)[0].replace("_m", "")
        ax.set_title(f"({letter}) {name}", loc="left")
        ax.legend(fontsize=8)
    fig.suptitle(title)
    fig.savefig(path, dpi=130)
    plt.close(fig)


def plot_study_force(cases: Sequence[tuple[str, TimeSeries, float, HertzHistory]], path: Path, title: str) -> None:
    """Contact force (kN) of each case against the time since first contact (us), each with its Hertz
    curve (dashed, same colour)."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(8, 4.8), constrained_layout=True)
    longest = max(h.contact_time for _, _, _, h in cases)
    for i, (label, ts, t0, hist) in enumerate(cases):
        color = f"C{i}"
        rel = ts.time - t0
        sel = (rel >= -0.1 * longest) & (rel <= 1.3 * longest)
        ax.plot(rel[sel] * 1e6, ts["contact_force_N"][sel] / 1e3, color=color, lw=1.8, label=f"{label}")
        ax.plot(
            hist.time * 1e6, hist.force / 1e3, "--", color=color, lw=1.0, label=f"{label}, Hertz" if i == 0 else None
        )
    ax.plot([], [], "k--", lw=1.0, label="dashed: Hertz (quasi-static, half-space)")
    ax.set_xlabel("time since first contact [us]")
    ax.set_ylabel("contact force [kN]")
    ax.set_title(title)
    ax.grid(alpha=0.3)
    handles, labels = ax.get_legend_handles_labels()
    keep = [(h, lab) for h, lab in zip(handles, labels) if not lab.endswith(", Hertz")]
    ax.legend([h for h, _ in keep], [lab for _, lab in keep], fontsize=8)
    fig.savefig(path, dpi=130)
    plt.close(fig)


def plot_study_trends(
    x: np.ndarray,
    xlabel: str,
    quantities: Sequence[tuple[str, np.ndarray, np.ndarray | None]],
    path: Path,
    title: str,
) -> None:
    """Peaks against the parameter on log-log axes, each normalised by its value at the first case:
    simulation (markers and line) beside Hertz's prediction for the same scenes (dashed).

    ``quantities``: (name, simulated values, Hertz values or None).
    """
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7.5, 5), constrained_layout=True)
    for i, (name, sim, hz) in enumerate(quantities):
        color = f"C{i}"
        sim = np.asarray(sim, float)
        if not np.all(np.isfinite(sim)) or sim[0] == 0:
            continue
        ax.plot(x, np.abs(sim / sim[0]), "o-", color=color, label=name)
        if hz is not None and np.all(np.isfinite(hz)) and hz[0] != 0:
            ax.plot(x, np.abs(np.asarray(hz) / hz[0]), "--", color=color, lw=1.0)
    ax.plot([], [], "k--", lw=1.0, label="dashed: Hertz")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.minorticks_off()
    ax.set_xticks(x)
    ax.set_xticklabels([f"{v:g}" for v in x])
    lo, hi = ax.get_ylim()
    ticks = [m * 10.0**e for e in range(-3, 4) for m in (1, 1.5, 2, 3, 5, 7)]
    ticks = [v for v in ticks if lo <= v <= hi]
    if len(ticks) > 12:
        ticks = [v for v in ticks if str(v).lstrip("0.").startswith(("1", "2", "5"))]
    ax.set_yticks(ticks)
    ax.set_yticklabels([f"{v:g}" for v in ticks])
    ax.set_xlabel(xlabel)
    ax.set_ylabel("peak / peak of the first case")
    ax.set_title(title)
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    fig.savefig(path, dpi=130)
    plt.close(fig)


def plot_study_restitution(
    speed: np.ndarray, e: np.ndarray, path: Path, title: str, thornton: tuple[float, str] | None = None
) -> None:
    """Restitution against impact speed (log axis), with Thornton's 1997 curve for the yield-onset
    speed ``thornton = (V_y in m/s, label)`` (none for elastic materials) and the elastic e = 1."""
    from ..theory.thornton import restitution_thornton

    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7, 4.5), constrained_layout=True)
    ax.plot(speed, e, "o-", color="C0", label="millimpact")
    lo, hi = float(np.min(speed)), float(np.max(speed))
    v = np.geomspace(lo / 1.5, hi * 1.5, 200)
    ax.plot(v, np.ones_like(v), ":", color="0.4", lw=1.0, label="elastic, quasi-static (e = 1)")
    if thornton is not None:
        vy, label = thornton
        ax.plot(v, restitution_thornton(v, vy), "--", color="C3", lw=1.2, label=label)
        if lo / 1.5 < vy < hi * 1.5:
            ax.axvline(vy, color="C3", lw=0.6, alpha=0.5)
    ax.set_xscale("log")
    ax.set_xlabel("impact speed [m/s]")
    ax.set_ylabel("restitution e")
    ax.set_ylim(0.0, 1.05)
    ax.set_title(title)
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    fig.savefig(path, dpi=130)
    plt.close(fig)
