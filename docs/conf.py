"""Sphinx configuration of millimpact's documentation (Debian's python3-sphinx, myst-parser, furo,
sphinx-argparse, libjs-mathjax). Build: ./dev docs (warnings are errors) -> docs/_build/html/index.html.

Local extensions (docs/_ext/): scene_fields (the scene field reference), demo_pages (the demos as
pages, from their quick variants: see its docstring), local_mathjax (MathJax copied into the site)."""
import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(Path(__file__).parent / "_ext"))
os.environ.setdefault("MPLBACKEND", "Agg")

import millimpact  # noqa: E402

project = "millimpact"
author = "the millimpact developers"
release = version = millimpact.__version__
extensions = ["myst_parser", "sphinx.ext.autodoc", "sphinx.ext.napoleon", "local_mathjax", "sphinxarg.ext",
              "scene_fields", "demo_pages"]
source_suffix = {".md": "markdown", ".rst": "restructuredtext"}
exclude_patterns = ["_build"]
html_theme = "furo"
html_title = f"millimpact {release}"
myst_enable_extensions = ["dollarmath"]
# MathJax 2 (Debian's): its default tex2jax reads the \( \) and \[ \] Sphinx writes; myst's MathJax 3
# class options would only be noise to it
myst_update_mathjax = False
myst_heading_anchors = 3
autodoc_member_order = "bysource"
autodoc_default_options = {"members": True, "undoc-members": False, "show-inheritance": False}
autodoc_typehints = "none"
nitpicky = False
suppress_warnings = ["myst.header"]


def _write_api_pages(app):
    """One page per module of the package (docs/api/, regenerated at each build, not tracked)."""
    import pkgutil

    out = Path(app.srcdir) / "api"
    out.mkdir(exist_ok=True)
    for old in out.glob("*.rst"):
        old.unlink()
    for mod in pkgutil.walk_packages(millimpact.__path__, "millimpact."):
        name = mod.name
        (out / f"{name}.rst").write_text(f"{name}\n{'=' * len(name)}\n\n.. automodule:: {name}\n")


def _escape_bars(app, what, name, obj, options, lines):
    """Docstrings write |x| for magnitudes; reStructuredText reads |x| as a substitution."""
    import re

    for i, line in enumerate(lines):
        if not re.match(r"\s*([|+].*[|+]\s*$)", line):   # not a table row
            lines[i] = line.replace("|", "\\|")


def setup(app):
    app.connect("builder-inited", _write_api_pages)
    app.connect("autodoc-process-docstring", _escape_bars)
