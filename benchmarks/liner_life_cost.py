"""Liner life's cost: 3 profile steps of liner-segment with its SAG charge, against 60 minutes on 2 cores.

The target: the mill on the new liner, its damage map and ``millimpact life --damage DIR --cycles
3`` (the mill run again on each worn profile) in under 60 minutes of wall time on 2 cores, and the
share of each stage: DEM (the mill runs), the damage map's bins (table cases) and its repeated
impacts, the profile update (wear and the worn profile), and the rest ("other": reading, binning,
outputs and figures, process start). The stages' times are those the commands record themselves
(``wall_time_s`` in damage.json and in life's summary.json); each command's whole wall and CPU time
(wait4: the process and the ranks or Yade it waited for) is measured here.

The docs' coarse settings:

- the mill (docs/dem-mill.md, "A SAG charge"; docs/liner-life.md, the Sarcheshmeh-like steps):
  ``millimpact mill liner-segment --charge sag`` at the plan's charge (J 0.28, J_B 0.12, rock
  0.1-0.2 m), 75 % of critical speed, moduli x 0.01, each run one revolution, 0.6 of warm-up and
  0.4 logged (``--warmup 0.6 --revolutions 0.4``), Yade on ``--threads`` threads (2: a SAG slice
  runs 1.2-1.4x faster on two threads of an idle machine, docs/dem-mill.md "Speed");
- the damage map (docs/damage.md, "Measured": the coarse mesh of the suite's real-engine tests):
  ``mpirun -n 2 millimpact damage liner-segment --impacts mill/impacts.csv --ranks-per-case 1
  --max-bins 30 --repeat-impacts 6 --set model.h_far=0.04 --set model.h_contact=0.004`` (the
  revolutions and the lifters from the mill's summary.json beside the log);
- the life (docs/liner-life.md): ``millimpact life liner-segment --mill mill --damage damage
  --cycles 3 --hours 1000``, the order-of-magnitude constants (the cost does not depend on them).

    .venv/bin/python benchmarks/liner_life_cost.py                # the benchmark (idle machine)
    .venv/bin/python benchmarks/liner_life_cost.py --revolutions 0.02 --warmup 0.02 --max-bins 4 \\
        --repeat-impacts 1 --ranks 1 --threads 1 --out /tmp/cost     # a check of the script, in minutes

Each step is skipped when its folder is complete (mill/summary.json, damage/damage.json saying
``"complete": true``, life/summary.json), and every step after one that ran runs again. A skipped
step's times are those of the earlier run (times.json in --out), and the report says so; without
such a record, the command's own summary (its process start not counted). Writes --out (default
benchmarks/out/liner_life_cost/): cost.md, cost.csv (one row per stage), cost_commands.csv (one
row per command), cost.json (all of it), times.json and each command's log.
"""
from __future__ import annotations

import argparse
import datetime
import json
import os
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

from _report import timed_run_cpu, write_report  # noqa: E402

TARGET_S = 3600.0
#: where a skipped step's time comes from when times.json has no record of it
UNRECORDED = {
    "mill": "an earlier run's summary.json: Yade's own wall time only",
    "damage": "an earlier run's damage.json: its process start not counted",
    "life": "an earlier run's summary.json: its process start not counted",
}
#: the coarse mesh of docs/damage.md's benchmark and the suite's real-engine tests
COARSE = ["--set", "model.h_far=0.04", "--set", "model.h_contact=0.004"]


def commands(a, out: Path) -> dict[str, tuple[list[str], int]]:
    """Each step's millimpact arguments and its ranks, in order."""
    mill, damage, life = out / "mill", out / "damage", out / "life"
    return {
        "mill": (["mill", "liner-segment", "--charge", "sag", "--revolutions", str(a.revolutions), "--warmup",
                  str(a.warmup), "--threads", str(a.threads), "--force", "--out", str(mill)], 1),
        "damage": (["damage", "liner-segment", "--impacts", str(mill / "impacts.csv"), "--ranks-per-case", "1",
                    "--max-bins", str(a.max_bins), "--repeat-impacts", str(a.repeat_impacts), *COARSE, "--force",
                    "--out", str(damage)], a.ranks),
        "life": (["life", "liner-segment", "--mill", str(mill), "--damage", str(damage), "--cycles", str(a.cycles),
                  "--hours", f"{a.hours:g}", "--force", "--out", str(life)], 1),
    }


