"""What a lifter's top corners take in each step of a life: the edges' wear against the faces'.

    .venv/bin/python benchmarks/liner_life_corners.py OUT [--cycles 4]

OUT is a folder of ``benchmarks/liner_life.py`` (finished or interrupted: its first mill run and
the mill re-runs its life kept). The life's steps are redone as ``millimpact life
--calibrate-life 152:58:4000 --cycles N`` made them (equal falls of the height, the kept runs in
order; the profiles do not depend on the constants' scale, only the hours do). Per mill run it
prints the profile it ran on (height, face angles, chamfer legs, flat top), each face's turn in
the step that follows, the mean depth of the bins at each top corner (the chamfer's and the one
beside it on each side, :func:`millimpact.life.profile.corner_bins`) over its face's mean, and the
share of the lifter's wear the corners take (what cuts the chamfers; it is left out of the face
lines and the top's mean).
"""
from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np
from liner_life import SCENE

from millimpact.commandkit.settings import command_scene
from millimpact.life.calibration import DEFAULT_LAW
from millimpact.life.loop import run_life
from millimpact.life.profile import LifterProfile, corner_bins
from millimpact.life.wear import depth_rates, read_mill_record, surface_depths


class _NotKept(Exception):
    """The life's next mill run is not in OUT yet."""


def _corner_figures(lp: LifterProfile, rec) -> tuple[float, float, float]:
    """(the trailing corner's mean bin depth over the trailing face's, the same leading, the
    corners' share of the lifter's wear) of the run ``rec`` on the profile ``lp``."""
    depths = surface_depths(rec, depth_rates(rec, DEFAULT_LAW), 1.0)
    bt, tt, tl, bl = lp.corners()
    bins = corner_bins(lp, depths, rec.bin_m, (math.dist(bt, tt), math.dist(tl, bl)))
    ratios = [
        bins.corners[k] / max(bins.corner_bins[k], 1) / max(float(np.mean(face[1])), 1e-30)
        for k, face in enumerate((bins.trailing_face, bins.leading_face))
    ]
    lifter = sum(float(depths[s][1].sum()) for s in ("trailing_face", "top", "leading_face"))
    return ratios[0], ratios[1], sum(bins.corners) / max(lifter, 1e-30)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path, help="a folder of benchmarks/liner_life.py")
    ap.add_argument("--cycles", type=int, default=4)
    a = ap.parse_args()
    scene = command_scene(SCENE[0], [s for s in SCENE[1:] if s != "--set"])
    r = scene.ball.radius
    profiles = [LifterProfile.from_liner(scene.liner)]
    folders = [a.out / "mill"]
    kept = sorted((a.out / "life" / "mills").glob("cycle-*"), key=lambda p: int(p.name.split("-")[1]))

    def run_mill_on(lp, cycle):
        profiles.append(lp)
        if cycle > len(kept):
            raise _NotKept
        folders.append(kept[cycle - 1])
        return kept[cycle - 1]

    first = read_mill_record(folders[0], profiles[0].mill_profile(r))
    finished = False
    try:
        steps, _, _ = run_life(profiles[0], first, DEFAULT_LAW, 4000.0, a.cycles, (0.0, 0.0), run_mill_on, r,
                               stop_height=0.058)
        profiles.append(steps[-1].profile)
        finished = True
    except _NotKept:
        pass
    print("| height (mm) | faces, trailing / leading (deg) | chamfers (mm) | flat top (mm) | turn in the step (deg) "
          "| corner bins / face mean, trailing / leading | corners' share of the lifter's wear |")
    print("|---|---|---|---|---|---|---|")
    for k, lp in enumerate(profiles):
        q = lp.record()
        row = (f"| {q['lifter_height_mm']:.1f} | {lp.trailing_angle_deg:.1f} / {lp.leading_angle_deg:.1f} | "
               f"{q['trailing_chamfer_mm']:.1f} / {q['leading_chamfer_mm']:.1f} | {q['top_width_mm']:.1f} |")
        if k < len(folders):
            nxt = profiles[k + 1]
            rt, rl, share = _corner_figures(lp, read_mill_record(folders[k], lp.mill_profile(r)))
            row += (f" {nxt.trailing_angle_deg - lp.trailing_angle_deg:+.1f} / "
                    f"{nxt.leading_angle_deg - lp.leading_angle_deg:+.1f} | {rt:.1f} / {rl:.1f} | {share:.2f} |")
        else:
            row += " (the life's end) | | |" if finished else " (its mill run not kept yet) | | |"
        print(row)


if __name__ == "__main__":
    main()
