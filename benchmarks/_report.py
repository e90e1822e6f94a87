"""Shared output of the benchmark scripts: one CSV row per case and a Markdown table."""
from __future__ import annotations

import csv
import platform
from pathlib import Path
from typing import Callable, Sequence


def write_report(out: str | Path, name: str, rows: list[dict], ranks: int, columns: Sequence[str],
                 cells: Callable[[dict], Sequence[str]], note: str = "") -> None:
    """Write ``out/name.csv`` (all fields of ``rows``) and ``out/name.md`` (a table with the
    ``columns`` headers and the ``cells`` of each row, under a line naming the machine), and
    print the table."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    with open(out / f"{name}.csv", "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)
    lines = [f"machine: {platform.node()} {platform.processor() or platform.machine()}, {ranks} rank(s){note}", "",
             "| " + " | ".join(columns) + " |", "|" + "---|" * len(columns)]
    lines += ["| " + " | ".join(cells(r)) + " |" for r in rows]
    (out / f"{name}.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
