"""Figures (matplotlib, Agg): contact force with the Hertz curve, the paper's four contact-point
panels, gauge stresses and the energy balance. Called by rank 0 after a run; never by solvers."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..theory.hertz import HertzHistory
from .timeseries import TimeSeries


def pyplot():
    """``matplotlib.pyplot`` on the Agg backend (files only, no display), the one every figure
    of the package draws with; the backend is selected on the first call."""
    import matplotlib

    if not _BACKEND:
        matplotlib.use("Agg")
        _BACKEND.append("Agg")
    import matplotlib.pyplot as plt

    return plt


_BACKEND: list[str] = []


#: prefixes by power of ten, for axis units chosen by the data's span
_PREFIX = {-9: "n", -6: "\u00b5", -3: "m", 0: "", 3: "k", 6: "M", 9: "G"}


def time_unit(span: float) -> tuple[float, str]:
    """(factor, unit) for a time axis spanning ``span`` seconds: µs below 1 ms, ms below 1 s, else
    s, so the tick labels stay between about 0.1 and 1000 (a 2 ms axis reads 0-2 ms, not 0-2000 µs)."""
    if span < 1e-3:
        return 1e6, "\u00b5s"
    if span < 1.0:
        return 1e3, "ms"
    return 1.0, "s"


def value_unit(column: str, values: np.ndarray) -> tuple[float, str]:
    """(factor, unit) for a time-series column (SI, the unit its name's suffix): the SI prefix that
    puts the largest magnitude between 1 and 1000 (N -> kN, m -> µm, Pa -> MPa or GPa, ...)."""
    for suffix, unit in (  # noqa: B007 (the unit of the suffix found is used after the loop)
        ("_m_s2", "m/s\u00b2"),
        ("_m_s", "m/s"),
        ("_N_s", "N s"),
        ("_Pa", "Pa"),
        ("_N", "N"),
        ("_J", "J"),
        ("_m", "m"),
        ("_s", "s"),
    ):
        if column.endswith(suffix):
            break
    else:
        return 1.0, ""
    if unit in ("N s",):
        return 1.0, unit
    peak = float(np.max(np.abs(values))) if len(values) else 0.0
    power = 0 if peak == 0 or not np.isfinite(peak) else int(np.floor(np.log10(peak) / 3.0)) * 3
    power = min(max(power, -9), 9)
    return 10.0**-power, _PREFIX[power] + unit


def _contact_window(ts: TimeSeries, pad: float = 0.5) -> tuple[float, float]:
    """Time window (s) around the contact pulse, padded by ``pad`` x its length."""
    t, f = ts.time, ts["contact_force_N"]
    on = np.nonzero(f > 1e-3 * max(f.max(), 1e-30))[0]
    if len(on) == 0:
        return float(t[0]), float(t[-1])
    t0, t1 = t[on[0]], t[on[-1]]
    d = max(t1 - t0, 1e-12)
    return float(max(t[0], t0 - pad * d)), float(min(t[-1], t1 + pad * d))


def plot_force(ts: TimeSeries, path: Path, hertz: HertzHistory | None = None, title: str = "") -> None:
    """Contact force against time, with the Hertz history shifted to the same first contact."""
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7, 4.2), constrained_layout=True)
    t, f = ts.time, ts["contact_force_N"]
    lo, hi = _contact_window(ts)
    sel = (t >= lo) & (t <= hi)
    ts_, tu = time_unit(hi - lo)
    fs, fu = value_unit("contact_force_N", f)
    ax.plot(t[sel] * ts_, f[sel] * fs, lw=2, label="simulation")
    if hertz is not None:
        on = np.nonzero(f > 1e-3 * max(f.max(), 1e-30))[0]
        t0 = t[on[0] - 1] if len(on) and on[0] > 0 else 0.0
        ax.plot((hertz.time + t0) * ts_, hertz.force * fs, "k--", lw=1.3, label="Hertz (quasi-static)")
    ax.set_xlabel(f"time [{tu}]")
    ax.set_ylabel(f"contact force [{fu}]")
    ax.set_title(title or "Contact force")
    ax.grid(alpha=0.3)
    ax.legend()
    fig.savefig(path, dpi=130)
    plt.close(fig)


CONTACT_POINT_PANELS = [
    ("contact_point_displacement_m", 1e6, "displacement [\u00b5m]"),
    ("contact_point_velocity_m_s", 1.0, "velocity [m/s]"),
    ("contact_point_acceleration_m_s2", 1e-3, "acceleration [km/s\u00b2]"),
    ("contact_point_stress_Pa", 1e-9, "normal stress [GPa]"),
]


def plot_contact_point(
    series: dict[str, TimeSeries], path: Path, title: str = "", window: tuple[float, float] | None = None
) -> None:
    """The paper's four panels (displacement, velocity, acceleration, stress of the liner's contact
    point, along the face normal) against time; one line per labelled series."""
    plt = pyplot()
    fig, axes = plt.subplots(2, 2, figsize=(10, 7), constrained_layout=True)
    windows = {label: window or _contact_window(ts, pad=1.0) for label, ts in series.items()}
    span = max(hi - lo for lo, hi in windows.values())
    tscale, tu = time_unit(span)
    for ax, (col, _, label_) in zip(axes.flat, CONTACT_POINT_PANELS):
        name = label_.split(" [")[0]
        present = [ts[col] for ts in series.values() if col in ts]
        scale, unit = value_unit(col, np.concatenate(present) if present else np.zeros(0))
        for label, ts in series.items():
            lo, hi = windows[label]
            sel = (ts.time >= lo) & (ts.time <= hi)
            if col in ts:
                ax.plot(ts.time[sel] * tscale, ts[col][sel] * scale, label=label)
        ax.set_ylabel(f"{name} [{unit}]")
    for ax, letter in zip(axes.flat, "abcd"):
        ax.set_xlabel(f"time [{tu}]")
        ax.grid(alpha=0.3)
        ax.set_title(f"({letter})", loc="left")
    if len(series) > 1:
        axes.flat[0].legend()
    fig.suptitle(title or "Contact point of the liner (normal components)")
    fig.savefig(path, dpi=130)
    plt.close(fig)


def plot_gauges(ts: TimeSeries, path: Path, title: str = "") -> bool:
    """Gauge stresses against time: the whole run and, when the run is much longer than the impact,
    a second panel around it; units chosen by span (:func:`time_unit`, :func:`value_unit`). Returns
    False when the series has no gauge."""
    cols = [c for c in ts.columns if c.startswith("gauge_") and c.endswith("_Pa")]
    if not cols:
        return False
    plt = pyplot()
    lo, hi = _contact_window(ts, pad=3.0)
    t = ts.time
    # a second panel "around the impact" only when it shows something the whole run does not
    two = (t[-1] - t[0]) > 4.0 * (hi - lo)
    fig, axes = plt.subplots(1, 2 if two else 1, figsize=(11, 4) if two else (7, 4.2), constrained_layout=True)
    axes = list(np.atleast_1d(axes))
    vs, vu = value_unit("gauge_stress_Pa", np.concatenate([ts[c] for c in cols]))
    windows = [(float(t[0]), float(t[-1]))] + ([(lo, hi)] if two else [])
    for ax, (a, b) in zip(axes, windows):
        sel = (t >= a) & (t <= b)
        tscale, tu = time_unit(b - a)
        for c in cols:
            ax.plot(
                t[sel] * tscale,
                ts[c][sel] * vs,
                lw=0.8 if a == t[0] and two else 1.3,
                label=c[len("gauge_") : -len("_stress_Pa")],
            )
        ax.set_xlabel(f"time [{tu}]")
    if two:
        axes[0].set_title("whole run")
        axes[1].set_title("around the impact")
    for ax in axes:
        ax.set_ylabel(f"gauge stress \u03c3 = E \u03b5 [{vu}]")
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
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7, 4.2), constrained_layout=True)
    t = ts.time
    scale, unit = time_unit(float(t[-1] - t[0]))
    for col, label in (
        ("kinetic_energy_J", "kinetic"),
        ("strain_energy_J", "elastic strain"),
        ("total_energy_J", "kinetic + elastic"),
        ("ball_kinetic_energy_J", "ball kinetic"),
        ("friction_dissipation_J", "dissipated by friction"),
        ("plastic_dissipation_J", "plastic work (dissipated)"),
    ):
        if col in ts:
            ax.plot(t * scale, ts[col], label=label, lw=2 if col == "total_energy_J" else 1.2)
    lost = [c for c in ("friction_dissipation_J", "plastic_dissipation_J") if c in ts]
    if lost:
        ax.plot(
            t * scale,
            ts["total_energy_J"] + sum(ts[c] for c in lost),
            "k--",
            lw=1.5,
            label="kinetic + elastic + dissipated (conserved)",
        )
    ax.set_xlabel(f"time [{unit}]")
    es, eu = value_unit("total_energy_J", ts["total_energy_J"])
    for line in ax.get_lines():
        line.set_ydata(np.asarray(line.get_ydata()) * es)
    ax.relim()
    ax.autoscale_view()
    ax.set_ylabel(f"energy [{eu}]")
    ax.set_title(title or "Energy balance")
    ax.grid(alpha=0.3)
    ax.legend()
    fig.savefig(path, dpi=130)
    plt.close(fig)
    return True


def plot_friction(ts: TimeSeries, path: Path, mu: float, title: str = "") -> None:
    """Friction of an oblique impact: normal and tangential contact forces with the Coulomb bounds
    +-mu F_n (kN), and the ball's tangential velocity (m/s), against time (us)."""
    plt = pyplot()
    fig, (ax, bx) = plt.subplots(2, 1, figsize=(7, 6), sharex=True, constrained_layout=True)
    t, fn, ft = ts.time, ts["contact_force_N"], ts["tangential_force_N"]
    lo, hi = _contact_window(ts)
    sel = (t >= lo) & (t <= hi)
    tscale, tu = time_unit(hi - lo)
    fs, fu = value_unit("contact_force_N", fn)
    us = t[sel] * tscale
    ax.plot(us, fn[sel] * fs, lw=2, label="normal force")
    ax.plot(us, ft[sel] * fs, lw=2, label="tangential force (along the incoming tangential velocity)")
    ax.fill_between(us, -mu * fn[sel] * fs, mu * fn[sel] * fs, color="0.85", label=f"Coulomb cone |F_t| <= {mu:g} F_n")
    ax.set_ylabel(f"force on the ball [{fu}]")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    bx.plot(us, ts["ball_tangential_velocity_m_s"][sel], lw=2, color="C2")
    bx.set_xlabel(f"time [{tu}]")
    bx.set_ylabel("ball tangential velocity [m/s]")
    bx.grid(alpha=0.3)
    fig.suptitle(title or "Friction")
    fig.savefig(path, dpi=130)
    plt.close(fig)


