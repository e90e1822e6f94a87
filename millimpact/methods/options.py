"""Method options (``--option KEY=VALUE``, PETSc-style ``-KEY VALUE``): typed reading with one-line
errors that name the option."""
from __future__ import annotations

from typing import Optional

from ..errors import InputError
from ..integration.solvers import note_option_read


def take(options: dict, key: str):
    """Pop the method setting ``key`` (None if absent) and record it as read (so it is not
    reported as an option nothing used)."""
    note_option_read(key)
    return options.pop(key, None)


def _typed_option(options: dict, key: str, default, kind: type, what: str):
    """Pop a method option converted by ``kind`` (``default`` if absent or empty); a bad value is
    an :class:`InputError` naming the option."""
    value = take(options, key)
    if value is None or value == "":
        return default
    try:
        return kind(value)
    except (TypeError, ValueError):
        raise InputError(f"option {key} = {value!r}: must be {what}") from None


def int_option(options: dict, key: str, default: Optional[int]) -> Optional[int]:
    """Pop ``key`` as an integer."""
    return _typed_option(options, key, default, int, "an integer")


def float_option(options: dict, key: str, default: Optional[float]) -> Optional[float]:
    """Pop ``key`` as a number."""
    return _typed_option(options, key, default, float, "a number")
