"""impacts.csv (millimpact.dem.impacts): a written log reads back equal; bad files are refused
with one line naming the column and the row."""
from __future__ import annotations

import math

import pytest

from millimpact.dem.impacts import (
    IMPACT_COLUMNS,
    OPTIONAL_COLUMNS,
    Impact,
    ball_impacts,
    impact_column,
    kind_totals,
    read_impacts,
    write_impacts,
)
from millimpact.errors import InputError


def _impacts():
    # a 125 mm ball (r 62.5 mm, 7800 kg/m^3: m = 7.98 kg) at 5 m/s normal, 2 m/s tangential
    m = 7800 * 4 / 3 * math.pi * 0.0625 ** 3
    return [Impact(0.125, 0.0625, 5.0, 2.0, 0.5 * m * (25 + 4), "lifter_face", -0.031),
            Impact(0.5, 0.0625, 0.25, 0.0, 0.5 * m * 0.0625, "plate", 0.12)]


def test_round_trip(tmp_path):
    path = tmp_path / "impacts.csv"
    write_impacts(path, _impacts())
    assert path.read_text().splitlines()[0] == ",".join(IMPACT_COLUMNS + OPTIONAL_COLUMNS)
    assert read_impacts(path) == _impacts()
    # the angle from the normal: atan(2 / 5)
    assert read_impacts(path)[0].angle_deg == pytest.approx(math.degrees(math.atan(0.4)), rel=1e-12)


@pytest.mark.parametrize("edit, words", [
    (lambda t: t.replace("normal_speed_m_s", "normal_speed_mm_s", 1), "missing column 'normal_speed_m_s' (found 'normal_speed_mm_s'"),
    (lambda t: t.replace(",place,", ",where,", 1), "missing column 'place'"),
    (lambda t: t.replace(",5.0,", ",nan,", 1), "row 2: normal_speed_m_s is nan"),
    (lambda t: t.replace(",5.0,", ",-5.0,", 1), "row 2: normal_speed_m_s -5 is negative"),
    (lambda t: t.replace(",5.0,", ",5000.0,", 1), "row 2: normal_speed_m_s 5000 is above 100"),
    (lambda t: t.replace("lifter_face", "shell", 1), "row 2: place 'shell'"),
    (lambda t: t.splitlines()[0] + "\n", "no impacts"),
])
def test_bad_files_are_refused_naming_the_column(tmp_path, edit, words):
    good = tmp_path / "good.csv"
    write_impacts(good, _impacts())
    bad = tmp_path / "bad.csv"
    bad.write_text(edit(good.read_text()))
    with pytest.raises(InputError) as exc:
        read_impacts(bad)
    assert words in str(exc.value) and "\n" not in str(exc.value)


def test_a_large_log_is_read_as_columns_and_said(tmp_path):
    """2e5 rows (22 MB): read as numpy columns, with a line before and after, equal to the row
    reader's impacts. Before, each row was checked and kept as a Python object: 1e6 rows (113 MB)
    took 48 s with no word and 413 MB; the budget of the damage map is 500 MB at 1e6 rows, ~150 MB
    of it the process itself: 70 MB scaled to 2e5 rows. The row reader took 83 MB here."""
    import tracemalloc

    import numpy as np

    from millimpact.dem.impacts import _read_rows

    n = 200_000
    rng = np.random.default_rng(0)
    vn, vt = rng.uniform(0.1, 6.0, n), rng.uniform(0.0, 3.0, n)
    places = np.array(["lifter_face", "lifter_top", "plate"])[rng.integers(0, 3, n)]
    path = tmp_path / "impacts.csv"
    with open(path, "w") as fh:
        fh.write(",".join(IMPACT_COLUMNS) + "\n")
        fh.writelines(f"{k * 1e-4!r},0.0625,{a!r},{b!r},{4 * (a * a + b * b)!r},{p},{0.1 * a!r}\n"
                      for k, (a, b, p) in enumerate(zip(vn, vt, places)))
    lines: list[str] = []
    tracemalloc.start()
    log = read_impacts(path, lines.append)
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert peak < 70e6, f"{peak / 1e6:.0f} MB"
    assert len(lines) == 2 and lines[0].startswith(f"reading {path}") and f"read {n:,} impacts" in lines[1]
    rows = _read_rows(path)
    assert len(log) == n and log[0] == rows[0] and log[-1] == rows[-1] and log[n // 2] == rows[n // 2]


def _sag_impacts():
    """Two balls' impacts and a rock's (a 150 mm rock of 2700 kg/m^3: 4.77 kg) with their masses."""
    m = 7800 * 4 / 3 * math.pi * 0.0625 ** 3
    m_rock = 2700 * 4 / 3 * math.pi * 0.075 ** 3
    return [Impact(0.125, 0.0625, 5.0, 2.0, 0.5 * m * 29, "lifter_face", -0.031, "ball", m),
            Impact(0.25, 0.075, 3.0, 0.0, 0.5 * m_rock * 9, "lifter_face", 0.01, "rock", m_rock),
            Impact(0.5, 0.0625, 0.25, 0.0, 0.5 * m * 0.0625, "plate", 0.12, "ball", m)]


def test_kinds_and_masses_round_trip_and_the_balls_are_picked(tmp_path):
    """A SAG log's kind and mass read back equal (as columns and as rows); the damage map's balls are
    the ball rows; the rock's energy per place and revolution is its impacts' sum."""
    path = tmp_path / "impacts.csv"
    write_impacts(path, _sag_impacts())
    log = read_impacts(path)
    assert list(log) == _sag_impacts()
    assert list(impact_column(log, "kind")) == ["ball", "rock", "ball"]
    assert list(ball_impacts(log)) == [_sag_impacts()[0], _sag_impacts()[2]]
    rock = kind_totals(log, "rock", revolutions=2.0)
    assert rock["lifter_face"]["impacts_per_rev"] == 0.5
    assert rock["lifter_face"]["impact_energy_J_per_rev"] == pytest.approx(_sag_impacts()[1].impact_energy_J / 2)
    assert rock["plate"]["impacts_per_rev"] == 0.0
    # a log without the kind column (a balls-only log of before) holds balls
    old = tmp_path / "old.csv"
    old.write_text("\n".join(",".join(r.split(",")[:7]) for r in path.read_text().splitlines()) + "\n")
    assert set(impact_column(read_impacts(old), "kind")) == {"ball"}


@pytest.mark.parametrize("edit, words", [
    (lambda t: t.replace(",rock,", ",gravel,", 1), "row 3: kind 'gravel' is not one of ball, rock"),
    (lambda t: t.replace(",rock,", ",rock,-", 1), "row 3: mass_kg -"),
])
def test_bad_kinds_and_masses_are_refused(tmp_path, edit, words):
    path = tmp_path / "impacts.csv"
    write_impacts(path, _sag_impacts())
    path.write_text(edit(path.read_text()))
    with pytest.raises(InputError, match=words):
        read_impacts(path)
