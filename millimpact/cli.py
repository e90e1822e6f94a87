"""The ``millimpact`` command line.

Bad input ends in one line on stderr naming the field and its allowed range, and exit status 2.
PETSc options (``-impact_ksp_type gmres`` ...) may follow any run command and reach PETSc.
"""

from __future__ import annotations

import argparse
import faulthandler
import logging
import os
import re
import signal
import sys
from pathlib import Path

from .console import enable_stages, say, world_rank
from .errors import InputError, MillimpactError, OutputError, Terminated
from .fem.jit_cache import release_interrupted_compile, stale_jit_claim
from .interrupts import ON_SIGNAL, command_signals, pending_signal
from .methods.registry import DEFAULT_METHOD, method_entry, method_help, method_names
from .results.output_folder import FORCE_HELP, OUT_HELP, claim_output, default_out, interrupt_note, release_locks

EXIT_INPUT = 2
EXIT_FAILURE = 1

DESCRIPTION = """\
millimpact: 3D impact dynamics of a grinding ball on a SAG mill liner (DOLFINx).

Typical use:
  millimpact run                        the default scene (paper-rig) -> out/paper-rig/
  millimpact run hertz-halfspace --method hertz --out out/hh
  millimpact hertz                      Hertz values of the default scene
  millimpact scene export paper-rig > my.toml   (edit, then: millimpact run my.toml)
"""


_PETSC_OPTION = re.compile(r"^-[A-Za-z][A-Za-z0-9_]+$")


def split_petsc_options(argv: list[str]) -> tuple[list[str], dict[str, str]]:
    """Separate PETSc-style options (``-impact_ksp_type gmres``, ``-log_view``: one dash, a name
    of two or more characters, an optional value) from the arguments argparse reads."""
    rest: list[str] = []
    opts: dict[str, str] = {}
    i = 0
    while i < len(argv):
        tok = argv[i]
        if _PETSC_OPTION.match(tok):
            nxt = argv[i + 1] if i + 1 < len(argv) else None
            if nxt is not None and not nxt.startswith("-") or (nxt is not None and _is_number(nxt)):
                opts[tok[1:]] = nxt
                i += 2
                continue
            opts[tok[1:]] = ""
        else:
            rest.append(tok)
        i += 1
    return rest, opts


def _is_number(text: str) -> bool:
    try:
        float(text)
        return True
    except ValueError:
        return False


# --- commands ---------------------------------------------------------------------------------
def cmd_hertz(args: argparse.Namespace) -> int:
    from .scene.builtin import resolve_scene

    scene = resolve_scene(args.scene)
    from .scene.plan import scene_hertz  # numpy and scipy: after the input is read

    h = scene_hertz(scene)
    say(f"Hertz impact of scene '{scene.name}' (ball on a half-space of the block's material)")
    for name, value, unit, _ in h.table():
        say(f"  {name:<26s} {value:12.5g} {unit}")
    from .scene.plan import first_yield_notes

    for note in first_yield_notes(
        h, scene.ball.material, scene.target_material, "liner" if scene.liner is not None else "block"
    ):
        say(f"  note: {note}")
    return 0


