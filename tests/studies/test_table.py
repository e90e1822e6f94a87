"""``millimpact table`` (issue 16): one impact per (speed, angle), the reduction reused per mesh band.

Cases on the coarse half-space (h_contact = 0.58 mm = a_max / 2 at 3 m/s, h_far = 12 mm: ~9k
DOFs, improved ~1.3k reduced coordinates); every tolerance's source is at its assertion.
"""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from conftest import run_cli
from millimpact.scene.builtin import builtin_scene
from millimpact.studies.table import case_t_end, case_velocity

#: the half model for every case: the normal impacts (which alone keep a quarter) share the oblique
#: ones' mesh, so that the two are compared on one mesh
COARSE = ["--set", "model.h_contact=5.8e-4", "--set", "model.h_far=0.012", "--set", "model.symmetry=half"]
#: v = 3 m/s normal and 30 deg oblique, and the normal impact at the oblique one's normal speed
#: (3 cos 30 = 2.598 m/s): normal speeds 2.25-3 m/s, one rung of the band ladder ([2.25, 3.375) m/s):
#: one mesh band
SPEEDS, ANGLES = "2.598076211353316,3", "0,30"


def _rows(out):
    return json.loads((out / "contact_table.json").read_text())["rows"]


@pytest.fixture(scope="module")
def table(tmp_path_factory):
    out = tmp_path_factory.mktemp("table") / "t"
    r = run_cli("table", "hertz-halfspace", "--velocity", SPEEDS, "--angle", ANGLES, *COARSE, "--out", str(out))
    assert r.returncode == 0, r.stderr[-3000:]
    return out, r


def test_table_files_and_reuse(table):
    out, r = table
    rows = _rows(out)
    assert len(rows) == 4 and all(row["status"] == "ok" for row in rows)
    # one band: one reduction, reused by the three other cases
    assert sum(row["reduction_reused"] for row in rows) == 3
    lines = (out / "contact_table.csv").read_text().splitlines()
    assert lines[0].startswith("# millimpact") and any(l.startswith("# restitution_tangential [-]") for l in lines)
    assert lines[[l.startswith("#") for l in lines].index(False)].startswith("impact_speed_m_s,impact_angle_deg")
    import h5py
    with h5py.File(out / "contact_table.h5") as h5:
        assert h5["peak_normal_force_N"].attrs["unit"] == "N" and len(h5["restitution_normal"]) == 4
    laws = json.loads((out / "contact_laws.json").read_text())
    assert "hertz_stiffness" in laws and "restitution_power_law" in laws
    for f in ("e_n_speed.png", "e_t_angle.png", "force_speed.png"):
        assert (out / f).stat().st_size > 0


def test_frictionless_oblique_impact_is_the_normal_impact_of_its_normal_speed(table):
    """Without friction the normal and tangential motions decouple: the 30 deg impact at 3 m/s is
    the normal impact at 2.598 m/s (same mesh) in e_n, peak force and duration, to the time-step
    error (the steps follow each case's Hertz t_c, t_c / 100: ~1e-3), with no tangential impulse;
    and the normal impulse is the ball's momentum change m v_n (1 + e_n) (Newton's second law)."""
    out, _ = table
    rows = _rows(out)
    obl = [r for r in rows if r["impact_angle_deg"] == 30 and r["impact_speed_m_s"] == 3][0]
    nor = [r for r in rows if r["impact_angle_deg"] == 0 and abs(r["impact_speed_m_s"] - 2.598076211353316) < 1e-12][0]
    assert obl["normal_velocity_in_m_s"] == pytest.approx(nor["normal_velocity_in_m_s"], rel=1e-12)
    assert obl["restitution_normal"] == pytest.approx(nor["restitution_normal"], abs=2e-3)
    assert obl["peak_normal_force_N"] == pytest.approx(nor["peak_normal_force_N"], rel=2e-3)
    assert obl["tangential_impulse_N_s"] == 0.0 and obl["restitution_tangential"] == 1.0
    m = builtin_scene("hertz-halfspace").ball.mass
    for row in rows:
        # the trapezoidal impulse against the momentum change: 1 % (the pulse's ~100 samples)
        assert row["normal_impulse_N_s"] == pytest.approx(m * row["normal_velocity_in_m_s"] * (1 + row["restitution_normal"]), rel=0.01)


