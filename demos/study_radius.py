"""Ball radius study (paper section 4.3, conclusion (4)): r = 15, 20, 25 mm at 3 m/s.

Hertz: F_max ~ R^2, t_c ~ R and a peak pressure p0 that does not depend on R (force and contact
area both grow as R^2). On the rig's block, clamped at its base and struck on its side, a heavier
ball also makes the block bend more: the force grows a little slower than R^2 and more of the impact
energy stays in the block's vibration. The demo checks both.

    .venv/bin/python demos/study_radius.py            # full size: 3 cases x 40 ms
    .venv/bin/python demos/study_radius.py --small    # 2 cases, 0.2 ms impacts
"""
import millimpact  # noqa: F401  (before numpy: it chooses OpenBLAS's kernels, millimpact/__init__.py)
import numpy as np

from _common import column, exponent, parse, run

if __name__ == "__main__":
    args = parse("radius", __doc__)
    res = run("radius", args)

    r, force = column(res, "F_max")
    _, stress = column(res, "stress")
    _, vib = column(res, "vibration_share")
    k_f = exponent(r, force)
    print(f"F_max ~ r^{k_f:.3f} (Hertz 2), contact stress {np.round(stress / 1e9, 2)} GPa (Hertz: same for all r), "
          f"vibration share {np.round(100 * vib)} %")
    assert abs(k_f / 2.0 - 1) < 0.10, k_f                 # 10 % on the exponent
    assert np.ptp(stress) / stress.mean() < 0.15, stress  # p0 independent of R, up to the sampling noise
    assert np.all(np.diff(vib) > 0), vib                  # the heavier ball leaves more in the block
    print(f"trends beside the paper's conclusion (4): {res.out / 'study.md'}")
