"""The wear law's constants and their calibration on one measured figure of one mill.

A calibration is a JSON file (``calibration.json``) that ``millimpact life --calibrate-...`` writes
and ``--calibration FILE`` reads: the law's k_a, k_i, H and rho (:class:`~millimpact.life.wear.WearLaw`),
what it was calibrated on (the mill run, the measured figure and its source as the user gave it)
and its spread.

One figure fixes one number: the ratio k_i / k_a is held (``--impact-ratio``, 1 by default: a
joule of impact energy the liner absorbs removes as much steel as a newton-metre of Archard's
integral, an assumption the life's report states with the shares it gives) and both are scaled so
that the model gives the figure:

- ``--calibrate-height H0:H1:HOURS``: lifters that went from H0 to H1 mm high in HOURS of operation
  (Sarcheshmeh's SAG: 152 to 58 mm in 4000 h; Yahyaei & Banisi, Minerals Eng. 23 (2010) 1213). A
  lifter's height falls as a first-order decay, H(t) = H0 exp(-t / tau) (the thickness loss of
  Sarcheshmeh's liners follows one), so the new lifter loses height at H0 / tau,
  tau = HOURS / ln(H0 / H1): the model's rate of height loss of the new lifter (its top's mean
  depth rate less the plate's) is set to that;
- ``--calibrate-life H0:H1:HOURS``: the same figure on the life's own height curve, no decay
  assumed: the profile is moved and the mill run again in ``--cycles`` equal falls of the height
  (:func:`~millimpact.life.loop.run_life`) at the constants of ``--calibrate-height`` until the
  lifters are H1 high, T hours on; a factor on both
  constants only rescales the hours (every depth is a rate times the hours, every rate linear in
  the constants), so the constants times T / HOURS wear the same profiles and reach H1 at HOURS
  (:func:`through_life`);
- ``--calibrate-mass G_PER_KWH``: the liner's mass lost per kWh of the mill's net power (Brunswick:
  2.6 g/kWh, Orford et al. 2003): the model's mass rate per metre of mill length over the run's net
  power per metre is set to it.

Uncalibrated constants (:data:`DEFAULT_LAW`) are an order of magnitude only: k_a = 1e-3, within
the 1e-4 to 1e-2 of three-body abrasion of steels by hard minerals (E. Rabinowicz, Friction and
Wear of Materials, 2nd ed., 1995, ch. 8), and H of a Cr-Mo liner steel of 325 HB (3.19 GPa; liner
makers give 300-380 HB).
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

from ..errors import InputError
from .wear import WearLaw

#: k_a, k_i (= k_a), H (325 HB x 9.807 MPa), rho (steel)
DEFAULT_LAW = WearLaw(abrasion=1e-3, impact=1e-3, hardness_Pa=325 * 9.807e6, density_kg_m3=7850.0)
#: the relative spread of a calibration's constants by default (+-30 %)
DEFAULT_SPREAD = 0.3


@dataclass(frozen=True)
class Calibration:
    law: WearLaw
    calibrated_on: dict = field(default_factory=dict)
    spread: float = DEFAULT_SPREAD

    def to_json(self) -> str:
        return json.dumps(
            {"law": asdict(self.law), "calibrated_on": self.calibrated_on, "spread": self.spread}, indent=1
        )


def read_calibration(path: Path | str) -> Calibration:
    """A calibration file (InputError naming the file and what is wrong)."""
    path = Path(path)
    try:
        data = json.loads(path.read_text())
        law = WearLaw(**{k: float(v) for k, v in data["law"].items()})
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise InputError(f"--calibration {path}: not a calibration file ({exc})") from None
    for name in ("abrasion", "impact", "hardness_Pa", "density_kg_m3"):
        x = getattr(law, name)
        if not (math.isfinite(x) and x >= 0) or (name in ("hardness_Pa", "density_kg_m3") and x == 0):
            raise InputError(f"--calibration {path}: law.{name} {x!r} must be a finite number >= 0 (> 0 for H, rho)")
    return Calibration(law, data.get("calibrated_on", {}), float(data.get("spread", DEFAULT_SPREAD)))


def parse_height_figure(text: str, option: str = "--calibrate-height") -> tuple[float, float, float]:
    """H0:H1:HOURS (mm, mm, h), checked: H0 > H1 > 0, HOURS > 0."""
    try:
        h0, h1, hours = (float(x) for x in text.split(":"))
    except ValueError:
        raise InputError(f"{option} {text!r}: give H0:H1:HOURS, e.g. 152:58:4000 (mm, mm, h)") from None
    if not (h0 > h1 > 0 and 0 < hours <= 1e6 and all(math.isfinite(x) for x in (h0, h1, hours))):
        raise InputError(f"{option} {text!r}: needs H0 > H1 > 0 mm and HOURS in (0, 1e6]")
    return h0, h1, hours


def initial_height_rate(h0: float, h1: float, hours: float) -> float:
    """The new lifter's rate of height loss (mm per 1000 h) of the first-order decay through
    (0, h0) and (hours, h1): h0 ln(h0 / h1) / hours x 1000."""
    return h0 * math.log(h0 / h1) / hours * 1000.0


def scaled(law: WearLaw, factor: float, impact_ratio: float) -> WearLaw:
    """The law with k_a times ``factor`` and k_i = ``impact_ratio`` k_a."""
    k_a = law.abrasion * factor
    return WearLaw(
        abrasion=k_a, impact=impact_ratio * k_a, hardness_Pa=law.hardness_Pa, density_kg_m3=law.density_kg_m3
    )


def liner_steel(material) -> dict:
    """What a calibration holds of the liner's steel (a scene's ``liner.material``): its elastic
    and plastic data and source. The constants k_a, k_i are the steel's (its hardness and its
    response to abrasion and impact), so a calibration serves the steel it was made on."""
    return {
        "density_kg_m3": material.density,
        "shear_modulus_Pa": material.shear_modulus,
        "yield_stress_Pa": material.yield_stress,
        "hardening": [material.hardening_modulus, material.flow_curve, material.voce, material.swift],
        "source": material.source,
    }


def check_same_steel(cal: Calibration, steel: dict, path) -> None:
    """InputError when ``cal`` was made on another liner steel than ``steel`` (:func:`liner_steel`;
    a calibration that does not say, or an uncalibrated one, is taken as it is)."""
    theirs = cal.calibrated_on.get("liner_steel")
    if not isinstance(theirs, dict):
        return
    ours = json.loads(json.dumps(steel))  # as the file holds it (tuples as lists)
    keys = ("density_kg_m3", "shear_modulus_Pa", "yield_stress_Pa", "hardening")
    if any(theirs.get(k) != ours.get(k) for k in keys):

        def say(s: dict) -> str:
            y = s.get("yield_stress_Pa")
            curve = (s.get("hardening") or [None, None])[1]
            y = curve[0][1] if y is None and curve else y
            name = str(s.get("source", "")).split("(")[0].split(",")[0].strip()
            return f"{name or 'a steel'} of yield {'(elastic)' if y is None else f'{y / 1e6:g} MPa'}"

        raise InputError(
            f"--calibration {path}: made on another liner steel, {say(theirs)}, than this scene's, {say(ours)}; "
            "calibrate on this steel (--calibrate-height or --calibrate-mass)"
        )


def through_life(cal: Calibration, reached_hours: float, hours: float) -> tuple[Calibration, float]:
    """(the calibration whose constants reach the figure's height at ``hours``, the factor on the
    constants) from ``cal``, whose life reaches it at ``reached_hours`` (the module docstring,
    ``--calibrate-life``)."""
    factor = reached_hours / hours
    law = replace(cal.law, abrasion=cal.law.abrasion * factor, impact=cal.law.impact * factor)
    on = dict(cal.calibrated_on)
    on.update(
        what="the lifters' height after the figure's hours on the life's own profile steps",
        target=on.pop("h1_mm"),
        first_run_rate_factor=factor,
        first_run_rate_is="the constants over those that give the first-order decay's rate on the first mill run",
    )
    return Calibration(law, on, cal.spread), factor