def test_normal_case_equals_the_standalone_run(table, tmp_path):
    """A table case is the standalone run of its scene on the same mesh, cut to the impact:
    the same numbers to round-off (the same model, reduction and steps; the band's reduction is
    built for a normal impact at its rung's fast edge, 3.375 m/s, whose contact candidates and
    mesh cover this case's)."""
    out, _ = table
    row = [r for r in _rows(out) if r["impact_angle_deg"] == 0 and r["impact_speed_m_s"] == 3][0]
    assert json.loads((out / "cases" / f"{row['key']}.json").read_text())["case"] == row["case"]
    # the band's mesh: h_contact (given), zone, gap, cutoff and symmetry of the table's case scene
    r = run_cli("run", "hertz-halfspace", *COARSE, *_band_sets(out, row), "-q", "--out", str(tmp_path / "run"))
    assert r.returncode == 0, r.stderr[-2000:]
    s = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert s["restitution"] == pytest.approx(row["restitution_normal"], rel=1e-9)
    assert s["peak_contact_force_N"] == pytest.approx(row["peak_normal_force_N"], rel=1e-9)


def _band_sets(out, row):
    """--set arguments that give the standalone run the table case's band settings."""
    from millimpact.studies.table import define_cases
    base = (builtin_scene("hertz-halfspace").with_value("model.h_contact", 5.8e-4).with_value("model.h_far", 0.012)
            .with_value("model.symmetry", "half"))
    cases = define_cases(base, [2.598076211353316, 3.0], [0.0, 30.0], [base.ball.radius], "improved", {})
    case = [c for c in cases if c.key == row["key"]][0]
    sc = case.scene
    from millimpact.methods.reduced import reduced_plan
    from millimpact.scene.plan import make_plan
    # the band's contact candidates: the band scene's (a normal impact at its rung's fast edge)
    radius = reduced_plan(case.band_scene, make_plan(case.band_scene))[2]
    return ["-candidate_radius", repr(radius), "--set", f"model.fine_radius={sc.model.fine_radius!r}",
            "--set", f"model.zone_radius={sc.model.zone_radius!r}", "--set", f"impact.gap={sc.impact.gap!r}",
            "--set", f"model.f_cut={sc.model.f_cut!r}", "--set", f"time.dt_contact={sc.time.dt_contact!r}",
            "--set", f"model.symmetry={sc.model.symmetry}",
            "--set", f"time.end={case_t_end(sc)!r}"]


def test_rerun_computes_only_missing_cases(table, tmp_path):
    import shutil
    out, _ = table
    copy = tmp_path / "t"
    shutil.copytree(out, copy)
    rows = _rows(copy)
    (copy / "cases" / f"{rows[1]['key']}.json").unlink()
    r = run_cli("table", "hertz-halfspace", "--velocity", SPEEDS, "--angle", ANGLES, *COARSE, "--out", str(copy))
    assert r.returncode == 0, r.stderr[-2000:]
    assert "3 from" in r.stdout and "1 to compute" in r.stdout
    again = _rows(copy)
    assert again[1]["restitution_normal"] == pytest.approx(rows[1]["restitution_normal"], rel=1e-9)


