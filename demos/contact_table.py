"""A DEM contact table (``millimpact table``, ``export``): restitution and force over speed and angle, the law in Yade.

A discrete-element model of a mill needs, for every ball-liner contact, how much of the normal
speed comes back (the restitution e_n) and how hard the contact pushes (the peak force) at that
contact's impact speed and angle. ``millimpact table`` runs one finite-element impact per (speed,
angle) of a scene and writes the table with its fitted laws; ``millimpact export --to yade``
turns it into contact parameters for Yade's Hertz-Mindlin law, and ``--check`` runs them in Yade
(one ball on a wall per table point) to compare with the table.

The scene: paper-rig-plastic with its block clamped at its back face (a half-space-like target:
no cantilever bending to take energy), the forged ball on the Cr-Mo block, whose yield onset
speed is V_y = 0.12 m/s (Thornton 1997, eq. 13): every speed here yields. The demo checks each
point against the two closed-form limits that bracket it, at its normal speed:

- restitution: above Thornton's (1997) e(V) (his flat-topped pressure, capped at the first-yield
  pressure 1.6 Y, over-dissipates: a lower bound) and below 1 (Hertz, elastic);
- peak force: above Thornton's loading law's force at his largest approach (the same capped
  pressure) and below Hertz's elastic peak force;
- the round trip (where ``yade`` is installed): Yade's e_n within 0.02 and peak force within 5 %
  of the table's (the export's tolerances, docs: DEM codes).

The full size adds Coulomb friction mu = 0.2 (steel on wet steel, as the liner scenes), which gives
the oblique impacts a tangential restitution e_t; the quick variant is frictionless (e_t = 1: the
friction's sticking phase costs it ~3x the time). ``e_n_speed.png``, ``e_t_angle.png`` and ``force_speed.png`` are the
table's figures, ``roundtrip.png`` the Yade check's (the table's points and Yade's side by side).

    .venv/bin/python demos/contact_table.py            # full size: 5 speeds x 3 angles at the plan's mesh
    .venv/bin/python demos/contact_table.py --small    # 3 speeds x 2 angles, coarse mesh (h_contact 0.6 mm)
"""
import argparse
import csv
import json
import math
import shutil
from pathlib import Path

from _common import millimpact

#: the half-space-like rig: the block clamped at its back face
BACK = ["--set", "block.support=back"]
#: the full size's Coulomb friction (the liner scenes')
FRICTION = ["--set", "contact.friction=0.2"]
#: the quick variant's coarse mesh (h_contact 0.6 mm ~ a_max / 1.2 at 1 m/s, a_max / 2.3 at 4 m/s)
COARSE = ["--set", "model.h_contact=6e-4", "--set", "model.h_far=0.012"]


def read_rows(path: Path) -> list[dict]:
    """The rows of a millimpact CSV (its '#' header lines skipped), numbers as floats."""
    with open(path) as fh:
        rows = list(csv.DictReader(line for line in fh if not line.startswith("#")))
    return [{k: (v if k == "status" else float(v)) for k, v in r.items()} for r in rows]


