"""What a command prints: rank 0 talks, the other ranks stay quiet.

The rank is read without initialising MPI when the process was not started by ``mpirun``, so
commands that never touch MPI (``--help``, ``scene list``) stay fast.
"""
from __future__ import annotations

import os


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
