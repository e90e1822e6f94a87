"""Running Yade (Debian's ``yade``, 2023.02a) as a subprocess: ``yade -n -x SCRIPT``.

Yade is a separate program with its own Python; millimpact never imports it. A script is written
to a folder together with its inputs (JSON), run there with ``-n`` (no GUI) and ``-x`` (exit when
the script ends), and leaves its results as files in that folder. Lines the script prints that
start with :data:`PROGRESS_PREFIX` are handed to a callback as they arrive (progress of long DEM
runs); everything else is kept for the error message if the run fails.
"""

from __future__ import annotations

import os
import queue
import shutil
import signal
import subprocess
import threading
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path

from ..errors import InputError, MillimpactError
from ..interrupts import children_signals

#: how a user gets Yade on this project's machines (Debian 12)
INSTALL_HINT = "apt-get install yade (Debian 12: Yade 2023.02a)"
#: a line of a Yade script's output that reports progress
PROGRESS_PREFIX = "PROGRESS "


class YadeError(MillimpactError):
    """A Yade run that did not end normally."""


def yade_executable() -> str:
    """The path of the ``yade`` program (``MILLIMPACT_YADE`` overrides); InputError if absent."""
    exe = os.environ.get("MILLIMPACT_YADE") or shutil.which("yade")
    if not exe or not (os.path.isfile(exe) and os.access(exe, os.X_OK)):
        raise InputError(f"yade: not installed (needed by this command); install it with: {INSTALL_HINT}")
    return exe


def run_yade(
    script: Path,
    workdir: Path,
    args: Sequence[str] = (),
    timeout: float | None = None,
    on_progress: Callable[[str], None] | None = None,
) -> str:
    """Run ``yade -n -x script [args]`` in ``workdir``; returns its standard output.

    Raises :class:`YadeError` with the last lines of its output when Yade exits non-zero or
    overruns ``timeout`` (s). One thread per run (``-j 1``) unless ``MILLIMPACT_YADE_THREADS``
    says otherwise, so runs side by side do not oversubscribe the cores.
    """
    exe = yade_executable()
    threads = os.environ.get("MILLIMPACT_YADE_THREADS", "1")
    cmd = [exe, "-n", "-j", threads, "-x", str(script), *map(str, args)]
    env = {**os.environ, "OMP_NUM_THREADS": threads}
    lines: list[str] = []
    with children_signals():  # Ctrl-C reaches Yade as well (millimpact.interrupts)
        proc = subprocess.Popen(
            cmd,
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
    out = "".join(lines)
    if rc < 0:  # killed (SIGKILL: the kernel's out-of-memory killer, or a user): one line, not its log
        try:
            name = signal.Signals(-rc).name
        except ValueError:
            name = f"signal {-rc}"
        last = next((ln.strip() for ln in reversed(lines) if ln.strip()), "")
        raise YadeError(
            f"yade was killed by {name} running {Path(script).name}"
            + (f" (its last line: {last[:160]})" if last else "")
        )
    if rc != 0:
        tail = "".join(lines[-15:])
        raise YadeError(f"yade exited with status {rc} running {Path(script).name}:\n{tail}")
    return out


def _lines_of(stream) -> Iterator[str]:
    """The lines of a child's output, read by a helper thread: the main thread waits in short
    steps, so a Ctrl-C (delivered to it by :mod:`millimpact.interrupts` at its next bytecode)
    stops the wait at once, not at the child's next line."""
    lines: queue.Queue = queue.Queue()

    def pump() -> None:
        for line in stream:
            lines.put(line)
        lines.put(None)

    threading.Thread(target=pump, name="millimpact-yade-output", daemon=True).start()
    while True:
        try:
            line = lines.get(timeout=0.2)
        except queue.Empty:
            continue
        if line is None:
            return
        yield line
