"""Reference files: a run written so that another implementation (DEM, Hertz spring, another FE
code) can be scored against it with ``millimpact compare``.

``millimpact run SCENE --reference`` adds to the run folder

- ``reference.h5``: root attributes ``format = "millimpact-reference"``, ``format_version = 1``,
  ``millimpact_version``, ``scene``, ``method``, ``scene_toml`` (the resolved scene),
  ``summary_json``, ``time_origin``, ``first_contact_s``; group ``timeseries`` with one float64
  dataset per column (attributes ``unit``, ``description``; the group's ``columns`` attribute keeps
  the column order, ``time_s`` first); groups ``hertz`` (the Hertz values of the scene),
  ``metrics`` (peak force, duration, ...) and ``model`` (method, sizes, plan) as attributes;
- ``reference.csv``: the same columns as ``timeseries.csv`` (one header row of ``name_unit``
  names, then numbers), with the sidecar ``reference.json`` (``format = "millimpact-reference-csv"``,
  the same metadata and a ``columns`` list of name, unit, description).

:func:`read_reference` reads either (or a run folder, or a plain ``timeseries.h5/.csv``).
"""

from __future__ import annotations

import csv
import json
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .. import __version__
from ..errors import InputError
from .output_folder import hdf5_file, is_millimpact_output
from .timeseries import TimeSeries, fill_hdf5, jsonable, unit_of

REFERENCE_FORMAT = "millimpact-reference"
REFERENCE_CSV_FORMAT = "millimpact-reference-csv"
REFERENCE_VERSION = 1

TIME_ORIGIN = (
    "t = 0 when the ball, moving at its arrival velocity, is the gap `first_contact_s` x normal "
    "speed away from the struck face; first contact at t = first_contact_s"
)

#: what each column means (sign conventions included); gauges match ``gauge_<name>_stress_Pa``
DESCRIPTIONS = {
    "time_s": "time since the start of the run (see time_origin)",
    "contact_force_N": "total normal contact force between ball and liner, full body (>= 0)",
    "approach_m": "mutual approach: ball centre travel along the impact normal less the initial gap",
    "contact_radius_m": "radius of the contact patch (outermost point carrying force)",
    "ball_velocity_m_s": "ball centre-of-mass velocity along the impact normal, towards the liner positive",
    "contact_point_displacement_m": "liner displacement at the contact point along the impact normal, "
    "into the liner positive",
    "contact_point_velocity_m_s": "liner velocity at the contact point along the impact normal, into the liner positive: "
    "FE methods: the centre of mass of the half-ball of radius a_max (Hertz) under it; "
    "Hertz models: the surface point",
    "contact_point_acceleration_m_s2": "liner acceleration at the contact point along the impact normal, "
    "into the liner positive: FE methods: the centre of mass of the half-ball of "
    "radius a_max (Hertz) under it; Hertz models: the surface point",
    "contact_point_stress_Pa": "normal stress (sigma_yy, along the impact normal) just below the contact point, "
    "compression negative",
    "contact_point_von_mises_Pa": "von Mises stress just below the contact point",
    "ball_kinetic_energy_J": "kinetic energy of the ball",
    "kinetic_energy_J": "kinetic energy of ball and liner",
    "strain_energy_J": "elastic strain energy of ball and liner",
    "total_energy_J": "kinetic + strain energy",
}

_GAUGE = re.compile(r"^gauge_(.+)_stress_Pa$")


def describe(column: str) -> str:
    """What a time-series column means (empty if unknown)."""
    if column in DESCRIPTIONS:
        return DESCRIPTIONS[column]
    m = _GAUGE.match(column)
    if m:
        return f"strain-gauge stress sigma = E (d . eps . d) at gauge {m.group(1)} on the liner surface"
    return ""


def is_known_column(column: str) -> bool:
    """True for the column names millimpact writes (any gauge name)."""
    return column in DESCRIPTIONS or bool(_GAUGE.match(column))


@dataclass
class Reference:
    """A reference run read back: its time series and metadata (scene, method, Hertz values...)."""

    path: Path
    series: TimeSeries
    meta: dict[str, Any] = field(default_factory=dict)

    @property
    def label(self) -> str:
        scene, method = self.meta.get("scene"), self.meta.get("method")
        return f"{scene}: {method}" if scene and method else self.path.name

    @property
    def is_reference_file(self) -> bool:
        """True for a versioned reference file (``millimpact run --reference``); False for a run's
        plain ``timeseries.h5`` / ``timeseries.csv``, which lacks the reference metadata."""
        return self.meta.get("format") in (REFERENCE_FORMAT, REFERENCE_CSV_FORMAT)


