"""Liner thickness study (paper section 4.4, conclusion (5)): b = 30, 40, 50 mm.

Hertz has no b: the local contact of a ball on a thick target is that of a half-space. The rig's
block, though, is clamped at its base and struck on its side, so it bends like a short cantilever
whose stiffness grows ~ b^3: a thinner block gives way more, keeps more of the impact energy as
vibration (a lower restitution) and the contact force falls below Hertz. The demo checks that.

    .venv/bin/python demos/study_thickness.py            # full size: 3 cases x 40 ms
    .venv/bin/python demos/study_thickness.py --small    # 2 cases, 0.2 ms impacts
"""
import millimpact  # noqa: F401  (before numpy: it chooses OpenBLAS's kernels, millimpact/__init__.py)
import numpy as np

from _common import column, parse, run

if __name__ == "__main__":
    args = parse("thickness", __doc__)
    res = run("thickness", args)

    b, force = column(res, "F_max")
    _, hertz = column(res, "F_max_hertz")
    _, vib = column(res, "vibration_share")
    print(f"b = {b} mm: F_max / Hertz {np.round(force / hertz, 3)}, vibration share {np.round(100 * vib)} %")
    assert np.all(force < hertz), force        # the finite, bending block is softer than a half-space
    assert np.all(np.diff(force) > 0), force   # ... less so when thicker
    assert np.all(np.diff(vib) < 0), vib       # and keeps less of the impact energy
    print(f"trends beside the paper's conclusion (5): {res.out / 'study.md'}")
