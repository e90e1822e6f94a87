"""Shared parts of the benchmark scripts: a timed run under mpirun with its peak memory, and the
output (one CSV row per case and a Markdown table)."""
from __future__ import annotations

import csv
import os
import platform
import subprocess
import time
from pathlib import Path
from typing import Callable, Sequence


def timed_run(cmd: list[str], ranks: int, cwd: Path) -> tuple[int, float, float]:
    """Run ``cmd`` (under ``mpirun -n ranks`` when ranks > 1); returns (exit code, wall time s,
    peak resident memory GB of the busiest process). The memory is ``wait4``'s ru_maxrss: the
    largest resident set of the process and the descendants it waited for (mpirun's ranks)."""
    return timed_run_cpu(cmd, ranks, cwd)[:3]


def timed_run_cpu(cmd: list[str], ranks: int, cwd: Path, log: Path | None = None
                  ) -> tuple[int, float, float, float]:
    """:func:`timed_run` and the CPU time (s, user + system) of the process and the descendants
    it waited for, from the same ``wait4``: on a loaded machine the wall time is inflated, the CPU
    time much less. ``log``: a file for the run's output (stdout and stderr), else the terminal."""
    if ranks > 1:
        cmd = ["mpirun", "-n", str(ranks), *cmd]
    env = {**os.environ, "OMPI_ALLOW_RUN_AS_ROOT": "1", "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM": "1",
           "OMPI_MCA_rmaps_base_oversubscribe": "1"}
    fh = open(log, "w") if log is not None else None
    t0 = time.perf_counter()
    try:
        proc = subprocess.Popen(cmd, cwd=cwd, env=env, stdout=fh, stderr=subprocess.STDOUT if fh else None)
        _, status, usage = os.wait4(proc.pid, 0)
    finally:
        if fh is not None:
            fh.close()
    return (os.waitstatus_to_exitcode(status), time.perf_counter() - t0, usage.ru_maxrss / 1024**2,
            usage.ru_utime + usage.ru_stime)


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


def add_panel_arguments(ap, h_far: float = 0.05) -> None:
    """The liner-panel benchmarks' mesh and time arguments (a coarse panel by default)."""
    ap.add_argument("--h-far", type=float, default=h_far, help="far element size, m (0: the plan's)")
    ap.add_argument("--h-contact", type=float, default=0.005, help="contact element size, m (0: the plan's)")
    ap.add_argument("--zone", type=float, default=0.024, help="contact-zone radius, m (0: the method's)")
    ap.add_argument("--end", type=float, default=5e-4, help="simulated time, s (default 0.5 ms)")


def panel_sets(args, root: Path, mesh_out: Path) -> list[str]:
    """The ``--set`` arguments of :func:`add_panel_arguments`'s values (no figures, no fields), after
    meshing once into ``mesh_out`` so that no timed run pays for gmsh (the mesh cache serves them)."""
    import sys

    sets = ["--set", f"time.end={args.end!r}", "--set", "outputs.figures=false", "--set", "outputs.xdmf=false"]
    mesh_sets = []
    for field, value in (("model.h_far", args.h_far), ("model.h_contact", args.h_contact),
                         ("model.zone_radius", args.zone)):
        if value > 0:
            mesh_sets += ["--set", f"{field}={value!r}"]
    subprocess.run([sys.executable, "-m", "millimpact.cli", "mesh", "liner-panel", *mesh_sets, "--out", str(mesh_out)],
                   cwd=root, check=True, stdout=subprocess.DEVNULL)
    return sets + mesh_sets

