"""The mill run with an exported contact law (``millimpact mill --law DIR``).

``DIR`` is a folder ``millimpact export TABLE --to yade`` wrote: ``contact_law_yade.py`` (the law
``MILLIMPACT_LAW`` and its Yade runtime, ``millimpact/dem/export/yade_scripts/contact_law_runtime.py``)
and ``contact_law.json``. The mill's Yade script runs that file as the user's own model would
(docs/dem.md): the balls get the ``millimpact_ball`` material, the liner's facets
``millimpact_liner``, the interactions ``millimpact_ip2()`` (Hertz-Mindlin in betan mode with the
table's median damping: ball-ball and ball-end-wall contacts keep it) and the runtime's PyRunner
sets each new ball-liner contact's Hertz coefficient k_no = (4/3) E* r^(1/2), damping
betan = zeta / 6^(1/2) and friction from its impact speed and angle, bilinear in (ln speed,
angle) over the table's grid.

- Stiffness: the law's contact moduli (E* per table point, and the constant one of the materials)
  are multiplied by ``--stiffness-scale`` like the scene's. The law's restitution depends on zeta
  alone, e(zeta) of the Hertz-dashpot law (:mod:`millimpact.theory.hertz_dashpot`, equation (2)), not on k_no: the
  softer contact keeps every e_n of the table; F_max scales as K^(2/5).
- Cost: the runtime's update loops over Yade's interactions in Python. It runs every
  ``law_every`` steps (default: the impact check's period, t_c / 8): a contact then runs at most
  law_every - 1 steps (of its >= 25, t_c / dt at the fastest impact) on the median law before it
  gets its own: at most 8 % of its duration, while the overlap is under sin(0.08 pi) = 25 % of the
  largest and the force under 12 % of the peak (the dropped balls of tests/dem/test_mill_law.py
  rebound within 0.003 of the table's e_n).
- The law was fitted for the table's ball: a mill with balls of another radius is refused.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

from ...errors import InputError

#: the files of a ``millimpact export --to yade`` folder
LAW_SCRIPT, LAW_JSON = "contact_law_yade.py", "contact_law.json"
#: the mill's ball radius may differ from the table's by this fraction
RADIUS_TOLERANCE = 0.01


@dataclass(frozen=True)
class MillLaw:
    """An exported Yade law: its folder, its script and the ``MILLIMPACT_LAW`` data it embeds."""

    folder: Path
    script: Path
    data: dict

    @property
    def ball_radius(self) -> float:
        return float(self.data["ball_radius_m"])

    @property
    def friction(self) -> float:
        return float(self.data["friction"])

    @property
    def young(self) -> float:
        """Young's modulus of the law's materials (Pa): two of them give the constant law's E*."""
        return float(self.data["yade"]["young_Pa"])

    @property
    def poisson(self) -> float:
        return float(self.data["yade"]["poisson"])

    @property
    def e_star_max(self) -> float:
        """The stiffest ball-liner contact modulus of the table (Pa)."""
        return max(max(row) for row in self.data["e_star_Pa"])

    @property
    def restitution_range(self) -> tuple[float, float]:
        """The smallest and largest e_n of the table."""
        e = [x for row in self.data["restitution_normal_table"] for x in row]
        return min(e), max(e)

    @property
    def speeds(self) -> list[float]:
        return [float(s) for s in self.data["speeds_m_s"]]


def _refuse(folder, why: str) -> InputError:
    return InputError(f"--law {folder}: {why}; give a folder written by `millimpact export TABLE --to yade`")


def read_mill_law(folder) -> MillLaw:
    """The law of an export folder for Yade; InputError (one line) for anything else."""
    d = Path(folder)
    if not d.is_dir():
        raise _refuse(folder, "not a folder")
    meta_path, script = d / LAW_JSON, d / LAW_SCRIPT
    if not meta_path.is_file():
        raise _refuse(folder, f"has no {LAW_JSON}")
    try:
        meta = json.loads(meta_path.read_text())
        code = meta.get("code")
    except (ValueError, AttributeError, OSError):
        raise _refuse(folder, f"{LAW_JSON} is not an export's") from None
    if code != "yade":
        raise _refuse(folder, f"an export for {code!r}, the mill runs Yade")
    if not script.is_file():
        raise _refuse(folder, f"has no {LAW_SCRIPT}")
    text = script.read_text()
    key = "MILLIMPACT_LAW = "
    try:
        data, _ = json.JSONDecoder().raw_decode(text, text.index(key) + len(key))
        for k in (
            "speeds_m_s",
            "angles_deg",
            "zeta",
            "e_star_Pa",
            "restitution_normal_table",
            "friction",
            "ball_radius_m",
        ):
            data[k]
        for k in ("young_Pa", "poisson", "ball_material", "liner_material"):
            data["yade"][k]
    except (ValueError, KeyError, TypeError):
        raise _refuse(folder, f"{LAW_SCRIPT} holds no MILLIMPACT_LAW") from None
    if "def millimpact_update" not in text:
        raise _refuse(folder, f"{LAW_SCRIPT} has no runtime (millimpact_update)")
    return MillLaw(d.resolve(), script.resolve(), data)


def check_law_ball(law: MillLaw, ball_radius: float) -> None:
    """Refuse a mill whose balls are not the table's (radius within RADIUS_TOLERANCE)."""
    if abs(ball_radius / law.ball_radius - 1.0) > RADIUS_TOLERANCE:
        raise InputError(
            f"--law {law.folder}: its table is for balls of radius {law.ball_radius:g} m, the "
            f"scene's are {ball_radius:g} m; export a table of this ball "
            f"(or --set ball.radius={law.ball_radius:g})"
        )
