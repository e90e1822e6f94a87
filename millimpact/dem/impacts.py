"""The impact log of a mill DEM run, ``impacts.csv``: its columns, a writer and a checked reader.

One row per ball-liner impact (the first instant of a new ball-liner contact), SI units, the unit
in each column's name:

==========================  ===================================================================
``time_s``                  simulated time of the impact (s)
``ball_radius_m``           the ball's radius (m)
``normal_speed_m_s``        relative speed along the liner's normal at first contact, >= 0 (m/s)
``tangential_speed_m_s``    relative speed of the ball's centre along the liner surface, >= 0 (m/s)
``impact_energy_J``         the ball's kinetic energy of relative motion, 1/2 m (v_n^2 + v_t^2) (J)
``place``                   ``lifter_face``, ``lifter_top`` or ``plate``
``arc_position_m``          where on the liner profile (m): arc length along the shell's inner
                            circle from the centre line of the nearest lifter, positive towards
                            that lifter's leading face (the one that lifts the charge)
``kind``                    ``ball`` or ``rock`` (optional: a log without it holds balls only)
``mass_kg``                 the particle's mass (kg; optional)
``surface_position_m``      where on the liner's profile (m; optional): the distance along the
                            profile from the lifter's trailing foot (trailing face, top, leading
                            face, then the plate to the next lifter)
==========================  ===================================================================

For a rock, ``ball_radius_m`` is the rock's radius. The damage map computes the balls' impacts
(:func:`ball_impacts`) and sets the rock's impact energy per place beside them.

:func:`read_impacts` refuses (:class:`~millimpact.errors.InputError`, one line naming the column
and row) a file without these columns, a column given in other units (``normal_speed_mm_s``, or speeds above 100 m/s), a
number that is NaN, infinite or negative where it must not be, and an unknown place. It reads the
columns with numpy's parser and checks them as arrays (a log of 1e6 rows, 113 MB: 8.4 s and 206 MB
peak on 2 shared cores; ``millimpact damage`` says the reading), and returns an :class:`ImpactLog`: a sequence of :class:`Impact` over those columns.
"""

from __future__ import annotations

import csv
import math
import time
import warnings
from collections.abc import Callable, Iterable, Sequence
from collections.abc import Sequence as SequenceABC
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import InputError

#: the columns of impacts.csv, in order
IMPACT_COLUMNS = (
    "time_s",
    "ball_radius_m",
    "normal_speed_m_s",
    "tangential_speed_m_s",
    "impact_energy_J",
    "place",
    "arc_position_m",
)
#: the optional columns (a balls-only log may leave them out) and their values for such a log
OPTIONAL_COLUMNS = ("kind", "mass_kg", "surface_position_m")
#: the kinds of particle
KINDS = ("ball", "rock")
#: the places of the liner an impact can strike
PLACES = ("lifter_face", "lifter_top", "plate")
#: numeric columns that must be >= 0 (arc_position_m is signed)
_NON_NEGATIVE = ("time_s", "ball_radius_m", "normal_speed_m_s", "tangential_speed_m_s", "impact_energy_J")
#: upper bounds that catch values given in other units (mm/s for m/s, mm for m): a mill's balls
#: strike at 3-13 m/s (foundations.md section 10) and the scenes' largest ball radius is 1 m
_UPPER = {"normal_speed_m_s": 100.0, "tangential_speed_m_s": 100.0, "ball_radius_m": 1.0}


@dataclass(frozen=True)
class Impact:
    """One ball-liner impact (SI units; see the module docstring)."""

    time_s: float
    ball_radius_m: float
    normal_speed_m_s: float
    tangential_speed_m_s: float
    impact_energy_J: float
    place: str
    arc_position_m: float
    kind: str = "ball"
    mass_kg: float | None = None
    surface_position_m: float | None = None

    @property
    def angle_deg(self) -> float:
        """Impact angle from the liner's normal, atan(v_t / v_n) (degrees)."""
        return math.degrees(math.atan2(self.tangential_speed_m_s, self.normal_speed_m_s))


