"""Running Yade (Debian's ``yade``, 2023.02a) as a subprocess: ``yade -n -x SCRIPT``.

Yade is a separate program with its own Python; millimpact never imports it. A script is written
to a folder together with its inputs (JSON), run there with ``-n`` (no GUI) and ``-x`` (exit when
the script ends), and leaves its results as files in that folder. Lines the script prints that
start with :data:`PROGRESS_PREFIX` are handed to a callback as they arrive (progress of long DEM
runs); everything else is kept for the error message if the run fails.
"""

from __future__ import annotations

import os
import signal
from collections.abc import Callable, Sequence
from pathlib import Path

from ..errors import MillimpactError
from .programs import PROGRESS_PREFIX, find_program, run_program

#: how a user gets Yade on this project's machines (Debian 12)
INSTALL_HINT = "apt-get install yade (Debian 12: Yade 2023.02a)"
__all__ = ["INSTALL_HINT", "PROGRESS_PREFIX", "YadeError", "run_yade", "yade_executable"]


class YadeError(MillimpactError):
    """A Yade run that did not end normally."""


def yade_executable() -> str:
    """The path of the ``yade`` program (``MILLIMPACT_YADE`` overrides); InputError if absent."""
    return find_program("yade", "MILLIMPACT_YADE", INSTALL_HINT)


def run_yade(
    script: Path,
    workdir: Path,
    args: Sequence[str] = (),
    timeout: float | None = None,
    on_progress: Callable[[str], None] | None = None,
    threads: int | None = None,
) -> str:
    """Run ``yade -n -x script [args]`` in ``workdir``; returns its standard output.

    Raises :class:`YadeError` with the last lines of its output when Yade exits non-zero or
    overruns ``timeout`` (s). ``threads`` OpenMP threads (``-j``), else ``MILLIMPACT_YADE_THREADS``,
    else one, so runs side by side do not oversubscribe the cores.
    """
    exe = yade_executable()
    n = str(threads) if threads is not None else os.environ.get("MILLIMPACT_YADE_THREADS", "1")
    cmd = [exe, "-n", "-j", n, "-x", str(script), *map(str, args)]
    env = {**os.environ, "OMP_NUM_THREADS": n}
    rc, lines = run_program(cmd, workdir, env, timeout, on_progress)
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
