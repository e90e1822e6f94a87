"""Helpers for the output policy's tests of each command (docs/outputs.md): another process
writing the same folder, and the one line that refuses the second writer."""
from __future__ import annotations

import subprocess
import sys
from contextlib import contextmanager
from pathlib import Path
from typing import Iterator

from conftest import ROOT, mpi_env

#: a process that claims a folder as a command does (the lock) and holds it until its stdin closes
HOLDER = ("import sys\n"
          "from millimpact.results.output_folder import claim_output\n"
          "claim_output(sys.argv[1], sys.argv[2])\n"
          "print('held', flush=True)\n"
          "sys.stdin.read()\n")


@contextmanager
def another_writer(out: Path, kind: str) -> Iterator[int]:
    """A second millimpact process that has claimed ``out`` for ``kind`` (it holds the lock while
    the block runs); yields its process id."""
    p = subprocess.Popen([sys.executable, "-c", HOLDER, str(out), kind], stdin=subprocess.PIPE,
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT, env=mpi_env())
    try:
        line = p.stdout.readline()
        assert line.strip() == "held", p.stderr.read()
        yield p.pid
    finally:
        p.stdin.close()
        p.wait(timeout=60)


def assert_refused_by_the_lock(code: int, stderr: str, out: Path, pid: int) -> None:
    """Exit status 2 and one line naming --out, the other writer and its process id."""
    lines = [line for line in stderr.strip().splitlines() if line.strip()]
    assert code == 2 and len(lines) == 1 and "Traceback" not in stderr, (code, stderr[-3000:])
    assert f"--out {out}" in lines[0] and "another millimpact" in lines[0] and f"process {pid}" in lines[0], lines


def assert_notes_kept(out: Path, said: str) -> None:
    """The user's notes.txt in a rerun's folder: untouched, and the results line says it was kept."""
    assert (out / "notes.txt").read_text() == "my notes\n"
    assert "kept 1 entry millimpact did not write: notes.txt" in said, said[-3000:]


def main_in_process(capsys, argv: list[str]) -> tuple[int, str, str]:
    """``millimpact ARGV`` in this process (its SIGTERM handler put back after): (exit code,
    stdout, stderr)."""
    import signal

    from millimpact.cli import main

    sigterm = signal.getsignal(signal.SIGTERM)
    try:
        code = main(argv)
    finally:
        signal.signal(signal.SIGTERM, sigterm)
    got = capsys.readouterr()
    return code, got.out, got.err