class ImpactLog(SequenceABC):
    """The impacts of a log as numpy columns (SI units; the module docstring's columns), read as a
    sequence of :class:`Impact` made on demand: a million impacts cost their arrays, not a million
    objects. :meth:`column` gives one column as an array."""

    def __init__(self, columns: dict[str, np.ndarray], place_codes: np.ndarray, kind_codes: np.ndarray | None = None):
        self._columns = columns
        self._codes = place_codes
        self._kinds = np.zeros(len(place_codes), dtype=np.int8) if kind_codes is None else kind_codes

    def __len__(self) -> int:
        return len(self._codes)

    def __getitem__(self, k):
        if isinstance(k, slice):
            return [self[i] for i in range(*k.indices(len(self)))]
        k = range(len(self))[k]
        c = self._columns
        return Impact(
            float(c["time_s"][k]),
            float(c["ball_radius_m"][k]),
            float(c["normal_speed_m_s"][k]),
            float(c["tangential_speed_m_s"][k]),
            float(c["impact_energy_J"][k]),
            PLACES[self._codes[k]],
            float(c["arc_position_m"][k]),
            KINDS[self._kinds[k]],
            _optional(c, "mass_kg", k),
            _optional(c, "surface_position_m", k),
        )

    def __eq__(self, other) -> bool:
        return isinstance(other, SequenceABC) and len(other) == len(self) and list(self) == list(other)

    def column(self, name: str) -> np.ndarray:
        """One column: floats (m, m/s, J, s, kg: NaN where the log has no mass), or strings for
        ``place`` and ``kind``."""
        if name == "place":
            return np.asarray(PLACES)[self._codes]
        if name == "kind":
            return np.asarray(KINDS)[self._kinds]
        if name in OPTIONAL_COLUMNS and name not in self._columns:
            return np.full(len(self), math.nan)
        return self._columns[name]

    def subset(self, keep: np.ndarray) -> ImpactLog:
        """The log's rows where ``keep`` (a boolean array) is true."""
        return ImpactLog({k: v[keep] for k, v in self._columns.items()}, self._codes[keep], self._kinds[keep])


def impact_column(impacts: Sequence[Impact], name: str) -> np.ndarray:
    """Column ``name`` of ``impacts`` as an array (an :class:`ImpactLog`'s own, or gathered)."""
    if isinstance(impacts, ImpactLog):
        return impacts.column(name)
    if name in ("mass_kg", "surface_position_m"):
        return np.array([math.nan if getattr(i, name) is None else getattr(i, name) for i in impacts], dtype=float)
    return np.array([getattr(i, name) for i in impacts], dtype=object if name in ("place", "kind") else float)


def ball_impacts(impacts: Sequence[Impact]) -> Sequence[Impact]:
    """The balls' impacts of a log (all of a log without kinds)."""
    kinds = impact_column(impacts, "kind")
    keep = kinds == "ball"
    if keep.all():
        return impacts
    if isinstance(impacts, ImpactLog):
        return impacts.subset(keep)
    return [i for i, k in zip(impacts, keep) if k]


def kind_totals(impacts: Sequence[Impact], kind: str, revolutions: float, lifters: int = 1) -> dict:
    """Per place: the impacts of one kind of particle per revolution and lifter, and their impact
    energy (J) per revolution and lifter."""
    k = impact_column(impacts, "kind") == kind
    place = impact_column(impacts, "place")
    energy = impact_column(impacts, "impact_energy_J")
    per = 1.0 / (revolutions * lifters)
    return {
        p: {
            "impacts_per_rev": float(np.count_nonzero(k & (place == p))) * per,
            "impact_energy_J_per_rev": float(energy[k & (place == p)].sum()) * per,
        }
        for p in PLACES
    }


def write_impacts(path: Path, impacts: Iterable[Impact]) -> None:
    """Write ``impacts`` to ``path`` as impacts.csv with the optional columns (the caller stages the folder)."""
    columns = IMPACT_COLUMNS + OPTIONAL_COLUMNS
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(columns)
        for imp in impacts:
            row = [repr(float(getattr(imp, c))) if c != "place" else imp.place for c in IMPACT_COLUMNS]
            extra = ["" if x is None else repr(float(x)) for x in (imp.mass_kg, imp.surface_position_m)]
            w.writerow([*row, imp.kind, *extra])