def _metadata(scene, plan, out, summary) -> dict[str, Any]:
    h = plan.hertz
    metrics = {
        k: summary.get(k)
        for k in (
            "peak_contact_force_N",
            "contact_duration_s",
            "max_approach_m",
            "impulse_N_s",
            "restitution",
            "wall_time_s",
        )
    }
    return {
        "millimpact_version": __version__,
        "scene": scene.name,
        "method": out.method,
        "time_origin": TIME_ORIGIN,
        "first_contact_s": plan.gap / h.speed,
        "hertz": summary.get("hertz", {}),
        "metrics": metrics,
        "model": summary.get("model", {}),
        "plan": summary.get("plan", {}),
    }


def write_reference(folder: Path, scene, plan, out, summary: dict, scene_toml: str) -> list[str]:
    """Write ``reference.h5``, ``reference.csv`` and ``reference.json`` into ``folder`` (rank 0)."""
    ts = out.series
    meta = _metadata(scene, plan, out, summary)
    columns = list(ts.columns)
    with hdf5_file(folder / "reference.h5") as h5:  # in memory, one write: a full disk is one line
        fill_hdf5(h5, ts, summary, scene_toml)
        h5.attrs["format"] = REFERENCE_FORMAT
        h5.attrs["format_version"] = REFERENCE_VERSION
        for key in ("scene", "method", "time_origin", "first_contact_s"):
            h5.attrs[key] = meta[key]
        g = h5["timeseries"]
        g.attrs["columns"] = json.dumps(columns)
        for name in columns:
            g[name].attrs["description"] = describe(name)
        for group in ("hertz", "metrics"):
            sub = h5.create_group(group)
            for k, v in jsonable(meta[group]).items():
                sub.attrs[k] = np.nan if v is None else v
        sub = h5.create_group("model")
        sub.attrs["method"] = out.method
        for k, v in jsonable(meta["model"]).items():
            if isinstance(v, (int, float, str)) and not isinstance(v, bool):
                sub.attrs[k] = v
        sub.attrs["model_json"] = json.dumps(jsonable(meta["model"]))
        sub.attrs["plan_json"] = json.dumps(jsonable(meta["plan"]))
    ts.write_csv(folder / "reference.csv")
    side = {
        "format": REFERENCE_CSV_FORMAT,
        "format_version": REFERENCE_VERSION,
        "csv": "reference.csv",
        **meta,
        "columns": [{"name": n, "unit": unit_of(n), "description": describe(n)} for n in columns],
        "scene_toml": scene_toml,
    }
    (folder / "reference.json").write_text(json.dumps(jsonable(side), indent=2) + "\n")
    return ["reference.h5", "reference.csv", "reference.json"]


# --- reading ------------------------------------------------------------------------------------
def read_history_csv(path: Path, what: str = "file") -> TimeSeries:
    """Read a history CSV: ``#`` lines and blank lines are skipped, the first other line is the
    header (comma-separated ``name_unit`` names), every later line one row of numbers.

    Raises :class:`InputError` (one line) for a missing/unreadable file, duplicate names, a
    missing ``time_s`` column, a non-number, a row of the wrong length, fewer than two rows, or
    times that do not strictly increase.
    """
    path = Path(path)
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:  # -sig: a spreadsheet's BOM
            lines = [(i + 1, line) for i, line in enumerate(fh) if line.strip() and not line.lstrip().startswith("#")]
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{what} {path}: cannot read ({exc.__class__.__name__}: {exc})") from None
    if not lines:
        raise InputError(f"{what} {path}: empty (expected a header row starting with time_s)")
    rows = list(csv.reader([line for _, line in lines]))
    names = [n.strip() for n in rows[0]]
    dupes = sorted({n for n in names if names.count(n) > 1})
    if dupes:
        raise InputError(f"{what} {path}: duplicate column(s) {', '.join(dupes)}")
    if "time_s" not in names:
        raise InputError(
            f"{what} {path}: no 'time_s' column (header: {', '.join(names)[:200]}); "
            "time must be a column named time_s, in seconds"
        )
    data = []
    for (lineno, _), row in zip(lines[1:], rows[1:]):
        if len(row) != len(names):
            raise InputError(f"{what} {path}: line {lineno} has {len(row)} values, the header {len(names)}")
        vals = []
        for name, cell in zip(names, row):
            try:
                x = float(cell)
            except ValueError:
                raise InputError(
                    f"{what} {path}: line {lineno}, column {name}: {cell.strip()!r} is not a number"
                ) from None
            if not math.isfinite(x):
                raise InputError(f"{what} {path}: line {lineno}, column {name}: {cell.strip()!r} is not finite")
            vals.append(x)
        data.append(vals)
    if len(data) < 2:
        raise InputError(f"{what} {path}: {len(data)} data row(s); at least 2 needed")
    ts = TimeSeries.from_rows(names, data)
    _check_time(ts.time, path, what)
    return ts


