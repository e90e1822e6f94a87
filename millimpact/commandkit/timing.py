"""Where a command's wall time goes: seconds per stage, for its summary and its last line.

A :class:`StageClock` starts with the command; ``with clock.stage("bins"):`` adds the block's wall
time (``time.perf_counter``) to the stage ``bins`` and keeps each pass as a lap (a stage entered
once per cycle has one lap per cycle). :meth:`StageClock.record` gives, in seconds,

    {stage: t_stage, ..., "other": T - sum of t_stage, "total": T},

T the time since the clock started, so the stages and ``other`` add up to ``total`` exactly; a
stage still open counts up to now (a summary written inside its ``report`` stage counts the report
so far). Stages must not nest (a nested block's time would count twice and ``other`` fall below
zero). Under MPI each rank keeps its own clock; rank 0's is written and printed.
"""

from __future__ import annotations

import time
from collections.abc import Iterator
from contextlib import contextmanager


class StageClock:
    """Wall seconds per named stage since the clock started (module docstring)."""

    def __init__(self) -> None:
        self.start = time.perf_counter()
        self.laps: dict[str, list[float]] = {}
        self._open: dict[str, float] = {}

    @contextmanager
    def stage(self, name: str) -> Iterator[None]:
        """Time the block as one lap of the stage ``name``."""
        t0 = time.perf_counter()
        self._open[name] = t0
        try:
            yield
        finally:
            del self._open[name]
            self.laps.setdefault(name, []).append(time.perf_counter() - t0)

    def record(self) -> dict[str, float]:
        """Seconds per stage (an open stage up to now), ``other`` and ``total``: they add up."""
        now = time.perf_counter()
        out = {name: sum(laps) for name, laps in self.laps.items()}
        for name, t0 in self._open.items():
            out[name] = out.get(name, 0.0) + now - t0
        total = now - self.start
        return {**out, "other": total - sum(out.values()), "total": total}


def time_line(record: dict[str, float], names: dict[str, str]) -> str:
    """``wall time T s: <name> t s (p %), ...`` of a :meth:`StageClock.record`, the stages in the
    order and words of ``names`` (stage -> words), ``other`` last."""
    total = record["total"]
    parts = [
        f"{words} {record[key]:.3g} s ({100 * record[key] / total:.0f} %)"
        for key, words in {**names, "other": "other"}.items()
        if key in record and total > 0
    ]
    return f"wall time {total:.3g} s: " + ", ".join(parts)