def test_gross_sliding_with_friction(tmp_path):
    """mu = 0.05 at 60 deg: tan(60) = 1.73 >> 7/2 mu (1 + e) ~ 0.35, Maw-Barber-Fawcett's gross
    sliding: the tangential impulse is -mu times the normal one (to the slip-detection tolerance,
    1e-3), and e_t = 1 - 7/2 mu (1 + e_n) / tan(angle) follows from it (rigid-ball spin)."""
    out = tmp_path / "f"
    r = run_cli("table", "hertz-halfspace", "--velocity", "3", "--angle", "60", *COARSE, "--set", "contact.friction=0.05",
                "--out", str(out))
    assert r.returncode == 0, r.stderr[-2000:]
    (row,) = _rows(out)
    assert row["tangential_impulse_N_s"] / row["normal_impulse_N_s"] == pytest.approx(-0.05, rel=1e-3)
    e_t = 1 - 3.5 * 0.05 * (1 + row["restitution_normal"]) / math.tan(math.radians(60))
    assert row["restitution_tangential"] == pytest.approx(e_t, rel=0.01)
    assert row["rebound_spin_rad_s"] > 0 and row["friction_dissipation_J"] > 0


def test_sticking_with_reversal_with_friction(tmp_path):
    """mu = 0.5 at 30 deg: tan(30) / mu = 1.15, far below the 7/2 (1 + e) ~ 7 of gross sliding:
    Maw-Barber-Fawcett's regime where the contact sticks over most of the impact: the tangential
    impulse stays well below mu J_n, Coulomb bounds the peak tangential force, and the contact
    point leaves with about no tangential velocity (rigid sticking: e_t = 0; gross sliding would
    need e_t = 1 - 7/2 mu (1 + e_n) / tan(30) = -5, frictionless 1). MBF's elastic reversal
    (e_t < 0) needs the micro-slip annulus resolved: this coarse mesh (2 elements across a_max)
    gives e_t = +0.026, the scene's default mesh (4 across) -0.078 but in 3.4 min, too long here."""
    out = tmp_path / "s"
    r = run_cli("table", "hertz-halfspace", "--velocity", "3", "--angle", "30", *COARSE, "--set", "contact.friction=0.5",
                "--out", str(out))
    assert r.returncode == 0, r.stderr[-2000:]
    (row,) = _rows(out)
    assert abs(row["tangential_impulse_N_s"]) < 0.5 * 0.5 * row["normal_impulse_N_s"]
    # Coulomb at every instant, |f_t| <= mu f_n, so at the peaks too (the slip tolerance: 1e-3)
    assert row["peak_tangential_force_N"] <= 0.5 * row["peak_normal_force_N"] * (1 + 1e-3)
    assert -0.5 < row["restitution_tangential"] < 0.2


def test_restitution_near_hunter(table):
    """Hunter (1957): an elastic sphere on a half-space radiates ~1.3 % of the impact energy as
    waves at 3 m/s, e_n ~ 0.99; much lower is numerical dissipation, above 1 energy creation (the
    band as test_full's bound on the full method, 0.98-1.001)."""
    out, _ = table
    for row in _rows(out):
        assert 0.98 < row["restitution_normal"] < 1.001


@pytest.mark.mpi
def test_mpi_table_equals_serial(table, tmp_path):
    """mpirun -n 2 --ranks-per-case 1: the two groups share the cases; the rows equal the serial
    table's (1e-9 relative: each case is the same serial computation)."""
    out, _ = table
    r = run_cli("table", "hertz-halfspace", "--velocity", SPEEDS, "--angle", ANGLES, *COARSE, "--ranks-per-case", "1",
                "--out", str(tmp_path / "np2"), np=2)
    assert r.returncode == 0, r.stderr[-3000:]
    a, b = _rows(out), _rows(tmp_path / "np2")
    for ra, rb in zip(a, b):
        for k in ("restitution_normal", "peak_normal_force_N", "normal_impulse_N_s", "max_approach_m"):
            assert rb[k] == pytest.approx(ra[k], rel=1e-9), k


@pytest.mark.parametrize("args, words", [
    (["--velocity", ""], "--velocity"),
    (["--velocity", "1,x"], "'x' is not a number"),
    (["--velocity", "0,1"], "outside (0, 100] m/s"),
    (["--velocity", "1", "--angle", "90"], "outside [0, 90) deg"),
    (["--velocity", "1", "--ranks-per-case", "3"], "--ranks-per-case 3"),
])
def test_bad_input_one_line(args, words, tmp_path):
    r = run_cli("table", "hertz-halfspace", *args, "--out", str(tmp_path / "x"))
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and words in r.stderr, r.stderr


