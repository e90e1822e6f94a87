"""``millimpact export``: a contact table's law written for a DEM code, and checked in that code.

Reads a ``millimpact table`` folder (:mod:`.table_input`), fits the Hertz-dashpot law that gives
the table's e_n and F_max at each of its points in that code's own damping formula
(:mod:`millimpact.theory.hertz_dashpot`, :mod:`.files`; LAMMPS' plastic mdr law, :mod:`.mdr_fit`) and writes the
files to include. ``--check`` runs them in the code, one ball per table point, and writes
``roundtrip.csv`` and ``roundtrip.png`` (:mod:`.code_checks`).
"""

from __future__ import annotations

import argparse
from pathlib import Path

from ...results.output_folder import FORCE_HELP, OUT_HELP

HELP = "write a contact table's law for a DEM code (yade, liggghts, lammps); --check runs it in that code"

DESCRIPTION = """\
Write the contact parameters that make a DEM code's Hertz model reproduce a millimpact contact
table (the folder `millimpact table` wrote): the contact modulus that gives F_max, the damping
that gives e_n in that code's damping formula, friction and Mindlin's tangential stiffness.
Yade gets the whole table (a PyRunner sets each new ball-liner contact's law from its impact
speed and angle); LIGGGHTS and LAMMPS get one constant law and the speed band where it holds,
and LAMMPS with the mdr model also a plastic law whose yield stress fits the table's e_n.
With --check, the code itself runs the exported file for one ball at each of the table's speeds
and angles: roundtrip.csv and roundtrip.png compare e_n, e_t and F_max with the table.

Examples:
  millimpact export out/table-rig --to yade --out out/dem-yade --check
  millimpact export out/table-rig --to liggghts --out out/dem-liggghts --check
"""


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("table", metavar="TABLE_DIR", help="a folder written by millimpact table")
    p.add_argument("--to", required=True, metavar="CODE", help="the DEM code: yade, liggghts or lammps")
    p.add_argument("--out", help=OUT_HELP.format(default="out/dem-CODE-TABLE"))
    p.add_argument("--check", action="store_true", help="run the law in the code: roundtrip.csv and roundtrip.png")
    p.add_argument("--force", action="store_true", help=FORCE_HELP)
    p.add_argument("-q", "--quiet", action="store_true", help="no progress output")


def main(args: argparse.Namespace) -> int:
    from ...console import say, world_rank
    from ...errors import InputError
    from ...results.output_folder import claim_output, default_out
    from .code_checks import extra_law_files, require_code, run_check
    from .files import CODES, WRITERS, checked_lines, fit_law, write_law_json
    from .table_input import read_table

    code = str(args.to).lower()
    if code not in CODES:
        raise InputError(f"--to {args.to!r}: must be one of {', '.join(CODES)}")
    table = read_table(args.table)
    require_code(code, args.check)  # not installed: one line and exit 2, before any output
    out = args.out if args.out is not None else default_out(Path(args.table).resolve().name, prefix=f"dem-{code}-")
    target = claim_output(out, "export", force=args.force)  # before fitting: checks, lock, leftovers
    if world_rank() != 0:
        return 0  # a serial command: under mpirun rank 0 alone writes
    talk = (lambda *a: None) if args.quiet else say
    law = fit_law(table)
    with target.staged(collective=False) as stage:
        files = [WRITERS[code](stage, law), write_law_json(stage, law, code)]
        talk(
            f"export {code}: {len(table.speeds)} speeds x {len(table.angles)} angles of {table.folder} "
            f"(scene {table.scene_name}, method {table.method})"
        )
        for line in checked_lines(table, " "):
            talk(line)
        if law.band:
            talk(f"  constant law (LIGGGHTS/LAMMPS): valid for normal speeds {law.band[0]:.3g}-{law.band[1]:.3g} m/s")
        files[1:1] = extra_law_files(code, law, stage, talk)
        checked = run_check(code, law, files, stage, talk) if args.check else []
    talk(
        f"  results in {target.shown}/ ({', '.join(f.name for f in files)}"
        f"{''.join(', ' + name for name in checked)})" + target.replaced_note()
    )
    return 0
