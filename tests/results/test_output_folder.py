"""Output folders (issue 18): checked before computing, never deleting what millimpact did not
write, and an interrupted run leaves nothing that looks complete."""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import pytest

from conftest import ROOT, default_sigint, mpi_env, run_cli
from millimpact.errors import InputError
from millimpact.results.output_folder import MARKER, is_millimpact_output, prepare_output
from millimpact.results.output_folder import staged_output


def test_refusals_name_the_path(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "user").mkdir()
    (tmp_path / "user" / "thesis.tex").write_text("mine")
    (tmp_path / "afile").write_text("mine")
    cases = {"user": "did not write", "afile": "is a file", ".": "current folder", str(tmp_path.parent): "current folder",
             "afile/sub": "is a file, so no folder", "/proc/millimpact-test": "no folder can be made"}
    for out, words in cases.items():
        with pytest.raises(InputError, match=words) as exc:
            prepare_output(out)
        assert str(exc.value).startswith(f"--out {out}:") and "\n" not in str(exc.value)
    assert (tmp_path / "user" / "thesis.tex").read_text() == "mine" and (tmp_path / "afile").read_text() == "mine"
    assert prepare_output("user", force=True) == tmp_path / "user"          # --force: the user asked
    assert prepare_output("new/deeper") == tmp_path / "new" / "deeper"       # parents are made
    assert not (tmp_path / "new" / "deeper").exists()                        # but not the folder itself
    assert [p.name for p in (tmp_path / "new").iterdir()] == []               # nor a stray probe


def test_staged_output_marks_replaces_and_cleans_up(tmp_path):
    out = tmp_path / "run"
    with staged_output(out) as stage:
        (stage / "summary.json").write_text("{}")
    assert (out / MARKER).is_file() and is_millimpact_output(out)
    mask = os.umask(0)
    os.umask(mask)
    assert (out.stat().st_mode & 0o777) == 0o777 & ~mask                      # not mkdtemp's 0700
    prepare_output(out)                                                      # an earlier output: accepted
    with pytest.raises(RuntimeError):
        with staged_output(out) as stage:
            (stage / "half.csv").write_text("1,2")
            raise RuntimeError("solver failed")
    assert sorted(p.name for p in out.iterdir()) == [MARKER, "summary.json"]   # the earlier result stays
    assert [p.name for p in tmp_path.iterdir()] == ["run"]                      # no partial folder left


def test_cli_refuses_a_user_folder_before_computing(tmp_path):
    user = tmp_path / "user"
    user.mkdir()
    (user / "data.csv").write_text("1")
    t0 = time.perf_counter()
    r = run_cli("run", "--out", str(user))                                    # the default improved run
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "did not write" in r.stderr
    assert time.perf_counter() - t0 < 30                                      # refused before the ~15 s run
    assert [p.name for p in user.iterdir()] == ["data.csv"]


@pytest.mark.parametrize("sig, code", [(signal.SIGTERM, 143), (signal.SIGINT, 130)])
def test_interrupted_run_leaves_nothing(tmp_path, sig, code):
    """A run stopped mid-way (during meshing, reduction or the time loop) exits 130/143 with one
    line, and leaves no folder that could be taken for a result."""
    out = tmp_path / "run"
    # not -q: the stage lines on stderr say where the run stood if the signal is not answered
    p = subprocess.Popen([sys.executable, "-m", "millimpact.cli", "run", "--out", str(out)], cwd=ROOT,
                         env=mpi_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         preexec_fn=default_sigint)
    time.sleep(6.0)   # past the imports (~2 s), inside meshing, reduction or the time loop (~15 s in all)
    t_sent = time.perf_counter()
    p.send_signal(sig)
    _, err = p.communicate(timeout=120)
    assert p.returncode == code, f"exit {p.returncode} {time.perf_counter() - t_sent:.1f} s after the signal:\n{err}"
    lines = [l for l in err.splitlines() if l.strip()]
    assert lines[-1].startswith("millimpact: interrupted") and f"nothing written to {out}" in lines[-1]
    assert "Traceback" not in err
    assert list(tmp_path.iterdir()) == []


def test_a_swallowed_interrupt_still_publishes_nothing(tmp_path):
    """A library can swallow the exception a signal handler raises (a bare ``except:`` between two
    bytecodes); the handler also records the signal, so the staged result is still discarded and
    the command still ends as interrupted (interrupts.raise_if_interrupted)."""
    from millimpact.errors import Terminated
    from millimpact.interrupts import clear_interrupts, on_interrupt_signal

    clear_interrupts()
    try:
        try:
            on_interrupt_signal(signal.SIGTERM, None)
        except:  # noqa: E722  - the library's bare except
            pass
        out = tmp_path / "run"
        with pytest.raises(Terminated):
            with staged_output(out) as stage:
                (stage / "summary.json").write_text("{}")
        assert list(tmp_path.iterdir()) == []                                     # neither folder nor stage
        clear_interrupts()                                                       # a new command's start
        with staged_output(out) as stage:
            (stage / "summary.json").write_text("{}")
        assert (out / "summary.json").is_file()
    finally:
        clear_interrupts()