def cmd_scene(args: argparse.Namespace) -> int:
    from .scene.builtin import BUILTIN_SCENES, BUILTIN_STUDIES, DEFAULT_SCENE, resolve_scene
    from .scene.toml_io import dump_scene

    if args.action == "list":
        say("built-in scenes:")
        for name in BUILTIN_SCENES:
            s = resolve_scene(name)
            say(f"  {name:<16s}{' (default)' if name == DEFAULT_SCENE else ''}  {s.description}")
        say("built-in studies (millimpact study NAME):")
        for name, st in BUILTIN_STUDIES.items():
            say(f"  {name:<16s} {st.label} = {', '.join(f'{v:g}' for v in st.display)} {st.unit} on {st.base}")
        return 0
    scene = resolve_scene(args.name)
    if args.action == "export":
        sys.stdout.write(dump_scene(scene))
        return 0
    # show: resolved scene with units, and the plan of the method that will run
    method_entry(args.method)
    from .scene.plan import make_plan  # numpy and scipy: after the input is read

    plan = make_plan(scene)
    method_notes: list[str] = []
    if args.method in method_names("reduced") and args.method != "hertz-modal":
        from .methods.reduced import REDUCED_METHODS, reduced_plan

        scene, plan, _, method_notes = reduced_plan(scene, plan)
        method_notes = [f"P{REDUCED_METHODS[args.method][0]} ({REDUCED_METHODS[args.method][1]} zone)"] + method_notes
    b, k, i = scene.ball, scene.block, scene.impact
    say(f"scene '{scene.name}': {scene.description}")
    say(
        f"  ball    radius {b.radius * 1e3:g} mm, mass {b.mass * 1e3:.4g} g, rho {b.material.density:g} kg/m^3, "
        f"G {b.material.shear_modulus / 1e9:g} GPa, nu {b.material.poisson:g} (E {b.material.youngs_modulus / 1e9:.4g} GPa)"
    )
    if scene.liner is not None:
        ln, p, n = scene.liner, scene.impact_point, scene.contact_normal
        say(
            f"  liner   plate {ln.length * 1e3:g} x {ln.width * 1e3:g} x {ln.thickness * 1e3:g} mm, {ln.n_lifters} lifter(s) "
            f"{ln.lifter_height * 1e3:g} mm high, top {ln.lifter_top_width * 1e3:g} mm, face angle {ln.lifter_face_angle:g} deg, "
            f"mill radius {ln.mill_radius:g} m; rho {ln.material.density:g} kg/m^3, G {ln.material.shear_modulus / 1e9:g} "
            f"GPa, nu {ln.material.poisson:g}"
        )
        if ln.bolt_holes():
            say(
                f"  bolts   {len(ln.bolt_holes())} holes of {ln.bolt_hole_diameter * 1e3:g} mm (clamped) at x "
                f"{', '.join(f'{x * 1e3:g}' for x in ln.bolt_x)} mm x arc {', '.join(f'{a * 1e3:g}' for a in ln.bolt_arc)} mm; "
                + (
                    "back face clamped"
                    if ln.backing == "clamped"
                    else f"back face on a rubber backing: E_c {ln.backing_modulus / 1e9:.3g} GPa, {ln.backing_thickness * 1e3:g} mm, "
                    f"k_n {ln.backing_stiffness:.3g} Pa/m"
                )
            )
        say(
            f"  impact  velocity ({', '.join(f'{c:g}' for c in i.velocity)}) m/s, |v| {i.speed:g} m/s, normal "
            f"{scene.normal_speed:.4g} m/s; point ({', '.join(f'{c * 1e3:.4g}' for c in p)}) mm on lifter "
            f"{ln.impact_lifter} face {ln.impact_face}, normal ({', '.join(f'{c:.4g}' for c in n)})"
            if ln.impact_place == "lifter_face"
            else f"  impact  velocity ({', '.join(f'{c:g}' for c in i.velocity)}) m/s, |v| {i.speed:g} m/s, normal "
            f"{scene.normal_speed:.4g} m/s; point ({', '.join(f'{c * 1e3:.4g}' for c in p)}) mm on the "
            f"{'top of lifter ' + str(ln.impact_lifter) if ln.impact_place == 'lifter_top' else 'plate'}, "
            f"{ln.impact_arc * 1e3:.4g} mm from lifter {ln.impact_lifter}'s centre line, normal "
            f"({', '.join(f'{c:.4g}' for c in n)})"
        )
    else:
        say(
            f"  block   {k.length * 1e3:g} x {k.thickness * 1e3:g} x {k.height * 1e3:g} mm (length x thickness x height), "
            f"support '{k.support}', rho {k.material.density:g} kg/m^3, G {k.material.shear_modulus / 1e9:g} GPa, "
            f"nu {k.material.poisson:g}"
        )
        x, _, z = scene.impact_point
        say(
            f"  impact  velocity ({', '.join(f'{c:g}' for c in i.velocity)}) m/s, |v| {i.speed:g} m/s, "
            f"point (x {x * 1e3:g} mm, z {z * 1e3:g} mm) on face y = 0"
        )
    if scene.contact.friction > 0:
        say(f"  contact Coulomb friction mu = {scene.contact.friction:g}")
    for g in scene.gauges:
        say(
            f"  gauge {g.name}  at ({', '.join(f'{c * 1e3:g}' for c in g.position)}) mm, "
            f"direction ({', '.join(f'{c:g}' for c in g.direction)})"
        )
    say(f"  time    end {scene.time.end * 1e3:g} ms")
    say(f"plan of --method {args.method} (derived from the Hertz estimate; override in [model], [time], impact.gap):")
    # an analytical model meshes nothing: only its flight gap and time step apply
    analytical = args.method in method_names("analytical")
    for name, value, why in plan.table():
        if analytical and name not in ("gap", "dt_contact"):
            continue
        if name == "degree" and method_notes:
            value, why = method_notes[0].split(" ", 1)[0], "the method's"
        if name == "zone_radius" and method_notes:
            why = "the reduced methods' (note below)"
        say(f"  {name:<14s} {value:<28s} {why}")
    for note in method_notes[1:]:
        say(f"  note: {note}")
    if args.method != "hertz":
        from .methods.memory import estimate_memory

        est = estimate_memory(scene, plan, args.method)
        say(
            f"  size: ~{est.dofs:,} P{est.degree} DOFs, peak memory ~{est.per_rank / 1e9:.3g} GB at 1 rank "
            "(estimated before meshing: millimpact/scene/sizing.py, methods/memory.py)"
        )
    return 0


