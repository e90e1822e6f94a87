"""The demos (``demos/*.py``) as pages of the documentation: prose, the figures, the printed checks, the code.

At ``builder-inited`` each demo gets a MyST page ``docs/demos/<name>.md`` (generated at each build,
not tracked) made of its docstring, the command of its quick variant, what that run printed (the
numbers the demo checks), every figure it wrote and its code; ``docs/demos/index.md`` lists them.
The figures come from the demo's **quick variant** (``--small``, 20-80 s each on 2 cores), run by the
build when its record is missing or stale: a record ``<demo_runs>/<name>/demo-run.json`` keeps the
fingerprint (a hash of the demo, ``demos/_common.py`` and the package's sources), the command and
what it printed; the outputs lie beside it in ``out/``. So a fresh clone's ``./dev docs`` runs the
eleven quick variants once, two at a time (``DEMO_JOBS`` says otherwise; ~2 min on 2 cores), and a
rebuild with unchanged sources reuses them; so does ``tests/test_demos.py``. A demo that
fails (its own physics checks are asserts) stops the build, with the end of what it printed.

The demos never run at full size here: the full-size figures need minutes to hours (the paper's
rig and the studies over 40 ms, a mill's two revolutions in Yade). ``tests/test_demos.py`` runs the same quick variants (or
takes the build's current records) and builds their pages with this extension, so a demo or a page
that breaks fails the test suite too.

Config values: ``demo_runs`` (folder of the records, default ``docs/_build/demo-runs``),
``demo_names`` (default: every ``demos/*.py`` not starting with ``_``), ``demo_run_missing`` (False:
a missing or stale record is an error instead of a run; the test uses it to build from its own runs).
"""
from __future__ import annotations

import ast
import hashlib
import json
import os
import shutil
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
DEMOS = ROOT / "demos"
RECORD = "demo-run.json"
#: figures shown first when a demo wrote them (the rest follow in name order)
FIGURE_ORDER = ["contact_force.png", "trends.png", "force_approach.png", "energy.png", "restitution.png",
                "shakedown.png", "e_n_speed.png", "spectrum.png", "damage_map.png"]
#: the extra arguments of a quick variant (the studies compute their two cases side by side)
EXTRA_ARGS = {"study_": ["--jobs", "2"]}


class DemoFailed(RuntimeError):
    """A demo's quick variant exited with an error (a failed physics check is an AssertionError)."""


def demo_names() -> list[str]:
    """The demos' stems (``paper_rig``, ``study_velocity``, ...), helpers (``_common``) left out."""
    return sorted(p.stem for p in DEMOS.glob("*.py") if not p.name.startswith("_"))


def fingerprint(name: str) -> str:
    """A hash of what a demo's output depends on: the demo, the demos' helper, the package's sources
    and data files (scenes, materials). A rebuild reuses a record only when it matches."""
    h = hashlib.sha256()
    files = [DEMOS / f"{name}.py", DEMOS / "_common.py"]
    files += sorted(p for p in (ROOT / "millimpact").rglob("*") if p.suffix in (".py", ".toml", ".json"))
    for p in files:
        if p.is_file():
            h.update(str(p.relative_to(ROOT)).encode())
            h.update(p.read_bytes())
    return h.hexdigest()


def quick_command(name: str, out: Path) -> list[str]:
    """The quick variant's command line (the test suite's reduced size)."""
    extra = next((a for prefix, a in EXTRA_ARGS.items() if name.startswith(prefix)), [])
    return [sys.executable, str(DEMOS / f"{name}.py"), "--small", "--out", str(out), *extra]


