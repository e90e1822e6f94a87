"""The demos run as-is at reduced size (``--small``) and pass their own checks (each demo asserts
its physics: Hertz exponents, the rig's 5 % to Hertz and 1 % energy balance, ...); each then becomes
its documentation page (docs/_ext/demo_pages.py, the extension ``./dev docs`` uses), built by
Sphinx with warnings as errors, with its figures and the local MathJax."""
import html as html_text
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import ROOT, mpi_env, shared_out

sys.path.insert(0, str(ROOT / "docs" / "_ext"))
import demo_pages  # noqa: E402

DEMOS = ["paper_rig", "study_velocity", "study_radius", "study_poisson", "study_thickness",
         "plastic_impact", "contact_table", "repeated_impacts", "mill_spectrum", "damage_map", "liner_life"]
#: a file each demo's run leaves in its output folder (the command's own output beside the figures)
OUTPUT = {"paper_rig": "summary.json", "plastic_impact": "summary.json", "contact_table": "contact_table.csv",
          "repeated_impacts": "impacts.csv", "mill_spectrum": "impacts.csv", "damage_map": "map/damage.json",
          "liner_life": "life/summary.json"}
#: the demos that run Yade (contact_table leaves its round trip out without it)
NEEDS_YADE = {"mill_spectrum", "damage_map", "liner_life"}


#: where ``./dev docs`` keeps its demo runs (docs/_ext/demo_pages.py: ``demo_runs``' default)
DOCS_RUNS = ROOT / "docs" / "_build" / "demo-runs"


def _current_docs_record(demo: str) -> dict | None:
    """The documentation build's record of ``demo`` when it is current: made from the same demo and
    package sources (its fingerprint) and its output folder still there; else None."""
    record = demo_pages.read_record(DOCS_RUNS / demo)
    if record is None or record.get("fingerprint") != demo_pages.fingerprint(demo):
        return None
    return record if Path(record["out"]).is_dir() else None


def test_every_demo_is_listed():
    assert demo_pages.demo_names() == sorted(DEMOS)


def _build_page(name, runs, tmp_path):
    """A one-demo Sphinx site from the run record under ``runs`` (no demo run by the build); its html folder."""
    src, html = tmp_path / "site", tmp_path / "html"
    src.mkdir()
    (src / "conf.py").write_text(
        f"import sys\nsys.path.insert(0, {str(ROOT / 'docs' / '_ext')!r})\n"
        f"extensions = ['myst_parser', 'local_mathjax', 'demo_pages']\nmyst_enable_extensions = ['dollarmath']\n"
        f"myst_update_mathjax = False\ndemo_runs = {str(runs)!r}\ndemo_names = [{name!r}]\ndemo_run_missing = False\n")
    (src / "index.md").write_text("# Site\n\nThe contact modulus $E^*$.\n\n```{toctree}\ndemos/index\n```\n")
    r = subprocess.run([sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b", "html", str(src), str(html)],
                       capture_output=True, text=True, cwd=ROOT, env=mpi_env(), timeout=300)
    assert r.returncode == 0, (r.stdout + r.stderr)[-3000:]
    return html


@pytest.mark.parametrize("demo", DEMOS)
def test_demo_runs_at_reduced_size_and_makes_its_page(demo, tmp_path, tmp_path_factory):
    if demo in NEEDS_YADE and shutil.which("yade") is None:
        pytest.skip("Yade is not installed (apt-get install yade)")
    record = _current_docs_record(demo)
    if record is not None:
        # the documentation build ran this demo on these very sources (./dev docs, before the tests
        # in CI): its record is written only when the demo's checks passed, and its fingerprint
        # hashes the demo and the package, so running it again would repeat the same run
        runs, out = DOCS_RUNS, Path(record["out"])
    else:
        runs = tmp_path / "runs"
        # the studies: the folder test_study.py uses for the same study, so the case cache serves both
        out = shared_out(tmp_path_factory, demo[len("study_"):]) if demo.startswith("study_") else tmp_path / "out"
        try:
            record = demo_pages.run_demo(demo, runs / demo, out=out)
        except demo_pages.DemoFailed as e:
            pytest.fail(str(e))
    assert (out / OUTPUT.get(demo, "study.md")).is_file()
    figures = demo_pages.figures(out)
    assert figures, f"demos/{demo}.py wrote no figure"

    html = _build_page(demo, runs, tmp_path)
    page = (html / "demos" / f"{demo}.html").read_text()
    images = re.findall(r'<img [^>]*src="([^"]+)"', page)
    assert len(images) == len(figures)
    assert all((html / "demos" / src).resolve().is_file() for src in images)
    assert record["stdout"].splitlines()[-1].split(":")[0] in html_text.unescape(page)   # the demo's last printed line
    # equations typeset from the site's own copy of MathJax, no network
    index = (html / "index.html").read_text()
    assert '_static/mathjax/MathJax.js?config=' in index and "https://" not in "".join(
        re.findall(r"<script[^>]*>", index))
    assert (html / "_static" / "mathjax" / "MathJax.js").is_file()