def cmd_run(args: argparse.Namespace, petsc: dict[str, str]) -> int:
    method_entry(args.method)  # an unknown method: one line listing them, before any work
    if petsc:
        from .integration.solvers import check_type_options

        check_type_options(petsc)  # -..._ksp_type nosuch: one line, not a PETSc error number later
    from .scene.builtin import DEFAULT_SCENE

    scene = command_scene(args)
    out = args.out if args.out is not None else default_out(scene.name if args.scene else DEFAULT_SCENE)
    target = claim_output(out, "run", force=args.force)  # before any computing: a typo costs a second
    comm = _comm()
    enable_stages(not args.quiet)
    if args.method == "hertz":
        say("note: --method hertz is the quasi-static Hertz model (1 DOF), the lightest method.")
    options = dict(petsc)
    if args.degree:
        options["degree"] = args.degree
    if args.integrator:
        options["integrator"] = args.integrator
    for flag, key, value in (("--modes", "modes", args.modes), ("--f-cut", "f_cut", args.f_cut)):
        if value is None:
            continue
        reduced = method_names("reduced")
        if args.method not in reduced:
            raise InputError(
                f"{flag} {value:g}: applies to the reduced methods ({', '.join(reduced)}), not --method {args.method}"
            )
        if not value > 0 and not (key == "modes" and value == 0):
            raise InputError(
                f"{flag} {value:g}: must be > 0" + (" (or 0: constraint modes only)" if key == "modes" else " Hz")
            )
        options[key] = value
    from .methods.run import run_scene  # the computing stack: only once the input is accepted

    summary = run_scene(
        scene, args.method, target, options=options, progress=not args.quiet, comm=comm, reference=args.reference
    )
    h = summary["hertz"]
    rel = summary["relative_to_hertz"]
    say(f"scene {scene.name}, method {args.method}: wall time {summary['wall_time_s']:.3g} s")
    say(
        f"  peak contact force  {summary['peak_contact_force_N'] / 1e3:10.4g} kN   (Hertz {h['F_max_N'] / 1e3:.4g} kN, "
        f"{100 * rel['peak_contact_force']:+.2f} %)"
    )
    say(
        f"  contact duration    {summary['contact_duration_s'] * 1e6:10.4g} us   (Hertz {h['t_c_s'] * 1e6:.4g} us, "
        f"{100 * rel['contact_duration']:+.2f} %)"
    )
    if summary.get("max_approach_m"):
        say(
            f"  max approach        {summary['max_approach_m'] * 1e6:10.4g} um   (Hertz {h['delta_max_m'] * 1e6:.4g} um)"
        )
    if summary.get("restitution") is not None:
        say(f"  restitution         {summary['restitution']:10.4f}")
    for note in summary.get("notes", []):
        say(f"  note: {note}")
    say(f"  results in {target.shown}/ ({', '.join(summary.get('files', []))})" + target.replaced_note())
    return 0