def _check_time(t: np.ndarray, path: Path, what: str) -> None:
    bad = np.flatnonzero(np.diff(t) <= 0)
    if bad.size:
        i = int(bad[0])
        raise InputError(f"{what} {path}: time_s must strictly increase (row {i + 2}: {t[i + 1]:g} s after {t[i]:g} s)")


def read_reference(path: Path) -> Reference:
    """Read a reference: ``reference.h5`` / ``timeseries.h5``, ``reference.csv`` (with its optional
    sidecar ``reference.json``) / ``timeseries.csv``, or a run folder holding one of them."""
    path = Path(path)
    if path.is_dir():
        for name in ("reference.h5", "timeseries.h5", "reference.csv", "timeseries.csv"):
            if (path / name).is_file():
                return read_reference(path / name)
        raise InputError(f"reference {path}: folder without reference.h5, timeseries.h5 or reference.csv")
    if not path.is_file():
        raise InputError(f"reference {path}: no such file")
    if path.suffix.lower() in (".h5", ".hdf5"):
        return _read_reference_h5(path)
    side = path.with_suffix(".json")
    if not side.is_file() and not is_millimpact_output(path.parent):
        raise InputError(
            f"reference {path}: not a millimpact reference (no {side.name} beside it and not in a "
            "millimpact run folder); write one with 'millimpact run SCENE --reference'"
        )
    ts = read_history_csv(path, "reference")
    meta: dict[str, Any] = {}
    if side.is_file():
        try:
            meta = json.loads(side.read_text())
        except (OSError, json.JSONDecodeError) as exc:
            raise InputError(f"reference sidecar {side}: not valid JSON ({exc})") from None
        if meta.get("format") == REFERENCE_CSV_FORMAT and int(meta.get("format_version", 0)) > REFERENCE_VERSION:
            raise InputError(
                f"reference sidecar {side}: format_version {meta['format_version']} is newer than "
                f"this millimpact reads (<= {REFERENCE_VERSION})"
            )
    return Reference(path, ts, meta)


def _read_reference_h5(path: Path) -> Reference:
    import h5py

    try:
        h5 = h5py.File(path, "r")
    except OSError as exc:
        raise InputError(f"reference {path}: not an HDF5 file ({exc})") from None
    with h5:
        fmt = h5.attrs.get("format")
        if fmt not in (REFERENCE_FORMAT, "millimpact-timeseries") or "timeseries" not in h5:
            raise InputError(
                f"reference {path}: attribute format = {fmt!r}: must be {REFERENCE_FORMAT!r} "
                "(written by millimpact run --reference)"
            )
        version = int(h5.attrs.get("format_version", 0))
        if version < 1 or version > REFERENCE_VERSION:
            raise InputError(
                f"reference {path}: format_version = {version}: this millimpact reads 1..{REFERENCE_VERSION}"
            )
        g = h5["timeseries"]
        order = (
            json.loads(g.attrs["columns"])
            if "columns" in g.attrs
            else ["time_s"] + sorted(n for n in g if n != "time_s")
        )
        if "time_s" not in order:
            raise InputError(f"reference {path}: no timeseries/time_s dataset")
        ts = TimeSeries({n: np.asarray(g[n][...], dtype=float) for n in order})
        meta: dict[str, Any] = {
            k: (v.decode() if isinstance(v, bytes) else v) for k, v in h5.attrs.items() if k not in ("summary_json",)
        }
        meta = jsonable({k: (v.item() if hasattr(v, "item") else v) for k, v in meta.items()})
        for group in ("hertz", "metrics"):
            if group in h5:
                meta[group] = jsonable({k: (v.item() if hasattr(v, "item") else v) for k, v in h5[group].attrs.items()})
    _check_time(ts.time, path, "reference")
    return Reference(path, ts, meta)
