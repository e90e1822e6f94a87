"""The package's own exceptions. The CLI turns :class:`InputError` into one line and exit status 2."""
from __future__ import annotations

from typing import Any


class MillimpactError(Exception):
    """Base class of millimpact's errors."""


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


#: the signals (SIGINT 2, SIGTERM 15) whose handler ran during the command and whose exception has
#: not been seen by the command's own handler: a library can swallow the exception a handler raises
#: (a bare ``except:`` anywhere between two bytecodes), after which the run would go on and publish
#: as if never stopped. Checked where a result is published (:func:`raise_if_interrupted`).
_PENDING_SIGNALS: list[int] = []


def on_interrupt_signal(signum: int, frame) -> None:
    """The CLI's SIGINT and SIGTERM handler: records the signal, then raises ``KeyboardInterrupt``
    (SIGINT) or :class:`Terminated` (SIGTERM) where the program stands."""
    _PENDING_SIGNALS.append(signum)
    raise Terminated() if signum == 15 else KeyboardInterrupt()


def raise_if_interrupted() -> None:
    """Raise the recorded signal's exception again if its first one was lost (no-op otherwise):
    called before a result is published and between time steps."""
    if _PENDING_SIGNALS:
        raise Terminated() if _PENDING_SIGNALS[-1] == 15 else KeyboardInterrupt()


def clear_interrupts() -> None:
    """Forget recorded signals (a command's start; its own handler has seen them)."""
    _PENDING_SIGNALS.clear()