def run_demo(name: str, run_dir: Path, out: Path | None = None, timeout: float = 900) -> dict:
    """Run demo ``name``'s quick variant into ``out`` (default ``run_dir/out``) and write its record
    ``run_dir/demo-run.json``; returns the record. Raises :class:`DemoFailed` with the end of its
    output when it fails. An old record is removed first, so an interrupted run leaves none."""
    run_dir = Path(run_dir)
    run_dir.mkdir(parents=True, exist_ok=True)
    (run_dir / RECORD).unlink(missing_ok=True)
    if out is None:
        out = run_dir / "out"
        if out.exists():
            shutil.rmtree(out)                # the build's own folder, made by an earlier build
    cmd = quick_command(name, out)
    env = dict(os.environ, MPLBACKEND="Agg", OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1")
    t0 = time.perf_counter()
    r = subprocess.run(cmd, capture_output=True, text=True, env=env, cwd=ROOT, timeout=timeout)
    if r.returncode != 0:
        raise DemoFailed(f"demos/{name}.py --small failed (exit {r.returncode}):\n{(r.stdout + r.stderr)[-3000:]}")
    record = {"demo": name, "fingerprint": fingerprint(name), "out": str(Path(out).resolve()),
              "command": " ".join(["python", f"demos/{name}.py", "--small", "--out", "OUT", *cmd[5:]]),
              "stdout": r.stdout.replace(str(Path(out).resolve()), "OUT").replace(str(out), "OUT"), "wall_time_s": round(time.perf_counter() - t0, 1)}
    tmp = run_dir / (RECORD + ".part")
    tmp.write_text(json.dumps(record, indent=1) + "\n")
    tmp.replace(run_dir / RECORD)
    return record


def run_demos(names: list[str], runs: Path, log=print) -> dict[str, dict]:
    """Run the quick variants of ``names``, DEMO_JOBS at a time (default: up to 2, the cores a
    small machine has; each demo is one process, the studies two), into ``runs/<name>``; their
    records. The first failure raises :class:`DemoFailed` once the running demos have ended."""
    from concurrent.futures import ThreadPoolExecutor

    jobs = max(1, int(os.environ.get("DEMO_JOBS", min(2, os.cpu_count() or 1))))

    def one(name: str) -> dict:
        log(f"[demos] running the quick variant of demos/{name}.py ...")
        record = run_demo(name, runs / name)
        log(f"[demos] demos/{name}.py: {record['wall_time_s']} s")
        return record

    with ThreadPoolExecutor(max_workers=jobs) as pool:
        futures = {name: pool.submit(one, name) for name in names}
        try:
            return {name: f.result() for name, f in futures.items()}
        except BaseException:
            pool.shutdown(cancel_futures=True)       # the queued ones do not start
            raise


def read_record(run_dir: Path) -> dict | None:
    try:
        return json.loads((Path(run_dir) / RECORD).read_text())
    except (OSError, ValueError):
        return None


def figures(out: Path) -> list[Path]:
    """The PNG figures a demo wrote at the top of its output folder, :data:`FIGURE_ORDER` first."""
    found = {p.name: p for p in Path(out).glob("*.png")}
    first = [found.pop(n) for n in FIGURE_ORDER if n in found]
    return first + [found[n] for n in sorted(found)]


def _docstring(name: str) -> tuple[str, str, str]:
    """(title, subtitle, body) of a demo's module docstring: its first line up to the first " (" or
    ":", the rest of that line, and the other lines."""
    doc = ast.get_docstring(ast.parse((DEMOS / f"{name}.py").read_text())) or name
    first, _, rest = doc.partition("\n")
    first = first.strip().rstrip(".")
    cut = min((i for i in (first.find(" ("), first.find(":")) if i > 0), default=len(first))
    return first[:cut], first[cut:].lstrip(" :"), rest.strip()


def page_text(name: str, record: dict, images: list[str], code: str) -> str:
    """The MyST page of one demo (images and code: paths relative to the page)."""
    title, subtitle, body = _docstring(name)
    fence = "````"
    lines = [f"# {title}", "", f"`demos/{name}.py`{': ' + subtitle if subtitle else ''}", "", body, "",
             "## The quick variant", "",
             "The figures and numbers on this page come from the demo's quick variant, the reduced size the "
             "test suite runs (the documentation build runs it when the sources changed; `OUT` stands for "
             "the output folder):", "",
             f"{fence}sh", record["command"], fence, "",
             "It printed (the demo asserts the checks its description names):", "",
             f"{fence}text", record["stdout"].rstrip(), fence, ""]
    if images:
        lines += ["## Figures", ""]
        for img in images:
            lines += [f"```{{figure}} {img}", ":width: 100%", "", f"`{Path(img).name}`", "```", ""]
    lines += ["## The code", "", f"```{{literalinclude}} {code}", ":language: python", "```", ""]
    return "\n".join(lines)


def index_text(names: list[str]) -> str:
    rows = [f"- [{_docstring(n)[0]}]({n}.md) (`{n}.py`): {_docstring(n)[1]}" for n in names]
    return "\n".join([
        "# Demos", "",
        "Literate scripts under `demos/`, each checking its own physics (Hertz's exponents, the rig's 5 % "
        "to Hertz and 1 % energy balance, the paper's trends, plastic restitution between Thornton's bound "
        "and the elastic rig, shakedown under repeated impacts, a mill's energy balance in Yade, the damage "
        "map's energy sums). Each page gives the demo's prose, the "
        "figures and numbers of its quick variant (`--small`, the size the test suite runs) and its "
        "code. Run one at full size with `.venv/bin/python demos/NAME.py` (its page says what full "
        "size is).", "", *rows, "",
        "```{toctree}", ":hidden:", "", *names, "```", ""])


def _write_if_changed(path: Path, text: str) -> None:
    if not path.is_file() or path.read_text() != text:
        path.write_text(text)


def write_pages(srcdir: Path, runs: Path, names: list[str], run_missing: bool = True, log=print) -> None:
    """Write ``srcdir/demos/`` (pages and figures) from the records under ``runs``, running the quick
    variant of each demo whose record is missing or stale when ``run_missing``."""
    pages = Path(srcdir) / "demos"
    pages.mkdir(exist_ok=True)
    records = {name: read_record(Path(runs) / name) for name in names}
    stale = [n for n, r in records.items()
             if r is None or r["fingerprint"] != fingerprint(n) or not Path(r["out"]).is_dir()]
    if stale and not run_missing:
        raise DemoFailed(f"demos/{stale[0]}.py: no current record in {Path(runs) / stale[0]} (demo_run_missing is off)")
    records.update(run_demos(stale, Path(runs), log))
    for name in names:
        record = records[name]
        fig_dir = pages / name
        if fig_dir.exists():
            shutil.rmtree(fig_dir)
        fig_dir.mkdir()
        images = []
        for fig in figures(Path(record["out"])):
            shutil.copy2(fig, fig_dir / fig.name)
            images.append(f"{name}/{fig.name}")
        _write_if_changed(pages / f"{name}.md", page_text(name, record, images,
                                                              os.path.relpath(DEMOS / f"{name}.py", pages)))
    _write_if_changed(pages / "index.md", index_text(names))


def _builder_inited(app):
    from sphinx.errors import ExtensionError
    from sphinx.util import logging

    logger = logging.getLogger(__name__)
    runs = Path(app.config.demo_runs or Path(app.srcdir) / "_build" / "demo-runs")
    names = app.config.demo_names or demo_names()
    try:
        write_pages(Path(app.srcdir), runs, names, app.config.demo_run_missing, log=logger.info)
    except (DemoFailed, subprocess.TimeoutExpired) as e:
        raise ExtensionError(str(e)) from None


def setup(app):
    app.add_config_value("demo_runs", "", "env")
    app.add_config_value("demo_names", [], "env")
    app.add_config_value("demo_run_missing", True, "env")
    app.connect("builder-inited", _builder_inited)
    return {"parallel_read_safe": True, "version": "1"}
