"""Voce and Swift hardening (millimpact.fem.hardening) as the return map's flow curves: the table
against the closed forms, a uniaxial path that follows the law, and the scene's checks."""
from __future__ import annotations

import numpy as np
import pytest

from millimpact.fem.hardening import strains, swift_stress, tabulated, voce_stress
from millimpact.fem.plasticity import FlowCurve, J2Material
from millimpact.scene.schema import Material, SceneError


def _table_error(points, exact, top=3.0):
    """Largest relative error of the tabulated curve (linear between its points, the last segment
    continued) against the closed form on a fine grid up to alpha = ``top``."""
    a, s = np.array(points).T
    flow = FlowCurve(float(s[0]), 0.0, tuple(points))
    x = np.linspace(0.0, top, 20001)
    return float(np.max(np.abs(flow.flow_stress(x) / exact(x) - 1.0)))


@pytest.mark.parametrize("q, b", [(1.4e9, 2.0), (1.0e9, 10.0), (0.5e9, 50.0)])
def test_voce_table_within_0_1_percent(q, b):
    """The module's bound: 0.1 % of the flow stress for b <= 50 (interpolation |s''| h^2 / 8)."""
    mat = Material(yield_stress=380e6, voce=(q, b))
    err = _table_error(tabulated(mat), lambda x: voce_stress(x, 380e6, q, b))
    assert err < 1e-3, err


@pytest.mark.parametrize("k, e0, n", [(1.2e9, 1e-3, 0.3), (1.5e9, 0.01, 0.5), (1.0e9, 0.05, 0.1)])
def test_swift_table_within_0_1_percent(k, e0, n):
    """Within 0.1 % up to the table's end (alpha 3; measured 0.05 % at most); beyond it the last
    segment continued overestimates the concave law a little (measured 0.3 % at alpha 3.5)."""
    mat = Material(swift=(k, e0, n))
    assert mat.initial_yield_stress == pytest.approx(k * e0**n)
    assert _table_error(tabulated(mat), lambda x: swift_stress(x, k, e0, n)) < 1e-3
    assert _table_error(tabulated(mat), lambda x: swift_stress(x, k, e0, n), top=3.5) < 5e-3


def test_a_uniaxial_path_follows_the_voce_law():
    """Uniaxial stress to a plastic strain of 0.5 by the return map on the tabulated Voce law: the
    stress at each step is the law's at the step's alpha (the table's 0.1 %), and alpha is the
    plastic strain (uniaxial J2)."""
    from test_plasticity import uniaxial

    E, nu, y, q, b = 200e9, 0.3, 380e6, 1.4e9, 4.0
    mat = Material(yield_stress=y, voce=(q, b))
    pts = tabulated(mat)
    j2 = J2Material(E, nu, FlowCurve(y, 0.0, pts))
    eps = np.linspace(0.0, 0.5, 101)[1:]
    res, _, _ = uniaxial(j2, eps)
    sig, alpha = res[:, 0], res[:, 1]
    yielded = alpha > 0
    assert np.allclose(sig[yielded], voce_stress(alpha[yielded], y, q, b), rtol=1e-3)
    assert alpha[-1] == pytest.approx(0.5 - sig[-1] / E, rel=1e-6)


@pytest.mark.parametrize("kwargs, words", [
    (dict(voce=(1e9, 2.0)), "needs yield_stress"),
    (dict(yield_stress=380e6, voce=(1e9, 0.0)), "must be [Q >= 0 Pa, b > 0]"),
    (dict(yield_stress=380e6, voce=(1e9, 2.0), flow_curve=((0.0, 380e6), (0.1, 500e6))), "give one of"),
    (dict(yield_stress=380e6, voce=(1e9, 2.0), hardening_modulus=1e9), "give one of"),
    (dict(swift=(1e9, 0.0, 0.3)), "0 < eps0 <= 1"),
    (dict(swift=(1e9, 0.01, 0.3), yield_stress=5e8), "must equal Swift's K eps0^n"),
])
def test_bad_hardening_laws_are_refused(kwargs, words):
    with pytest.raises(SceneError, match=words.replace("[", r"\[").replace("^", r"\^")):
        Material(**kwargs).validate("liner.material")


