"""Every reference in the checkout resolves inside it, and user-facing text does not speak of the
development's history.

Scans the tracked text files (``git ls-files``; a copy without git: every file under the same
folders) of README.md, docs/, millimpact/, tests/, demos/ and benchmarks/ for:

- references to files a checkout does not have: the developers' external design, style and
  DOLFINx notes (named in :data:`EXTERNAL` only in pieces, so this file names none of them), a
  machine path, a shared folder outside the repository (everywhere);
- the word "session" and "issue N" in user-facing places: README.md, docs/, benchmarks/README.md,
  and the code, comments and messages of millimpact/, demos/ and benchmarks/*.py (the design lives
  in docs/foundations.md; a figure is given with its command, not with the history that led to it).

A failure lists every offender as ``file:line: text``, so all of them can be fixed in one pass.
"""
from __future__ import annotations

import re
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SCANNED = ("README.md", "docs/", "millimpact/", "tests/", "demos/", "benchmarks/")
TEXT_SUFFIXES = {".py", ".md", ".rst", ".toml", ".txt", ".sh", ".cfg", ".cff", ".json", ".yml",
                 ".yaml", ".csv", ".c", ".html"}
#: a reference to a file outside the checkout (the names are split so that this file has none)
_NOTES = ("DES" "IGN", "ST" "YLE")
EXTERNAL = re.compile("|".join(rf"{n}\.md" for n in _NOTES) + r"|NOTES-" r"dolfinx|/wo" r"rk/|(?<![\w.-])sha" r"red/")
#: the development's history in user-facing text ("gmsh_session" is a name, not the word)
HISTORY = re.compile(r"\bsessions?\b|\b[Ii]ssues? #?\d+", re.IGNORECASE)


def tracked_files() -> list[str]:
    """The checkout's tracked files under SCANNED (every file there without git)."""
    try:
        out = subprocess.run(["git", "ls-files", "--", *SCANNED], cwd=ROOT, capture_output=True,
                             text=True, check=True).stdout.split("\n")
        files = [f for f in out if f]
    except (OSError, subprocess.CalledProcessError):
        files = []
    if not files:
        files = [p.relative_to(ROOT).as_posix() for s in SCANNED for p in
                 ([ROOT / s] if not s.endswith("/") else (ROOT / s).rglob("*"))
                 if p.is_file() and "_build" not in p.parts and ".venv" not in p.parts]
    return sorted(f for f in files if Path(f).suffix in TEXT_SUFFIXES)


def user_facing(path: str) -> bool:
    """README, the docs, benchmarks/README.md and the code of the package, the demos and the
    benchmark scripts (not the tests, whose comments may quote a tolerance's history)."""
    return (path == "README.md" or path.startswith(("docs/", "millimpact/", "demos/"))
            or path == "benchmarks/README.md"
            or (path.startswith("benchmarks/") and path.count("/") == 1
                and path.endswith((".py", ".sh"))))


def offenders(files: list[str], pattern: re.Pattern, root: Path = ROOT) -> list[str]:
    """``file:line: text`` of every line of ``files`` that ``pattern`` matches."""
    found = []
    for name in files:
        try:
            text = (root / name).read_text(encoding="utf-8")
        except (UnicodeDecodeError, FileNotFoundError):
            continue
        for number, line in enumerate(text.splitlines(), 1):
            if pattern.search(line):
                found.append(f"{name}:{number}: {line.strip()[:160]}")
    return found


def _report(found: list[str], what: str) -> str:
    return f"{len(found)} line(s) with {what}:\n" + "\n".join(found)


def test_the_scan_sees_the_checkout():
    files = tracked_files()
    # the scan is only as good as its file list: it must hold the package, the docs and itself's peers
    assert "README.md" in files and "docs/index.md" in files and "millimpact/cli.py" in files
    assert any(f.startswith("tests/") for f in files)


def test_no_reference_leaves_the_checkout():
    found = offenders(tracked_files(), EXTERNAL)
    assert not found, _report(found, "a reference to a file outside the checkout")


def test_user_facing_text_has_no_development_history():
    found = offenders([f for f in tracked_files() if user_facing(f)], HISTORY)
    assert not found, _report(found, "'session' or 'issue N' in user-facing text")


def test_the_scan_finds_a_planted_offender(tmp_path):
    """The patterns catch what they are for, and only that (a check that cannot fail is no check)."""
    design = _NOTES[0] + ".md"
    bad = {"docs/a.md": f"see {design} section 3\n", "millimpact/b.py": "# measured in the third session\n",
           "demos/c.py": "# the target of issue 31\n", "benchmarks/d.py": "x = '/wo" "rk/sha" "red/x.py'\n"}
    good = {"docs/e.md": "see docs/foundations.md, section 3\n", "millimpact/f.py": "with gmsh_session():\n"}
    for name, text in {**bad, **good}.items():
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text(text)
    names = sorted({**bad, **good})
    external = offenders(names, EXTERNAL, root=tmp_path)
    history = offenders(names, HISTORY, root=tmp_path)
    assert [f.split(":")[0] for f in external] == ["benchmarks/d.py", "docs/a.md"]
    assert [f.split(":")[0] for f in history] == ["demos/c.py", "millimpact/b.py"]
    assert external[1] == f"docs/a.md:1: see {design} section 3"
