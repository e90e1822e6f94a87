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
number that is NaN, infinite or negative where it must not be, and an unknown place.
"""
from __future__ import annotations

import csv
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Iterable, Sequence

from ..errors import InputError

#: the columns of impacts.csv, in order
IMPACT_COLUMNS = ("time_s", "ball_radius_m", "normal_speed_m_s", "tangential_speed_m_s",
                  "impact_energy_J", "place", "arc_position_m")
#: the places of the liner an impact can strike
PLACES = ("lifter_face", "lifter_top", "plate")
#: numeric columns that must be >= 0 (arc_position_m is signed)
_NON_NEGATIVE = ("time_s", "ball_radius_m", "normal_speed_m_s", "tangential_speed_m_s", "impact_energy_J")
#: upper bounds that catch values given in other units (mm/s for m/s, mm for m): a mill's balls
#: strike at 3-13 m/s (design.md section 10) and the scenes' largest ball radius is 1 m
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


def read_impacts(path: Path | str) -> list[Impact]:
    """The impacts of an impacts.csv, checked (InputError naming the column and the row)."""
    path = Path(path)
    try:
        fh = open(path, newline="", encoding="utf-8-sig")
    except OSError as exc:
        raise InputError(f"--impacts {path}: cannot be read ({exc.strerror or exc})") from None
    with fh:
        reader = csv.reader(fh)
        try:
            header = [h.strip() for h in next(reader)]
        except StopIteration:
            raise InputError(f"--impacts {path}: empty file (expected the columns {', '.join(IMPACT_COLUMNS)})") from None
        except (csv.Error, UnicodeDecodeError) as exc:
            raise InputError(f"--impacts {path}: not a CSV file ({exc})") from None
        for column in IMPACT_COLUMNS:
            if column not in header:
                raise InputError(f"--impacts {path}: missing column '{column}'"
                                 f"{_missing_column_hint(header, column)}; expected {', '.join(IMPACT_COLUMNS)}")
        idx = {c: header.index(c) for c in IMPACT_COLUMNS}
        impacts: list[Impact] = []
        try:
            for row_no, row in enumerate(reader, start=2):
                if not row or all(not cell.strip() for cell in row):
                    continue
                values = {}
                for column in IMPACT_COLUMNS:
                    cell = row[idx[column]].strip() if idx[column] < len(row) else ""
                    if column == "place":
                        if cell not in PLACES:
                            raise InputError(f"--impacts {path}: row {row_no}: place '{cell}' is not one of "
                                             f"{', '.join(PLACES)}")
                        values[column] = cell
                        continue
                    try:
                        x = float(cell)
                    except ValueError:
                        raise InputError(f"--impacts {path}: row {row_no}: {column} '{cell}' is not a number") from None
                    if not math.isfinite(x):
                        raise InputError(f"--impacts {path}: row {row_no}: {column} is {cell} (must be a finite number)")
                    if column in _NON_NEGATIVE and x < 0:
                        raise InputError(f"--impacts {path}: row {row_no}: {column} {x:g} is negative (must be >= 0)")
                    if x > _UPPER.get(column, math.inf):
                        raise InputError(f"--impacts {path}: row {row_no}: {column} {x:g} is above {_UPPER[column]:g} "
                                         "(SI units expected: m, m/s)")
                    values[column] = x
                impacts.append(Impact(**values))
        except (csv.Error, UnicodeDecodeError) as exc:
            raise InputError(f"--impacts {path}: not a readable CSV file ({exc})") from None
    if not impacts:
        raise InputError(f"--impacts {path}: no impacts (a header and no rows)")
    return impacts
