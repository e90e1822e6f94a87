"""Poisson-ratio study (paper section 4.1, conclusion (2)): u = nu_ball / nu_block = 0.5, 1.0, 1.5.

The block keeps nu = 0.3; the ball's nu is 0.15, 0.30, 0.45 at a fixed shear modulus G, so its
Young's modulus E = 2G(1+nu) rises with u and so does the contact modulus E*. Hertz then raises the
peak pressure as E*^(4/5) (+19 % over the range) and the force as E*^(2/5) (+9 %). The demo checks
that the contact stress and force rise with u.

    .venv/bin/python demos/study_poisson.py            # full size: 3 cases x 40 ms
    .venv/bin/python demos/study_poisson.py --small    # 2 cases, 0.2 ms impacts
"""
import millimpact  # noqa: F401  (before numpy: it chooses OpenBLAS's kernels, millimpact/__init__.py)
import numpy as np

from _common import column, parse, run

if __name__ == "__main__":
    args = parse("poisson", __doc__)
    res = run("poisson", args)

    u, stress = column(res, "stress")
    _, force = column(res, "F_max")
    print(f"u = {u}: contact stress {np.round(stress / 1e9, 3)} GPa, F_max {np.round(force / 1e3, 2)} kN")
    assert np.all(np.diff(stress) > 0), stress
    assert np.all(np.diff(force) > 0), force
    print(f"trends beside the paper's conclusion (2): {res.out / 'study.md'}")
