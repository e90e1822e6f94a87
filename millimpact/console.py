"""What a command prints: rank 0 talks, the other ranks stay quiet.

The rank is read without initialising MPI when the process was not started by ``mpirun``, so
commands that never touch MPI (``--help``, ``scene list``) stay fast.
"""

from __future__ import annotations

import os
from typing import Any


def world_rank() -> int:
    """This process's rank in MPI_COMM_WORLD (0 outside ``mpirun``)."""
    if "OMPI_COMM_WORLD_RANK" in os.environ or "PMI_RANK" in os.environ:
        from mpi4py import MPI

        return MPI.COMM_WORLD.rank
    return 0


def say(*args, **kw) -> None:
    """``print`` on rank 0 only."""
    if world_rank() == 0:
        print(*args, **kw)


def sayer(quiet: bool = False, comm=None):
    """A command's progress printer: ``print`` (flushed, so lines keep their order beside a
    subprocess's) on rank 0 of ``comm`` (default MPI_COMM_WORLD), nothing on the other ranks or
    when ``quiet``."""
    rank = world_rank() if comm is None else comm.rank
    if quiet or rank != 0:
        return _silent
    return _say_flushed


def _silent(*args, **kw) -> None:
    return None


def _say_flushed(*args, **kw) -> None:
    print(*args, **kw, flush=True)


#: whether commands report their stages (set by the CLI: on unless -q)
STAGES: dict[str, Any] = {"enabled": False, "t0": None}


def enable_stages(on: bool) -> None:
    """Turn the one-line-per-stage reports on (the CLI, unless -q) or off (the library's default)."""
    import time

    STAGES["enabled"] = bool(on)
    STAGES["t0"] = time.perf_counter()


class stage:
    """``with stage("meshing"):`` prints ``[  1.2 s] meshing ...`` on rank 0 (stderr) and, at the
    end, the stage's time; silent unless :func:`enable_stages` turned the reports on."""

    def __init__(self, what: str):
        self.what = what

    def __enter__(self):
        import sys
        import time

        self.t = time.perf_counter()
        if STAGES["enabled"] and world_rank() == 0:
            print(f"[{self.t - STAGES['t0']:7.1f} s] {self.what} ...", file=sys.stderr, flush=True)
        return self

    def __exit__(self, exc_type, exc, tb):
        import sys
        import time

        if STAGES["enabled"] and exc_type is None and world_rank() == 0:
            now = time.perf_counter()
            print(
                f"[{now - STAGES['t0']:7.1f} s] {self.what}: done in {now - self.t:.2f} s", file=sys.stderr, flush=True
            )
        return False
