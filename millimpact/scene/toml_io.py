"""Scenes in and out of TOML: plain data to a validated :class:`~.schema.Scene` and back (None values omitted:
they mean 'the plan decides'), files read and written.
"""

from __future__ import annotations

import dataclasses
import tomllib
from pathlib import Path
from typing import Any

from ..errors import SceneError
from .liner_shape import LinerShape
from .schema import Block, Liner, Scene, from_table


def scene_from_dict(data: dict) -> Scene:
    """Build (and validate) a scene from a TOML-like dict; unknown keys and wrong types refused."""
    return from_table(Scene, data, "")


def scene_to_dict(scene: Scene) -> dict:
    """The scene as plain TOML-able data (None values omitted: they mean 'the plan decides')."""

    def clean(v: Any) -> Any:
        if isinstance(v, dict):
            return {k: clean(x) for k, x in v.items() if x is not None}
        if isinstance(v, (list, tuple)):
            return [clean(x) for x in v]
        return v

    d = clean(dataclasses.asdict(scene))
    if scene.liner is not None and scene.block == Block():
        d.pop("block", None)  # unused by a liner scene
    if scene.liner is not None:
        # a liner without bolt holes and clamped writes (and hashes: study, table and bench cache
        # keys) as it did before these fields; its backing's values only matter on a rubber backing
        defaults = dict(LinerShape.OPTIONAL_DEFAULTS)
        if scene.liner.backing == "clamped":
            defaults.update({f.name: f.default for f in dataclasses.fields(Liner) if f.name.startswith("backing_")})
        defaults.update(Liner.PLACE_DEFAULTS)  # an impact on a lifter face, as before the places
        for name, default in defaults.items():
            if getattr(scene.liner, name) == default:
                d["liner"].pop(name, None)
    return d


def load_scene(path: str | Path) -> Scene:
    """Read a scene TOML file."""
    p = Path(path)
    try:
        raw = p.read_bytes()
    except OSError as exc:
        raise SceneError("scene", str(p), f"cannot be read ({exc.strerror})") from None
    text = scene_text(raw, str(p))
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SceneError("scene", str(p), f"is not valid TOML ({exc})") from None
    if not data:
        raise SceneError(
            "scene", str(p), "is empty; start from a built-in scene: millimpact scene export paper-rig > my.toml"
        )
    data.setdefault("name", p.stem)
    return scene_from_dict(data)


def scene_text(raw: bytes, where: str) -> str:
    """A scene file's bytes as text. TOML is UTF-8; a UTF-8 byte-order mark (Windows editors write
    one) is dropped; other encodings (Latin-1, Windows-1252) are refused in one line naming the
    first byte that is not UTF-8, since which characters were meant cannot be known."""
    if raw.startswith(b"\xef\xbb\xbf"):
        raw = raw[3:]
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = raw[: exc.start].count(b"\n") + 1
        column = exc.start - (raw.rfind(b"\n", 0, exc.start) + 1) + 1
        raise SceneError(
            "scene",
            where,
            f"is not UTF-8 text (byte 0x{raw[exc.start]:02x} at line {line}, column "
            f"{column}; Latin-1 or Windows-1252?): save it as UTF-8, the encoding of TOML",
        ) from None


def dump_scene(scene: Scene) -> str:
    """The scene as TOML text, with a header that states the units."""
    import tomli_w

    head = (
        "# millimpact scene. SI units: m, s, kg/m^3, Pa, m/s.\n"
        "# Block: x in [-length/2, length/2], y in [-thickness, 0], z in [0, height]; struck face y = 0.\n"
        "# Liner scenes: the [liner] table replaces the block (struck lifter face, contact normal = its normal).\n"
        "# Omitted optional values (impact.point, impact.gap, time.dt_*, model.*) are chosen by the plan.\n"
    )
    return head + tomli_w.dumps(scene_to_dict(scene))
