"""Liner life from a SAG charge (``millimpact mill --charge sag``, ``millimpact life``): where the liner is lost, and how fast.

A SAG mill's charge is mostly rock; the balls are a tenth of the mill's volume. ``millimpact mill
--charge sag`` fills a slice of the mill with balls and rock (a size distribution above a cut-off,
rolling resistance for the rock's shape) and logs, beside every impact on the liner, the sliding
of every particle over it: the friction work and Archard's integral int F_n ds per place and
position along the lifter's profile (abrasion.csv). ``millimpact life`` turns both into the steel
lost per 1000 h (Archard's law for the sliding, an impact-energy law for the impacts), calibrated
on one measured figure of one mill: here a lifter's height loss as a first-order decay.

The demo runs the mill and the life, and checks:

- the charge is what was asked: the particles' volume gives back the fills (J and J_B) within 2 %
  and 5 % (whole particles), the balls a tenth of the particles' volume or so;
- the sliding at the liner is part of the energy balance: the friction work at the liner that
  abrasion.csv logs after the warm-up is positive and below the whole run's friction at the liner;
- the calibration gives its figure back: the calibrated law's rate of height loss of the new lifter
  (the top's wear less the plate's) is the first-order decay's initial rate, H0 ln(H0/H1) / T;
- the masses add up: wear.csv's mass rates sum to the surfaces' in summary.json.

``wear.png`` is the wear along a lifter's profile (abrasion and impact), ``charge.png`` the balls
and rock in the mill with the shoulder and the toe.

    .venv/bin/python demos/liner_life.py            # full size: liner-panel's 11 m mill, 1 revolution (~1 h)
    .venv/bin/python demos/liner_life.py --small    # a 0.8 m mill, 0.3 revolution after 0.3 (~40 s)
"""
import argparse
import csv
import json
import math
import shutil
from pathlib import Path

from _common import millimpact

#: the tests' small mill: 0.8 m across, 17 lifters 50 mm high, 60 mm balls, rock 30-60 mm
SMALL_MILL = ["liner-segment", "--set", "liner.width=0.3", "--set", "liner.thickness=0.04",
              "--set", "liner.lifter_height=0.05", "--set", "liner.lifter_top_width=0.03",
              "--set", "liner.lifter_spacing=0.15", "--set", "liner.mill_radius=0.4", "--set", "ball.radius=0.03",
              "--set", "contact.friction=0.3"]

if __name__ == "__main__":
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--small", action="store_true", help="a 0.8 m mill, 0.3 revolution after 0.3 (~40 s)")
    p.add_argument("--out", type=Path, help="output folder (default out/demo-liner-life[-small])")
    args = p.parse_args()
    out = args.out or Path("out") / f"demo-liner-life{'-small' if args.small else ''}"
    if args.small:
        scene = SMALL_MILL
        mill_args = ["--rock-top-size", 0.06, "--rock-cutoff", 0.03, "--stiffness-scale", 0.001, "--fill", 0.3,
                     "--revolutions", 0.3, "--warmup", 0.3]
        h0, h1, hours = 50.0, 30.0, 2000.0
        reline = ["--reline-height", 20, "--reline-plate", 10]
    else:
        scene = ["liner-panel"]
        mill_args = ["--revolutions", 1]
        h0, h1, hours = 180.0, 70.0, 4000.0
        reline = []
    millimpact("mill", *scene, "--charge", "sag", *mill_args, "--force", "--out", out / "mill")
    millimpact("life", *scene, "--mill", out / "mill", "--calibrate-height", f"{h0:g}:{h1:g}:{hours:g}", *reline,
               "--force", "--out", out / "life")
    for src in (out / "life" / "wear.png", out / "mill" / "charge.png"):
        shutil.copy(src, out / src.name)
    m = json.loads((out / "mill" / "summary.json").read_text())
    life = json.loads((out / "life" / "summary.json").read_text())
    asked = 0.3 if args.small else 0.28
    fills = m["power"]["model_inputs"]
    at_liner = m["energy_balance"]["dissipated_by_kind_J"]["friction_at_liner"]
    logged = m["abrasion"]["friction_work_J_per_revolution"] * m["clock"]["revolutions"]
    rates = life["rates"][0]
    model = rates["top"]["mean_mm_per_1000h"] - rates["plate"]["mean_mm_per_1000h"]
    decay = h0 * math.log(h0 / h1) / hours * 1000.0
    with open(out / "life" / "wear.csv") as fh:
        mass = sum(float(r["mass_kg_per_1000h"]) for r in csv.DictReader(fh))
    per_metre = sum(r["mass_kg_per_1000h_per_metre"] for r in rates.values())
    print(f"mill: D {m['mill']['diameter_m']:g} m, {m['charge']['balls']} balls and {m['charge']['rocks']} rocks; "
          f"J {fills['fill']:.3f} (asked {asked}), J_B {fills['ball_fill']:.3f} (asked 0.12)")
    print(f"  net power {m['power']['measured']['net_per_metre_W_m'] / 1e3:.3g} kW/m, Morrell "
          f"{m['power']['morrell_net_per_metre_W_m'] / 1e3:.3g} kW/m; shoulder {m['shoulder_deg']} deg, toe {m['toe_deg']} deg")
    print(f"  friction at the liner: {logged:.4g} J logged after the warm-up, {at_liner:.4g} J over the whole run; "
          f"{100 * (m['charge']['ball_contacts_on_rock_share'] or 0):.0f} % of the balls' contacts land on rock")
    for name, r in rates.items():
        print(f"  {name}: {r['mean_mm_per_1000h']:.3g} mm per 1000 h (largest {r['largest_mm_per_1000h']:.3g}), "
              f"abrasion {100 * r['abrasion_share']:.0f} %, impact {100 * r['impact_share']:.0f} %")
    print(f"  height loss of the new lifter {model:.4g} mm per 1000 h; the decay {h0:g} -> {h1:g} mm in {hours:g} h "
          f"starts at {decay:.4g}; relining after {life['relining']['hours']:.0f} h ({life['relining']['criterion']})")

    # whole particles: one ball is ~3 % of the small mill's balls, one rock far less of the whole
    assert abs(fills["fill"] / asked - 1) < 0.02 and abs(fills["ball_fill"] / 0.12 - 1) < 0.05, fills
    assert 0 < logged < at_liner, (logged, at_liner)
    # the calibration is exact arithmetic on the first run's rates: to rounding
    assert abs(model / decay - 1) < 1e-9, (model, decay)
    assert abs(mass / m["mill"]["slice_thickness_m"] / per_metre - 1) < 1e-9, (mass, per_metre)
    print("checks passed: the fills, the friction at the liner within the run's, the calibration, the masses")
