"""The cost of the exported Yade law's per-interaction update (docs/dem.md), side by side.

    .venv/bin/python benchmarks/dem_law_runner.py out/dem-yade/contact_law_yade.py [--balls 200] [--steps 100000]

200 balls of the law's radius dropped into a box of liner material (Yade 2023.02a, one thread,
dt 2e-6 s), run twice in separate Yade processes: with millimpact_ip2() alone, and with the
law's PyRunner after the InteractionLoop. Prints the wall time per step of each and the ratio.
"""
from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

from millimpact.dem.yade import run_yade

SCRIPT = r'''
import json, sys, time
from yade import utils, pack
cfg = json.load(open(sys.argv[-1]))
exec(open(cfg["law"]).read())
ball = O.materials.append(millimpact_ball_material())
liner = O.materials.append(millimpact_liner_material())
R = MILLIMPACT_LAW["ball_radius_m"]
L = 20 * R
O.bodies.append(utils.aabbWalls([(-L, -L, 0), (L, L, 4 * L)], thickness=R, material=liner))
sp = pack.SpherePack()
sp.makeCloud((-L + R, -L + R, R), (L - R, L - R, 2 * L), rMean=R, rRelFuzz=0, num=cfg["balls"], seed=1)
sp.toSimulation(material=ball)
O.engines = [ForceResetter(), InsertionSortCollider([Bo1_Sphere_Aabb(), Bo1_Box_Aabb()]),
             InteractionLoop([Ig2_Sphere_Sphere_ScGeom(), Ig2_Box_Sphere_ScGeom()], [millimpact_ip2()],
                             [Law2_ScGeom_MindlinPhys_Mindlin()]),
             *([millimpact_law_runner()] if cfg["law_runner"] else []),
             NewtonIntegrator(gravity=(0, 0, -9.81), damping=0.0)]
O.dt = 2e-6
t0 = time.time()
O.run(cfg["steps"], True)
json.dump({"s_per_step": (time.time() - t0) / cfg["steps"], "balls": len(sp)}, open(cfg["out"], "w"))
'''


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("law", help="contact_law_yade.py written by millimpact export --to yade")
    p.add_argument("--balls", type=int, default=200)
    p.add_argument("--steps", type=int, default=100000)
    a = p.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        (tmp / "bench.py").write_text(SCRIPT)
        res = {}
        for runner in (False, True):
            cfg = {"law": str(Path(a.law).resolve()), "balls": a.balls, "steps": a.steps, "law_runner": runner,
                   "out": str(tmp / f"r{int(runner)}.json")}
            (tmp / "cfg.json").write_text(json.dumps(cfg))
            run_yade(tmp / "bench.py", tmp, ["cfg.json"])
            res[runner] = json.loads((tmp / f"r{int(runner)}.json").read_text())
    plain, law = res[False]["s_per_step"], res[True]["s_per_step"]
    print(f"{res[False]['balls']} balls, {a.steps} steps: {1e3 * plain:.3f} ms/step without the law's runner, "
          f"{1e3 * law:.3f} ms/step with it: x{law / plain:.2f}")


if __name__ == "__main__":
    main()
