"""The finished pieces a command keeps as it goes (a table's cases, a damage map's bins and
sequences, a repeated-impact sequence's impacts, a study's cases), so that an interrupted command
run again computes only what is missing.

- The key (:func:`piece_key`): the first 16 hex digits of the SHA-1 of the JSON of what decides
  the piece (its resolved scene as TOML, method, options, version ...; keys sorted). A change of
  any of them is another key: the piece is computed again, never taken stale.
- The save (:func:`write_atomic`, :meth:`PieceStore.save`): written to a hidden temporary name in
  the same folder and renamed (``os.replace``, atomic on POSIX), so a piece on disk is complete.
- The load (:meth:`PieceStore.load`): the stored piece, or None when it is missing or unreadable.
- The note (:func:`kept_note`): the one line an interrupted command prints about what it kept.
"""

from __future__ import annotations

import hashlib
import json
import os
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any


def piece_key(what: Mapping[str, Any]) -> str:
    """The key of a piece decided by ``what`` (JSON-able, other values by ``str``): 16 hex digits."""
    text = json.dumps(dict(what), sort_keys=True, default=str)
    return hashlib.sha1(text.encode()).hexdigest()[:16]


def write_atomic(path: Path, write: Callable[[Path], Any] | str) -> None:
    """Write ``path`` whole or not at all: ``write`` (text, or a function writing a given path)
    goes to ``.NAME.PID.tmp`` beside it, then is renamed over ``path``."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        if isinstance(write, str):
            tmp.write_text(write)
        else:
            write(tmp)
        os.replace(tmp, path)
    finally:
        tmp.unlink(missing_ok=True)


class PieceStore:
    """Finished pieces as ``folder/<key>.json``, one JSON object each."""

    def __init__(self, folder: Path):
        self.folder = Path(folder)

    def path(self, key: str) -> Path:
        return self.folder / f"{key}.json"

    def load(self, key: str) -> dict | None:
        """The piece stored under ``key``, or None (missing, unreadable or not a JSON object)."""
        try:
            data = json.loads(self.path(key).read_text())
        except (OSError, ValueError):
            return None
        return data if isinstance(data, dict) else None

    def save(self, key: str, piece: Mapping[str, Any]) -> None:
        """Keep ``piece`` under ``key`` (atomically; numbers NumPy gives as floats)."""
        self.folder.mkdir(parents=True, exist_ok=True)
        write_atomic(self.path(key), json.dumps(dict(piece), indent=1, default=float))

    def count(self) -> int:
        """How many pieces the folder holds."""
        return len(list(self.folder.glob("*.json"))) if self.folder.is_dir() else 0


def kept_note(kept: Sequence[tuple[int, str, str]], unwritten: str) -> str:
    """The line an interrupted command prints: ``kept`` lists (count, what, where) of its finished
    pieces, ``unwritten`` what it did not write yet (its report)."""
    parts = [f"{n} finished {what}(s) {'kept ' if i == 0 else ''}in {where}" for i, (n, what, where) in enumerate(kept)]
    return f"{' and '.join(parts)} ({unwritten}); the same command, run again, continues from them"
