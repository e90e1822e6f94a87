"""The velocity of an oblique impact on a scene's face: its normal n and tangential direction t.

    v = V (-cos(theta) n + sin(theta) t)

with theta the angle from the face normal, n the scene's outward contact normal and t the scene's
own tangential direction (that of its impact velocity), or e_x x n for a normal impact (in the
plane x = x_p, which holds n on the block's face and on a liner's lifter faces, top and plate).
Used by the DEM tables and the repeated-impact sequences. numpy is imported where it computes
(the command line imports the scene stage).
"""

from __future__ import annotations

import math


def tangent_direction(scene):
    """The unit tangential direction t of the scene's oblique impacts (module docstring)."""
    import numpy as np

    n = np.asarray(scene.contact_normal, dtype=float)
    v = np.asarray(scene.impact.velocity, dtype=float)
    vt = v - (v @ n) * n
    if np.linalg.norm(vt) > 1e-9 * np.linalg.norm(v):
        return vt / np.linalg.norm(vt)
    t = np.cross([1.0, 0.0, 0.0], n)
    return t / np.linalg.norm(t)


def oblique_velocity(scene, speed: float, angle_deg: float) -> list[float]:
    """v = V (-cos(angle) n + sin(angle) t), m/s, rounded to 15 digits (a clean 0 for a normal impact)."""
    import numpy as np

    n = np.asarray(scene.contact_normal, dtype=float)
    a = math.radians(angle_deg)
    v = speed * (-math.cos(a) * n + math.sin(a) * tangent_direction(scene))
    return [float(round(c, 15)) + 0.0 for c in v]
