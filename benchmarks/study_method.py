"""Which method should `millimpact study` use by default? The fastest of traditional / improved /
full whose F_max and t_c lie within 1 % of `full` on the same scene and mesh.

Accuracy: the study base case (study-base: r = 20 mm, 3 m/s, b = 40 mm) over a short time span (the
impact) with each candidate. Speed: the candidates within tolerance over a study case's own time
span (40 ms), where the methods differ most (the reduced methods integrate the free vibration in
closed form). All runs one after another in this process (wall times on a shared machine are
noisy: compare them within one run). millimpact/study.py DEFAULT_METHOD records the result.

    .venv/bin/python benchmarks/study_method.py [--end 3e-4] [--time-end 0.04] [--methods full,traditional,improved]
"""
import argparse
import time

if __name__ == "__main__":
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--end", type=float, default=3e-4, help="simulated time of the accuracy runs, s (default 3e-4)")
    p.add_argument("--time-end", type=float, default=0.04, help="simulated time of the timing runs, s (default 0.04)")
    p.add_argument("--methods", default="full,traditional,improved")
    p.add_argument("--tol", type=float, default=0.01, help="relative tolerance against full (default 1 %%)")
    args = p.parse_args()

    from millimpact.methods.run import run_scene
    from millimpact.scene.builtin import resolve_scene

    base = resolve_scene("study-base")

    def timed(method: str, end: float):
        t0 = time.perf_counter()
        s = run_scene(base.with_value("time.end", end), method, None)
        return s, time.perf_counter() - t0

    rows = {m: timed(m, args.end) for m in args.methods.split(",")}
    f_ref, t_ref = rows["full"][0]["peak_contact_force_N"], rows["full"][0]["contact_duration_s"]
    print(f"study-base, accuracy over {args.end * 1e3:g} ms; tolerance {100 * args.tol:g} % against full")
    print(f"{'method':<12s} {'F_max kN':>9s} {'dF %':>7s} {'t_c us':>8s} {'dt_c %':>7s} {'wall s':>8s} {'dofs':>7s} {'reduced':>8s}")
    ok = []
    for m, (s, wall) in rows.items():
        df = s["peak_contact_force_N"] / f_ref - 1
        dt = s["contact_duration_s"] / t_ref - 1
        print(f"{m:<12s} {s['peak_contact_force_N'] / 1e3:9.3f} {100 * df:+7.2f} {s['contact_duration_s'] * 1e6:8.2f} "
              f"{100 * dt:+7.2f} {wall:8.1f} {s['model'].get('dofs')!s:>7s} {s['model'].get('reduced_dofs')!s:>8s}")
        if abs(df) <= args.tol and abs(dt) <= args.tol:
            ok.append(m)
    print(f"within tolerance: {', '.join(ok)}; timing them over {args.time_end * 1e3:g} ms:")
    walls = {}
    for m in ok:
        s, walls[m] = timed(m, args.time_end)
        print(f"  {m:<12s} {walls[m]:8.1f} s   (F_max {s['peak_contact_force_N'] / 1e3:.3f} kN)")
    best = min(walls, key=walls.get)
    print(f"fastest within tolerance: {best}" + "".join(f"; {m} / {best} = {walls[m] / walls[best]:.1f}"
                                                         for m in walls if m != best))