def complete(step: str, out: Path) -> bool:
    """Whether the step's folder holds a finished result."""
    if step == "damage":
        path = out / "damage" / "damage.json"
        return path.is_file() and json.loads(path.read_text()).get("complete") is True
    return (out / step / "summary.json").is_file()


def run_steps(a, out: Path) -> dict[str, dict]:
    """Run the steps not complete (and every one after a step that ran); each step's whole wall
    and CPU time (s), peak memory (GB), load before and after, and where they come from."""
    book = out / "times.json"
    earlier = json.loads(book.read_text()) if book.is_file() else {}
    os.environ["MILLIMPACT_YADE_THREADS"] = str(a.threads)  # the life's mill re-runs (docs/dem-mill.md)
    times, ran = {}, False
    for step, (args, ranks) in commands(a, out).items():
        if complete(step, out) and not ran:
            times[step] = {**earlier[step], "source": f"an earlier run ({earlier[step]['date']})"} \
                if step in earlier else {"source": UNRECORDED[step]}
            continue
        ran = True
        load = os.getloadavg()[0]
        print(f"{step}: {'mpirun -n %d ' % ranks if ranks > 1 else ''}millimpact {' '.join(args)}", flush=True)
        code, wall, peak, cpu = timed_run_cpu([sys.executable, "-m", "millimpact.cli", *args], ranks, ROOT,
                                              log=out / f"{step}.log")
        if code != 0:
            raise SystemExit(f"{step} failed (exit {code}): see {out / f'{step}.log'}")
        times[step] = earlier[step] = {
            "wall_s": wall, "cpu_s": cpu, "peak_rss_gb": peak, "ranks": ranks, "load_1min_before": load,
            "load_1min_after": os.getloadavg()[0], "date": datetime.datetime.now().isoformat(timespec="seconds"),
            "command": ("mpirun -n %d " % ranks if ranks > 1 else "") + "millimpact " + " ".join(args)}
        times[step]["source"] = "this run"
        book.write_text(json.dumps(earlier, indent=1) + "\n")
    return times


