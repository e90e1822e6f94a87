"""A run's peak memory, estimated from its plan before meshing, and the up-front refusal of a run
that would not fit (rather than the kernel killing it halfway).

Estimate: the DOFs N of the plan's mesh (:func:`millimpact.scene.sizing.estimate_mesh`) at the
method's Lagrange degree, and the model peak = MEMORY_MARGIN (base + c N^(4/3) / ranks) per rank:
the base is the interpreter with DOLFINx, PETSc and the forms; N^(4/3) is how the fill of a sparse direct
factorization of a 3D mesh grows (Lipton, Rose and Tarjan, SIAM J. Numer. Anal. 16 (1979) 346-358),
and the factorizations dominate the peak. Fitted to the peak RSS of liner-panel runs at 1 rank
(``benchmarks/memory_fit.py``; the table and the fit's error are in docs/scenes.md, "Memory");
the margin covers what a whole impact at the plan's contact size adds to the short fitting runs
(and full P2, fitted by full P1's law, its denser factors: :data:`FULL_P2_MARGIN`);
the division by the ranks (MUMPS distributes its factors) is an assumption, not yet measured.
A reduced run whose struck body is cut into slabs (:mod:`millimpact.reduction.substructures`,
by itself from 600k interior DOFs) factorizes one slab at a time: its model is the largest slab's
factorization by the same fit plus the model's matrices spread over the ranks (:data:`SLAB_MODEL`).
``full`` has its own fit; the reduced methods (``improved``, ``modal-p2``, ``traditional``,
``hertz-modal``) use the ``improved`` fit (factorization, SLEPc and the constraint modes dominate
all of them); ``hertz`` is not checked.

Available: ``MemAvailable`` of /proc/meminfo, and, when the cgroup (v2) sets a limit,
``memory.max - memory.current`` of /sys/fs/cgroup, the smaller; the ranks on one node share it.
A run is refused when its ranks on this node would need more than :data:`USABLE_SHARE` of it.
``MILLIMPACT_AVAILABLE_MEMORY`` (bytes) overrides the available memory (tests), and
``MILLIMPACT_MEMORY_CHECK=off`` turns the check off.
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path
from typing import NamedTuple

from ..errors import InputError
from ..integration.solvers import normalize_options
from ..reduction.substructures import substructure_settings
from ..scene.plan import Plan, smallest_size
from ..scene.schema import Scene
from ..scene.sizing import estimate_mesh

#: peak RSS model per method family: (base bytes, c bytes), peak = base + c N^(4/3) / ranks, fitted
#: to short runs (time.end 0.1 ms, h_contact = h_far / 10; docs/scenes.md, "Memory"): full P1 over
#: 5.2k-54k DOFs within 1.4 %, improved P2 over 31k-167k DOFs within 3.5 %
MEMORY_MODELS: dict[str, tuple[float, float]] = {
    "full": (221e6, 513.0),
    "reduced": (250e6, 613.0),
}
#: whole impacts at the plan's h_contact (plastic zone, its tangent factorizations, the time
#: series) peaked at up to this many times the short runs' fit at the same DOFs (full P1 at 13.8k
#: and 26.5k DOFs: 1.31x and 1.37x; improved P2 at 90.8k: 1.12x; docs/scenes.md, "Memory"): the
#: estimate includes it
MEMORY_MARGIN = 1.4
#: ... but full P2 (whose fit is full P1's) peaked at 2.27x it in a whole plastic impact (90.8k
#: DOFs, 5.25 GB; elastic: 0.95x): one run measured
FULL_P2_MARGIN = 2.3
#: the substructured reduction (one slab factorized at a time on each rank, the largest the one
#: around the zone): (the largest slab's share of the DOFs, bytes a DOF of the model spread over the
#: ranks on top of the slab's own fit), from the liner panel's million-DOF run (1,194,723 DOFs, 2
#: ranks, 16 slabs, margin 0.25: the zone's slab 244,114 DOFs, 20.4 %): base + c L^(4/3) by the
#: reduced fit is 9.6 GB, the busiest rank peaked at 8.88 GB (10.1-10.9 GB before the products
#: K_iz G, M_iz G stopped holding the interior rows of K and M): no term on top (one run, a whole
#: impact, 8 % high). Since the zone's slab is cut again across (its largest piece 80k dofs) the
#: busiest rank peaks at 7.67-7.83 GB: the estimate is ~22 % high, kept (one measured size)
SLAB_MODEL = (0.204, 0.0)
#: the exponent of N in the model (module docstring)
EXPONENT = 4.0 / 3.0
#: the Lagrange degree each method meshes with (``full``: the plan's or ``--degree``)
METHOD_DEGREE = {"improved": 2, "modal-p2": 2, "traditional": 1}
#: refuse when the estimate exceeds this share of the available memory (the fit's error and what
#: else runs on the machine)
USABLE_SHARE = 0.9
GB = 1e9


class MemoryEstimate(NamedTuple):
    """A run's estimated peak memory per rank (bytes), with what it came from."""

    per_rank: float
    dofs: int
    degree: int
    ranks: int