def plot_force_approach(ts: TimeSeries, path: Path, title: str = "") -> None:
    """Contact force against approach over the first impact: loading and unloading (the loop a DEM
    contact law is fitted to; its area is the energy the contact kept: plastic work and waves)."""
    plt = pyplot()
    f, d = ts["contact_force_N"], ts["approach_m"]
    on = np.nonzero(f > 0)[0]
    fig, ax = plt.subplots(figsize=(7, 4.5), constrained_layout=True)
    if len(on):
        sel = slice(max(on[0] - 1, 0), min(on[-1] + 2, len(f)))
        i_peak = int(np.argmax(f))
        fs, fu = value_unit("contact_force_N", f)
        ds, du = value_unit("approach_m", d[sel])
        ax.plot(d[sel.start : i_peak + 1] * ds, f[sel.start : i_peak + 1] * fs, lw=2, label="loading")
        ax.plot(d[i_peak : sel.stop] * ds, f[i_peak : sel.stop] * fs, lw=2, label="unloading")
        ax.set_xlabel(f"approach [{du}]")
        ax.set_ylabel(f"contact force [{fu}]")
        ax.legend()
    ax.grid(alpha=0.3)
    ax.set_title(title or "Force against approach")
    fig.savefig(path, dpi=130)
    plt.close(fig)


