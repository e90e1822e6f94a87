"""``.. scene-fields::``: the table of every scene field (dotted name, type, default, unit, range,
meaning), generated from the schema's dataclasses and millimpact/scene/field_docs.py so it cannot
drift from the code (tests/scene/test_field_docs.py checks that both list the same fields)."""
from __future__ import annotations

from docutils import nodes
from docutils.parsers.rst import Directive


class SceneFields(Directive):
    def run(self):
        from millimpact.scene.field_docs import scene_field_rows

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
        for cells in scene_field_rows():
            row(cells, body)
        return [table]


def setup(app):
    app.add_directive("scene-fields", SceneFields)
    return {"parallel_read_safe": True}
