"""``--set FIELD=VALUE`` (a scene field) and ``--option KEY=VALUE`` (a method option), read the same
way by every command.

Values are read as TOML (:func:`millimpact.scene.schema.parse_value`: ``0.02``, ``true``,
``"name"``, ``[0, -3, 0]``). All ``--set`` assignments of a command are applied together and the
scene validated once (:meth:`~millimpact.scene.schema.Scene.with_values`), so two fields checked
against each other (``impact.gap`` at most ``ball.radius``) can be changed in either order. A
malformed argument, a field the command sets itself, or a value out of range is one line naming it.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from ..errors import InputError
from ..scene.schema import Scene, parse_value

#: the name before ``=`` and an example, per argument
_FORMS = {"--set": ("FIELD", "ball.radius=0.02"), "--option": ("KEY", "modes=20")}


def parse_assignments(items: Sequence[str] | None, flag: str) -> list[tuple[str, Any]]:
    """Each ``NAME=VALUE`` of ``items`` (the values of ``flag``: ``--set`` or ``--option``) as
    ``(NAME, value read as TOML)``, in order; one line for a malformed one."""
    name, example = _FORMS[flag]
    out = []
    for item in items or ():
        key, eq, value = item.partition("=")
        if not eq or not key.strip() or not value.strip():
            raise InputError(f"{flag} {item}: expected {name}=VALUE, e.g. {flag} {example}")
        out.append((key.strip(), parse_value(value)))
    return out


def apply_sets(scene: Scene, sets: Sequence[str] | None, reserved: Mapping[str, str] | None = None) -> Scene:
    """``scene`` with every ``--set`` of ``sets`` applied together and validated once (their order
    does not matter). ``reserved``: fields the command sets itself -> what sets them; a ``--set`` of
    one (or of a part of it, or of a table holding it) is refused."""
    assignments = parse_assignments(sets, "--set")
    for key, _ in assignments:
        for field, what in (reserved or {}).items():
            if key == field or key.startswith(field + ".") or field.startswith(key + "."):
                raise InputError(f"--set {key}: conflicts with {what}")
    return scene.with_values(assignments) if assignments else scene


def command_scene(name: str | None, sets: Sequence[str] | None, reserved: Mapping[str, str] | None = None) -> Scene:
    """The scene a command runs: the built-in scene or TOML file ``name`` (None: the default
    scene), with its ``--set`` assignments (:func:`apply_sets`)."""
    from ..scene.builtin import resolve_scene

    return apply_sets(resolve_scene(name), sets, reserved)


def parse_options(items: Sequence[str] | None) -> dict[str, Any]:
    """``--option KEY=VALUE`` arguments as a dict of method options (a later KEY wins); a
    malformed one, or a PETSc type or reduction setting out of range, is one line before any case
    runs. PETSc is imported only when there is an option to check."""
    options = dict(parse_assignments(items, "--option"))
    if options:
        from ..integration.solvers import check_type_options

        check_type_options(options)
    return options
