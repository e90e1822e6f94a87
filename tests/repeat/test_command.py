"""``millimpact repeat``: bad input, the verdict's rules, an interrupted sequence continued."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time

import pytest

from conftest import ROOT, default_sigint, mpi_env, run_cli
from millimpact.repeat.report import read_impacts_csv
from millimpact.repeat.sequence import OUTCOME_COLUMNS, ImpactOutcome
from millimpact.repeat.verdict import classify

COARSE = ["--set", "model.h_contact=8e-4", "--set", "model.h_far=0.012", "-q"]


@pytest.mark.parametrize("args, words", [
    (["--impacts", "0"], "--impacts 0"),
    # no upper bound before: a spec per impact built first, ~250 MB/s, and Ctrl-C not honoured
    (["--impacts", "1000000000"], "--impacts 1000000000: must lie in [1, 1000]"),
    (["--impacts", "3", "--velocities", "1,2"], "--velocities"),
    (["--impacts", "2", "--angles", "10,20,30"], "--angles"),
    (["--impacts", "2", "--offset", "0.05,0"], "leaves the face"),
    (["--impacts", "2", "--offset", "0.001"], "--offset"),
    (["--impacts", "2", "--velocities", "-1"], "speed"),
    (["--impacts", "2", "--method", "hertz"], "--method"),
    # the plan's refusals: before, they came after --out was claimed and left its folder
    (["--impacts", "2", "--set", "time.end=1e-9"], "time.end"),
    (["--impacts", "2", "--set", "model.h_contact=0.01"], "model.h_contact"),
])
def test_bad_input_is_one_line_exit_2_and_no_folder(tmp_path, args, words):
    out = tmp_path / "r"
    r = run_cli("repeat", "paper-rig-plastic", *args, "--out", str(out))
    assert r.returncode == 2, r.stderr
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and words in lines[0], r.stderr
    assert not out.exists()


def _outcomes(w, d):
    return [ImpactOutcome(k + 1, 0.8, float("nan"), 1e4, 8e-5, wk, dk, 1e-3, 0.03) for k, (wk, dk) in enumerate(zip(w, d))]


def test_verdicts_follow_their_definitions():
    """Johnson (1985) ch. 9's three outcomes from plastic work and dent per impact."""
    # plastic work below 1 % of the first's from impact 4 on: elastic shakedown there
    v = classify(_outcomes([1.0, 0.2, 0.05, 0.009, 0.001], [10, 12, 12.5, 12.51, 12.511]))
    assert v.kind == "elastic shakedown" and v.impacts_to_shakedown == 4
    # a constant dent growth: ratcheting
    v = classify(_outcomes([1.0, 0.5, 0.5, 0.5, 0.5], [10, 13, 16, 19, 22]))
    assert v.kind == "ratcheting"
    # plastic work every impact but the dent stops growing: a closed plastic cycle
    v = classify(_outcomes([1.0, 0.4, 0.3, 0.3, 0.3], [10, 11, 11.05, 11.05, 11.05]))
    assert v.kind == "plastic shakedown" and v.impacts_to_shakedown == 3     # dD_3 = 0.05 < 1 % of 10
    # decaying but not yet small: undecided, with the impacts still needed
    v = classify(_outcomes([1.0, 0.5, 0.25, 0.12, 0.06], [10, 15, 17.5, 18.75, 19.4]))
    assert v.kind == "undecided" and v.numbers["impacts_more_to_closed_share"] > 1
    assert classify(_outcomes([1.0, 0.5], [10, 12])).kind == "undecided"


@pytest.mark.slow
def test_interrupted_sequence_keeps_its_impacts_and_a_rerun_continues(tmp_path):
    # 6 impacts, the interrupt sent within 0.1 s of the first one's file: the other 5 take ~9 s,
    # so the run is still computing when the signal lands. The child answers SIGINT as from a
    # terminal (default_sigint): a suite started in the background (`./dev test &`, a CI runner)
    # ignores SIGINT and its children inherit that, so the sequence ran to its end with exit 0
    # (the failure seen twice, first taken for a race with the faster plastic step)
    n = 6
    out = tmp_path / "seq"
    cmd = [sys.executable, "-m", "millimpact.cli", "repeat", "paper-rig-plastic", "--impacts", str(n), *COARSE,
           "--out", str(out)]
    p = subprocess.Popen(cmd, cwd=ROOT, env=mpi_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         preexec_fn=default_sigint)
    first = out / "impacts" / "impact-001.json"
    t0 = time.time()
    while not first.exists() and p.poll() is None and time.time() - t0 < 500:
        time.sleep(0.1)
    assert first.exists(), p.communicate()[1][-2000:]
    assert p.poll() is None, "the sequence ended before the interrupt"
    p.send_signal(signal.SIGINT)
    _, err = p.communicate(timeout=300)
    assert p.returncode == 130, err
    assert "finished impact(s) kept" in err and "continues" in err
    assert not (out / "summary.json").exists()
    kept = sorted(f.name for f in (out / "impacts").glob("impact-*.json"))
    assert kept and kept[0] == "impact-001.json"
    before = json.loads(first.read_text())["outcome"]
    r = run_cli("repeat", "paper-rig-plastic", "--impacts", str(n), *COARSE[:-1], "--out", str(out))
    assert r.returncode == 0, r.stderr[-3000:]
    assert f"{len(kept)} finished impact file(s)" in r.stdout + r.stderr
    rows = read_impacts_csv(out / "impacts.csv")
    assert [o.impact for o in rows] == list(range(1, n + 1))
    assert rows[0].restitution_normal == pytest.approx(before["restitution_normal"], rel=1e-9)
    header = [ln for ln in (out / "impacts.csv").read_text().splitlines() if not ln.startswith("#")][0]
    assert header.split(",") == list(OUTCOME_COLUMNS)
    summary = json.loads((out / "summary.json").read_text())
    assert summary["verdict"]["kind"] in ("elastic shakedown", "plastic shakedown", "ratcheting", "undecided")
    for name in ("restitution.png", "dent.png", "summary.txt"):
        assert (out / name).is_file()
    assert os.path.getsize(out / "dent.png") > 1000