def command_scene(args: argparse.Namespace):
    """The scene ``run`` and ``mesh`` compute: SCENE with its ``--set`` assignments, validated
    together (:func:`millimpact.commandkit.settings.command_scene`)."""
    from .commandkit.settings import command_scene as resolve

    return resolve(args.scene, args.set)


def cmd_mesh(args: argparse.Namespace) -> int:
    scene = command_scene(args)
    from .scene.plan import make_plan

    plan = make_plan(scene)
    out = args.out if args.out is not None else default_out(scene.name, suffix="-mesh")
    target = claim_output(out, "mesh", force=args.force)  # before meshing, and before importing gmsh, DOLFINx
    from .geometry.mesh import create_mesh, mesh_report, write_mesh_xdmf

    with target.staged() as stage:
        md = create_mesh(scene, plan, _comm(), export=stage / "mesh.msh")
        write_mesh_xdmf(md, stage / "mesh.xdmf")
    out = target.shown
    say(
        f"mesh of scene '{scene.name}' -> {out}/mesh.msh (gmsh, physical groups: meshes/README.md), {out}/mesh.xdmf"
        + target.replaced_note()
    )
    for name, value in mesh_report(md):
        say(f"  {name:<28s} {value}")
    return 0


#: commands that live in their own modules: each module has HELP (one line), add_arguments(parser)
#: and main(args) -> exit status, and imports nothing heavy (dolfinx, petsc4py, gmsh) at its top
EXTRA_COMMANDS = {
    "study": "millimpact.studies.study",
    "table": "millimpact.studies.table_command",
    "bench": "millimpact.studies.bench",
    "stability": "millimpact.studies.stability",
    "compare": "millimpact.studies.compare",
    "export": "millimpact.dem.export.command",
    "mill": "millimpact.dem.mill.command",
    "damage": "millimpact.damage.command",
    "life": "millimpact.life.command",
    "repeat": "millimpact.repeat.command",
}


def _command_module(name: str):
    import importlib

    return importlib.import_module(EXTRA_COMMANDS[name])


def _comm():
    from mpi4py import MPI

    return MPI.COMM_WORLD


# --- parser -----------------------------------------------------------------------------------
_RST_ROLE = re.compile(r":[a-z]+:`~?([^`<]+?)(?:\s*<[^>]*>)?`")


def plain_text(doc: str) -> str:
    """A module docstring (reStructuredText) as plain help text: roles (:mod:`x`) and literals
    (``x``) become x, section underlines and table rules go."""
    text = _RST_ROLE.sub(lambda m: m.group(1).split(".")[-1] if m.group(0).startswith(":func:") else m.group(1), doc)
    text = text.replace("``", "")
    lines = [l for l in text.splitlines() if not re.fullmatch(r"\s*[=\-~^+]{3,}[=\-~^+ ]*", l)]
    return "\n".join(lines).strip()