def test_the_table_is_dense_where_the_curves_bend():
    a = strains()
    assert a[0] == 0.0 and a[-1] == pytest.approx(3.0) and np.all(np.diff(a) > 0)
    assert a[1] < 1e-4  # the first segment is short: Swift bends hardest at alpha 0


#: tensile tests spanning the steels the package meets: an annealed carbon steel, a quenched and
#: tempered one, a hardened one (Y, S_u, e_u; representative values, the functions' domain)
TENSILE = [(295e6, 395e6, 0.25), (1100e6, 1300e6, 0.08), (1860e6, 1980e6, 0.04)]


@pytest.mark.parametrize("law", ["swift", "voce"])
@pytest.mark.parametrize("y, su, eu", TENSILE)
def test_a_law_from_a_tensile_test_necks_where_the_test_did(law, y, su, eu):
    """The law fitted to (Y, S_u, e_u), driven through a uniaxial tension by the return map on its
    table (true strain eps, engineering stress S = sigma exp(-eps), engineering strain e = exp(eps)
    - 1): it yields at Y, its largest S is S_u and lies at e_u. Tolerances: the table's 0.1 % and
    Considere's condition taken on the plastic strain (the elastic share sigma / E of the strain
    increment, < 1 %) give S_max within 0.3 %; the maximum is flat (S'' ~ -sigma_u / n there), so
    the strain at the largest S on a grid of 0.02 % strain is within 10 % of e_u."""
    from test_plasticity import uniaxial

    from millimpact.fem.hardening import swift_from_tensile, voce_from_tensile

    E, nu = 205e9, 0.3
    if law == "swift":
        mat = Material(swift=swift_from_tensile(y, su, eu, E))
    else:
        mat = Material(yield_stress=y, voce=voce_from_tensile(y, su, eu, E))
    mat.validate("block.material")
    assert mat.initial_yield_stress == pytest.approx(y, rel=1e-9)
    j2 = J2Material(E, nu, FlowCurve(mat.initial_yield_stress, 0.0, tabulated(mat)))
    eps = np.arange(1, int(2.0 * np.log1p(eu) / 2e-4)) * 2e-4
    res, _, _ = uniaxial(j2, eps)
    s_eng = res[:, 0] * np.exp(-eps)
    k = int(np.argmax(s_eng))
    assert s_eng[k] == pytest.approx(su, rel=3e-3)
    assert np.expm1(eps[k]) == pytest.approx(eu, rel=0.1)


def test_a_steel_that_necks_before_it_hardens_enough_has_no_voce_law():
    """Y = 0.99 S_u with e_u = 0.25: (sigma_u - Y) / (sigma_u alpha_u) = 0.96 < 1, so no Voce law
    with its yield at Y necks at e_u; Swift's law exists (its condition ln(sigma_u / Y) > alpha_u
    holds whenever Y <= S_u, since alpha_u < ln(1 + e_u)) and necks there."""
    from millimpact.fem.hardening import swift_from_tensile, voce_from_tensile

    with pytest.raises(ValueError, match="no Voce law"):
        voce_from_tensile(990e6, 1000e6, 0.25, 205e9)
    k, e0, n = swift_from_tensile(990e6, 1000e6, 0.25, 205e9)
    assert k * e0**n == pytest.approx(990e6)


@pytest.mark.parametrize("name, y, su, n", [
    ("aisi-1020-as-rolled", 260e6, 441e6, 0.19),
    ("aisi-4142-qt450", 1378e6, 1413e6, 0.051),
    ("aisi-4142-qt205", 1688e6, 2240e6, 0.091),
])
def test_named_steels_swift_laws_come_from_their_tensile_data(name, y, su, n):
    """Each tensile-data steel's Swift law is the one swift_from_tensile gives for its source's
    yield, tensile strength and uniform true strain n (Considere), to the file's 6 digits."""
    import math

    from millimpact.fem.hardening import swift_from_tensile
    from millimpact.scene.materials import named_material

    fields = named_material(name, "block.material")
    mat = Material(**{k: tuple(v) if isinstance(v, list) else v for k, v in fields.items()})
    fitted = swift_from_tensile(y, su, math.expm1(n), mat.youngs_modulus)
    assert mat.swift == pytest.approx(fitted, rel=1e-5)
    assert mat.initial_yield_stress == pytest.approx(y, rel=1e-4)