def plot_dent(profile: dict, path: Path, depth: float, radius: float, title: str = "") -> None:
    """The residual dent: depth below the undeformed face against the distance from the contact
    point (``profile`` = {"r_m": [...], "depth_m": [...]}, the summary's residual_dent_profile)."""
    plt = pyplot()
    r, d = np.asarray(profile["r_m"]), np.asarray(profile["depth_m"])
    fig, ax = plt.subplots(figsize=(7, 4), constrained_layout=True)
    rs, ru = value_unit("r_m", r)
    ds, du = value_unit("depth_m", d if d.size else np.zeros(1))
    ax.plot(r * rs, -d * ds, lw=2)
    ax.axvline(radius * rs, color="0.5", ls="--", lw=1, label=f"dent radius {radius * rs:.3g} {ru}")
    ax.axhline(-depth * ds, color="0.7", ls=":", lw=1, label=f"depth {depth * ds:.3g} {du}")
    ax.set_xlabel(f"distance from the contact point along the face [{ru}]")
    ax.set_ylabel(f"surface height [{du}]")
    ax.grid(alpha=0.3)
    ax.legend()
    ax.set_title(title or "Residual dent")
    fig.savefig(path, dpi=130)
    plt.close(fig)


def plot_plastic_section(section: dict, path: Path, title: str = "") -> None:
    """The plastic zone on the section through the contact axis: the equivalent plastic strain of
    the zone's quadrature points near the plane (``section`` from
    :func:`millimpact.results.dent.plastic_section`), filled contours over the distance from the
    contact axis and the depth (the struck body below the face, the ball above), with the Hertz
    contact radius a_max, the predicted plastic radius and the contact zone's boundary."""
    import matplotlib.tri as mtri

    plt = pyplot()
    s, d, alpha = (np.asarray(section[k]) for k in ("s_m", "depth_m", "alpha"))
    zone = float(section["zone_radius_m"])
    fig, ax = plt.subplots(figsize=(7.5, 5.5), constrained_layout=True)
    sc, unit = value_unit("r_m", np.array([zone]))
    top = float(alpha.max()) if alpha.size else 0.0
    if alpha.size >= 3 and top > 0:
        tri = mtri.Triangulation(s * sc, d * sc)
        # drop the long, thin triangles Delaunay makes across the gap between the two bodies
        xy = np.column_stack([s, d]) * sc
        edges = np.max(
            [np.linalg.norm(xy[tri.triangles[:, i]] - xy[tri.triangles[:, (i + 1) % 3]], axis=1) for i in range(3)],
            axis=0,
        )
        tri.set_mask(edges > 4.0 * np.median(edges))
        levels = np.linspace(0.0, top, 11)
        levels[0] = 1e-6 * top
        cf = ax.tricontourf(tri, alpha, levels=levels, cmap="viridis", extend="neither")
        fig.colorbar(cf, ax=ax, label="equivalent plastic strain")
    else:
        ax.text(0.5, 0.5, "no plastic strain", transform=ax.transAxes, ha="center")
    th = np.linspace(0.0, 2.0 * np.pi, 200)
    for r, style, label in (
        (zone, "k-", f"contact zone, radius {zone * sc:.3g} {unit}"),
        (float(section["predicted_radius_m"]), "C1--", "predicted plastic radius (cavity model)"),
    ):
        if r > 0:
            ax.plot(r * sc * np.cos(th), r * sc * np.sin(th), style, lw=1.0, label=label)
    a = float(section["a_max_m"]) * sc
    ax.plot([-a, a], [0.0, 0.0], color="C3", lw=3, label="Hertz contact diameter 2 a_max")
    ax.axhline(0.0, color="0.5", lw=0.5)
    ax.set_xlim(-1.1 * zone * sc, 1.1 * zone * sc)
    ax.set_ylim(1.1 * zone * sc, -1.1 * zone * sc)  # depth down
    ax.set_aspect("equal")
    ax.set_xlabel(f"distance from the contact axis in the section [{unit}]")
    ax.set_ylabel(f"depth below the struck face [{unit}] (ball above)")
    ax.legend(fontsize=7, loc="lower right")
    ax.set_title(title or "Plastic zone on the section through the contact axis")
    fig.savefig(path, dpi=130)
    plt.close(fig)