class _LineFormatter(argparse.HelpFormatter):
    """Wraps each line of a help text on its own, so a list (one method per line) stays a list."""

    def _split_lines(self, text, width):
        lines = []
        for line in text.splitlines():
            lines += super()._split_lines(line, width) or [""]
        return lines


class _Parser(argparse.ArgumentParser):
    """argparse with millimpact's one-line errors: ``millimpact: error: ...`` and exit status 2 for
    every command (argparse's own: a usage block and a per-command prefix)."""

    def error(self, message: str):
        command = self.prog.split(" ", 1)[1] if " " in self.prog else ""
        where = f"millimpact {command}".strip()
        if world_rank() == 0:
            print(
                f"millimpact: error: {command + ': ' if command else ''}{message}; see '{where} --help'",
                file=sys.stderr,
            )
        sys.exit(EXIT_INPUT)


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="millimpact", description=DESCRIPTION, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("-v", "--verbose", action="store_true", help="log progress details")
    p.add_argument(
        "--version",
        action=_VersionAction,
        nargs=0,
        help="print millimpact's version and those of DOLFINx, PETSc, SLEPc and gmsh",
    )
    sub = p.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)

    r = sub.add_parser(
        "run",
        help="simulate a scene and write summary, time series, fields and figures",
        formatter_class=_LineFormatter,
        description="Simulate SCENE (a built-in name or a .toml file; default paper-rig) and "
        "write DIR/summary.json, timeseries.csv/.h5, scene.toml, figures and fields. "
        "PETSc options such as -impact_ksp_type may follow.",
    )
    r.add_argument("scene", nargs="?", help="built-in scene name or TOML file (default: paper-rig)")
    r.add_argument(
        "--method",
        default=DEFAULT_METHOD,
        metavar="METHOD",
        help=f"solution method (default {DEFAULT_METHOD}):\n{method_help()}",
    )
    r.add_argument("--out", help=OUT_HELP.format(default="out/SCENE"))
    r.add_argument("--force", action="store_true", help=FORCE_HELP)
    r.add_argument(
        "--set",
        action="append",
        metavar="FIELD=VALUE",
        help="override a scene field, e.g. --set ball.radius=0.02 --set model.h_contact=2e-4",
    )
    r.add_argument(
        "--degree",
        type=int,
        choices=[1, 2],
        help="Lagrange degree of --method full (default the plan's, P1: F_max about +3 %%, P2 within "
        "~1 %%); the reduced methods have their own (improved, modal-p2: P2; traditional: P1)",
    )
    r.add_argument(
        "--integrator",
        choices=["newmark-mr", "newmark", "central-penalty"],
        help="time integrator of FE methods: newmark-mr (default: Newmark average acceleration with "
        "mass redistribution), newmark (plain, chatters), central-penalty (explicit)",
    )
    r.add_argument(
        "--modes",
        type=int,
        metavar="N",
        help="reduced methods: fixed-interface modes kept per body (wins over the cutoff)",
    )
    r.add_argument(
        "--f-cut",
        type=float,
        metavar="HZ",
        help="reduced methods: modal cutoff of the reduction in Hz (default the plan's 4 / t_c; "
        "the output grid keeps the plan's)",
    )
    r.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    r.add_argument(
        "--reference",
        action="store_true",
        help="also write reference.h5 / reference.csv (+ .json): a versioned reference file other "
        "implementations are scored against with 'millimpact compare'",
    )

    h = sub.add_parser(
        "hertz",
        help="print the Hertz impact values of a scene",
        description="Closed-form Hertz impact of the scene's ball on a half-space of the "
        "block's material: delta_max, F_max, t_c, a_max, p0, max shear and depth.",
    )
    h.add_argument("scene", nargs="?", help="built-in scene name or TOML file (default: paper-rig)")

    s = sub.add_parser(
        "scene",
        help="list, show or export scenes",
        description="list: built-in scenes and studies; show NAME|FILE: the resolved scene "
        "with units and the plan; export NAME|FILE: TOML to stdout, to edit.",
    )
    s.add_argument("action", choices=["list", "show", "export"])
    s.add_argument("name", nargs="?", help="built-in scene name or TOML file (default: paper-rig)")
    s.add_argument(
        "--method",
        default=DEFAULT_METHOD,
        metavar="METHOD",
        help=f"show: the plan of this method (default {DEFAULT_METHOD}; the reduced methods shrink the zone)",
    )

    m = sub.add_parser(
        "mesh",
        help="mesh a scene (gmsh) and write it as XDMF with its tags",
        description="Build (or take from the cache in meshes/) the graded two-body mesh of "
        "SCENE and write DIR/mesh.xdmf; prints element counts, h_c, zone sizes, quality.",
    )
    m.add_argument("scene", nargs="?", help="built-in scene name or TOML file (default: paper-rig)")
    m.add_argument("--out", help=OUT_HELP.format(default="out/SCENE-mesh"))
    m.add_argument("--force", action="store_true", help=FORCE_HELP)
    m.add_argument("--set", action="append", metavar="FIELD=VALUE", help="override a scene field")

    for q in sub.choices.values():
        q.add_argument("-v", "--verbose", action="store_true", default=argparse.SUPPRESS, help="log progress details")
    # commands that live in their own modules (EXTRA_COMMANDS): each module has
    # HELP (one line), add_arguments(parser) and main(args) -> exit status
    for name in EXTRA_COMMANDS:
        mod = _command_module(name)
        q = sub.add_parser(
            name,
            help=mod.HELP,
            description=plain_text(getattr(mod, "DESCRIPTION", mod.HELP)),
            formatter_class=argparse.RawDescriptionHelpFormatter,
        )
        mod.add_arguments(q)
        q.add_argument("-v", "--verbose", action="store_true", default=argparse.SUPPRESS, help="log progress details")
    return p


