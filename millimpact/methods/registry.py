"""The method registry: every ``--method`` in one table.

Each entry names the module (under :mod:`millimpact.methods`) and the function that runs it,
``run(scene, plan, options, progress) -> RunOutput``. The table imports nothing: a method's
module (and with it DOLFINx, PETSc, SLEPc) is loaded when the method runs, so ``--help`` lists
every method at once and cheaply. To add a method: write its module, add one row here.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from typing import NamedTuple

from ..errors import InputError


class MethodEntry(NamedTuple):
    """A run method: its ``--method`` name, family, one-line summary and where its runner lives."""

    name: str
    family: str  #: "analytical", "fe" (full finite elements) or "reduced" (Craig-Bampton)
    summary: str
    module: str  #: module under millimpact.methods
    function: str = "run"
    #: what the contact point's velocity and acceleration are: "patch" (the centre of mass of the
    #: half-ball of radius a_max under it: FE models) or "surface" (the surface point of the
    #: quasi-static Hertz solution, share * d(delta)/dt: the Hertz models, which have no patch)
    contact_point_kinematics: str = "patch"


METHODS: tuple[MethodEntry, ...] = (
    # the paper's improved multivariable method: contact zone by first-order manifold covers on
    # P2, non-contact region by Craig-Bampton modes up to f_cut
    MethodEntry("improved", "reduced", "P2 NMM contact zone + modal region (the paper's)", "reduced", "run_improved"),
    # the paper's traditional multivariable method: the zone's nodal P1 unknowns kept
    MethodEntry("traditional", "reduced", "P1 nodal contact zone + modal region (paper)", "reduced", "run_traditional"),
    MethodEntry("modal-p2", "reduced", "as traditional on the P2 model", "reduced", "run_modal_p2"),
    # the converged reference is P2 (--degree 2); the plan's P1 is cheaper and ~3 % stiff
    MethodEntry(
        "full", "fe", "unreduced finite elements: P1 by default (~3 % stiff), the reference with --degree 2", "full"
    ),
    MethodEntry(
        "hertz-modal",
        "reduced",
        "Hertz spring (rigid ball) on the block's modes",
        "hertz_modal",
        contact_point_kinematics="surface",
    ),
    MethodEntry(
        "hertz",
        "analytical",
        "quasi-static Hertz, 1 DOF: the lightest model",
        "hertz",
        contact_point_kinematics="surface",
    ),
)

#: the method of ``millimpact run`` when none is given: within 0.3 % of full P2 on the same mesh
#: (F_max, t_c) at a fraction of its cost (benchmarks/reduced_vs_full.py)
DEFAULT_METHOD = "improved"

_BY_NAME = {m.name: m for m in METHODS}


def method_names(family: str | None = None) -> list[str]:
    """The registered names (of one family, if given), in table order."""
    return [m.name for m in METHODS if family is None or m.family == family]


def method_entry(name: str) -> MethodEntry:
    """The entry of ``name``; an unknown name is an :class:`InputError` listing the methods."""
    try:
        return _BY_NAME[name]
    except KeyError:
        raise InputError(f"--method = {name!r}: must be one of {', '.join(method_names())}") from None


def method_runner(name: str) -> Callable:
    """The runner of method ``name``, imported on first use."""
    entry = method_entry(name)
    module = importlib.import_module(f"{__package__}.{entry.module}")
    return getattr(module, entry.function)


def method_help() -> str:
    """One line per method, for ``--help`` (an argparse help text: its % are doubled)."""
    return "\n".join(f"{m.name}: {m.summary}" for m in METHODS).replace("%", "%%")
