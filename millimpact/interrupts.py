"""Ctrl-C and SIGTERM during a command: always seen, whatever a library does with the signal.

Why a command does not simply install a handler: libraries install their own for the length of a
call. METIS (GKlib's ``gk_sigtrap``, on every ``METIS_NodeND`` that CHOLMOD's and MUMPS's
orderings make) sets SIGTERM (and SIGABRT) to a handler that ``longjmp``s out of METIS, which then
returns an error; CHOLMOD orders with AMD instead and the run goes on. Measured 2026-11-28 (gdb:
``sigaction(15, ...)`` from ``gk_sigtrap`` under ``cholmod_analyze_p2`` in the reduction's
factorizations): a default ``millimpact run`` sent SIGTERM 7 s in, on a cold mesh cache, finished
and published its results with exit 0 in 2 of 22 probes, and the CI's interrupt test failed so in
one run of three. gmsh sets SIGINT to SIG_DFL when it is imported.

So a command (:func:`command_signals`) blocks SIGINT and SIGTERM before any other thread starts;
every thread it starts (MPI's progress thread, OpenMP's workers) inherits the mask, so the kernel
keeps such a signal pending for the process. One thread waits for it (``sigwait``) and interrupts
the main thread with it (``_thread.interrupt_main``): the Python handler
:func:`on_interrupt_signal` runs in the main thread at its next bytecode, as for a delivered
signal, and no library's handler ever sees one. The waiter records the signal first and, while an
import has the handler set to SIG_DFL (gmsh's module does, until millimpact.geometry puts it back),
waits for it: ``interrupt_main`` does nothing for a signal Python does not handle, and a Ctrl-C
during that import would be lost. Child processes are started with the signals
unblocked (:func:`children_signals`), so Ctrl-C still reaches them.

The handler also records the signal, and :func:`raise_if_interrupted` raises it again where a
result is published and before each time step: an exception a library swallows (a bare
``except:`` between two bytecodes) cannot turn an interrupted run into a published one.

One signal, one exception: the waiter interrupts the main thread only for a signal the main thread
has not answered yet (by the handler or by :func:`raise_if_interrupted`, which may see the record
before the waiter's hooks are done), and a delivery that lands while the command ends is dropped.
Before, ``mpirun -n 2`` and Ctrl-C printed a traceback of a second ``Terminated`` raised while the
command's end joined the waiter (1 of 3 clean-clone suite runs).
"""

from __future__ import annotations

import _thread
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager

from .errors import Terminated

#: the signals (SIGINT 2, SIGTERM 15) whose handler ran during the command and whose exception the
#: command's own handler has not seen yet
_PENDING_SIGNALS: list[int] = []
#: the signals the current command waits for (empty outside a command)
_WAITED: set[int] = set()
#: how long (s) a received signal waits for the command's handler to be back (a library import
#: that set it to SIG_DFL for its length) before the main thread is interrupted anyway
HANDLER_WAIT_S = 5.0
#: called in the waiting thread with the signal as soon as it arrives, before the main thread is
#: interrupted: what cannot wait for the main thread (under mpirun, which follows its SIGTERM with
#: SIGKILL 1 s later while a rank may sit in a collective solve: the CLI says its line and drops its
#: lock there). A hook's exception is ignored.
ON_SIGNAL: list[Callable[[int], None]] = []


class _Deliveries:
    """What the waiting thread received and what the main thread has answered, under one lock
    (reentrant: the handler can run in the main thread while it holds it)."""

    def __init__(self) -> None:
        self.lock = threading.RLock()
        self.received = 0  # signals the waiting thread took
        self.answered = 0  # of those, the ones whose exception the main thread has raised
        self.closing = False  # the command is ending: a late delivery is dropped


_DELIVERIES = _Deliveries()


def _let_pending_handler_run() -> None:
    """Nothing: a Python call, at whose start the main thread runs a handler that
    ``interrupt_main`` has left pending (CPython checks for one on entering a function)."""


def on_interrupt_signal(signum: int, frame) -> None:
    """The command's SIGINT and SIGTERM handler: records the signal, then raises
    ``KeyboardInterrupt`` (SIGINT) or :class:`~millimpact.errors.Terminated` (SIGTERM) where the
    main thread stands; while the command ends, does nothing."""
    with _DELIVERIES.lock:
        if _DELIVERIES.closing:
            return
        _PENDING_SIGNALS.append(signum)
        _DELIVERIES.answered = _DELIVERIES.received
    raise Terminated() if signum == signal.SIGTERM else KeyboardInterrupt()


def raise_if_interrupted() -> None:
    """Raise the recorded signal's exception again if its first one was lost (no-op otherwise):
    called before a result is published and between time steps. A delivery already on its way
    raises here, from the handler; the ones recorded are answered, so none follows."""
    with _DELIVERIES.lock:  # the waiter cannot deliver meanwhile
        _let_pending_handler_run()
        if not _PENDING_SIGNALS:
            return
        _DELIVERIES.answered = _DELIVERIES.received
        signum = _PENDING_SIGNALS[-1]
    raise Terminated() if signum == signal.SIGTERM else KeyboardInterrupt()