class _CompilerChatter(logging.Filter):
    """The form compiler's C build (cffi / setuptools) logs each gcc command on the root logger and
    raises the root level to INFO while it does: one line "compiling forms" instead, unless -v."""

    def __init__(self, verbose: bool):
        super().__init__()
        self.verbose, self.told = verbose, False

    def filter(self, record: logging.LogRecord) -> bool:
        if record.name != "root" or record.levelno >= logging.WARNING or self.verbose:
            return True
        if not self.told and world_rank() == 0:
            print("compiling forms (first run only: JIT, a few seconds per form)", file=sys.stderr)
            self.told = True
        return False


class _VersionAction(argparse.Action):
    """``--version``: computed when asked, not for every command."""

    def __call__(self, parser, namespace, values, option_string=None):
        say(version_text())
        parser.exit(0)


#: the stack ``--version`` reports: (name, Python module, its distribution's name or None)
STACK = (
    ("DOLFINx", "dolfinx", "fenics-dolfinx"),
    ("PETSc", "petsc4py", "petsc4py"),
    ("SLEPc", "slepc4py", "slepc4py"),
    ("gmsh", "gmsh", None),
)


def version_text() -> str:
    """millimpact's version and the stack's, for ``--version`` and bug reports.

    Read without importing the stack (importing DOLFINx, PETSc and gmsh takes ~1 s): from the
    installed distribution's metadata when it describes the module Python would import, else from
    the module's source (``__version__ = "..."`` or gmsh's ``GMSH_API_VERSION = "..."``), else by
    importing it."""
    import importlib
    import importlib.metadata
    import importlib.util

    from . import __version__

    parts = [f"millimpact {__version__}"]
    for name, module, dist in STACK:
        try:
            spec = importlib.util.find_spec(module)
        except (ImportError, ValueError):
            spec = None
        if spec is None or spec.origin is None:
            parts.append(f"{name} not installed")
            continue
        origin = Path(spec.origin)
        where = origin.parent if origin.name == "__init__.py" else origin
        version = None
        if dist is not None:
            try:
                d = importlib.metadata.distribution(dist)
                if Path(str(d.locate_file(where.name))).resolve() == where.resolve():
                    version = d.version
            except (importlib.metadata.PackageNotFoundError, OSError):
                pass
        if version is None and origin.suffix == ".py":
            try:
                found = re.search(
                    r'^(?:__version__|GMSH_API_VERSION)\s*=\s*["\']([^"\']+)["\']',
                    origin.read_text(errors="replace"),
                    re.M,
                )
                version = found.group(1) if found else None
            except OSError:
                pass
        if version is None:
            try:
                version = importlib.import_module(module).__version__
            except Exception:  # a broken install: say so rather than fail --version
                version = "(version unknown)"
        parts.append(f"{name} {version}")
    return ", ".join(parts)


