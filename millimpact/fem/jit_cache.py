"""The JIT cache after an interrupted compile.

FFCx (0.5) compiles a form or an element into ``CACHE/libffcx_*.c`` in three moves: it claims the
module by creating the ``.c`` file (``open(..., "x")``), compiles it, then writes
``.c.cached``, which tells every other process the module is ready. A process that finds the
``.c`` without ``.c.cached`` waits for it (10 s by default) and then fails with
``TimeoutError: JIT compilation timed out, probably due to a failed previous compile``. FFCx
renames the ``.c`` to ``.c.failed`` when the compile raises an ``Exception``
(ffcx/codegeneration/jit.py) but not on ``KeyboardInterrupt``: until 2026-11-28 Ctrl-C or SIGTERM
during a first run's "compiling forms" left the claim behind, and the next run failed 10 s in
with that traceback (measured: SIGTERM 4 s into a run on an empty cache, then ``millimpact run``:
exit 1 after 12.8 s).

:func:`release_interrupted_compile` does for an interrupt what FFCx does for a failure, for the
module this process was compiling only (read from the interrupted frames); a module another
process is compiling, which this one was waiting for, is left alone. A claim left by a killed run
is named by :func:`stale_jit_claim`, for the CLI's one line.
"""

from __future__ import annotations

import os
import re
from pathlib import Path
from types import TracebackType

#: FFCx's functions that claim a module (create its .c) before compiling it
_COMPILERS = ("compile_elements", "compile_forms", "compile_expressions")


def release_interrupted_compile(exc: BaseException) -> Path | None:
    """After the interrupt ``exc``: the module this process was compiling, released as FFCx
    releases a failed one (:func:`_release_claim`), looking through the exceptions ``exc``
    replaced (a study re-raises the interrupt as its own); returns the renamed claim, or None."""
    current: BaseException | None = exc
    seen = 0
    while current is not None and seen < 8:
        claim = _release_claim(current.__traceback__)
        if claim is not None:
            return claim
        current, seen = current.__cause__ or current.__context__, seen + 1
    return None


def stale_jit_claim(exc: BaseException) -> str | None:
    """The ``.c`` file FFCx names when it gives up waiting for a module (its ``TimeoutError``), or
    None for any other error."""
    found = re.search(r"remove (\S+\.c)\)", str(exc))
    return found.group(1) if found and "JIT compilation timed out" in str(exc) else None


def _release_claim(tb: TracebackType | None) -> Path | None:
    """If the traceback ``tb`` of an interrupt passes through an FFCx compile this process
    claimed (not its wait for another process), rename the claim ``MODULE.c`` to
    ``MODULE.c.failed`` as FFCx does for a failed compile; returns the renamed file, or None."""
    claim = None
    while tb is not None:
        code = tb.tb_frame.f_code
        if code.co_filename.endswith(os.path.join("ffcx", "codegeneration", "jit.py")):
            if code.co_name == "get_cached_module":
                return None  # waiting for (or claiming) a module: not compiled here yet
            if code.co_name in _COMPILERS:
                local = tb.tb_frame.f_locals
                if local.get("cache_dir") is not None and local.get("module_name"):
                    claim = Path(local["cache_dir"]) / (str(local["module_name"]) + ".c")
        tb = tb.tb_next
    if claim is None or not claim.is_file() or claim.with_suffix(".c.cached").exists():
        return None
    try:
        os.replace(claim, claim.with_suffix(".c.failed"))
    except OSError:
        return None
    return claim
