"""The docs' scene-field table cannot drift from the schema: every field the schema has is
documented (unit, range, meaning), and every documented field exists."""
from __future__ import annotations

import dataclasses

from millimpact.scene.field_docs import FIELD_DOCS, MATERIAL_DOCS, scene_field_rows
from millimpact.scene.schema import Material, coerce_value


def test_every_schema_field_is_documented():
    rows = list(scene_field_rows())
    assert len(rows) >= 60
    missing = [r[0] for r in rows if not r[5]]
    assert missing == []
    # every material table carries the same documented fields, `name` first
    for body in ("ball", "block", "liner"):
        names = [r[0] for r in rows if r[0].startswith(f"{body}.material.")]
        assert names[0] == f"{body}.material.name" and len(names) == len(MATERIAL_DOCS)


def test_every_documented_field_exists():
    walked = {r[0] for r in scene_field_rows()}
    assert set(FIELD_DOCS) <= walked
    fields = {f.name for f in dataclasses.fields(Material)} | {"name"}
    assert set(MATERIAL_DOCS) == fields
    # a material table's `name` is a key the loader takes
    assert coerce_value(Material, {"name": "cr-mo-liner"}, "block.material").yield_stress is not None
