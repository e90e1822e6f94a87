"""Shared helpers of the demos: the study demos' command line (full size by default, ``--small`` for a
quick check), one millimpact command run in-process, the figure backend."""
from __future__ import annotations

import argparse
from pathlib import Path

#: reduced size: the first and last value of the study, the impact only (the longest pulse, r = 25 mm
#: at 3 m/s, lasts 0.15 ms), no per-case figures, the ~10x faster traditional method
SMALL = dict(subset=(0, 2), end=2e-4, case_figures=False, method="traditional")


def parse(name: str, doc: str, argv=None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=doc.splitlines()[0])
    p.add_argument("--small", action="store_true", help="reduced size: 2 cases, 0.2 ms impacts (~1 min)")
    p.add_argument("--out", type=Path, help=f"output folder (default out/study-{name}[-small], as "
                                            f"'millimpact study {name}': the two share the case cache)")
    p.add_argument("--jobs", type=int, default=1, help="cases computed at the same time (processes)")
    args = p.parse_args(argv)
    if args.out is None:
        args.out = Path("out") / f"study-{name}{'-small' if args.small else ''}"
    return args


def run(name: str, args: argparse.Namespace):
    """The built-in study ``name`` at full or reduced size; returns millimpact.studies.study.StudyResult."""
    from millimpact.studies.study import run_study

    res = run_study(name, out=args.out, jobs=args.jobs, **(SMALL if args.small else {}))
    if res.failed:
        raise SystemExit(f"{len(res.failed)} case(s) failed: {res.failed[0].error}")
    return res


def column(res, key: str):
    """One peak (SI) over the cases, in parameter order, and the parameter values."""
    import numpy as np

    a = res.analysis
    return a.x, np.array([p[key] for p in a.peaks])


def exponent(x, y) -> float:
    """k of y ~ x^k, least squares in log-log."""
    import numpy as np

    return float(np.polyfit(np.log(x), np.log(y), 1)[0])


def millimpact(*args: str) -> None:
    """Run one ``millimpact`` command in this process (as typed after ``millimpact``; its figures and
    files go where its ``--out`` says); a failed command stops the demo with its exit status."""
    from millimpact.cli import main

    code = main([str(a) for a in args])
    if code != 0:
        raise SystemExit(f"millimpact {' '.join(map(str, args))}: exit status {code}")


def figure_backend():
    """matplotlib's pyplot on the file-only backend the package's figures use (the demos write
    PNGs, never open a window)."""
    from millimpact.results.plots import pyplot

    return pyplot()
