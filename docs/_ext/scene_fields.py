"""``.. scene-fields::``: the table of every scene field (dotted name, type, default, unit, range),
generated from the schema's dataclasses so it cannot drift from the code."""
from __future__ import annotations

import dataclasses
import typing

from docutils import nodes
from docutils.parsers.rst import Directive


def _rows(cls, prefix=""):
    hints = typing.get_type_hints(cls)
    for f in dataclasses.fields(cls):
        tp = hints[f.name]
        inner = [a for a in typing.get_args(tp) if a is not type(None)]
        target = inner[0] if inner else tp
        if dataclasses.is_dataclass(target) and f.name != "gauges":
            yield from _rows(target, f"{prefix}{f.name}.")
            continue
        if f.default is not dataclasses.MISSING:
            default = repr(f.default)
        elif f.default_factory is not dataclasses.MISSING:
            default = repr(f.default_factory())
        else:
            default = "(required)"
        meta = f.metadata or {}
        yield (f"{prefix}{f.name}", getattr(tp, "__name__", str(tp)).replace("typing.", ""), default,
               meta.get("unit", ""), meta.get("range", ""), meta.get("doc", ""))


class SceneFields(Directive):
    def run(self):
        from millimpact.scene.schema import Scene

        table = nodes.table()
        group = nodes.tgroup(cols=6)
        table += group
        for w in (22, 12, 16, 6, 18, 26):
            group += nodes.colspec(colwidth=w)
        head = nodes.thead()
        group += head
        body = nodes.tbody()
        group += body

        def row(cells, into):
            r = nodes.row()
            for c in cells:
                e = nodes.entry()
                e += nodes.paragraph(text=str(c))
                r += e
            into += r

        row(("field", "type", "default", "unit", "allowed", "meaning"), head)
        for cells in _rows(Scene):
            row(cells, body)
        return [table]


def setup(app):
    app.add_directive("scene-fields", SceneFields)
    return {"parallel_read_safe": True}
