"""Results: time series with units, the run summary, and their files (CSV, JSON, HDF5).

Column names carry their unit as a suffix (``time_s``, ``contact_force_N``); :data:`UNITS` maps
each known column to its unit. Files are written by rank 0 only, into a staging folder that is
renamed into place when complete, so an interrupted run never leaves a folder that looks finished.
"""

from __future__ import annotations

import csv
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .. import __version__
from .output_folder import hdf5_file

#: known time-series columns and their units (names end with the unit)
UNITS = {
    "time_s": "s",
    "contact_force_N": "N",
    "approach_m": "m",
    "contact_radius_m": "m",
    "ball_velocity_m_s": "m/s",
    "contact_point_displacement_m": "m",
    "contact_point_velocity_m_s": "m/s",
    "contact_point_acceleration_m_s2": "m/s^2",
    "contact_point_stress_Pa": "Pa",
    "contact_point_von_mises_Pa": "Pa",
    "ball_kinetic_energy_J": "J",
    "kinetic_energy_J": "J",
    "strain_energy_J": "J",
    "total_energy_J": "J",
}


def unit_of(column: str) -> str:
    """Unit of a column from its name (``gauge_A_stress_Pa`` -> ``Pa``)."""
    if column in UNITS:
        return UNITS[column]
    for suffix, unit in (
        ("_m_s2", "m/s^2"),
        ("_m_s", "m/s"),
        ("_Pa", "Pa"),
        ("_N", "N"),
        ("_J", "J"),
        ("_m", "m"),
        ("_s", "s"),
    ):
        if column.endswith(suffix):
            return unit
    return ""


@dataclass
class TimeSeries:
    """Named columns of equal length; ``time_s`` first."""

    columns: dict[str, np.ndarray] = field(default_factory=dict)

    def __getitem__(self, name: str) -> np.ndarray:
        return self.columns[name]

    def __contains__(self, name: str) -> bool:
        return name in self.columns

    @property
    def time(self) -> np.ndarray:
        return self.columns["time_s"]

    @classmethod
    def from_rows(cls, names: list[str], rows: list[list[float]]) -> TimeSeries:
        data = np.asarray(rows, dtype=float).reshape(len(rows), len(names))
        return cls({n: data[:, i].copy() for i, n in enumerate(names)})

    def write_csv(self, path: Path) -> None:
        names = list(self.columns)
        data = np.column_stack([self.columns[n] for n in names])
        with open(path, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow(names)
            for row in data:
                w.writerow([f"{x:.10g}" for x in row])

    @classmethod
    def read_csv(cls, path: Path) -> TimeSeries:
        with open(path, newline="") as fh:
            rows = list(csv.reader(fh))
        names = [n.strip() for n in rows[0]]
        return cls.from_rows(names, [[float(x) for x in r] for r in rows[1:] if r])


def contact_metrics(ts: TimeSeries) -> dict[str, float]:
    """Peak force (N), contact duration (s), maximum approach (m) and impulse (N s) of the first
    contact pulse.

    The duration runs from the first to the last sample of the first pulse with force > 0, each end
    refined by extrapolating F^(2/3) linearly to zero from the two samples beside it: near its ends a
    Hertz pulse goes as F ~ (t - t0)^(3/2), so this is exact there and removes the up-to-one-step
    bias of taking the zero samples.
    """
    t, f = ts.time, ts["contact_force_N"]
    fmax = float(np.max(f)) if len(f) else 0.0
    out = {
        "peak_contact_force_N": fmax,
        "contact_duration_s": 0.0,
        "impulse_N_s": float(np.trapz(f, t)),
        "time_of_peak_force_s": float(t[int(np.argmax(f))]) if len(f) else 0.0,
    }
    if "approach_m" in ts:
        out["max_approach_m"] = float(np.max(ts["approach_m"]))
    if fmax <= 0:
        return out
    on = f > 1e-9 * fmax
    i0 = int(np.argmax(on))
    i1 = i0
    while i1 + 1 < len(f) and on[i1 + 1]:
        i1 += 1
    y = np.maximum(f, 0.0) ** (2.0 / 3.0)

    def edge(i_in: int, i_next: int, i_out: int) -> float:
        """Zero of the line through (t[i_in], y[i_in]) and (t[i_next], y[i_next]), kept between the
        last zero sample i_out and i_in."""
        if i_out < 0 or i_out >= len(f):
            return float(t[i_in])
        if i_next == i_in or y[i_next] == y[i_in]:
            return float(t[i_out])
        tz = t[i_in] - y[i_in] * (t[i_next] - t[i_in]) / (y[i_next] - y[i_in])
        lo, hi = sorted((t[i_out], t[i_in]))
        return float(min(max(tz, lo), hi))

    t_start = edge(i0, min(i0 + 1, i1), i0 - 1)
    t_end = edge(i1, max(i1 - 1, i0), i1 + 1)
    out["contact_duration_s"] = t_end - t_start
    out["contact_start_s"] = t_start
    return out


def jsonable(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {str(k): jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v) for v in obj]
    if isinstance(obj, (np.floating, float)):
        v = float(obj)
        return v if math.isfinite(v) else None
    if isinstance(obj, np.integer):
        return int(obj)
    if isinstance(obj, np.ndarray):
        return jsonable(obj.tolist())
    return obj


def write_summary(folder: Path, summary: dict) -> None:
    """``summary.json`` with the package version."""
    data = {"millimpact_version": __version__, **summary}
    (folder / "summary.json").write_text(json.dumps(jsonable(data), indent=2) + "\n")


def write_hdf5(folder: Path, ts: TimeSeries, summary: dict, scene_toml: str, filename: str = "timeseries.h5") -> Path:
    """``timeseries.h5``: one dataset per column with a ``unit`` attribute, the summary as JSON and
    the scene as TOML text in the root attributes. Returns the file's path."""
    with hdf5_file(folder / filename) as h5:
        fill_hdf5(h5, ts, summary, scene_toml)
    return folder / filename


def fill_hdf5(h5, ts: TimeSeries, summary: dict, scene_toml: str) -> None:
    """The datasets and attributes of :func:`write_hdf5` in an open ``h5py.File``."""
    h5.attrs["format"] = "millimpact-timeseries"
    h5.attrs["format_version"] = 1
    h5.attrs["millimpact_version"] = __version__
    h5.attrs["scene_toml"] = scene_toml
    h5.attrs["summary_json"] = json.dumps(jsonable(summary))
    g = h5.create_group("timeseries")
    for name, col in ts.columns.items():
        d = g.create_dataset(name, data=np.asarray(col, dtype=float))
        d.attrs["unit"] = unit_of(name)