#: a command whose library takes SIGTERM for itself for a while, as METIS does in every ordering
#: (GKlib's gk_sigtrap sets its own handler, whose longjmp makes METIS return an error and CHOLMOD
#: order with AMD instead: the signal is gone). Here the library's handler is SIG_IGN, set with
#: libc's signal() as METIS does, during which the process gets SIGTERM; then the library puts the
#: handler back. Prints what the command saw.
LIBRARY_TAKES_SIGTERM = """
import ctypes, os, signal, sys, time
from millimpact.interrupts import children_signals, command_signals
libc = ctypes.CDLL(None)
libc.signal.restype = ctypes.c_void_p
libc.signal.argtypes = [ctypes.c_int, ctypes.c_void_p]
try:
    with command_signals():
        with children_signals():
            import subprocess
            child = subprocess.run(["grep", "SigBlk", "/proc/self/status"], capture_output=True, text=True).stdout
        print("child", int(child.split()[1], 16) & (1 << 14), flush=True)      # SIGTERM's bit
        old = libc.signal(signal.SIGTERM, ctypes.c_void_p(1))                  # SIG_IGN, as a library
        os.kill(os.getpid(), signal.SIGTERM)
        libc.signal(signal.SIGTERM, ctypes.c_void_p(old))                      # the library's exit
        for _ in range(500):                                                   # 5 s of Python
            time.sleep(0.01)
        print("not interrupted", flush=True)
except KeyboardInterrupt as exc:
    print("interrupted", type(exc).__name__, flush=True)
"""


def test_sigterm_reaches_the_command_while_a_library_holds_the_handler():
    """millimpact.interrupts: the command blocks SIGTERM and a thread of its own waits for it, so a
    library's handler never sees it. Without that, this program printed 'not interrupted'. A child
    process starts with the signal unblocked (Ctrl-C still reaches Yade and bench workers)."""
    r = subprocess.run([sys.executable, "-c", LIBRARY_TAKES_SIGTERM], cwd=ROOT, env=mpi_env(), capture_output=True,
                       text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    assert r.stdout.split("\n")[:2] == ["child 0", "interrupted Terminated"], (r.stdout, r.stderr)


def test_a_symlinked_out_writes_through_into_its_target(tmp_path):
    """--out a link to an earlier output: the new output goes into the link's target under the
    target's rules, and the user's link stays as it was (before: the link was renamed to a hidden
    .NAME.old-PID and a real folder published in its place; the target kept the old results)."""
    from millimpact.results.output_folder import claim_output

    target = tmp_path / "target"
    with staged_output(target) as stage:
        (stage / "summary.json").write_text('{"old": 1}')
    link = tmp_path / "link"
    link.symlink_to(target, target_is_directory=True)
    claim = claim_output(link, "run")
    with claim.staged() as stage:
        (stage / "summary.json").write_text('{"new": 1}')
    assert link.is_symlink() and os.readlink(link) == str(target)
    assert (target / "summary.json").read_text() == '{"new": 1}'
    assert sorted(p.name for p in tmp_path.iterdir()) == ["link", "target"]     # nothing hidden left
    # a link to the user's own folder is refused as that folder is
    user = tmp_path / "user"
    user.mkdir()
    (user / "thesis.tex").write_text("mine")
    (tmp_path / "ulink").symlink_to(user)
    with pytest.raises(InputError, match="did not write"):
        claim_output(tmp_path / "ulink", "run")
    assert (tmp_path / "ulink").is_symlink() and (user / "thesis.tex").read_text() == "mine"


def test_an_output_forced_beside_another_kind_leaves_each_its_own(tmp_path):
    """``export ... --out TABLE --force`` beside a table: the table's entries stay the table's, so
    the next ``table`` into that folder is accepted and replaces only its own entries (before: the
    table's files became "not written by millimpact" and the table was refused in its own folder)."""
    from millimpact.results.output_folder import claim_output, read_manifest

    out = tmp_path / "table"
    with staged_output(out, kind="table") as stage:
        (stage / "contact_table.csv").write_text("old table")
    claim = claim_output(out, "export", force=True)
    with claim.staged() as stage:
        (stage / "yade_law.py").write_text("export")
    assert read_manifest(out)["beside"] == {"table": ["contact_table.csv"]}
    claim = claim_output(out, "table")                       # its own folder: no --force needed
    with claim.staged() as stage:
        (stage / "contact_table.csv").write_text("new table")
    assert "kept the export's 1 entry" in claim.replaced_note() and "did not write" not in claim.replaced_note()
    assert (out / "contact_table.csv").read_text() == "new table" and (out / "yade_law.py").read_text() == "export"
    m = read_manifest(out)
    assert m["kind"] == "table" and m["files"] == ["contact_table.csv"] and m["beside"] == {"export": ["yade_law.py"]}
    with pytest.raises(InputError, match="not a run"):       # a third kind is still refused
        claim_output(out, "run")


def test_another_kinds_folder_is_refused_with_its_article(tmp_path):
    """"not an export" (before: "not a export")."""
    from millimpact.results.output_folder import claim_output

    out = tmp_path / "t"
    with staged_output(out, kind="table") as stage:
        (stage / "contact_table.csv").write_text("t")
    with pytest.raises(InputError, match="millimpact table output, not an export; "):
        claim_output(out, "export")
