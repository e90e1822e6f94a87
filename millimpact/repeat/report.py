"""What ``millimpact repeat`` writes: ``impacts.csv``, the figures, ``summary.json`` / ``summary.txt``.

``impacts.csv``: one row per impact, the columns of
:data:`millimpact.repeat.sequence.OUTCOME_COLUMNS` (SI; the unit is each name's suffix,
restitutions and the plastic strain dimensionless), with a ``#`` header saying so.
Figures: ``restitution.png`` (e_n, and e_t for oblique impacts, against the impact number),
``dent.png`` (dent depth and the plastic work of each impact against the impact number),
``hardening.png`` for a plastic target (the surface hardness 3 sigma_y in HB at the impact point and
the dent's diameter against the impact number).
``summary.json``: the scene, method, impacts, the verdict (:func:`millimpact.repeat.verdict.classify`)
with its numbers, per-impact details (energy balance, rotation, launch shift, wall time) and the
small-strain note; written last, its presence marks a complete sequence.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import asdict
from pathlib import Path
from typing import Any

import numpy as np

from ..commandkit.store import write_atomic
from .sequence import HB_PER_PA, OUTCOME_COLUMNS, ImpactOutcome, ImpactSpec
from .verdict import Verdict


def small_strain_line(outcomes: Sequence[ImpactOutcome], rotations: Sequence[float]) -> str:
    """One line: the sequence's largest plastic strain and rotation at a peak force, and whether
    the small-strain model holds (:func:`millimpact.results.dent.small_strain_note`)."""
    from ..results.dent import small_strain_note

    eps = max((o.max_equivalent_plastic_strain for o in outcomes), default=0.0)
    rot = max((r for r in rotations if r is not None and math.isfinite(r)), default=math.nan)
    return small_strain_note(eps, rot, "at a peak force")


def write_impacts_csv(path: Path, outcomes: Sequence[ImpactOutcome]) -> None:
    """``impacts.csv`` (module docstring)."""
    lines = [
        "# repeated impacts at one spot (millimpact repeat): one row per impact, SI units "
        "(suffix of each name); restitutions and the equivalent plastic strain dimensionless; "
        "the dent is the residual state's after the impact (cumulative), the plastic work the impact's own",
        ",".join(OUTCOME_COLUMNS),
    ]
    for o in outcomes:
        d = asdict(o)
        lines.append(",".join(str(d[c]) if c == "impact" else f"{d[c]:.10g}" for c in OUTCOME_COLUMNS))
    path.write_text("\n".join(lines) + "\n")


def read_impacts_csv(path: Path) -> list[ImpactOutcome]:
    """The outcomes of an ``impacts.csv``."""
    rows = [ln for ln in Path(path).read_text().splitlines() if ln and not ln.startswith("#")]
    head = rows[0].split(",")
    out = []
    for ln in rows[1:]:
        vals = dict(zip(head, ln.split(",")))
        out.append(
            ImpactOutcome(
                impact=int(vals["impact"]),
                **{c: float(vals.get(c, "nan")) for c in OUTCOME_COLUMNS if c != "impact"},
            )
        )
    return out


def plot_sequence(folder: Path, outcomes: Sequence[ImpactOutcome], title: str) -> list[str]:
    """``restitution.png`` and ``dent.png`` (module docstring); returns their names."""
    from ..results.plots import pyplot

    plt = pyplot()
    from matplotlib.ticker import MaxNLocator

    k = np.array([o.impact for o in outcomes])
    e_n = np.array([o.restitution_normal for o in outcomes])
    e_t = np.array([o.restitution_tangential for o in outcomes])
    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    ax.plot(k, e_n, "o-", label="normal e_n")
    if np.any(np.isfinite(e_t)):
        ax.plot(k, e_t, "s--", label="tangential e_t")
    ax.set_xlabel("impact number")
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))  # impacts are counted, not measured
    ax.set_ylabel("coefficient of restitution (-)")
    ax.set_title(f"{title}: restitution")
    ax.grid(True, alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(folder / "restitution.png", dpi=120)
    plt.close(fig)

    figures = [
        (
            "dent.png",
            ([o.residual_dent_depth_m * 1e6 for o in outcomes], "dent depth", "residual dent depth (um)", "C0", "o-"),
            (
                [o.plastic_dissipation_J * 1e3 for o in outcomes],
                "plastic work",
                "plastic work of the impact (mJ)",
                "C3",
                "s--",
            ),
            "dent and plastic work",
        )
    ]
    hb = np.array([o.surface_flow_stress_Pa for o in outcomes]) * HB_PER_PA
    if np.any(np.isfinite(hb)):
        figures.append(
            (
                "hardening.png",
                (hb.tolist(), "surface hardness", "surface hardness 3 sigma_y (HB)", "C2", "o-"),
                (
                    [2e3 * o.residual_dent_radius_m for o in outcomes],
                    "dent diameter",
                    "residual dent diameter (mm)",
                    "C0",
                    "s--",
                ),
                "work hardening at the impact point",
            )
        )
    for name, left, right, what in figures:
        _twin_plot(plt, folder / name, k, left, right, f"{title}: {what}")
    return ["restitution.png", *(f[0] for f in figures)]


def _twin_plot(plt, path: Path, k, left: tuple, right: tuple, title: str) -> None:
    """One figure against the impact number: ``left`` and ``right`` are (values, label, axis label,
    colour, style) on two y axes."""
    from matplotlib.ticker import MaxNLocator

    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    axes = (ax, ax.twinx())
    for a, (values, label, axis_label, colour, style) in zip(axes, (left, right)):
        a.plot(k, values, style, color=colour, label=label)
        a.set_ylabel(axis_label, color=colour)
    for a in axes:
        a.set_ylim(bottom=0.0)
    ax.set_xlabel("impact number")
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    ax.set_title(title)
    ax.grid(True, alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def verdict_text(v: Verdict) -> str:
    """One line: the verdict and its reason."""
    return (
        f"verdict: {v.kind}"
        + (f" from impact {v.impacts_to_shakedown}" if v.impacts_to_shakedown else "")
        + (f" ({v.numbers['reason']})" if "reason" in v.numbers else "")
    )


def write_sequence(
    folder: Path,
    scene,
    method: str,
    impacts: Sequence[ImpactSpec],
    outcomes: Sequence[ImpactOutcome],
    verdict: Verdict,
    details: Sequence[dict],
    extra: dict,
) -> dict[str, Any]:
    """Write the sequence's files into ``folder`` (rank 0); ``summary.json`` last. Returns the summary."""
    from .. import __version__
    from ..scene.toml_io import dump_scene

    folder = Path(folder)
    write_impacts_csv(folder / "impacts.csv", outcomes)
    figures = plot_sequence(folder, outcomes, f"{scene.name}, {method}")
    (folder / "scene.toml").write_text(dump_scene(scene))
    note = small_strain_line(outcomes, [d.get("max_rotation_at_peak_rad", math.nan) for d in details])
    reached = [k for k, d in enumerate(details, 1) if d.get("zone_boundary_elastic") is False]
    notes = [note]
    if reached:
        notes.append(
            f"WARNING: the plastic region reached the contact zone's boundary (where the model is linear) "
            f"in impact(s) {', '.join(map(str, reached))}: rerun with a larger --set model.zone_radius"
        )
    summary = {
        "millimpact_version": __version__,
        "scene": scene.name,
        "method": method,
        "impacts": [
            {"speed_m_s": s.speed_m_s, "angle_deg": s.angle_deg, "offset_m": list(s.offset_m)} for s in impacts
        ],
        "verdict": {
            "kind": verdict.kind,
            "impacts_to_shakedown": verdict.impacts_to_shakedown,
            "numbers": verdict.numbers,
        },
        "outcomes": [asdict(o) for o in outcomes],
        "details": list(details),
        "notes": notes,
        **extra,
        "files": sorted(["impacts.csv", "scene.toml", *figures]),
    }
    lines = [
        f"millimpact repeat {scene.name}, method {method}: {len(outcomes)} impacts",
        verdict_text(verdict),
        *notes,
        "",
        f"{'impact':>6} {'e_n':>7} {'F_max kN':>9} {'t_c us':>7} {'W_p mJ':>8} {'dent um':>8} {'dent mm':>8} "
        f"{'eps_p':>6} {'HB':>5}",
    ]
    for o in outcomes:
        lines.append(
            f"{o.impact:6d} {o.restitution_normal:7.4f} {o.peak_normal_force_N / 1e3:9.4g} "
            f"{o.contact_duration_s * 1e6:7.4g} {o.plastic_dissipation_J * 1e3:8.4g} "
            f"{o.residual_dent_depth_m * 1e6:8.4g} {2e3 * o.residual_dent_radius_m:8.4g} "
            f"{o.max_equivalent_plastic_strain:6.3g} {o.surface_flow_stress_Pa * HB_PER_PA:5.0f}"
        )
    (folder / "summary.txt").write_text("\n".join(lines) + "\n")
    write_atomic(folder / "summary.json", json.dumps(_jsonable(summary), indent=1) + "\n")
    return summary


def _jsonable(x):
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, (np.floating, float)):
        return float(x) if math.isfinite(x) else None
    if isinstance(x, np.integer):
        return int(x)
    return x
