"""The verdict of a repeated-impact sequence: elastic shakedown, plastic shakedown or ratcheting.

Johnson, Contact Mechanics (1985), ch. 9 (9.2, repeated loading of a contact): under a repeated
load a body either shakes down, residual stresses and hardening making every later cycle elastic;
or reaches a closed plastic cycle (plastic shakedown: plastic work in every cycle, no net growth of
the deformation); or ratchets (the permanent deformation grows each cycle). The same ball
repeated on one spot unloads along the last unloading curve, which holds only e_1^2 of the impact
energy, so it yields again beyond the previous peak with smaller increments (foundations.md section 10).
From the per-impact outcomes (plastic work W_k, dent depth D_k, increments dD_k = D_k - D_(k-1)
with D_0 = 0):

- elastic shakedown: from impact k on, W stays below ELASTIC_SHARE of W_1 (k reported);
- plastic shakedown: W stays above that share but the dent increments have fallen below
  CLOSED_SHARE of dD_1 (a closed plastic cycle: plastic work without dent growth);
- ratcheting: the dent increments do not decay: their ratio from impact to impact, fitted over
  the last FIT_IMPACTS increments (log-linear), is at least RATCHET_RATIO;
- undecided: the increments decay but are not yet small; the impacts the fitted ratio needs to
  bring them to CLOSED_SHARE are reported.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

#: elastic shakedown: an impact's plastic work below this share of the first's
ELASTIC_SHARE = 0.01
#: plastic shakedown: dent increments below this share of the first impact's dent
CLOSED_SHARE = 0.01
#: ratcheting: dent increments that shrink by less than 10 % an impact are not decaying
RATCHET_RATIO = 0.9
#: the decay ratio is fitted over the last this many dent increments
FIT_IMPACTS = 3


@dataclass(frozen=True)
class Verdict:
    """What a sequence of impacts does: ``kind`` one of "elastic shakedown", "plastic shakedown",
    "ratcheting", "undecided"; the impact from which the sequence is shaken down (None
    otherwise); ``numbers``: the figures the verdict rests on."""

    kind: str
    impacts_to_shakedown: int | None
    numbers: dict = field(default_factory=dict)


def decay_ratio(increments: Sequence[float] | np.ndarray) -> float:
    """The geometric ratio q of the last FIT_IMPACTS positive increments (dD_k ~ c q^k, a
    log-linear least-squares fit); nan with fewer than two positive ones."""
    x = np.asarray(increments, dtype=float)[-FIT_IMPACTS:]
    k = np.arange(len(x), dtype=float)
    good = x > 0
    if good.sum() < 2:
        return math.nan
    slope = np.polyfit(k[good], np.log(x[good]), 1)[0]
    return float(math.exp(slope))


def classify(outcomes: Sequence[Any]) -> Verdict:
    """The verdict of a sequence (:class:`millimpact.repeat.sequence.ImpactOutcome` values, or
    anything with ``plastic_dissipation_J`` and ``residual_dent_depth_m``; module docstring)."""
    n = len(outcomes)
    w = np.array([o.plastic_dissipation_J for o in outcomes], dtype=float)
    d = np.array([o.residual_dent_depth_m for o in outcomes], dtype=float)
    inc = np.diff(np.concatenate([[0.0], d]))
    numbers: dict[str, Any] = {"impacts": n}
    if n == 0:
        return Verdict("undecided", None, numbers)
    w1, d1 = float(w[0]), float(inc[0])
    numbers.update(
        {
            "plastic_work_first_J": w1,
            "plastic_work_last_J": float(w[-1]),
            "plastic_work_share_last": float(w[-1] / w1) if w1 > 0 else math.nan,
            "dent_first_m": d1,
            "dent_last_m": float(d[-1]),
            "dent_increment_last_m": float(inc[-1]),
            "dent_increment_share_last": float(inc[-1] / d1) if d1 > 0 else math.nan,
            "elastic_share_threshold": ELASTIC_SHARE,
            "closed_share_threshold": CLOSED_SHARE,
            "ratchet_ratio_threshold": RATCHET_RATIO,
        }
    )
    if w1 <= 0:
        numbers["reason"] = "the first impact did no plastic work: elastic from the start"
        return Verdict("elastic shakedown", 1, numbers)
    small = w < ELASTIC_SHARE * w1
    if n >= 2 and small[-1]:
        k = n
        while k - 1 >= 1 and small[k - 2]:
            k -= 1
        numbers["reason"] = f"plastic work below {ELASTIC_SHARE:.0%} of the first impact's from impact {k} on"
        return Verdict("elastic shakedown", k, numbers)
    if n < 3:
        numbers["reason"] = "too few impacts for a trend (3 or more)"
        return Verdict("undecided", None, numbers)
    q = decay_ratio(inc[1:])
    numbers["dent_increment_decay_ratio"] = q
    if d1 > 0 and inc[-1] < CLOSED_SHARE * d1:
        k = n
        while k - 1 >= 2 and inc[k - 2] < CLOSED_SHARE * d1:
            k -= 1
        numbers["reason"] = (
            f"plastic work {w[-1] / w1:.3g} of the first impact's, dent increments below "
            f"{CLOSED_SHARE:.0%} of the first dent from impact {k} on: a closed plastic cycle"
        )
        return Verdict("plastic shakedown", k, numbers)
    if not math.isfinite(q) or q >= RATCHET_RATIO:
        numbers["reason"] = (
            f"dent increments not decaying (ratio {q:.3g} an impact over the last "
            f"{min(FIT_IMPACTS, n - 1)}, threshold {RATCHET_RATIO:g})"
        )
        return Verdict("ratcheting", None, numbers)
    need = math.log(CLOSED_SHARE * d1 / inc[-1]) / math.log(q) if inc[-1] > 0 and d1 > 0 else math.nan
    numbers["impacts_more_to_closed_share"] = float(need)
    numbers["reason"] = (
        f"dent increments decaying by a ratio {q:.3g} an impact, still {inc[-1] / d1:.3g} of the "
        f"first dent; ~{max(1, math.ceil(need))} more impact(s) to reach {CLOSED_SHARE:.0%} at that rate"
    )
    return Verdict("undecided", None, numbers)
