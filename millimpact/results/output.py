"""What a method hands back: the time series, scalar results, model sizes, notes and writers."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .timeseries import TimeSeries


@dataclass
class RunOutput:
    """What a method computed: the time series, scalar results, model sizes, and optional writers
    of extra files (e.g. XDMF fields) called with the output folder on every rank (collective)."""

    method: str
    series: TimeSeries
    results: dict[str, Any]
    model: dict[str, Any]
    extra_writers: list[Callable[[Path], None]] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
