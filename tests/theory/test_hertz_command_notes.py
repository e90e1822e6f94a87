"""``millimpact hertz`` says when p0 exceeds the elastic limit (issue 35, row 8): first yield
under a Hertz contact at p0 = 1.60 Y (Johnson, Contact Mechanics, 1985, section 6.2)."""
import re

from conftest import run_cli
from millimpact.scene.builtin import builtin_scene


def p0_gpa(stdout: str) -> float:
    return float(re.search(r"peak pressure p0\s+([0-9.]+) GPa", stdout).group(1))


def test_a_plastic_scene_beyond_first_yield_is_noted_per_body():
    r = run_cli("hertz", "paper-rig-plastic")
    assert r.returncode == 0, r.stderr
    scene = builtin_scene("paper-rig-plastic")
    p0 = p0_gpa(r.stdout)
    notes = [line for line in r.stdout.splitlines() if line.strip().startswith("note:")]
    for body, m in (("ball", scene.ball.material), ("block", scene.block.material)):
        limit = 1.6 * m.yield_stress / 1e9
        assert p0 > limit       # 5.46 GPa against 3.04 (ball, Y 1.9) and 1.52 (block, Y 0.95)
        assert any(f"exceeds the {body}'s first-yield pressure 1.6 Y = {limit:.3g} GPa" in n for n in notes), notes


def test_an_elastic_scene_is_compared_with_a_typical_liner_steel():
    r = run_cli("hertz", "paper-rig")
    assert r.returncode == 0, r.stderr
    assert p0_gpa(r.stdout) > 1.6 * 0.95
    assert "note: elastic model beyond the elastic limit" in r.stdout
