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
copyright = "2026, the millimpact developers (MIT licence)"
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
    """One page per subpackage (its modules, each with automodule) and one for the top-level modules
    (docs/api/, regenerated at each build, not tracked): the API sidebar lists the stages."""
    import pkgutil

    out = Path(app.srcdir) / "api"
    out.mkdir(exist_ok=True)
    for old in out.glob("*.rst"):
        old.unlink()
    top = [m.name for m in pkgutil.iter_modules(millimpact.__path__, "millimpact.") if not m.ispkg]
    pages = {"Top-level modules": ("millimpact.top", top)}
    for pkg in pkgutil.iter_modules(millimpact.__path__, "millimpact."):
        if pkg.ispkg:
            sub = __import__(pkg.name, fromlist=["__path__"])
            mods = [m.name for m in pkgutil.walk_packages(sub.__path__, pkg.name + ".")]
            pages[pkg.name] = (pkg.name, [pkg.name, *mods])
    for title, (stem, modules) in pages.items():
        text = [title, "=" * len(title), ""]
        for name in modules:
            if name == stem:    # the subpackage's own docstring opens its page
                text += [f".. automodule:: {name}", ""]
                continue
            heading = f"``{name}``"
            text += [heading, "-" * len(heading), "", f".. automodule:: {name}", ""]
        (out / f"{stem}.rst").write_text("\n".join(text))


def _escape_bars(app, what, name, obj, options, lines):
    """Docstrings write |x| for magnitudes; reStructuredText reads |x| as a substitution."""
    import re

    for i, line in enumerate(lines):
        if not re.match(r"\s*([|+].*[|+]\s*$)", line):   # not a table row
            lines[i] = line.replace("|", "\\|")


_PROSE = {}


def _keep_constant_prose(app, what, name, obj, options, lines):
    """A constant's ``#:`` comment is prose, but napoleon reads "words: more words" on its first
    line as "type: description" (a Type field under the constant). Before napoleon: keep the lines;
    after it: put them back."""
    if what in ("data", "attribute"):
        _PROSE[name] = list(lines)


def _restore_constant_prose(app, what, name, obj, options, lines):
    if what in ("data", "attribute") and name in _PROSE:
        lines[:] = _PROSE.pop(name)


def setup(app):
    app.connect("builder-inited", _write_api_pages)
    app.connect("autodoc-process-docstring", _keep_constant_prose, priority=100)    # before napoleon
    app.connect("autodoc-process-docstring", _restore_constant_prose, priority=900)  # after it
    app.connect("autodoc-process-docstring", _escape_bars, priority=950)
