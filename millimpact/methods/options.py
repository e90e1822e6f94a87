"""Method options (``--option KEY=VALUE``, PETSc-style ``-KEY VALUE``): typed reading with one-line
errors that name the option."""

from __future__ import annotations

from typing import overload

from ..errors import InputError
from ..integration.solvers import note_option_read, option_key


def peek(options: dict, key: str):
    """The method setting ``key`` however it was spelled (``free_phase``, ``-free_phase``,
    ``impact_free_phase``: :func:`~millimpact.integration.solvers.option_key`; the last one given
    wins), or None."""
    value = None
    for k, v in options.items():
        if option_key(k) == key:
            value = v
    return value


def take(options: dict, key: str):
    """Pop the method setting ``key`` (None if absent), every spelling of it (:func:`peek`), and
    record it as read (so it is not reported as an option nothing used). Popping the raw key alone
    let ``-impact_free_phase step`` pass as read while the run took the default."""
    note_option_read(key)
    value = None
    for k in [k for k in options if option_key(k) == key]:
        value = options.pop(k)
    return value


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


@overload
def int_option(options: dict, key: str, default: int) -> int: ...
@overload
def int_option(options: dict, key: str, default: int | None) -> int | None: ...
def int_option(options: dict, key: str, default: int | None) -> int | None:
    """Pop ``key`` as an integer."""
    return _typed_option(options, key, default, int, "an integer")


@overload
def float_option(options: dict, key: str, default: float) -> float: ...
@overload
def float_option(options: dict, key: str, default: float | None) -> float | None: ...
def float_option(options: dict, key: str, default: float | None) -> float | None:
    """Pop ``key`` as a number."""
    return _typed_option(options, key, default, float, "a number")
