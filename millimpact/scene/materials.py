"""Named materials for scene files (``material = "NAME"``): ``scene/materials.toml``, every value with its source."""

from __future__ import annotations

import tomllib
from pathlib import Path
from typing import Any

from ..errors import SceneError

#: named materials (``material = "NAME"``): scene/materials.toml, every value with its source
NAMED_MATERIALS: dict[str, dict] = tomllib.loads((Path(__file__).with_name("materials.toml")).read_text())


def named_material(name: Any, where: str) -> dict:
    """The fields of a named material; an unknown name is a :class:`SceneError` listing the names."""
    if not isinstance(name, str) or name not in NAMED_MATERIALS:
        raise SceneError(where, name, f"unknown material; named materials: {', '.join(NAMED_MATERIALS)}")
    return dict(NAMED_MATERIALS[name])
