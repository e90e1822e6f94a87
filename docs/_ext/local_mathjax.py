"""MathJax from Debian's ``libjs-mathjax`` (2.7), copied into the built site: pages typeset their
equations with no network (many mill sites' machines reach no CDN).

Sets ``mathjax_path`` to ``_static/mathjax/MathJax.js`` with the combined configuration
``TeX-AMS_CHTML`` (TeX input, CommonHTML output) and, when the build finishes, copies the part of
``/usr/share/javascript/mathjax`` that configuration loads (~3 MB of the package's 54 MB: the
TeX input, the CommonHTML output and its TeX web fonts, the TeX extensions, the English messages).
Without the package the build stops with one line naming it (``packages.txt`` lists it).
"""
from __future__ import annotations

import shutil
from pathlib import Path

MATHJAX = Path("/usr/share/javascript/mathjax")
CONFIG = "TeX-AMS_CHTML"
#: what the TeX-AMS_CHTML configuration loads (checked with a headless browser, no network)
PARTS = ["MathJax.js", f"config/{CONFIG}.js", "config/local", "extensions", "jax/input/TeX", "jax/element",
         "jax/output/CommonHTML", "fonts/HTML-CSS/TeX/woff", "fonts/HTML-CSS/TeX/otf", "localization/en"]


def _config_inited(app, config):
    from sphinx.errors import ConfigError

    if not (MATHJAX / "MathJax.js").is_file():
        raise ConfigError(f"local_mathjax: {MATHJAX}/MathJax.js not found: install Debian's libjs-mathjax")
    config.mathjax_path = f"mathjax/MathJax.js?config={CONFIG}"


def _build_finished(app, exc):
    if exc is not None or app.builder.format != "html":
        return
    dest = Path(app.outdir) / "_static" / "mathjax"
    for part in PARTS:
        src, dst = MATHJAX / part, dest / part
        if src.is_dir():
            shutil.copytree(src, dst, dirs_exist_ok=True)
        elif src.is_file():
            dst.parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dst)


def setup(app):
    app.setup_extension("sphinx.ext.mathjax")
    app.connect("config-inited", _config_inited)
    app.connect("build-finished", _build_finished)
    return {"parallel_read_safe": True, "version": "1"}