def method_degree(method: str, plan: Plan, options: dict | None = None) -> int:
    """The Lagrange degree a ``method`` run of ``plan`` uses."""
    if method in METHOD_DEGREE:
        return METHOD_DEGREE[method]
    asked = (options or {}).get("degree")
    return int(asked) if asked not in (None, "") else plan.degree


def substructured(dofs: int, options: dict | None = None) -> bool:
    """Whether a reduced run of ``dofs`` DOFs cuts its struck body into slabs
    (``-impact_reduction_block_substructures``, or by itself: :func:`~millimpact.reduction.substructures.auto_slabs`).
    The model's DOFs stand in for the region's interior dofs, which the plan does not know (the
    ball and the zone are ~6 % of the panel's): near the threshold the two can disagree."""
    body = "reduction_block_"  # the reduction's own decision, on the run's options for the block
    mine = {k[len(body) :]: v for k, v in normalize_options(options).items() if k.startswith(body)}
    return substructure_settings("impact_" + body, mine, dofs) is not None


def estimate_memory(
    scene: Scene, plan: Plan, method: str, options: dict | None = None, ranks: int = 1
) -> MemoryEstimate:
    """Peak memory per rank (bytes) of a ``method`` run of ``scene`` with ``plan`` on ``ranks``
    ranks: MEMORY_MARGIN (base + c N^(4/3) / ranks) (:data:`MEMORY_MODELS`), N the estimated DOFs;
    a substructured reduction (:func:`substructured`): base + c L^(4/3) + b N / ranks with L the
    largest slab (:data:`SLAB_MODEL`)."""
    degree = method_degree(method, plan, options)
    dofs = estimate_mesh(scene, plan).dofs(degree)
    base, c = MEMORY_MODELS["full" if method == "full" else "reduced"]
    if method != "full" and substructured(dofs, options):
        share, b = SLAB_MODEL
        return MemoryEstimate(base + c * (share * dofs) ** EXPONENT + b * dofs / max(ranks, 1), dofs, degree, ranks)
    margin = FULL_P2_MARGIN if method == "full" and degree == 2 else MEMORY_MARGIN
    return MemoryEstimate(margin * (base + c * float(dofs) ** EXPONENT / max(ranks, 1)), dofs, degree, ranks)


def available_memory() -> tuple[float, str]:
    """(bytes, where from): the smaller of MemAvailable and the cgroup's free limit, or the
    ``MILLIMPACT_AVAILABLE_MEMORY`` override."""
    override = available_override()
    if override is not None:
        return override, "MILLIMPACT_AVAILABLE_MEMORY"
    best, where = float("inf"), "unknown"
    try:
        for line in Path("/proc/meminfo").read_text().splitlines():
            if line.startswith("MemAvailable:"):
                best, where = float(line.split()[1]) * 1024, "MemAvailable"
    except OSError:
        pass
    try:
        limit = Path("/sys/fs/cgroup/memory.max").read_text().strip()
        if limit != "max":
            used = float(Path("/sys/fs/cgroup/memory.current").read_text().strip())
            if float(limit) - used < best:
                best, where = float(limit) - used, "cgroup memory.max - memory.current"
    except (OSError, ValueError):
        pass
    return best, where


