# --- the law at run time (Yade's Python; needs MILLIMPACT_LAW above) --------------------------------
# Each new ball-liner interaction gets the Hertz coefficient k_no (F = k_no delta^1.5), the damping
# betan / betas and the friction of the table point of its impact: the contact point's relative
# velocity when the interaction becomes real gives the impact speed |u| and the angle from the
# normal, atan(|u_t| / u_n); zeta and E* are interpolated bilinearly in (ln speed, angle) over the
# table's grid, clipped to it (outside the table's speeds the nearest speed's values hold).
# Other interactions (ball-ball, ...) keep what millimpact_ip2() gives them (the table's median point).
import math as _mm_math

_mm_last = [-1]  # O.iter of the last update


def _mm_bracket(grid, x):
    """(i, j, w): x lies between grid[i] and grid[j] with weight w on grid[j] (clipped)."""
    if len(grid) == 1 or x <= grid[0]:
        return 0, 0, 0.0
    if x >= grid[-1]:
        n = len(grid) - 1
        return n, n, 0.0
    for j in range(1, len(grid)):
        if x <= grid[j]:
            return j - 1, j, (x - grid[j - 1]) / (grid[j] - grid[j - 1])
    return len(grid) - 1, len(grid) - 1, 0.0


def millimpact_point(speed, angle_deg):
    """(zeta, E*) of the law at impact speed |u| (m/s) and angle from the normal (deg)."""
    L = MILLIMPACT_LAW
    i0, i1, wi = _mm_bracket([_mm_math.log(s) for s in L["speeds_m_s"]], _mm_math.log(max(speed, 1e-12)))
    j0, j1, wj = _mm_bracket(L["angles_deg"], angle_deg)
    out = []
    for key in ("zeta", "e_star_Pa"):
        g = L[key]
        a = (1 - wj) * g[i0][j0] + wj * g[i0][j1]
        b = (1 - wj) * g[i1][j0] + wj * g[i1][j1]
        out.append((1 - wi) * a + wi * b)
    return out[0], out[1]


def _mm_point_velocity(body, point):
    s = body.state
    r = point - s.pos
    return s.vel + s.angVel.cross(r)


def millimpact_update():
    """Set the table's law on the ball-liner interactions made real since the last call."""
    L = MILLIMPACT_LAW
    ball_mat, liner_mat = L["yade"]["ball_material"], L["yade"]["liner_material"]
    last = _mm_last[0] if O.iter >= _mm_last[0] else -1  # O.reset(): start afresh
    _mm_last[0] = O.iter
    # the real interactions only (filtered in C++); new ones became real after the last call
    for i in [i for i in O.interactions.all(True) if i.iterMadeReal > last]:
        b1, b2 = O.bodies[i.id1], O.bodies[i.id2]
        if b1.material.label == ball_mat and b2.material.label == liner_mat:
            ball, liner, n_out = b1, b2, -i.geom.normal
        elif b2.material.label == ball_mat and b1.material.label == liner_mat:
            ball, liner, n_out = b2, b1, i.geom.normal
        else:
            continue
        cp = i.geom.contactPoint
        u = _mm_point_velocity(ball, cp) - _mm_point_velocity(liner, cp)
        u_n = -u.dot(n_out)  # approach speed, > 0
        u_t = (u + u_n * n_out).norm()  # tangential speed of the contact point
        speed = _mm_math.sqrt(u_n * u_n + u_t * u_t)
        angle = _mm_math.degrees(_mm_math.atan2(u_t, max(u_n, 1e-300)))
        zeta, e_star = millimpact_point(speed, angle)
        radius = ball.shape.radius
        p = i.phys
        p.kno = 4.0 / 3.0 * e_star * _mm_math.sqrt(radius)
        p.kso = 1.5 * L["tangential_stiffness_ratio"] * p.kno
        p.betan = zeta / _mm_math.sqrt(6.0)
        p.betas = L["yade"]["betas_per_betan"] * p.betan
        p.tangensOfFrictionAngle = L["friction"]


def millimpact_ball_material(**kw):
    """The ball's FrictMat (label MILLIMPACT_LAW['yade']['ball_material'])."""
    y = MILLIMPACT_LAW["yade"]
    return FrictMat(
        young=y["young_Pa"],
        poisson=y["poisson"],
        density=y["ball_density_kg_m3"],
        frictionAngle=_mm_math.atan(MILLIMPACT_LAW["friction"]),
        label=y["ball_material"],
        **kw,
    )


def millimpact_liner_material(**kw):
    """The liner's FrictMat (label MILLIMPACT_LAW['yade']['liner_material'])."""
    y = MILLIMPACT_LAW["yade"]
    return FrictMat(
        young=y["young_Pa"],
        poisson=y["poisson"],
        density=y["liner_density_kg_m3"],
        frictionAngle=_mm_math.atan(MILLIMPACT_LAW["friction"]),
        label=y["liner_material"],
        **kw,
    )


def millimpact_ip2():
    """Ip2_FrictMat_FrictMat_MindlinPhys with the table's median damping (betan mode: settable per
    interaction; 'en' would set Yade's internal alpha, which Python cannot change)."""
    y = MILLIMPACT_LAW["yade"]
    return Ip2_FrictMat_FrictMat_MindlinPhys(
        betan=MatchMaker(algo="val", val=y["betan_default"]),
        betas=MatchMaker(algo="val", val=y["betas_per_betan"] * y["betan_default"]),
    )


def millimpact_law_runner():
    """The PyRunner that sets the law on new interactions: put it right after the InteractionLoop."""
    return PyRunner(command="millimpact_update()", iterPeriod=1, label="millimpactLaw")
