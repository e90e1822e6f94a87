"""How much of each profile step's face turn comes from the lifter's top corners.

    .venv/bin/python benchmarks/liner_life_corners.py OUT [--cycles 4] [--max-step-depth F]

OUT is a folder of ``benchmarks/liner_life.py`` (finished or interrupted: its first mill run and
the mill re-runs its life kept). The steps are redone as the life made them (the constants of
``--calibrate-life`` before its rescale, which changes the hours and not the profiles). Each
step's turn of the trailing and leading faces is printed twice: as the life takes it, the face's
least-squares line of every bin's depth against the position along it
(:func:`millimpact.life.profile.worn_profile`), and with the face's bin at the top corner left
out. A face turns by atan((d_top - d_root) / L) (L its length), so a bin at the face's top end
with many times the face's mean depth turns it most; that ratio is printed too, and the top's
mean depth without its two end bins as a share of its mean (the top's fall less the plate's is
the lifter's height loss that the calibration fits).
"""
from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

from liner_life import SCENE, _run

from millimpact.commandkit.settings import command_scene
from millimpact.life.calibration import read_calibration
from millimpact.life.loop import step_hours
from millimpact.life.profile import LifterProfile, worn_profile
from millimpact.life.wear import depth_rates, read_mill_record, surface_depths

FACES = ("trailing_face", "leading_face")


def _provisional_law(out: Path):
    """The constants ``--calibrate-life 152:58:4000`` starts from (the decay rate of the new lifter)."""
    with tempfile.TemporaryDirectory() as tmp:
        cal = Path(tmp) / "cal"
        _run(["life", *SCENE, "--mill", str(out / "mill"), "--calibrate-height", "152:58:4000", "--cycles", "1",
              "--reline-height", "0", "--reline-plate", "0", "--no-plots", "-q", "--out", str(cal)], Path(tmp) / "log")
        return read_calibration(cal / "calibration.json").law


def _without_corner(depths: dict) -> dict:
    """The depths with each face's bin at the top corner left out (the trailing face's last, the
    leading face's first: each face runs in the profile's direction)."""
    out = dict(depths)
    u, d = depths["trailing_face"]
    out["trailing_face"] = (u[:-1], d[:-1])
    u, d = depths["leading_face"]
    out["leading_face"] = (u[1:], d[1:])
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out", type=Path, help="a folder of benchmarks/liner_life.py")
    ap.add_argument("--cycles", type=int, default=4)
    ap.add_argument("--max-step-depth", type=float, default=None)
    a = ap.parse_args()
    scene = command_scene(SCENE[0], [s for s in SCENE[1:] if s != "--set"])
    law = _provisional_law(a.out)
    lp, r, t = LifterProfile.from_liner(scene.liner), scene.ball.radius, 0.0
    mills = sorted((a.out / "life" / "mills").glob("cycle-*"), key=lambda p: int(p.name.split("-")[1]))
    print("| step from (h) | height (mm) | trailing / leading face (deg) | step (h) | turn, trailing / leading "
          "(deg) | without the corner bins | corner bin / face mean, trailing / leading | top's mean depth without "
          "its two end bins |")
    print("|---|---|---|---|---|---|---|---|")
    for folder in [a.out / "mill", *mills]:
        rec = read_mill_record(folder, lp.mill_profile(r))
        rates = depth_rates(rec, law)
        dt = step_hours(rec, rates, lp, 4000.0 / a.cycles, 1e9, a.max_step_depth)
        depths = surface_depths(rec, rates, dt)
        new, cut = worn_profile(lp, depths), worn_profile(lp, _without_corner(depths))
        ratio = [depths[f][1][i] / max(depths[f][1].mean(), 1e-30) for f, i in zip(FACES, (-1, 0))]
        top = depths["top"][1]
        print(f"| {t:.0f} | {1e3 * lp.height_above_plate:.1f} | {lp.trailing_angle_deg:.1f} / {lp.leading_angle_deg:.1f} "
              f"| {dt:.0f} | {new.trailing_angle_deg - lp.trailing_angle_deg:+.1f} / "
              f"{new.leading_angle_deg - lp.leading_angle_deg:+.1f} | {cut.trailing_angle_deg - lp.trailing_angle_deg:+.1f} / "
              f"{cut.leading_angle_deg - lp.leading_angle_deg:+.1f} | {ratio[0]:.1f} / {ratio[1]:.1f} | "
              f"{top[1:-1].mean() / top.mean():.2f} |")
        lp, t = new, t + dt


if __name__ == "__main__":
    main()
