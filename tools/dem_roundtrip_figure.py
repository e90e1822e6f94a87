"""The figure of docs/dem.md: a contact table against Yade with three inputs.

    .venv/bin/python tools/dem_roundtrip_figure.py TABLE_DIR docs/images/dem-roundtrip.png

Runs Yade (one ball on a wall per table point) with the exported per-interaction law
(``millimpact export --to yade``), the constant law LIGGGHTS and LAMMPS get, and the naive input
(the table's mean e_n as Yade's en, the materials' Young's modulus, Yade's default
NewtonIntegrator), and plots e_n and F_max against the normal impact speed.
"""
from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np

from millimpact.dem.export.files import fit_law, write_yade
from millimpact.dem.export.roundtrip import constant_law_file, roundtrip_rows, run_roundtrip
from millimpact.dem.export.table_input import read_table
from millimpact.results.plots import pyplot


def main(table_dir: str, png: str) -> None:
    law = fit_law(read_table(table_dir))
    t = law.table
    runs = {}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        runs["Yade, exported law (per interaction)"] = run_roundtrip(law, tmp / "law", "law", write_yade(tmp, law))
        (tmp / "const").mkdir()
        runs["Yade, constant law (LIGGGHTS, LAMMPS)"] = run_roundtrip(law, tmp / "const", "law",
                                                                      constant_law_file(law, tmp / "const" / "law.py"))
        runs["Yade, naive: en = mean e_n, default damping"] = run_roundtrip(law, tmp / "naive", "naive")
    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.3), constrained_layout=True)
    vn = t.normal_speed.ravel()
    order = np.argsort(vn)
    axes[0].plot(vn[order], t.e_n.ravel()[order], "ko-", lw=2, label=f"millimpact table ({t.scene_name}, {t.method})")
    axes[1].plot(vn[order], t.peak_force.ravel()[order] / 1e3, "ko-", lw=2, label="millimpact table")
    for (name, res), mk in zip(runs.items(), ("x", "s", "^")):
        rows = roundtrip_rows(t, res)
        e = np.array([r["restitution_normal_dem"] for r in rows])
        f = np.array([r["peak_normal_force_N_dem"] for r in rows]) / 1e3
        axes[0].plot(vn[order], e[order], mk + "--", ms=8, mfc="none", label=name)
        axes[1].plot(vn[order], f[order], mk + "--", ms=8, mfc="none", label=name)
    for ax, lab in zip(axes, ("normal restitution e_n", "peak normal force (kN)")):
        ax.set_xlabel("normal impact speed (m/s)")
        ax.set_ylabel(lab)
        ax.set_xscale("log")
        ax.grid(alpha=0.3, which="both")
    axes[0].legend(fontsize=7)
    fig.suptitle(f"the contact table of {t.scene_name} (impact speeds {', '.join(f'{s:g}' for s in t.speeds)} m/s x "
                 f"angles {', '.join(f'{a:g}' for a in t.angles)} deg) and Yade 2023.02a with three inputs")
    fig.savefig(png, dpi=110)
    for name, res in runs.items():
        rows = roundtrip_rows(t, res)
        print(f"{name}: largest |e_n - table| {max(abs(r['restitution_normal_dem'] - r['restitution_normal_table']) for r in rows):.4f}, "
              f"largest F_max error {100 * max(abs(r['peak_normal_force_N_dem'] / r['peak_normal_force_N_table'] - 1) for r in rows):.2f} %")


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
