"""The mill run's contact law and clock: the critical speed, Hertz contact times and the restitution
parameter of Yade's Hertz-Mindlin law.

Critical speed: a ball at the shell (radius R = D / 2) centrifuges when omega^2 R = g,

    omega_c = sqrt(g / R) = sqrt(2 g / D),   n_c = 60 omega_c / (2 pi) = 42.3 / sqrt(D) rpm (D in m)

(the textbook formula, e.g. Napier-Munn et al., Mineral Comminution Circuits, JKMRC 1996, ch. 11;
42.3 = 60 sqrt(2 x 9.81) / (2 pi)). A ball's centre runs at R - r, so the ball itself centrifuges at
sqrt(R / (R - r)) of n_c, 1.006 n_c for a 125 mm ball in an 11 m mill.

Restitution: Yade's ``Law2_ScGeom_MindlinPhys_Mindlin`` given ``en`` adds a normal damping force
c_n delta' with c_n proportional to sqrt(m k_n(delta)) (Tsuji, Tanaka & Ishida 1992's form), so the
coefficient of restitution does not depend on the speed, the sizes or the moduli. Run in Yade
2023.02a with ``NewtonIntegrator(damping=0)``, a 15 mm steel ball at 3 m/s on a facet rebounds at
e = 0.300, 0.500, 0.800, 0.948 for en = 0.3, 0.5, 0.8, 0.95 (tests/dem/test_mill_contact.py runs
it): the mill's script passes the wanted e as ``en`` and switches Yade's numerical damping off.
(a plain Yade drop of that ball measures e = 0.65 at en = 0.8 because it keeps
NewtonIntegrator's default damping = 0.2, Cundall's non-viscous damping, which removes energy
on top of the contact law.)

The default restitution of a scene's elastic-plastic materials is Thornton's (1997) e(V) at the
shell's speed omega R: the impact speeds of a mill's balls are of that order (foundations.md section 10);
Thornton's is a lower bound of an elastic-plastic sphere's e (:mod:`millimpact.theory.thornton`).
"""

from __future__ import annotations

import math

from ...errors import InputError

#: g (m/s^2)
GRAVITY = 9.81


def critical_omega(mill_radius: float, g: float = GRAVITY) -> float:
    """omega_c = sqrt(g / R) (rad/s), R the shell's inner radius (m)."""
    return math.sqrt(g / mill_radius)


def critical_rpm(mill_diameter: float, g: float = GRAVITY) -> float:
    """n_c = 60 sqrt(2 g / D) / (2 pi) rpm, = 42.3 / sqrt(D) for g = 9.81 m/s^2 (D in m)."""
    return 60.0 * math.sqrt(2.0 * g / mill_diameter) / (2.0 * math.pi)


def hertz_contact_time(mass: float, radius: float, e_star: float, speed: float) -> float:
    """Duration (s) of an undamped Hertz impact at ``speed`` (m/s): t_c = 2.943 delta_max / v with
    delta_max = (15 m v^2 / (16 E* sqrt(R)))^(2/5) (Johnson, Contact Mechanics, 11.4); ``mass``
    the effective mass (kg), ``radius`` the effective radius (m), ``e_star`` the contact modulus (Pa)."""
    d = (15.0 * mass * speed**2 / (16.0 * e_star * math.sqrt(radius))) ** 0.4
    return 2.9432 * d / speed


def scene_restitution(scene, speed: float) -> tuple[float, str]:
    """(e, source) for a mill run of ``scene`` without --restitution: Thornton's e(V) at ``speed``
    (m/s) with the yield stress of the softer of ball and liner; InputError for elastic materials."""
    from ...theory.hertz import effective_modulus
    from ...theory.thornton import restitution_thornton, yield_onset_velocity

    ball, liner = scene.ball.material, scene.liner.material
    ys = [y for y in (m.initial_yield_stress for m in (ball, liner)) if y is not None]
    if not ys:
        raise InputError(
            f"scene '{scene.name}': ball and liner are elastic (their restitution would be 1); "
            "give --restitution E (0 < E < 1, e.g. 0.6 for steel balls on a steel liner)"
        )
    y = min(ys)
    v_y = yield_onset_velocity(y, effective_modulus(ball, liner), ball.density)
    e = float(restitution_thornton(speed, v_y))
    return e, (
        f"Thornton (1997) e(V) at the shell speed {speed:.3g} m/s, yield {y / 1e9:.3g} GPa "
        f"(V_y {v_y:.3g} m/s): a lower bound"
    )