if __name__ == "__main__":
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--small", action="store_true", help="reduced size: 6 impacts on a coarse mesh (~1 min)")
    p.add_argument("--out", type=Path, help="output folder (default out/demo-contact-table[-small])")
    args = p.parse_args()
    out = args.out or Path("out") / f"demo-contact-table{'-small' if args.small else ''}"
    speeds, angles = ("1,2,4", "0,30") if args.small else ("0.5,1,2,4,8", "0,30,60")

    # the table: the figures (e_n_speed.png, e_t_angle.png, force_speed.png) land in OUT itself
    millimpact("table", "paper-rig-plastic", "--velocity", speeds, "--angle", angles, *BACK,
               *(COARSE if args.small else FRICTION), "-q", "--out", out)
    rows = read_rows(out / "contact_table.csv")
    laws = json.loads((out / "contact_laws.json").read_text())

    from millimpact.scene.builtin import resolve_scene
    from millimpact.theory.hertz import effective_modulus, hertz_impact
    from millimpact.theory.thornton import (FIRST_YIELD_PRESSURE_FACTOR, max_approach_thornton,
                                            restitution_thornton, yield_onset_velocity)

    scene = resolve_scene("paper-rig-plastic")
    ball, block = scene.ball.material, scene.block.material
    radius = scene.ball.radius
    mass = ball.density * 4 / 3 * math.pi * radius**3
    e_star = effective_modulus(ball, block)
    p_y = FIRST_YIELD_PRESSURE_FACTOR * block.yield_stress    # the softer body yields first
    v_y = yield_onset_velocity(block.yield_stress, e_star, ball.density)
    print(f"paper-rig-plastic (block clamped at its back), {len(rows)} impacts -> {out}/")
    print(f"  V_y {v_y:.3f} m/s; fitted e_n = {laws['restitution_power_law']['A']:.3f} "
          f"v_n^{laws['restitution_power_law']['k']:.3f}")
    print("  v (m/s) angle  v_n    e_n   Thornton  F_max (kN)  Thornton  Hertz")
    for r in rows:
        v_n = r["normal_velocity_in_m_s"]
        e_th = restitution_thornton(v_n, v_y)
        f_hertz = hertz_impact(radius, mass, v_n, e_star).force_max
        # Thornton's loading law at his largest approach: F = F_y + pi p_y R (delta - delta_y)
        d_y = radius * (math.pi * p_y / (2 * e_star)) ** 2
        f_y = 4 / 3 * e_star * radius**0.5 * d_y**1.5
        f_th = f_y + math.pi * p_y * radius * (max_approach_thornton(radius, mass, v_n, e_star, p_y) - d_y)
        r.update(e_th=e_th, f_th=f_th, f_hertz=f_hertz)
        print(f"  {r['impact_speed_m_s']:7.2f} {r['impact_angle_deg']:5.0f} {v_n:5.2f}  {r['restitution_normal']:.3f}"
              f"  {e_th:.3f}     {r['peak_normal_force_N'] / 1e3:7.2f}    {f_th / 1e3:6.2f}  {f_hertz / 1e3:6.2f}")

    for r in rows:
        # Thornton over-dissipates (a lower bound: Wu, Li & Thornton 2005); Hertz is elastic, e = 1
        assert r["status"] == "ok" and r["e_th"] < r["restitution_normal"] < 1, r
        # the capped pressure 1.6 Y < the FE's mean pressure (up to ~3 Y, Johnson 1985 6.2) < Hertz's
        assert r["f_th"] < r["peak_normal_force_N"] < r["f_hertz"], r
    print("checks passed: every point between Thornton's and Hertz's restitution and peak force")

    # the law for Yade, and its round trip where Yade is installed
    law = out / "yade-law"
    check = ["--check"] if shutil.which("yade") else []
    millimpact("export", out, "--to", "yade", *check, "-q", "--out", law)
    if not check:
        print("yade is not installed (apt-get install yade): the round trip was left out")
    else:
        trip = read_rows(law / "roundtrip.csv")
        de = max(abs(t["restitution_normal_dem"] - t["restitution_normal_table"]) for t in trip)
        df = max(abs(t["peak_normal_force_N_dem"] / t["peak_normal_force_N_table"] - 1) for t in trip)
        shutil.copy2(law / "roundtrip.png", out / "roundtrip.png")
        print(f"Yade with the exported law ({law.name}/contact_law_yade.py): e_n within {de:.2g}, "
              f"peak force within {100 * df:.2g} %")
        # the export's tolerances (tests/dem/test_export.py): 0.02 in e_n, 5 % in F_max
        assert de < 0.02 and df < 0.05, (de, df)
        print("checks passed: the exported law reproduces the table in Yade")