class _CheckedStdout:
    """Standard output whose failed writes (a full device: ``> /dev/full``) end the command in one
    line, exit status 1 (an ``OutputError``), not a traceback; a reader going away stays a
    ``BrokenPipeError``. After a failure the descriptor points to /dev/null, so the interpreter's
    final flush is quiet."""

    def __init__(self, stream):
        self._stream = stream

    def _guard(self, call, *args):
        try:
            return call(*args)
        except BrokenPipeError:
            raise
        except OSError as exc:
            try:
                os.dup2(os.open(os.devnull, os.O_WRONLY), self._stream.fileno())
            except (OSError, ValueError, AttributeError):
                pass
            raise OutputError(f"cannot write to standard output ({exc.strerror or exc})") from None

    def write(self, text):
        return self._guard(self._stream.write, text)

    def flush(self):
        return self._guard(self._stream.flush)

    def __getattr__(self, name):
        return getattr(self._stream, name)


def main(argv: list[str] | None = None) -> int:
    stdout = sys.stdout
    sys.stdout = _CheckedStdout(stdout)
    _SAID_INTERRUPT.clear()
    mpi_ranks = int(os.environ.get("OMPI_COMM_WORLD_SIZE", os.environ.get("PMI_SIZE", "1")))
    try:
        with command_signals():  # Ctrl-C and SIGTERM seen whatever a library does (interrupts.py)
            if mpi_ranks > 1:
                ON_SIGNAL.append(_interrupted_under_mpirun)
            code = _main(argv)
        sys.stdout.flush()
        return code
    except OutputError as exc:  # the last flush of standard output
        if world_rank() == 0:
            print(f"millimpact: failed: {exc}", file=sys.stderr)
        return EXIT_FAILURE
    finally:
        if _interrupted_under_mpirun in ON_SIGNAL:
            ON_SIGNAL.remove(_interrupted_under_mpirun)
        sys.stdout = stdout


#: the interrupt line was said already (by :func:`_interrupted_under_mpirun`)
_SAID_INTERRUPT: list[bool] = []


def _interrupt_line(code: int, text: str = "") -> None:
    """``millimpact: interrupted (SIGINT|SIGTERM): what is kept``, once, on rank 0."""
    if world_rank() == 0 and not _SAID_INTERRUPT:
        _SAID_INTERRUPT.append(True)
        print(
            f"millimpact: interrupted ({'SIGTERM' if code == 143 else 'SIGINT'}): {text or interrupt_note()}",
            file=sys.stderr,
            flush=True,
        )


def _interrupted_under_mpirun(signum: int) -> None:
    """Under mpirun, at the signal (in the waiting thread): mpirun sends SIGTERM to every rank and
    SIGKILL 1 s later, while the main thread may be inside a collective solve another rank has
    left. Say the line and drop the output's lock now (:data:`millimpact.interrupts.ON_SIGNAL`)."""
    import signal as _signal

    _interrupt_line(143 if signum == _signal.SIGTERM else 130)
    release_locks()


