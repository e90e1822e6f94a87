"""A DEM code (Yade, LIGGGHTS, LAMMPS) run as a subprocess: found on the PATH, its output read.

Each code is a separate program that millimpact never imports. :func:`find_program` finds it (an
environment variable may name it) or refuses in one line with the install command;
:func:`run_program` runs it in a folder, hands the lines that start with :data:`PROGRESS_PREFIX`
to a callback as they arrive and keeps the others for the error message of a failed run. The
output is read by a helper thread and the main thread waits in short steps, so a Ctrl-C stops the
wait at once (:mod:`millimpact.interrupts` delivers it at the main thread's next bytecode), and
the child gets the signal too.
"""

from __future__ import annotations

import os
import queue
import shutil
import subprocess
import threading
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path

from ..errors import InputError, MillimpactError
from ..interrupts import children_signals

#: a line of a DEM script's output that reports progress
PROGRESS_PREFIX = "PROGRESS "


class DemCodeError(MillimpactError):
    """A LIGGGHTS or LAMMPS run that did not end normally."""


def find_program(name: str, env_var: str, install_hint: str, needed_by: str = "this command") -> str:
    """The path of the program ``name`` (``env_var`` overrides the PATH); one line (InputError)
    with ``install_hint`` when it is not there."""
    exe = os.environ.get(env_var) or shutil.which(name)
    if not exe or not (os.path.isfile(exe) and os.access(exe, os.X_OK)):
        raise InputError(f"{name}: not installed (needed by {needed_by}); install it with: {install_hint}")
    return exe


def run_program(
    cmd: Sequence[str],
    workdir: Path,
    env: dict[str, str],
    timeout: float | None = None,
    on_progress: Callable[[str], None] | None = None,
) -> tuple[int, list[str]]:
    """Run ``cmd`` in ``workdir`` with the environment ``env`` (standard error joined to standard
    output, no standard input); its exit status (negative: the signal that killed it) and its
    output's lines. Progress lines go to ``on_progress`` as they arrive; overrunning ``timeout``
    (s) raises ``subprocess.TimeoutExpired``. Any exception (an interruption too) kills the child."""
    lines: list[str] = []
    with children_signals():  # Ctrl-C reaches the child as well (millimpact.interrupts)
        proc = subprocess.Popen(
            list(map(str, cmd)),
            cwd=workdir,
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL,
            text=True,
            env=env,
        )
    with proc:
        try:
            assert proc.stdout is not None
            for line in _lines_of(proc.stdout):
                if line.startswith(PROGRESS_PREFIX) and on_progress is not None:
                    on_progress(line[len(PROGRESS_PREFIX) :].strip())
                lines.append(line)
            rc = proc.wait(timeout=timeout)
        except BaseException:
            proc.kill()
            proc.wait()
            raise
    return rc, lines


def _lines_of(stream) -> Iterator[str]:
    """The lines of a child's output, read by a helper thread: the main thread waits in short
    steps, so a Ctrl-C stops the wait at once, not at the child's next line."""
    lines: queue.Queue = queue.Queue()

    def pump() -> None:
        for line in stream:
            lines.put(line)
        lines.put(None)

    threading.Thread(target=pump, name="millimpact-dem-output", daemon=True).start()
    while True:
        try:
            line = lines.get(timeout=0.2)
        except queue.Empty:
            continue
        if line is None:
            return
        yield line
