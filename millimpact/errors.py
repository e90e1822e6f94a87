"""The package's own exceptions. The CLI turns :class:`InputError` into one line and exit status 2."""

from __future__ import annotations

from typing import Any


class MillimpactError(Exception):
    """Base class of millimpact's errors."""

    #: under MPI: True when rank 0 says the line and the other ranks stay quiet (the CLI)
    said_by_rank0: bool = False


class InputError(MillimpactError):
    """Bad user input: reported as one line, exit status 2, no traceback."""


class SceneError(InputError, ValueError):
    """A scene field with a value outside its allowed range."""

    def __init__(self, field: str, value: Any, allowed: str):
        self.field, self.value, self.allowed = field, value, allowed
        super().__init__(f"{field} = {value!r}: {allowed}")


class MeshError(InputError):
    """Geometry or meshing failed for the scene (named parameter, reason)."""


class SolverError(MillimpactError):
    """A PETSc/SLEPc solve did not converge: names the reason, the step and the time."""


class OutputError(MillimpactError):
    """A result could not be written (full disk, quota, I/O error): one line, exit status 1."""


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised where the program stands so staged outputs are discarded as for Ctrl-C."""