@pytest.mark.slow
def test_one_impact_is_the_first_of_several(tmp_path):
    """``--impacts 1`` and ``--impacts 2`` give the same first impact (the same model and the same
    deterministic solves: 1e-10 leaves only the last digits; before, 1 impact had a smaller zone:
    e_n 0.7137 against 0.7114, plastic work -1.1 %). Without -q, the model's stages and the time
    loop's progress inside the impact are said (before: nothing until the impact's end, ~70 s at
    coarse settings)."""
    rows = {}
    for n in (1, 2):
        out = tmp_path / f"n{n}"
        r = run_cli("repeat", "paper-rig-plastic", "--impacts", str(n), *(COARSE if n > 1 else COARSE[:-1]),
                    "--out", str(out))
        assert r.returncode == 0, r.stderr[-3000:]
        rows[n] = read_impacts_csv(out / "impacts.csv")[0]
        if n == 1:
            assert "reduction" in r.stderr and "% (" in r.stderr and "simulated" in r.stderr, r.stderr[-2000:]
    for c in OUTCOME_COLUMNS[1:]:
        x, y = getattr(rows[1], c), getattr(rows[2], c)
        assert (x != x and y != y) or x == pytest.approx(y, rel=1e-10, abs=1e-300), c


@pytest.mark.slow
@pytest.mark.mpi
def test_mpi_sequence_equals_serial(tmp_path):
    """Two impacts under mpirun -n 2 (each rank stores and reloads its own part of the plastic
    state) equal the serial sequence (round-off of the distributed solves: 1e-7)."""
    rows = {}
    for np_ in (1, 2):
        out = tmp_path / f"np{np_}"
        r = run_cli("repeat", "paper-rig-plastic", "--impacts", "2", *COARSE, "--out", str(out), np=np_, timeout=1200)
        assert r.returncode == 0, r.stderr[-3000:]
        rows[np_] = read_impacts_csv(out / "impacts.csv")
        assert len(list((out / "impacts").glob("impact-002.rank*.npz"))) == np_
    for a, b in zip(rows[1], rows[2]):
        for c in OUTCOME_COLUMNS[1:]:
            x, y = getattr(a, c), getattr(b, c)
            assert (x != x and y != y) or x == pytest.approx(y, rel=1e-7, abs=1e-12), c


@pytest.mark.slow
@pytest.mark.mpi
@pytest.mark.parametrize("phase", ["model", "impacts"])
def test_mpi_sequence_interrupted_says_so_and_leaves_no_lock(tmp_path, phase):
    """``mpirun -n 2 repeat`` and Ctrl-C while the model is built (the header line is out) or between
    impacts (the first impact's line is out): rank 0 prints the interrupt line and every rank ends;
    no lock file is left beside the folder (before: no line, exit 1 after 37 s, a stale .NAME.lock).

    Open MPI's mpirun answers Ctrl-C with SIGCONT, SIGTERM 1 s later and SIGKILL 1 s after that
    (measured, docs/outputs.md). Rank 0's signal thread says the line at the SIGTERM, but it needs
    the interpreter's lock, which the main thread holds inside a PETSc/SLEPc call: beside the
    suite's other worker and its mpirun ranks on 2 cores that can outlast the second before SIGKILL
    (3 of 4 full-suite runs missed it once; never alone). Up to three tries, each a fresh run: a
    broken mechanism fails all three."""
    import shutil

    if shutil.which("mpirun") is None:
        pytest.skip("mpirun not installed")
    cue = "repeat paper-rig-plastic" if phase == "model" else "[1/3]"
    tries = []
    for attempt in range(3):
        base = tmp_path / f"try{attempt}"
        base.mkdir()
        out = base / "x"
        cmd = ["mpirun", "-n", "2", sys.executable, "-m", "millimpact.cli", "repeat", "paper-rig-plastic",
               "--impacts", "3", *COARSE[:-1], "--set", "time.end=3e-4", "--out", str(out)]
        p = subprocess.Popen(cmd, cwd=ROOT, env=mpi_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                             text=True, preexec_fn=default_sigint)
        for line in p.stdout:
            if cue in line:
                break
        assert p.poll() is None, p.communicate()[1][-2000:]
        p.send_signal(signal.SIGINT)
        _, err = p.communicate(timeout=120)
        assert "Traceback" not in err and not (out / "summary.json").exists()
        said = p.returncode != 0 and "millimpact: interrupted" in err and "finished impact(s) kept" in err
        clean = sorted(q.name for q in base.iterdir()) == ["x"]  # no .x.lock, no staging
        tries.append((said, clean, err[-1500:]))
        if said and clean:
            return
    pytest.fail("no try said the interrupt line and left no lock:\n" + "\n---\n".join(t[2] for t in tries))