def _missing_column_hint(header: Sequence[str], column: str) -> str:
    stem = column.rsplit("_", 2)[0] if column.endswith("_m_s") else column.rsplit("_", 1)[0]
    other = [h for h in header if h.startswith(stem) and h != column]
    if other:
        return f" (found '{other[0]}': give it in SI units as '{column}')"
    return ""


#: a log larger than this (bytes) is said as it is read
SAY_READING_BYTES = 10_000_000


def read_impacts(path: Path | str, say: Callable | None = None) -> Sequence[Impact]:
    """The impacts of an impacts.csv, checked (InputError naming the column and the row): numpy's
    parser and array checks (:class:`ImpactLog`); a file they refuse is read again row by row for
    the line that names the first bad cell. ``say`` gets a line before and after a large log."""
    path = Path(path)
    say = say or (lambda *a: None)
    size = path.stat().st_size if path.is_file() else 0
    t0 = time.perf_counter()
    if size > SAY_READING_BYTES:
        say(f"reading {path} ({size / 1e6:.0f} MB) ...")
    log = _read_columns(path)
    if log is None:
        return _read_rows(path)
    if size > SAY_READING_BYTES:
        say(f"read {len(log):,} impacts from {path} in {time.perf_counter() - t0:.1f} s")
    return log


def _read_columns(path: Path) -> ImpactLog | None:
    """The log read and checked as columns, or None when anything is off (:func:`_read_rows` then
    names it)."""
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh, warnings.catch_warnings():
            warnings.simplefilter("ignore")  # numpy's "no data": said by the row reader
            header = [h.strip() for h in next(csv.reader([fh.readline()]))]
            if any(c not in header for c in IMPACT_COLUMNS):
                return None
            idx = {c: header.index(c) for c in IMPACT_COLUMNS}
            numeric = [c for c in IMPACT_COLUMNS if c != "place"]
            values = np.loadtxt(
                fh, usecols=[idx[c] for c in numeric], dtype=float, ndmin=2, delimiter=",", comments=None, quotechar='"'
            )
            fh.seek(0)
            fh.readline()
            places = np.char.strip(
                np.loadtxt(
                    fh, usecols=[idx["place"]], dtype="U16", ndmin=1, delimiter=",", comments=None, quotechar='"'
                )
            )
            kinds, mass, surface = _optional_columns(fh, header)
    except (OSError, ValueError, UnicodeDecodeError, StopIteration, csv.Error):
        return None
    if len(places) == 0 or values.shape != (len(places), len(numeric)):
        return None
    codes = _codes(places, PLACES)
    kind_codes = None if kinds is None else _codes(kinds, KINDS)
    if codes is None or (kinds is not None and kind_codes is None) or not np.isfinite(values).all():
        return None
    columns = {c: np.ascontiguousarray(values[:, j]) for j, c in enumerate(numeric)}
    if mass is not None:
        if mass.shape != (len(places),) or not np.isfinite(mass).all() or (mass <= 0).any():
            return None
        columns["mass_kg"] = mass
    if surface is not None:
        if surface.shape != (len(places),) or not np.isfinite(surface).all() or (surface < 0).any():
            return None
        columns["surface_position_m"] = surface
    for c in _NON_NEGATIVE:
        if (columns[c] < 0).any():
            return None
    for c, top in _UPPER.items():
        if (columns[c] > top).any():
            return None
    return ImpactLog(columns, codes, kind_codes)


def _codes(values: np.ndarray, names: tuple[str, ...]) -> np.ndarray | None:
    """Each value's index in ``names``; None when one is not there."""
    codes = np.full(len(values), -1, dtype=np.int8)
    for k, name in enumerate(names):
        codes[values == name] = k
    return None if (codes < 0).any() else codes


def _optional_columns(fh, header: list[str]) -> tuple[np.ndarray | None, ...]:
    """The ``kind`` (strings), ``mass_kg`` and ``surface_position_m`` columns, each None when the
    header lacks it."""
    out: list[np.ndarray | None] = []
    for column, dtype in (("kind", "U8"), ("mass_kg", float), ("surface_position_m", float)):
        if column not in header:
            out.append(None)
            continue
        fh.seek(0)
        fh.readline()
        col = np.loadtxt(
            fh, usecols=[header.index(column)], dtype=dtype, ndmin=1, delimiter=",", comments=None, quotechar='"'
        )
        out.append(np.char.strip(col) if column == "kind" else col)
    return tuple(out)


