"""``millimpact compare`` with an other CSV off by a unit or of huge values (issue 35, row 18): a
time_s in ms gets a hint, values near 1e300 are scored without numpy overflow warnings."""
import math
import warnings

import numpy as np
import pytest

from conftest import run_cli
from millimpact import cli
from millimpact.results.timeseries import TimeSeries
from millimpact.studies.compare import compare_series, time_unit_hint


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """A Hertz run of hertz-halfspace with its reference file (a second of work) and its series."""
    out = tmp_path_factory.mktemp("cmp") / "ref"
    r = run_cli("run", "hertz-halfspace", "--method", "hertz", "--reference", "--set", "outputs.figures=false",
                "-q", "--out", str(out))
    assert r.returncode == 0, r.stderr
    return out, TimeSeries.read_csv(out / "timeseries.csv")


def write_other(path, ts: TimeSeries, time_factor: float = 1.0, value_factor: float = 1.0):
    t, f = ts.time * time_factor, ts["contact_force_N"] * value_factor
    path.write_text("time_s,contact_force_N\n" + "".join(f"{a!r},{b!r}\n" for a, b in zip(t, f)))
    return path


def test_a_time_in_ms_gets_a_hint(reference, tmp_path, capsys):
    ref_dir, ts = reference
    other = write_other(tmp_path / "ms.csv", ts, time_factor=1e3)
    status = cli.main(["compare", str(ref_dir), str(other), "--no-plots", "--out", str(tmp_path / "c")])
    out = capsys.readouterr().out
    assert status == 0
    assert "warning: the other's time_s spans" in out and "1e+03x the reference's" in out and "(in ms?)" in out
    # the same history in seconds: no hint
    assert time_unit_hint(ts, ts) is None


def test_huge_values_are_scored_without_overflow_warnings(reference):
    _, ts = reference
    other = TimeSeries({"time_s": ts.time, "contact_force_N": ts["contact_force_N"] * 1e300})
    ref = TimeSeries({"time_s": ts.time, "contact_force_N": ts["contact_force_N"]})
    with warnings.catch_warnings():
        warnings.simplefilter("error")             # a numpy RuntimeWarning fails the test
        (s,) = compare_series(ref, other)
        (back,) = compare_series(other, ref)
        (same,) = compare_series(other, other)
    # exact answers: other = 1e300 ref, so peak error 1e300 - 1 and L2 error |1e300 - 1| (relative)
    assert s.peak_error == pytest.approx(1e300, rel=1e-12) and s.l2_error == pytest.approx(1e300, rel=1e-9)
    assert back.peak_error == pytest.approx(-1.0, abs=1e-12) and back.l2_error == pytest.approx(1.0, rel=1e-9)
    assert same.peak_error == 0.0 and same.l2_error == 0.0 and math.isfinite(same.coverage)
    assert s.peak_other == pytest.approx(1e300 * s.peak_reference, rel=1e-12)