def test_case_velocity_angle():
    s = builtin_scene("paper-rig")
    v = np.array(case_velocity(s, 2.0, 30.0))
    n = np.array(s.contact_normal)
    assert np.linalg.norm(v) == pytest.approx(2.0) and -v @ n == pytest.approx(2.0 * math.cos(math.radians(30)))
    assert v[0] == 0.0          # in the plane x = x_p: the half model's symmetry plane


def test_bands_are_computed_one_after_the_other(tmp_path):
    """Normal speeds 1.5, 0.75, 3, 1.5 m/s (speeds 1.5 and 3 at 0 and 60 deg): three rungs of the
    band ladder, {0.75}, {1.5, 1.5} and {3}, listed interleaved by speed (the first and last
    rows share a band). Computed band after band, each reduction is built once (a group keeps only
    its current band: computing in the listed order rebuilt bands, 19 reductions instead of 6 on
    the 100-case benchmark)."""
    out = tmp_path / "b"
    r = run_cli("table", "hertz-halfspace", "--velocity", "1.5,3", "--angle", "0,60", *COARSE, "--out", str(out))
    assert r.returncode == 0, r.stderr[-2000:]
    rows = _rows(out)
    assert len({row["band"] for row in rows}) == 3 and rows[0]["band"] == rows[-1]["band"]
    assert sum(not row["reduction_reused"] for row in rows) == 3
    assert [row["impact_speed_m_s"] for row in rows] == [1.5, 1.5, 3, 3]     # the table stays listed by speed


def test_groups_take_different_bands():
    """next_case: with two groups and two bands of three cases, the second group starts the second
    band instead of joining the first (each group builds one reduction, not both); a group whose
    band is finished joins the band with cases left; every case is taken exactly once."""
    from millimpact.studies.table import next_case

    sizes = [3, 3]
    state = np.zeros(1 + 2 * len(sizes), dtype="i8")
    a = next_case(state, sizes, None)
    b = next_case(state, sizes, None)
    assert (a, b) == ((0, 0), (1, 0))
    taken = [a, b]
    cur = {"A": 0, "B": 1}
    for g in ["A", "A", "A", "B", "A"]:       # A finishes band 0 (2 more), then joins band 1
        pick = next_case(state, sizes, cur[g])
        taken.append(pick)
        cur[g] = pick[0] if pick else None
    assert taken[4] == (1, 1) and taken[5] == (1, 2)     # A moved to band 1 after band 0 ran out
    assert next_case(state, sizes, cur["A"]) is None and next_case(state, sizes, cur["B"]) is None
    assert sorted(t for t in taken if t) == [(0, 0), (0, 1), (0, 2), (1, 0), (1, 1), (1, 2)]


def test_a_group_takes_the_band_it_holds_first():
    """next_case with ``held`` (an adaptive table's group keeps its reductions between batches): the
    first group, holding band 1's reduction, takes band 1 rather than the dearest band 0; the second
    then starts band 0 (no group on it); when every open band has a group, a group joins the one it
    holds rather than the one with the most cases left. Without ``held``, the order is today's."""
    from millimpact.studies.table import next_case

    sizes = [3, 1]
    state = np.zeros(1 + 2 * len(sizes), dtype="i8")
    assert next_case(state, sizes, None, held=[1]) == (1, 0)
    assert next_case(state, sizes, None) == (0, 0)
    # band 1 is done: the first group leaves it and joins band 0 (the only band left)
    assert next_case(state, sizes, 1, held=[1]) == (0, 1)
    sizes = [4, 2]
    state = np.zeros(1 + 2 * len(sizes), dtype="i8")
    assert next_case(state, sizes, None) == (0, 0) and next_case(state, sizes, None) == (1, 0)
    # a third group, holding band 1: both bands have a group; it joins band 1, not band 0 (3 left of 4)
    assert next_case(state, sizes, None, held=[1]) == (1, 1)
    assert next_case(state, sizes, None) == (0, 1)


