"""The exported LIGGGHTS law run in LIGGGHTS (Debian's ``liggghts``, 3.8.0): the round trip.

The script (:mod:`.wall_impacts`) includes the exported ``contact_law_liggghts.in`` as it is and
adds the liner as a ``wall/gran`` plane of type 2 with the file's model (``model hertz tangential
history``, ``limitForce on``, no tangential damping). ``limitForce on`` matters: without it
LIGGGHTS keeps the dashpot's attractive force at the end of the contact, and a 15 mm steel ball at
3 m/s with ``coefficientRestitution 0.8`` rebounds at e = 0.8000 instead of relation (1)'s 0.8081
(measured both ways; docs/dem.md).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from ..programs import find_program
from .files import ExportedLaw
from .wall_impacts import impact_cases, run_cases, table_points

#: how a user gets LIGGGHTS on this project's machines (Debian 12)
INSTALL_HINT = "apt-get install liggghts (Debian 12: LIGGGHTS 3.8.0)"
#: the wall fix of the round trip: the exported file's model (type 2, the plane z = 0)
WALL = (
    "fix liner all wall/gran model hertz tangential history primitive type 2 zplane 0.0 "
    "limitForce on tangential_damping off"
)
SETUP = "atom_style granular\nnewton off\ncommunicate single vel yes"


def liggghts_executable() -> str:
    """The path of ``liggghts`` (``MILLIMPACT_LIGGGHTS`` overrides); InputError if absent."""
    return find_program("liggghts", "MILLIMPACT_LIGGGHTS", INSTALL_HINT, "--check")


def run_liggghts_roundtrip(
    law: ExportedLaw,
    law_file: Path,
    workdir: Path,
    timeout: float = 1800,
    on_progress: Callable[[str], None] | None = None,
) -> list[dict]:
    """LIGGGHTS' e_n, e_t, F_max at every table point with ``law_file``; rows in grid order."""
    t = law.table
    cases = impact_cases(table_points(t), t.ball_mass, t.radius, law.e_star_const)
    return run_cases(
        [liggghts_executable()],
        workdir,
        cases,
        t.radius,
        t.ball_density,
        SETUP,
        f"include {law_file.resolve()}",
        WALL,
        timeout=timeout,
        on_progress=on_progress,
    )
