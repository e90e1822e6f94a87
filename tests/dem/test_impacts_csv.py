"""impacts.csv (millimpact.dem.impacts): a written log reads back equal; bad files are refused
with one line naming the column and the row."""
from __future__ import annotations

import math

import pytest

from millimpact.dem.impacts import IMPACT_COLUMNS, Impact, read_impacts, write_impacts
from millimpact.errors import InputError


def _impacts():
    # a 125 mm ball (r 62.5 mm, 7800 kg/m^3: m = 7.98 kg) at 5 m/s normal, 2 m/s tangential
    m = 7800 * 4 / 3 * math.pi * 0.0625 ** 3
    return [Impact(0.125, 0.0625, 5.0, 2.0, 0.5 * m * (25 + 4), "lifter_face", -0.031),
            Impact(0.5, 0.0625, 0.25, 0.0, 0.5 * m * 0.0625, "plate", 0.12)]


def test_round_trip(tmp_path):
    path = tmp_path / "impacts.csv"
    write_impacts(path, _impacts())
    assert path.read_text().splitlines()[0] == ",".join(IMPACT_COLUMNS)
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
