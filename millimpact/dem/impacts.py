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
==========================  ===================================================================

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

    @property
    def angle_deg(self) -> float:
        """Impact angle from the liner's normal, atan(v_t / v_n) (degrees)."""
        return math.degrees(math.atan2(self.tangential_speed_m_s, self.normal_speed_m_s))


class ImpactLog(SequenceABC):
    """The impacts of a log as numpy columns (SI units; the module docstring's columns), read as a
    sequence of :class:`Impact` made on demand: a million impacts cost their arrays, not a million
    objects. :meth:`column` gives one column as an array."""

    def __init__(self, columns: dict[str, np.ndarray], place_codes: np.ndarray):
        self._columns = columns
        self._codes = place_codes

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
        )

    def __eq__(self, other) -> bool:
        return isinstance(other, SequenceABC) and len(other) == len(self) and list(self) == list(other)

    def column(self, name: str) -> np.ndarray:
        """One column: floats (m, m/s, J, s), or the places as strings for ``place``."""
        return np.asarray(PLACES)[self._codes] if name == "place" else self._columns[name]


def impact_column(impacts: Sequence[Impact], name: str) -> np.ndarray:
    """Column ``name`` of ``impacts`` as an array (an :class:`ImpactLog`'s own, or gathered)."""
    if isinstance(impacts, ImpactLog):
        return impacts.column(name)
    return np.array([getattr(i, name) for i in impacts], dtype=object if name == "place" else float)


def write_impacts(path: Path, impacts: Iterable[Impact]) -> None:
    """Write ``impacts`` to ``path`` as impacts.csv (the caller stages the folder)."""
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(IMPACT_COLUMNS)
        for imp in impacts:
            w.writerow([repr(float(getattr(imp, c))) if c != "place" else imp.place for c in IMPACT_COLUMNS])


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
    except (OSError, ValueError, UnicodeDecodeError, StopIteration, csv.Error):
        return None
    if len(places) == 0 or values.shape != (len(places), len(numeric)):
        return None
    codes = np.full(len(places), -1, dtype=np.int8)
    for k, p in enumerate(PLACES):
        codes[places == p] = k
    if (codes < 0).any() or not np.isfinite(values).all():
        return None
    columns = {c: np.ascontiguousarray(values[:, j]) for j, c in enumerate(numeric)}
    for c in _NON_NEGATIVE:
        if (columns[c] < 0).any():
            return None
    for c, top in _UPPER.items():
        if (columns[c] > top).any():
            return None
    return ImpactLog(columns, codes)


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
                impacts.append(Impact(**values))
        except (csv.Error, UnicodeDecodeError) as exc:
            raise InputError(f"--impacts {path}: not a readable CSV file ({exc})") from None
    if not impacts:
        raise InputError(f"--impacts {path}: no impacts (a header and no rows)")
    return impacts
