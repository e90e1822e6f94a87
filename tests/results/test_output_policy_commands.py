"""The output policy (docs/outputs.md, issue 35) in the commands added after it: a rerun into its
own folder keeps the user's files, and a second writer is refused in one line (the lock).

``export`` is checked next to its table fixture (tests/dem/test_export.py) and ``damage`` next to
its fake case runner (tests/damage/test_damage_map.py); ``mill`` here.
"""
from __future__ import annotations

import shutil

import pytest

from conftest import run_cli
from output_lock import another_writer, assert_notes_kept, assert_refused_by_the_lock

needs_yade = pytest.mark.skipif(shutil.which("yade") is None, reason="yade not installed (packages.txt has it)")

#: the cheapest mill run that writes: one ball, no warm-up, 0.05 revolutions, no figures (~11 s)
TINY_MILL = ["mill", "liner-segment", "--revolutions", "0.05", "--balls", "1", "--warmup", "0", "--no-plots"]


@needs_yade
@pytest.mark.slow
def test_mill_rerun_keeps_the_users_file_and_a_second_writer_is_refused(tmp_path):
    """Before the policy: the rerun kept notes.txt without saying so, and a second mill into a
    folder another millimpact was writing ran its DEM and published over it."""
    out = tmp_path / "mill"
    r = run_cli(*TINY_MILL, "--out", str(out))
    assert r.returncode == 0, r.stderr[-3000:]
    (out / "notes.txt").write_text("my notes\n")
    r = run_cli(*TINY_MILL, "--out", str(out))
    assert r.returncode == 0 and (out / "impacts.csv").is_file(), r.stderr[-3000:]
    assert_notes_kept(out, r.stdout + r.stderr)
    with another_writer(out, "mill") as pid:
        r = run_cli(*TINY_MILL, "--out", str(out))
    assert_refused_by_the_lock(r.returncode, r.stderr, out, pid)
