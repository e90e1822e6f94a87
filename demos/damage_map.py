"""The liner's damage map (``millimpact damage``): energy, plastic work and dent growth per place and revolution.

``millimpact mill`` logs every ball-liner impact of a mill in Yade; ``millimpact damage`` turns
that log into what the liner suffers. It sorts the impacts by place (lifter face, lifter top,
plate), normal speed and angle into bins, computes each bin's representative impact with the
finite-element table engine on the liner scene (the impact moved to the bin's place on the
lifter), and sums per revolution and per lifter: the impacts' energy, the energy the liner
absorbs, the plastic work and (with ``--repeat-impacts``) the dent's growth under repeated
impacts at each place. The model stops at small strain, removes no material (no wear) and has no
fatigue cracking.

The demo makes its own small log (the quick variant: 20 balls from rest in liner-segment's mill
for a tenth of a revolution), maps it and checks:

- the energy adds up: each bin's representative speeds are the root-mean-square speeds of its
  impacts, so its kinetic energy is their mean, and the sum over bins (those the finite-element
  side refused, beside an edge it cannot place a contact at, included) of (impacts per revolution
  x that energy) is the log's total impact energy per revolution and lifter, which the mill command
  counted on its own (its summary) - to rounding;
- each computed bin absorbs at most its impacts' energy, and its plastic work is at most what it
  absorbs (energy conservation).

``damage_map.png`` is the command's map (the liner profile coloured by the plastic work per
revolution and metre of arc, and the impact spectrum per place); ``energy_per_place.png`` sets
the impact energy, the energy absorbed and the plastic work per revolution side by side.

    .venv/bin/python demos/damage_map.py            # full size: 200 balls, 2 revolutions, 6 repeated impacts
    .venv/bin/python demos/damage_map.py --small    # 20 balls, 0.1 revolution, 4 bins on a coarse mesh
"""
import argparse
import json
import math
from pathlib import Path

from _common import figure_backend, millimpact

#: the quick variant: at most 4 bins on a coarse mesh (h_contact 4 mm ~ a_max / 1.6 for the 125 mm
#: ball at 8 m/s), no repeated impacts
SMALL = ["--max-bins", 4, "--repeat-impacts", 0, "--set", "model.h_contact=0.004", "--set", "model.h_far=0.04"]


def energy_figure(path: Path, places: dict) -> None:
    """Per place: impact energy, energy absorbed and plastic work per revolution and lifter (bars)."""
    plt = figure_backend()
    names = list(places)
    keys = [("impact_energy_J_per_rev", "impact energy"), ("energy_absorbed_J_per_rev", "absorbed"),
            ("plastic_work_J_per_rev", "plastic work")]
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    for j, (key, label) in enumerate(keys):
        ax.bar([i + 0.27 * (j - 1) for i in range(len(names))], [places[n][key] for n in names], 0.27, label=label)
    ax.set_xticks(range(len(names)))
    ax.set_xticklabels([n.replace("_", " ") for n in names])
    ax.set_ylabel("J per revolution and lifter")
    ax.legend()
    ax.set_title("where the impacts' energy goes, per place")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


if __name__ == "__main__":
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--small", action="store_true", help="reduced size: a small log, 4 coarse bins (~1 min)")
    p.add_argument("--out", type=Path, help="output folder (default out/demo-damage-map[-small])")
    args = p.parse_args()
    out = args.out or Path("out") / f"demo-damage-map{'-small' if args.small else ''}"

    # the log: a mill run of its own (its summary.json beside impacts.csv gives the revolutions and
    # lifters the damage command folds the log with)
    mill = out / "mill"
    millimpact("mill", "liner-segment", *(["--balls", 20, "--revolutions", 0.1, "--warmup", 0] if args.small
                                          else ["--balls", 200, "--revolutions", 2]), "--no-plots", "--out", mill)
    millimpact("damage", "liner-segment", "--impacts", mill / "impacts.csv", *(SMALL if args.small else []),
               "-q", "--out", out / "map")
    ms = json.loads((mill / "summary.json").read_text())
    d = json.loads((out / "map" / "damage.json").read_text())

    from millimpact.scene.builtin import resolve_scene

    ball = resolve_scene("liner-segment").ball
    mass = ball.material.density * 4 / 3 * math.pi * ball.radius**3
    lifters = ms["mill"]["lifters"]
    total_log = ms["energy_per_revolution_J"]["all"] / lifters
    per_rev = 1 / (d["revolutions"] * d["lifters"])     # one impact's rate, per revolution and lifter
    total_bins = sum(b["impacts"] * per_rev * 0.5 * mass * (b["normal_speed_m_s"]**2 + b["tangential_speed_m_s"]**2)
                     for b in d["bins"])
    print(f"liner-segment: {d['impacts']} impacts over {d['revolutions']:g} revolution(s) and {lifters} lifters, "
          f"{len(d['bins'])} bins, method {d['method']} -> {out}/")
    print("  place        impacts/rev  impact energy  absorbed  plastic work  (J per revolution and lifter)")
    for name, pl in d["places"].items():
        print(f"  {name:12s} {pl['impacts_per_rev']:11.2f}  {pl['impact_energy_J_per_rev']:13.2f}  "
              f"{pl['energy_absorbed_J_per_rev']:8.3f}  {pl['plastic_work_J_per_rev']:12.3f}"
              f"  ({pl['bins_computed']} of {pl['bins']} bins computed)")
    print(f"  impact energy per revolution and lifter: {total_log:.4f} J from the mill's summary, "
          f"{total_bins:.4f} J as the sum over bins of rate x energy")
    for name in ("damage_map.png",):
        (out / name).write_bytes((out / "map" / name).read_bytes())
    energy_figure(out / "energy_per_place.png", d["places"])

    # the RMS representative makes the sum exact; 1e-9 is floating-point rounding over ~100 impacts
    assert abs(total_bins / total_log - 1) < 1e-9, (total_bins, total_log)
    assert abs(sum(pl["impact_energy_J_per_rev"] for pl in d["places"].values()) / total_log - 1) < 1e-9
    computed = [b for b in d["bins"] if b["status"] == "ok"]
    assert computed, "no bin was computed"
    for b in computed:
        assert abs(b["impacts_per_rev"] / (b["impacts"] * per_rev) - 1) < 1e-12, b
        e_in = b["impacts_per_rev"] * 0.5 * mass * (b["normal_speed_m_s"]**2 + b["tangential_speed_m_s"]**2)
        # energy conservation; 1e-9 J of slack for the elastic bins' rounding (absorbed ~ +-1e-10 J)
        assert -1e-9 <= b["plastic_work_J_per_rev"] <= b["energy_absorbed_J_per_rev"] + 1e-9 <= e_in + 2e-9, b
    print("checks passed: the bins add up to the log's impact energy; absorbed <= impact energy, "
          "plastic work <= absorbed")