def _optional(columns: dict[str, np.ndarray], name: str, k: int) -> float | None:
    return float(columns[name][k]) if name in columns and math.isfinite(columns[name][k]) else None


def _read_rows(path: Path) -> list[Impact]:
    """The impacts read row by row: the first bad cell's line (InputError naming column and row)."""
    try:
        fh = open(path, newline="", encoding="utf-8-sig")
    except OSError as exc:
        raise InputError(f"--impacts {path}: cannot be read ({exc.strerror or exc})") from None
    with fh:
        reader = csv.reader(fh)
        try:
            header = [h.strip() for h in next(reader)]
        except StopIteration:
            raise InputError(
                f"--impacts {path}: empty file (expected the columns {', '.join(IMPACT_COLUMNS)})"
            ) from None
        except (csv.Error, UnicodeDecodeError) as exc:
            raise InputError(f"--impacts {path}: not a CSV file ({exc})") from None
        for column in IMPACT_COLUMNS:
            if column not in header:
                raise InputError(
                    f"--impacts {path}: missing column '{column}'"
                    f"{_missing_column_hint(header, column)}; expected {', '.join(IMPACT_COLUMNS)}"
                )
        idx = {c: header.index(c) for c in IMPACT_COLUMNS}
        impacts: list[Impact] = []
        try:
            for row_no, row in enumerate(reader, start=2):
                if not row or all(not cell.strip() for cell in row):
                    continue
                values: dict[str, Any] = {}  # place: str, the others float
                for column in IMPACT_COLUMNS:
                    cell = row[idx[column]].strip() if idx[column] < len(row) else ""
                    if column == "place":
                        if cell not in PLACES:
                            raise InputError(
                                f"--impacts {path}: row {row_no}: place '{cell}' is not one of {', '.join(PLACES)}"
                            )
                        values[column] = cell
                        continue
                    try:
                        x = float(cell)
                    except ValueError:
                        raise InputError(f"--impacts {path}: row {row_no}: {column} '{cell}' is not a number") from None
                    if not math.isfinite(x):
                        raise InputError(
                            f"--impacts {path}: row {row_no}: {column} is {cell} (must be a finite number)"
                        )
                    if column in _NON_NEGATIVE and x < 0:
                        raise InputError(f"--impacts {path}: row {row_no}: {column} {x:g} is negative (must be >= 0)")
                    if x > _UPPER.get(column, math.inf):
                        raise InputError(
                            f"--impacts {path}: row {row_no}: {column} {x:g} is above {_UPPER[column]:g} "
                            "(SI units expected: m, m/s)"
                        )
                    values[column] = x
                values.update(_optional_cells(path, row_no, row, header))
                impacts.append(Impact(**values))
        except (csv.Error, UnicodeDecodeError) as exc:
            raise InputError(f"--impacts {path}: not a readable CSV file ({exc})") from None
    if not impacts:
        raise InputError(f"--impacts {path}: no impacts (a header and no rows)")
    return impacts


def _optional_cells(path: Path, row_no: int, row: list[str], header: list[str]) -> dict:
    """A row's ``kind`` and ``mass_kg`` (when the header has them), checked."""
    out: dict[str, Any] = {}
    if "kind" in header:
        k = header.index("kind")
        cell = row[k].strip() if k < len(row) else ""
        if cell not in KINDS:
            raise InputError(f"--impacts {path}: row {row_no}: kind '{cell}' is not one of {', '.join(KINDS)}")
        out["kind"] = cell
    for name, positive in (("mass_kg", True), ("surface_position_m", False)):
        if name not in header:
            continue
        k = header.index(name)
        cell = row[k].strip() if k < len(row) else ""
        if not cell:
            continue
        try:
            x = float(cell)
        except ValueError:
            raise InputError(f"--impacts {path}: row {row_no}: {name} '{cell}' is not a number") from None
        if not math.isfinite(x) or x < 0 or (positive and x == 0):
            need = "a positive number" if positive else "a number >= 0"
            raise InputError(f"--impacts {path}: row {row_no}: {name} {cell} must be {need}")
        out[name] = x
    return out