def pending_signal() -> int | None:
    """The last signal recorded during the command (None if none): an exception that arrives with
    one recorded is the interruption's, whatever a library turned it into."""
    return _PENDING_SIGNALS[-1] if _PENDING_SIGNALS else None


def clear_interrupts() -> None:
    """Forget recorded signals (a command's start and end)."""
    with _DELIVERIES.lock:
        _PENDING_SIGNALS.clear()
        _DELIVERIES.received = _DELIVERIES.answered = 0


def _unraisable(hook):
    """``sys.unraisablehook`` of a command: an interruption raised inside a ``__del__`` or a
    finalizer (pyparsing's ``Forward.__del__`` while modules are imported at start-up) cannot
    propagate, and Python would print "Exception ignored in ..." with a traceback and go on. The
    signal is recorded; interrupt the main thread again, where the exception can propagate."""

    def unraisable(info) -> None:
        if info.exc_type is not None and issubclass(info.exc_type, KeyboardInterrupt):
            if _PENDING_SIGNALS:  # a moment later, from another thread: not inside this hook
                timer = threading.Timer(0.05, _thread.interrupt_main, args=(_PENDING_SIGNALS[-1],))
                timer.daemon = True
                timer.start()
            return
        hook(info)

    return unraisable


def _wait_and_interrupt(waited: set[int], stop: threading.Event) -> None:
    while True:
        signum = signal.sigwait(waited)
        if stop.is_set():
            return
        # recorded here first: raise_if_interrupted sees it even if the handler never runs
        with _DELIVERIES.lock:
            _PENDING_SIGNALS.append(signum)
            _DELIVERIES.received += 1
            index = _DELIVERIES.received
        for hook in list(ON_SIGNAL):
            try:
                hook(signum)
            except Exception:  # noqa: BLE001 - the interruption itself must go on
                pass
        # interrupt_main does nothing while the signal's handler is SIG_DFL: gmsh's module sets
        # SIGINT so during its import, until millimpact.geometry puts the handler back; wait
        # for the handler (HANDLER_WAIT_S at most), then interrupt
        deadline = time.monotonic() + HANDLER_WAIT_S
        while signal.getsignal(signum) is not on_interrupt_signal and time.monotonic() < deadline:
            time.sleep(0.01)
        with _DELIVERIES.lock:  # not if the main thread has answered it or the command is ending
            if not (stop.is_set() or _DELIVERIES.closing or _DELIVERIES.answered >= index):
                _thread.interrupt_main(signal.Signals(signum))  # runs on_interrupt_signal in the main thread


@contextmanager
def command_signals() -> Iterator[None]:
    """The command's signal handling (module docstring): SIGTERM, and SIGINT unless it is ignored
    (a background job), blocked in every thread and turned into the handler's exception in the
    main thread. On exit the caller's handlers and mask are back. Outside the main thread: no-op."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    clear_interrupts()
    waited = {signal.SIGTERM}
    if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        waited.add(signal.SIGINT)
    handlers = {s: signal.getsignal(s) for s in waited}
    for s in waited:
        signal.signal(s, on_interrupt_signal)
    mask = signal.pthread_sigmask(signal.SIG_BLOCK, waited)
    stop = threading.Event()
    waiter = threading.Thread(target=_wait_and_interrupt, args=(waited, stop), name="millimpact-signals", daemon=True)
    waiter.start()
    _WAITED.update(waited)
    unraisable_hook = sys.unraisablehook
    sys.unraisablehook = _unraisable(unraisable_hook)
    try:
        yield
    finally:
        with _DELIVERIES.lock:  # from here a delivery is dropped (the handler returns)
            _DELIVERIES.closing = True
            stop.set()
        sys.unraisablehook = unraisable_hook
        _WAITED.clear()
        if waiter.ident is not None:  # started above: it has one
            signal.pthread_kill(waiter.ident, signal.SIGTERM)  # wakes its sigwait; it ends on `stop`
        waiter.join(timeout=5.0)
        _let_pending_handler_run()  # a delivery made before `closing` ends here, not after the handlers
        clear_interrupts()  # the record lives as long as the command
        for s, handler in handlers.items():  # then a signal still pending is the caller's
            if handler is not None:
                signal.signal(s, handler)
        signal.pthread_sigmask(signal.SIG_SETMASK, mask)
        _DELIVERIES.closing = False


@contextmanager
def children_signals() -> Iterator[None]:
    """Start child processes inside this block: the main thread has SIGINT and SIGTERM unblocked
    while it is open, and a child inherits its mask, so Ctrl-C and SIGTERM reach the child as
    usual. (The block only runs Python and waits on the child: no library call that takes the
    signals for itself runs meanwhile; a signal to this process lands on its Python handler.)"""
    if not _WAITED or threading.current_thread() is not threading.main_thread():
        yield
        return
    blocked = set(_WAITED)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, blocked)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_BLOCK, blocked)