def test_bands_and_cases_are_taken_dearest_first():
    """costliest_first: the band with the fastest normal speed comes first, and within a band the
    case with the fastest normal speed (angle 0 before 60 deg); every case once. Two radii: at equal
    normal speeds the larger ball's band first."""
    from millimpact.studies.table import costliest_first, define_cases

    base = builtin_scene("hertz-halfspace").with_value("model.h_contact", 5.8e-4).with_value("model.h_far", 0.012)
    r = base.ball.radius
    cases = define_cases(base, [0.5, 1.0, 4.0], [0.0, 60.0], [r, 1.5 * r], "improved", {})
    groups = costliest_first(cases)
    fastest = [max(c.scene.normal_speed for c in g) for g in groups]
    assert fastest == sorted(fastest, reverse=True)
    assert groups[0][0].speed == 4.0 and groups[0][0].angle == 0.0 and groups[0][0].radius == 1.5 * r
    assert groups[1][0].speed == 4.0 and groups[1][0].radius == r
    for g in groups:
        assert len({c.band for c in g}) == 1
        speeds = [c.scene.normal_speed for c in g]
        assert speeds == sorted(speeds, reverse=True)
    assert sorted(c.index for g in groups for c in g) == list(range(len(cases)))


def test_a_table_interrupted_while_written_says_its_cases_are_kept(tmp_path):
    """Ctrl-C once the last case's line is out and the table's staging folder is there (its files
    are being written, ~1 s of figures): the line names the finished cases kept in cases/ (before: "no output was written",
    although they were kept and a rerun reused them)."""
    import signal
    import subprocess
    import sys
    import time

    from conftest import ROOT, default_sigint, mpi_env

    out = tmp_path / "t"
    p = subprocess.Popen([sys.executable, "-m", "millimpact.cli", "table", "--method", "hertz", "--velocity",
                          "1,2,3,4,5,6,7,8", "--out", str(out)], cwd=ROOT, env=mpi_env(), stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True, preexec_fn=default_sigint)
    for line in p.stdout:
        if "[8/8]" in line:
            break
    while not list(tmp_path.glob(".t.partial-*")) and p.poll() is None:   # the table's files are being staged
        time.sleep(0.01)
    p.send_signal(signal.SIGINT)
    _, err = p.communicate(timeout=120)
    assert p.returncode == 130, (p.returncode, err[-2000:])
    last = err.strip().splitlines()[-1]
    assert "no output was written" not in last and f"8 finished case(s) kept in {out}/cases/" in last, last
    assert not (out / "contact_table.csv").exists()


def test_a_full_disk_while_the_table_is_written_says_what_is_kept(tmp_path):
    """A 1 MB tmpfs with ~60 KB free: the finished case fits in cases/, the table's files do not.
    One line, exit 1, saying the case is kept (before: "nothing was written", with the folder, its
    case and its manifest left). Needs root for the mount; skipped otherwise."""
    import subprocess

    disk = tmp_path / "disk"
    disk.mkdir()
    if subprocess.run(["mount", "-t", "tmpfs", "-o", "size=1m", "tmpfs", str(disk)], capture_output=True).returncode:
        pytest.skip("cannot mount a tmpfs here (not root)")
    try:
        (disk / "fill").write_bytes(b"\0" * 1024 * (1024 - 60))
        r = run_cli("table", "--method", "hertz", "--velocity", "1", "--out", str(disk / "t"))
        lines = r.stderr.strip().splitlines()
        assert r.returncode == 1 and len(lines) == 1 and "No space left on device" in lines[0], r.stderr[-2000:]
        assert "nothing was written" not in lines[0] and f"1 finished case(s) kept in {disk / 't'}/cases/" in lines[0]
        assert len(list((disk / "t" / "cases").glob("*.json"))) == 1
        assert not (disk / "t" / "contact_table.csv").exists()
    finally:
        subprocess.run(["umount", str(disk)], check=True)
