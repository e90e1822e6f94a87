"""Repeated impacts at one spot (``millimpact repeat``): restitution, plastic work and the dent impact by impact.

A liner is struck at the same places again and again. ``millimpact repeat`` runs N impacts of the
scene's ball at one spot, each starting from the residual state the previous one left (plastic
strain, hardening, residual stress, and the dent the next contact sees). Here: the forged ball on
the Cr-Mo block of paper-rig-plastic at 3 m/s. The first impact dents the block; the dent's
conforming shape, the residual stress and the hardening then carry more of each following impact
elastically, so the plastic work falls impact by impact and the restitution rises towards the
elastic rig's: the block shakes down (Johnson, Contact Mechanics, 1985, ch. 9). The command's
verdict (elastic shakedown, plastic shakedown, ratcheting or undecided) reads the same numbers.

The demo runs the sequence, and the elastic twin of one impact (both steels elastic) for the
restitution the sequence tends to, and checks impact by impact:

- the plastic work falls and the dent's growth slows (the shakedown trend);
- the plastic work stays within the ball's lost kinetic energy, (1 - e^2) of the impact energy
  (the rest is the bodies' vibration: energy conservation, exact);
- the restitution rises and stays below the elastic rig's.

``shakedown.png`` shows the plastic work and the dent's growth per impact on a log scale;
``restitution.png`` and ``dent.png`` are the command's own.

    .venv/bin/python demos/repeated_impacts.py            # full size: 10 impacts at the plan's mesh
    .venv/bin/python demos/repeated_impacts.py --small    # 6 impacts on a coarse mesh (h_contact 0.8 mm)
"""
import argparse
import json
import sys
from pathlib import Path

from _common import figure_backend, millimpact

#: the quick variant: a coarse mesh (h_contact 0.8 mm ~ a_max / 1.4, h_far 12 mm; the repeat
#: command's tests use it) and the impact only for the elastic twin (t_c ~ 82 us)
COARSE = [("model.h_contact", 8e-4), ("model.h_far", 0.012)]
ELASTIC = [("ball.material.yield_stress", None), ("ball.material.hardening_modulus", 0.0),
           ("block.material.yield_stress", None), ("block.material.hardening_modulus", 0.0),
           ("time.end", 2e-4)]


def shakedown_figure(path: Path, rows: list[dict]) -> None:
    """Plastic work per impact and the dent's growth per impact, log scale."""
    plt = figure_backend()
    k = [r["impact"] for r in rows]
    w = [r["plastic_dissipation_J"] * 1e3 for r in rows]
    dents = [0.0] + [r["residual_dent_depth_m"] * 1e6 for r in rows]
    growth = [b - a for a, b in zip(dents, dents[1:])]
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    ax.semilogy(k, w, "o-", label="plastic work of the impact (mJ)")
    ax.semilogy(k, growth, "s--", label="dent growth in the impact (um)")
    ax.set_xlabel("impact number")
    ax.set_xticks(k)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend()
    ax.set_title("repeated impacts at one spot: towards shakedown")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


if __name__ == "__main__":
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--small", action="store_true", help="reduced size: 6 impacts, coarse mesh (~30 s)")
    p.add_argument("--out", type=Path, help="output folder (default out/demo-repeated-impacts[-small])")
    args = p.parse_args()
    out = args.out or Path("out") / f"demo-repeated-impacts{'-small' if args.small else ''}"
    n = 6 if args.small else 10
    sets = [a for field, value in (COARSE if args.small else []) for a in ("--set", f"{field}={value!r}")]

    # the sequence: the command a user types, run in this process
    millimpact("repeat", "paper-rig-plastic", "--impacts", n, "--velocities", 3, *sets, "-q", "--out", out)
    summary = json.loads((out / "summary.json").read_text())
    rows, details = summary["outcomes"], summary["details"]

    # the elastic twin: one impact with both steels elastic on the same mesh sizes
    from millimpact.methods.run import run_scene
    from millimpact.scene.builtin import resolve_scene

    twin = resolve_scene("paper-rig-plastic").with_values((COARSE if args.small else []) + ELASTIC)
    e_el = run_scene(twin, "improved", out / "elastic", progress=sys.stderr.isatty())["restitution"]

    print(f"paper-rig-plastic, {n} impacts at 3 m/s, improved -> {out}/")
    print(" impact  e_n    W_p (mJ)  W_p / lost energy  dent (um)  growth (um)")
    dent_before, growth, share = 0.0, [], []
    for r, d in zip(rows, details):
        e, w, dent = r["restitution_normal"], r["plastic_dissipation_J"], r["residual_dent_depth_m"]
        lost = (1 - e**2) * d["impact_energy_J"]
        growth.append(dent - dent_before)
        share.append(w / lost)
        print(f" {r['impact']:6d}  {e:.4f}  {w * 1e3:8.2f}  {w / lost:17.3f}  {dent * 1e6:9.2f}  "
              f"{growth[-1] * 1e6:11.3f}")
        dent_before = dent
    v = summary["verdict"]
    print(f"elastic twin's restitution {e_el:.4f}; verdict: {v['kind']} ({v['numbers'].get('reason', '')})")
    shakedown_figure(out / "shakedown.png", rows)

    e = [r["restitution_normal"] for r in rows]
    w = [r["plastic_dissipation_J"] for r in rows]
    # Johnson (1985) ch. 9: residual stress, hardening and the conforming dent carry each next
    # impact more elastically; the falls are tens of percent an impact, far above the ~0.03 %
    # energy error of one impact (the summary's energy_drift_over_impact_rel)
    assert all(b < a for a, b in zip(w, w[1:])), w
    assert all(b < a for a, b in zip(growth, growth[1:])), growth
    assert all(b > a for a, b in zip(e, e[1:])), e
    # energy conservation: the plastic work is part of the kinetic energy the ball lost
    assert all(0 < s < 1 for s in share), share
    # the elastic twin loses only vibration: no plastic impact rebounds faster
    assert max(e) < e_el, (e, e_el)
    print(f"checks passed: plastic work {w[0] * 1e3:.1f} -> {w[-1] * 1e3:.2f} mJ, dent growth slowing, "
          f"e {e[0]:.3f} -> {e[-1]:.3f} < elastic {e_el:.3f}")
