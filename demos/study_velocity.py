"""Impact velocity study (paper section 4.2, conclusion (3)): v = 1, 3, 5 m/s.

A 20 mm steel ball strikes the 40 mm thick block of the paper's rig (scene study-base) at three
speeds. Hertz's quasi-static theory predicts F_max ~ v^(6/5) and t_c ~ v^(-1/5): the force grows a
little faster than the speed and the contact gets shorter. The demo runs the study (cached: a second
run recomputes nothing), then checks the fitted exponents against Hertz.

    .venv/bin/python demos/study_velocity.py            # full size: 3 cases x 40 ms
    .venv/bin/python demos/study_velocity.py --small    # 2 cases, 0.2 ms impacts
"""
from _common import column, exponent, parse, run

if __name__ == "__main__":
    args = parse("velocity", __doc__)
    res = run("velocity", args)

    v, force = column(res, "F_max")
    _, duration = column(res, "t_c")
    k_f, k_t = exponent(v, force), exponent(v, duration)
    print(f"F_max ~ v^{k_f:.3f} (Hertz 1.2), t_c ~ v^{k_t:.3f} (Hertz -0.2)")
    # the tolerance on the force exponent: 10 %; the contact shortens as v grows
    assert abs(k_f / 1.2 - 1) < 0.10, k_f
    assert k_t < 0, k_t
    print(f"trends beside the paper's conclusion (3): {res.out / 'study.md'}")
