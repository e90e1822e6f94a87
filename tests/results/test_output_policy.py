"""The output policy (issue 35, docs/outputs.md): what millimpact wrote is recorded in a manifest and
replaced by a rerun, the user's files stay, other kinds of output need --force, one writer at a time,
leftovers of killed runs go, and a failed write is one line. Each test is a row of the issue's
table, run as a user would (the CLI as a subprocess, cheaply with --method hertz)."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from conftest import ROOT, default_sigint, mpi_env, run_cli
from millimpact.results.output_folder import MARKER

H = ("--method", "hertz", "-q")


def cli_in(cwd: Path, *args: str, stdout=subprocess.PIPE) -> subprocess.CompletedProcess:
    """``millimpact ARGS`` run in ``cwd`` (for relative and default output folders)."""
    env = {**mpi_env(), "PYTHONPATH": str(ROOT)}
    return subprocess.run([sys.executable, "-m", "millimpact.cli", *args], cwd=cwd, env=env, stdout=stdout,
                          stderr=subprocess.PIPE, text=True, timeout=600)


def one_line(r: subprocess.CompletedProcess, code: int, *words: str) -> str:
    """The stderr of a refused / failed command: one line, ``code``, with ``words``, no traceback."""
    lines = r.stderr.strip().splitlines()
    assert r.returncode == code and len(lines) == 1 and "Traceback" not in r.stderr, (r.returncode, r.stderr)
    for w in words:
        assert w in lines[0], lines[0]
    return lines[0]


def snapshot(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


# --- row 1: compare over a run folder --------------------------------------------------------------------
def test_compare_does_not_replace_the_run_it_reads(tmp_path):
    ref = tmp_path / "ref"
    assert run_cli("run", *H, "--out", str(ref)).returncode == 0
    other = tmp_path / "other.csv"
    other.write_text((ref / "timeseries.csv").read_text())
    before = snapshot(ref)
    r = run_cli("compare", str(ref), str(other), "--out", str(ref), "--no-plots")
    one_line(r, 2, f"--out {ref}", "millimpact run output, not a compare", "--force")
    assert snapshot(ref) == before                      # the reference it has just read is still there
    r = run_cli("compare", str(ref), str(other), "--out", str(ref), "--no-plots", "--force")
    assert r.returncode == 0, r.stderr
    after = snapshot(ref)
    assert {k: after[k] for k in before if k != MARKER} == {k: v for k, v in before.items() if k != MARKER}
    assert {"compare.json", "compare.csv"} <= set(after)   # written beside the run


# --- row 2: a rerun keeps the user's files; mesh into a run folder ---------------------------------------------
def test_rerun_keeps_the_users_files_and_says_so(tmp_path):
    run = tmp_path / "r"
    assert run_cli("run", *H, "--out", str(run)).returncode == 0
    (run / "notes.txt").write_text("mine")
    assert run_cli("run", *H, "--out", str(run / "nested")).returncode == 0   # a run nested in it
    written = json.loads((run / MARKER).read_text()).get("files")
    r = run_cli("run", "--method", "hertz", "--out", str(run))
    assert r.returncode == 0, r.stderr
    assert (run / "notes.txt").read_text() == "mine" and (run / "nested" / "summary.json").is_file()
    assert "kept 2 entries millimpact did not write: nested, notes.txt" in r.stdout
    assert "replaced the earlier run's" in r.stdout
    assert json.loads((run / MARKER).read_text())["files"] == written     # the manifest: the run's own
    one_line(run_cli("mesh", "--out", str(run)), 2, "millimpact run output, not a mesh")  # before meshing


def test_a_rerun_removes_its_own_stale_files(tmp_path):
    """What the earlier run wrote and this one does not (reference files, then a run without
    --reference) goes: the folder holds one run, not a mix."""
    run = tmp_path / "r"
    assert run_cli("run", *H, "--reference", "--out", str(run)).returncode == 0
    assert (run / "reference.h5").is_file()
    assert run_cli("run", *H, "--out", str(run)).returncode == 0
    assert not (run / "reference.h5").exists() and (run / "summary.json").is_file()


# --- row 3: study, table and mesh check --out before computing --------------------------------------------------
@pytest.mark.parametrize("args", [
    ("table", "--method", "hertz", "--velocity", "1"),
    ("study", "velocity", "--method", "hertz"),
    ("mesh",),
])
def test_study_table_mesh_refuse_a_bad_out_in_one_line(tmp_path, args):
    afile = tmp_path / "somefile"
    afile.write_text("mine")
    t0 = time.perf_counter()
    one_line(cli_in(tmp_path, *args, "--out", "somefile"), 2, "--out somefile: is a file")
    one_line(cli_in(tmp_path, *args, "--out", "."), 2, "current folder")
    one_line(cli_in(tmp_path, *args, "--out", "/proc/millimpact-test"), 2, "no folder can be made there")
    user = tmp_path / "user"
    user.mkdir()
    (user / "thesis.tex").write_text("mine")
    one_line(cli_in(tmp_path, *args, "--out", "user"), 2, "did not write", "--force")
    assert time.perf_counter() - t0 < 60          # refused before meshing / computing (a mesh alone: minutes)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["somefile", "user"] and afile.read_text() == "mine"
    assert [p.name for p in user.iterdir()] == ["thesis.tex"]


# --- row 4: a full disk and a full standard output ------------------------------------------------------------
@pytest.mark.parametrize("args", [("hertz",), ("scene", "export"), ("--help",), ("run", *H, "--out", "r")])
def test_full_standard_output_is_one_line(tmp_path, args):
    with open("/dev/full", "w") as full:
        r = cli_in(tmp_path, *args, stdout=full)
    one_line(r, 1, "cannot write to standard output", "No space left on device")
    assert list(tmp_path.iterdir()) == []         # the run stopped at its first line, before computing


@pytest.fixture
def small_disk(tmp_path):
    """A 1 MB tmpfs (needs root; skipped otherwise), unmounted afterwards."""
    disk = tmp_path / "disk"
    disk.mkdir()
    if subprocess.run(["mount", "-t", "tmpfs", "-o", "size=1m", "tmpfs", str(disk)], capture_output=True).returncode:
        pytest.skip("cannot mount a tmpfs here (not root): test_write_failure_is_one_line simulates ENOSPC")
    yield disk
    subprocess.run(["umount", str(disk)], check=True)


@pytest.mark.parametrize("free_kb", [0, 100, 300])
def test_full_disk_is_one_line_and_leaves_nothing(small_disk, free_kb):
    """A hertz run writes ~360 KB: with 0 KB free it is refused before computing; with 100 KB the
    HDF5 file hits the end (before: ~90 lines of HDF5 errors, then SIGSEGV at exit and PETSc's
    MPI_Abort, exit 59); with 300 KB a figure does (before: a PIL traceback)."""
    (small_disk / "fill").write_bytes(b"\0" * 1024 * (1024 - free_kb))
    r = run_cli("run", *H, "--out", str(small_disk / "r"))
    one_line(r, 1, f"--out {small_disk / 'r'}", "full" if free_kb == 0 else "No space left on device")
    assert sorted(p.name for p in small_disk.iterdir()) == ["fill"]      # no folder, no staging, no lock


def test_write_failure_is_one_line(tmp_path):
    """The same without a small disk: ENOSPC raised while writing into the staging folder."""
    import errno

    from millimpact.errors import OutputError
    from millimpact.results.output_folder import staged_output

    out = tmp_path / "r"
    with pytest.raises(OutputError, match=r"^x: No space left on device; nothing was written") as exc:
        with staged_output(out, what="x") as stage:
            (stage / "half.csv").write_text("1,2")
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
    assert "\n" not in str(exc.value) and list(tmp_path.iterdir()) == []


# --- row 10: an interrupted table says what it kept -------------------------------------------------------------
def test_interrupted_table_says_its_finished_cases_are_kept(tmp_path):
    out = tmp_path / "t"
    speeds = ",".join(f"{0.5 + 0.05 * i:g}" for i in range(30))
    p = subprocess.Popen([sys.executable, "-m", "millimpact.cli", "table", *H, "--velocity", speeds, "--out", str(out)],
                         cwd=ROOT, env=mpi_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         preexec_fn=default_sigint)
    deadline = time.monotonic() + 120
    while not list((out / "cases").glob("*.json")) and time.monotonic() < deadline:
        time.sleep(0.05)
    p.send_signal(signal.SIGINT)
    _, err = p.communicate(timeout=120)
    kept = len(list((out / "cases").glob("*.json")))
    assert p.returncode == 130 and 1 <= kept < 30, (p.returncode, kept, err)
    last = err.strip().splitlines()[-1]
    assert "no output was written" not in last and f"{kept} finished case(s) kept in {out}/cases/" in last
    r = run_cli("table", "--method", "hertz", "--velocity", speeds, "--out", str(out))   # the rerun reuses them
    assert r.returncode == 0 and f"{kept} from {out}/cases" in r.stdout, r.stderr


# --- row 12: two writers of one folder -----------------------------------------------------------------------------
def test_second_writer_is_refused_and_a_killed_holder_blocks_nothing(tmp_path):
    """A run into a folder another run is computing into (before: both exit 0, both say "results
    in", one result silently lost) is refused; killing the first (SIGKILL) leaves nothing that
    blocks the next."""
    out = tmp_path / "r"
    first = subprocess.Popen([sys.executable, "-m", "millimpact.cli", "run", "-q", "--out", str(out)], cwd=ROOT,
                             env=mpi_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:   # the default improved run: ~15 s of computing after its claim (~2 s of imports)
        deadline = time.monotonic() + 60
        while not (tmp_path / ".r.lock").exists() and time.monotonic() < deadline:
            time.sleep(0.05)
        r = run_cli("run", *H, "--out", str(out))
        assert first.poll() is None, "the first run ended before the second started: no overlap to test"
        one_line(r, 2, f"--out {out}", "another millimpact", f"process {first.pid}")
    finally:
        first.kill()                                   # SIGKILL: the kernel drops its lock
        first.communicate()
    r = run_cli("run", *H, "--out", str(out))
    assert r.returncode == 0 and (out / "summary.json").is_file(), r.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r"]          # the lock file goes with the run


# --- row 13: what a killed run leaves ---------------------------------------------------------------------------------
def test_staging_left_by_a_killed_run_is_removed_and_said(tmp_path):
    out = tmp_path / "r"
    code = ("import time; from pathlib import Path; from millimpact.results.output_folder import staged_output\n"
            f"with staged_output(Path({str(out)!r})) as s:\n"
            "    (s / 'timeseries.csv').write_bytes(b'0' * 100000); print('writing', flush=True); time.sleep(600)\n")
    p = subprocess.Popen([sys.executable, "-c", code], cwd=ROOT, env=mpi_env(), stdout=subprocess.PIPE, text=True)
    assert p.stdout.readline().strip() == "writing"
    p.send_signal(signal.SIGKILL)                      # as the OOM killer would
    p.wait()
    left = [q.name for q in tmp_path.iterdir()]
    assert len(left) == 1 and left[0].startswith(".r.partial-")        # today's leftover
    r = run_cli("run", "--method", "hertz", "--out", str(out))
    assert r.returncode == 0, r.stderr
    assert f"removed {left[0]}, left by an interrupted millimpact" in r.stdout
    assert sorted(q.name for q in tmp_path.iterdir()) == ["r"]


# --- row 15: --out '' and a scene name that leaves out/ ---------------------------------------------------------------
def test_empty_out_is_refused(tmp_path):
    one_line(cli_in(tmp_path, "run", *H, "--out", ""), 2, "--out ''", "empty")
    assert list(tmp_path.iterdir()) == []


def test_scene_name_cannot_leave_out(tmp_path):
    text = cli_in(tmp_path, "scene", "export", "hertz-halfspace").stdout
    scene = tmp_path / "escape.toml"
    scene.write_text(text.replace('name = "hertz-halfspace"', 'name = "../escape-p35"'))
    r = cli_in(tmp_path, "run", str(scene), *H)
    assert r.returncode == 0, r.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["escape.toml", "out"]
    assert [p.name for p in (tmp_path / "out").iterdir()] == ["escape-p35"]
    from millimpact.results.output_folder import default_out

    assert default_out("../../etc") == Path("out/etc") and default_out("a/../b", "study-") == Path("out/study-a-b")


def test_claim_refuses_another_kind_and_force_writes_beside(tmp_path):
    """In-process: the claim before computing, and --force's "replaced" naming the user's file."""
    from millimpact.results.output_folder import claim_output

    out = tmp_path / "r"
    with claim_output(out, "run").staged() as stage:
        (stage / "summary.json").write_text('{"millimpact_version": "x"}')
    (out / "compare.csv").write_text("the user's")
    with pytest.raises(Exception, match="millimpact run output, not a compare"):
        claim_output(out, "compare")
    target = claim_output(out, "compare", force=True)
    with target.staged() as stage:
        (stage / "compare.csv").write_text("ours")
    assert "replaced with --force: compare.csv" in target.replaced_note()
    assert (out / "summary.json").is_file() and (out / "compare.csv").read_text() == "ours"
