"""``millimpact export``'s work per DEM code: the code it needs, LAMMPS' mdr law, ``--check``.

``--check`` runs the exported file in the code it was exported to, one ball per table point
(:mod:`.roundtrip` for Yade, :mod:`.liggghts`, :mod:`.lammps`), and writes ``roundtrip.csv`` and
``roundtrip.png``; LAMMPS with the mdr model also gets ``contact_law_lammps_mdr.in`` (its yield
stress fitted to the table's e_n, :mod:`.mdr_fit`) and, checked, ``roundtrip_mdr.csv`` / ``.png``.
A code that is not installed is refused before any output (one line: how to install it).
"""

from __future__ import annotations

import shutil
from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np

from ...errors import InputError
from .files import BAND_E_N, BAND_F_MAX, ExportedLaw

#: the name a code's runs are reported under
RUNNER = {"yade": "Yade", "liggghts": "LIGGGHTS", "lammps": "LAMMPS"}


def require_code(code: str, check: bool) -> None:
    """InputError (one line, with the install command) when ``--check`` needs a code that is absent."""
    if not check:
        return
    if code == "yade":
        from ..yade import yade_executable

        yade_executable()
    elif code == "liggghts":
        from .liggghts import liggghts_executable

        liggghts_executable()
    else:
        from .lammps import lammps_executable

        lammps_executable()


def extra_law_files(code: str, law: ExportedLaw, stage: Path, talk: Callable[..., None]) -> list[Path]:
    """LAMMPS: the mdr law where the installed LAMMPS has it (else a line saying why not)."""
    if code != "lammps":
        return []
    from .lammps import INSTALL_HINT, has_mdr, lammps_executable
    from .mdr_fit import fit_mdr, write_lammps_mdr

    try:
        exe = lammps_executable()
    except InputError:
        talk(f"  mdr (plastic) law not written: LAMMPS is not installed; install it with: {INSTALL_HINT}")
        return []
    if not has_mdr(exe):
        talk(f"  mdr (plastic) law not written: {exe} has no mdr normal model (LAMMPS 22 Jul 2025 has it)")
        return []
    talk("  LAMMPS mdr: fitting the yield stress to the table's e_n")
    work = stage / "lammps_mdr_fit"
    mdr = fit_mdr(law.table, work, on_progress=lambda line: talk(f"    {line}"))
    shutil.rmtree(work)
    fitted = "normal-incidence points" if not mdr.fitted.all() else "points"
    talk(
        f"  LAMMPS mdr: yield stress {mdr.yield_stress:.4g} Pa, eta_n0 {mdr.damping:.3g}; e_n residual at the table's "
        f"{fitted}: largest {mdr.worst:.4f} ({mdr.worst_between:.4f} with the speeds between), rms {mdr.rms:.4f}"
    )
    if not mdr.fitted.all():
        talk(f"  LAMMPS mdr: at the oblique points (not fitted, no normal law follows them): {mdr.worst_oblique:.4f}")
    return [write_lammps_mdr(stage, law, mdr)]


def _errors(rows: Sequence[dict], vn: np.ndarray, band) -> str:
    de = np.array([abs(r["restitution_normal_dem"] - r["restitution_normal_table"]) for r in rows])
    df = np.array([abs(r["peak_normal_force_N_dem"] / r["peak_normal_force_N_table"] - 1) for r in rows])
    text = f"largest |e_n difference| {de.max():.4f}, largest F_max difference {100 * df.max():.2f} %"
    if band is not None:
        inside = (vn >= band[0]) & (vn <= band[1])
        text += (
            f"; in its band ({band[0]:.3g}-{band[1]:.3g} m/s, {int(inside.sum())} points): {de[inside].max():.4f}"
            f" and {100 * df[inside].max():.2f} % (held to {BAND_E_N} and {BAND_F_MAX:.0%})"
        )
    return text


def run_check(code: str, law: ExportedLaw, files: Sequence[Path], stage: Path, talk: Callable[..., None]) -> list[str]:
    """``--check``: the exported files run in ``code``; the names of the files written."""
    from .roundtrip import roundtrip_rows, write_roundtrip

    t = law.table
    vn = t.normal_speed.ravel()
    progress = lambda line: talk(f"    {line}")  # noqa: E731
    talk(f"  --check: {RUNNER[code]}, one ball per table point ({t.e_n.size})")
    if code == "yade":
        from .roundtrip import run_roundtrip

        (stage / "yade_check").mkdir()
        res = run_roundtrip(law, stage / "yade_check", "law", files[0], on_progress=progress)
    elif code == "liggghts":
        from .liggghts import run_liggghts_roundtrip

        res = run_liggghts_roundtrip(law, files[0], stage / "liggghts_check", on_progress=progress)
    else:
        from .lammps import run_lammps_roundtrip

        res = run_lammps_roundtrip(law, files[0], stage / "lammps_check", on_progress=progress)
    rows = roundtrip_rows(t, res)
    write_roundtrip(stage, t, rows, code, RUNNER[code])
    talk(f"  {RUNNER[code]} against the table: {_errors(rows, vn, None if code == 'yade' else law.band)}")
    written = ["roundtrip.csv", "roundtrip.png"]
    mdr_file = next((f for f in files if f.name == "contact_law_lammps_mdr.in"), None)
    if mdr_file is not None:
        from .lammps import run_lammps_roundtrip

        rows = roundtrip_rows(t, run_lammps_roundtrip(law, mdr_file, stage / "lammps_mdr_check", on_progress=progress))
        write_roundtrip(stage, t, rows, "lammps mdr", "LAMMPS (mdr)", stem="roundtrip_mdr")
        talk(f"  LAMMPS mdr against the table: {_errors(rows, vn, None)}")
        written += ["roundtrip_mdr.csv", "roundtrip_mdr.png"]
    return written