def _main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    # a native crash (DOLFINx, gmsh; PETSc has its own handler) prints the Python stack on stderr
    # instead of ending the process without a word
    try:
        faulthandler.enable()
    except (AttributeError, OSError, ValueError):  # stderr without a file descriptor (main() called in-process)
        pass
    try:
        parser = build_parser()
        argv, petsc = split_petsc_options(argv)
        args, rest = parser.parse_known_args(argv)
        # force: FFCx's __init__ calls logging.basicConfig() when it is imported, which made this
        # one a no-op (-v showed no INFO line of the package until 2026-11-26)
        logging.basicConfig(
            level=logging.INFO if args.verbose and world_rank() == 0 else logging.WARNING,
            format="%(name)s: %(message)s",
            force=True,
        )
        for handler in logging.getLogger().handlers:
            handler.addFilter(_CompilerChatter(args.verbose))
        if rest:
            where = f"'millimpact {args.command}'" if args.command else "'millimpact'"
            raise InputError(f"unrecognised arguments {' '.join(rest)!r} for {where}: see {where[:-1]} --help'")
        if args.command is None:
            parser.print_help()
            return 0
        if petsc and args.command != "run":
            raise InputError(f"PETSc options {sorted(petsc)} only apply to 'millimpact run'")
        if args.command == "run":
            return cmd_run(args, petsc)
        if args.command == "hertz":
            return cmd_hertz(args)
        if args.command == "scene":
            return cmd_scene(args)
        if args.command == "mesh":
            return cmd_mesh(args)
        return _command_module(args.command).main(args)
    except InputError as exc:
        if world_rank() == 0:
            print(f"millimpact: error: {exc}", file=sys.stderr)
        return EXIT_INPUT
    except MillimpactError as exc:
        if world_rank() == 0:
            print(f"millimpact: failed: {exc}", file=sys.stderr)
        elif not getattr(exc, "said_by_rank0", False):
            # a failure on another rank alone would otherwise end the run without a word (mpirun
            # only reports the exit code); a collective failure prints this once per rank
            print(f"millimpact: failed on rank {world_rank()}: {exc}", file=sys.stderr)
        return EXIT_FAILURE
    except KeyboardInterrupt as exc:
        release_interrupted_compile(exc)
        code = getattr(exc, "exit_code", 143 if isinstance(exc, Terminated) else 130)
        _interrupt_line(code, str(exc))
        return code
    except TimeoutError as exc:
        stale = stale_jit_claim(exc)
        if stale is None:
            raise
        if world_rank() == 0:  # FFCx's claim of a module whose compile never finished
            print(
                f"millimpact: failed: JIT compilation timed out waiting for {stale}, left by a compile that "
                f"did not finish (a run killed while compiling forms); remove that file and run again",
                file=sys.stderr,
            )
        return EXIT_FAILURE
    except BrokenPipeError:
        # the reader went away (``millimpact ... | head``): not an error of ours, and no traceback
        try:
            sys.stdout = open(os.devnull, "w")
        except OSError:
            pass
        return 0
    except Exception as exc:
        if pending_signal() is not None:
            # the interruption, turned into another exception by the code it stopped: Python 3.11
            # wraps one raised in a __set_name__ (matplotlib's import: Axes3D's class body) in a
            # RuntimeError; was a traceback and exit 1 in 1 of 20 Ctrl-Cs while a table was written
            release_interrupted_compile(exc)
            code = 143 if pending_signal() == signal.SIGTERM else 130
            _interrupt_line(code)
            return code
        # an unexpected failure on one rank must not leave the others waiting forever
        if "OMPI_COMM_WORLD_SIZE" in os.environ and int(os.environ["OMPI_COMM_WORLD_SIZE"]) > 1:
            import traceback

            traceback.print_exc()
            sys.stderr.flush()
            from mpi4py import MPI

            MPI.COMM_WORLD.Abort(1)
        raise


if __name__ == "__main__":
    sys.exit(main())