def stages(out: Path, times: dict) -> tuple[list[dict], dict]:
    """The stage rows (DEM, bins, repeated impacts, profile update, other, whole) and what the
    commands recorded."""
    mill = json.loads((out / "mill" / "summary.json").read_text())
    dmg = json.loads((out / "damage" / "damage.json").read_text())
    life = json.loads((out / "life" / "summary.json").read_text())
    whole = {"mill": times["mill"].get("wall_s", mill["yade"]["wall_s"]),
             "damage": times["damage"].get("wall_s", dmg["wall_time_s"]["total"]),
             "life": times["life"].get("wall_s", life["wall_time_s"]["total"])}
    total = sum(whole.values())
    dt, lt = dmg["wall_time_s"], life["wall_time_s"]
    reruns = sorted((out / "life" / "mills").glob("cycle-*/summary.json"))
    yade = [mill["yade"]] + [json.loads(p.read_text())["yade"] for p in reruns]
    src = {k: v["source"] for k, v in times.items()}
    rows = [
        {"stage": "DEM", "what": f"the mill on the new liner and {len(reruns)} re-run(s) on the worn profiles "
                                 f"({sum(y['steps'] for y in yade):,} Yade steps; Yade's own wall "
                                 f"{sum(y['wall_s'] for y in yade):.0f} s)",
         "wall_s": whole["mill"] + lt.get("mill_reruns", 0.0),
         "from": f"mill: {src['mill']}; re-runs: {src['life']}"},
        {"stage": "damage bins", "what": f"{sum(b['status'] == 'ok' for b in dmg['bins'])} of {len(dmg['bins'])} "
                                         "bins computed (table cases)", "wall_s": dt["bins"], "from": src["damage"]},
        {"stage": "repeated impacts", "what": f"{sum(1 for r in dmg['repeats'].values() if r)} place(s) x "
                                              f"{dmg['repeat_impacts']} impacts", "wall_s": dt["repeated_impacts"],
         "from": src["damage"]},
        {"stage": "profile update", "what": f"{len(life['profiles']) - 1} step(s) of wear and the worn profile",
         "wall_s": lt["wear_and_profile"], "from": src["life"]},
    ]
    rows.append({"stage": "other", "what": "reading, binning, outputs and figures, process start",
                 "wall_s": total - sum(r["wall_s"] for r in rows), "from": "the whole less the stages"})
    rows.append({"stage": "whole", "what": f"{total / 60:.1f} min against {TARGET_S / 60:.0f}: "
                                           f"{'met' if total < TARGET_S else 'NOT met'}", "wall_s": total,
                 "from": "; ".join(f"{k}: {v}" for k, v in src.items())})
    for r in rows:
        r["share"] = r["wall_s"] / total
    recorded = {"mill_yade": yade, "damage_wall_time_s": dt, "life_wall_time_s": lt,
                "life_wall_time_s_per_cycle": life.get("wall_time_s_per_cycle"), "commands_wall_s": whole,
                "profile_steps": len(life["profiles"]) - 1, "relined": life["relining"].get("reached_in_cycles")}
    return rows, recorded


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--revolutions", type=float, default=0.4, help="logged revolutions of each mill run")
    ap.add_argument("--warmup", type=float, default=0.6, help="warm-up revolutions of each mill run")
    ap.add_argument("--threads", type=int, default=2, help="Yade's threads (default 2)")
    ap.add_argument("--max-bins", type=int, default=30)
    ap.add_argument("--repeat-impacts", type=int, default=6)
    ap.add_argument("--ranks", type=int, default=2, help="the damage map's MPI ranks (default 2)")
    ap.add_argument("--cycles", type=int, default=3, help="profile steps (default 3)")
    ap.add_argument("--hours", type=float, default=1000.0)
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "out" / "liner_life_cost"))
    a = ap.parse_args()
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    times = run_steps(a, out)
    rows, recorded = stages(out, times)
    settings = (f"liner-segment, SAG charge; mill runs {a.warmup:g} + {a.revolutions:g} revolutions, "
                f"{a.threads} Yade thread(s); damage map on {a.ranks} rank(s), at most {a.max_bins} bins, "
                f"{a.repeat_impacts} repeated impacts, h_far 40 mm, h_contact 4 mm; life --cycles {a.cycles} "
                f"--hours {a.hours:g}")
    write_report(out, "cost", rows, a.ranks, ["stage", "wall (s)", "share", "what", "times from"],
                 lambda r: [r["stage"], _secs(r["wall_s"]), f"{100 * r['share']:.1f} %", r["what"], r["from"]],
                 note=f"; {settings}")
    cmds = [{"step": k, **{f: v.get(f) for f in ("wall_s", "cpu_s", "peak_rss_gb", "ranks", "load_1min_before",
                                                   "load_1min_after", "source", "command")}}
            for k, v in times.items()]
    write_report(out, "cost_commands", cmds, a.ranks,
                 ["step", "wall (s)", "CPU (s)", "peak RSS (GB)", "load (1 min) before / after", "times from"],
                 lambda r: [r["step"], _num(r["wall_s"], 1), _num(r["cpu_s"], 0), _num(r["peak_rss_gb"], 2),
                            f"{_num(r['load_1min_before'], 1)} / {_num(r['load_1min_after'], 1)}", r["source"]])
    if recorded["profile_steps"] < a.cycles:
        print(f"warning: the liner was relined after {recorded['profile_steps']} of {a.cycles} steps "
              f"({recorded['relined']}): fewer mill re-runs than the target's")
    with open(out / "cost.md", "a") as fh:
        fh.write("\nPer command:\n\n" + (out / "cost_commands.md").read_text() + "\n")
        fh.write("".join(f"- {k}: `{v.get('command', 'not recorded (the folder was there)')}`\n"
                         for k, v in times.items()))
    (out / "cost.json").write_text(json.dumps({"settings": settings, "target_s": TARGET_S, "stages": rows,
                                               "commands": times, "recorded": recorded}, indent=1) + "\n")
    return 0


def _secs(x: float) -> str:
    return f"{x:.1f}" if abs(x) >= 0.1 else f"{x:.2g}"


def _num(x, digits: int) -> str:
    return "" if x is None else f"{x:.{digits}f}"


if __name__ == "__main__":
    raise SystemExit(main())
