"""Output folders: checked before any computing, never deleting what millimpact did not write.

Every output folder millimpact writes (a run, a comparison, ...) holds a marker file
:data:`MARKER`; an earlier millimpact output is recognised by it, or, for folders written before the
marker existed, by a ``summary.json`` / ``compare.json`` that names a ``millimpact_version``.
:func:`prepare_output` is called by the commands before they compute, so a typo in ``--out`` costs
a second, not a simulation: it refuses (with one line naming the path) an existing file, the
current folder or one of its parents, a non-empty folder that is not a millimpact output (unless
``force``), and a place where no folder can be made (a read-only or pseudo file system, a path
under a file).
"""
from __future__ import annotations

import json
import os
import shutil
import tempfile
from pathlib import Path

from ..errors import InputError

#: the file that marks a folder as a millimpact output
MARKER = ".millimpact-output"


def is_millimpact_output(folder: Path) -> bool:
    """True if ``folder`` is an output millimpact wrote (marker, or an older run's summary)."""
    folder = Path(folder)
    if (folder / MARKER).is_file():
        return True
    for name in ("summary.json", "compare.json"):
        try:
            return "millimpact_version" in json.loads((folder / name).read_text())
        except (OSError, ValueError, TypeError):
            continue
    return False


def write_marker(folder: Path, kind: str) -> None:
    """Mark ``folder`` as a millimpact output of ``kind`` (run, compare, ...)."""
    from .. import __version__

    (Path(folder) / MARKER).write_text(json.dumps({"kind": kind, "millimpact_version": __version__}) + "\n")


def apply_umask(path: Path) -> None:
    """Give a folder made by :func:`tempfile.mkdtemp` (mode 0700) the mode the user's umask asks for."""
    mask = os.umask(0)
    os.umask(mask)
    os.chmod(path, 0o777 & ~mask)


def prepare_output(out: Path | str, option: str = "--out", force: bool = False) -> Path:
    """Check that ``out`` can receive an output, before any computing; returns it absolute.

    Refused with an :class:`InputError` (one line naming ``option`` and the path): an existing
    file; the current folder or one of its parents; a non-empty folder that is not a millimpact
    output (``force`` replaces it all the same); a place where no folder can be made. An earlier
    millimpact output is replaced when the new one is complete (the caller says so).
    """
    raw = str(out)
    out = Path(os.path.abspath(os.path.expanduser(raw)))
    cwd = Path.cwd().resolve()
    if out == cwd or out in cwd.parents or out == Path(out.anchor):
        raise InputError(f"{option} {raw}: is the current folder or one of its parents; give a folder "
                         "of its own (e.g. out/NAME)")
    if out.exists() and not out.is_dir():
        raise InputError(f"{option} {raw}: is a file; give a folder (an existing millimpact output "
                         "folder is replaced, any other is refused)")
    if out.is_dir() and any(out.iterdir()) and not is_millimpact_output(out) and not force:
        raise InputError(f"{option} {raw}: holds files millimpact did not write; give a new folder "
                         "or add --force to replace it")
    # a place where a folder can be made: make the parents and a probe folder there now
    parent = out.parent
    for p in [parent, *parent.parents]:
        if p.exists():
            if not p.is_dir():
                raise InputError(f"{option} {raw}: {p} is a file, so no folder can be made under it")
            break
    try:
        parent.mkdir(parents=True, exist_ok=True)
        probe = Path(tempfile.mkdtemp(prefix=f".{out.name}.probe-", dir=parent))
        shutil.rmtree(probe, ignore_errors=True)
    except OSError as exc:
        raise InputError(f"{option} {raw}: no folder can be made there ({exc.strerror or exc})") from None
    return out