# --- the output policy (docs/outputs.md, issue 35) -------------------------------------------------
def _fake_sequence(scene, impacts, method="improved", petsc_options=None, comm=None, progress=None, *,
                   store_dir=None, records=None):
    """Outcomes without finite elements: a dent whose increments halve (a plastic shakedown)."""
    return [ImpactOutcome(k, 0.8, float("nan"), 1e5, 1e-4, 1e-3 * 0.5**k, 1e-6 * (2 - 0.5 ** (k - 1)), 1e-4, 0.01)
            for k in range(1, len(impacts) + 1)]


def _repeat_in_process(monkeypatch, capsys, out) -> tuple[int, str, str]:
    """``millimpact repeat`` in this process with the fake sequence."""
    import millimpact.repeat.sequence as sequence
    from output_lock import main_in_process

    monkeypatch.setattr(sequence, "run_sequence", _fake_sequence)
    return main_in_process(capsys, ["repeat", "paper-rig-plastic", "--impacts", "3", "--out", str(out)])


def test_repeat_rerun_keeps_the_users_file_and_a_second_writer_is_refused(tmp_path, monkeypatch, capsys):
    """A rerun into its own folder replaces the sequence's files and keeps notes.txt (said in the
    results line); while another millimpact holds the folder, repeat is refused in one line before
    computing (before the policy: no lock, both wrote)."""
    from output_lock import another_writer, assert_notes_kept, assert_refused_by_the_lock

    out = tmp_path / "seq"
    code, stdout, stderr = _repeat_in_process(monkeypatch, capsys, out)
    assert code == 0 and (out / "summary.json").is_file(), stderr
    (out / "notes.txt").write_text("my notes\n")
    code, stdout, stderr = _repeat_in_process(monkeypatch, capsys, out)
    assert code == 0 and [o.impact for o in read_impacts_csv(out / "impacts.csv")] == [1, 2, 3], stderr
    assert_notes_kept(out, stdout + stderr)
    with another_writer(out, "repeat") as pid:
        code, stdout, stderr = _repeat_in_process(monkeypatch, capsys, out)
    assert_refused_by_the_lock(code, stderr, out, pid)


def test_a_sequence_grows_the_liner_zone_and_keeps_the_balls():
    """A sequence: the struck body's zone is REPEAT_ZONE_FACTOR a single impact's (plus the largest
    offset), the ball keeps a single impact's (model.ball_zone_radius; it is struck at the same
    point of its own); a sequence of one impact has the same model as one of two (before, one
    impact had the single zone and its first impact differed from a longer sequence's)."""
    from millimpact.repeat.sequence import REPEAT_ZONE_FACTOR, ImpactSpec, sequence_scene
    from millimpact.scene.builtin import resolve_scene
    from millimpact.scene.plan import make_plan
    from millimpact.scene.toml_io import dump_scene
    from millimpact.methods.reduced import reduced_plan

    scene = resolve_scene("paper-rig-plastic")
    alone = sequence_scene(scene, [ImpactSpec(3.0)], "improved")
    assert dump_scene(alone) == dump_scene(sequence_scene(scene, [ImpactSpec(3.0)] * 3, "improved"))
    single = scene.with_value("impact.velocity", [0.0, -3.0, 0.0])
    one = reduced_plan(single, make_plan(single))[1]        # a single impact's (``run``) zone
    two = sequence_scene(scene, [ImpactSpec(3.0)] * 2, "improved").model
    assert two.zone_radius == pytest.approx(REPEAT_ZONE_FACTOR * one.zone_radius, rel=1e-12)
    assert two.ball_zone_radius == pytest.approx(one.zone_radius, rel=1e-12)
    dz = 5e-4
    off = sequence_scene(scene, [ImpactSpec(3.0), ImpactSpec(3.0, 0.0, (0.0, dz))], "improved").model
    assert off.zone_radius == pytest.approx(REPEAT_ZONE_FACTOR * one.zone_radius + dz, rel=1e-12)
    assert off.ball_zone_radius == pytest.approx(one.zone_radius, rel=1e-12)