def available_override() -> float | None:
    """``MILLIMPACT_AVAILABLE_MEMORY`` in bytes (None: unset); not a number > 0 is one line (InputError)."""
    env = os.environ.get("MILLIMPACT_AVAILABLE_MEMORY")
    if not env:
        return None
    try:
        value = float(env)
    except ValueError:
        value = float("nan")
    if not (value > 0 and value != float("inf")):
        raise InputError(
            f"MILLIMPACT_AVAILABLE_MEMORY={env!r}: must be a number of bytes > 0 (e.g. 8e9), "
            "or unset to read the machine's"
        )
    return value


#: the values of ``MILLIMPACT_MEMORY_CHECK`` (case ignored; unset or empty: on)
CHECK_SWITCH = {
    "off": False,
    "0": False,
    "no": False,
    "false": False,
    "on": True,
    "1": True,
    "yes": True,
    "true": True,
    "": True,
}


def memory_check_applies(method: str) -> bool:
    """Whether :func:`check_memory` looks at a ``method`` run (not ``hertz``, not when
    ``MILLIMPACT_MEMORY_CHECK=off``); another value of it, or a ``MILLIMPACT_AVAILABLE_MEMORY``
    that is not a number of bytes, is one line (InputError), whatever the method."""
    available_override()
    value = os.environ.get("MILLIMPACT_MEMORY_CHECK", "")
    switch = CHECK_SWITCH.get(value.strip().lower())
    if switch is None:
        raise InputError(
            f"MILLIMPACT_MEMORY_CHECK={value!r}: must be off (or 0, no, false) to turn the memory "
            "check off, or on (1, yes, true; the default)"
        )
    return method != "hertz" and switch


def check_memory(
    scene: Scene, plan: Plan, method: str, options: dict | None = None, ranks: int = 1, ranks_on_node: int = 1
) -> MemoryEstimate | None:
    """Refuse (:class:`InputError`, one line: the estimate, the available memory and the option to
    change) a run whose ``ranks_on_node`` ranks would not fit in this node's available memory;
    returns the estimate (None when not checked)."""
    if not memory_check_applies(method):
        return None
    est = estimate_memory(scene, plan, method, options, ranks)
    avail, where = available_memory()
    need = est.per_rank * ranks_on_node
    if need <= USABLE_SHARE * avail:
        return est
    # the far size that would fit (the plan's sizes otherwise), to name in the message
    h, suggestion = plan.h_far, ""
    while h < smallest_size(scene):  # coarser than the smallest body size is no model
        h *= 1.1
        trial = dataclasses.replace(plan, h_far=h)
        e = estimate_memory(scene, trial, method, options, ranks)
        if e.per_rank * ranks_on_node <= USABLE_SHARE * avail:
            suggestion = f"--set model.h_far={h:.3g} (~{e.dofs:,} DOFs, {e.per_rank / GB:.3g} GB a rank)"
            break
    if not suggestion:
        suggestion = (
            f"--set model.h_contact=... (larger; no far size up to the smallest body size "
            f"{smallest_size(scene) * 1e3:.3g} mm fits)"
        )
    raise InputError(
        f"estimated peak memory {est.per_rank / GB:.3g} GB a rank x {ranks_on_node} rank(s) on this node "
        f"({method}, P{est.degree}, ~{est.dofs:,} DOFs, h_far {plan.h_far * 1e3:.3g} mm) exceeds "
        f"{USABLE_SHARE:.0%} of the available {avail / GB:.3g} GB ({where}): coarsen the mesh with "
        f"{suggestion}, or run on a machine with more memory"
    )
