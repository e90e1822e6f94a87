"""The command line: output contract, one-line errors with exit status 2, PETSc options."""
import json
from types import SimpleNamespace

import numpy as np
import pytest

from conftest import SMALL_RIG, run_cli
from millimpact.results.timeseries import TimeSeries
from output_lock import main_in_process


def scene_cli(capsys, *argv):
    """``millimpact scene ARGV`` in this process (it reads a scene and prints; as a subprocess each
    call paid ~2 s of imports): the fields of run_cli's answer that the tests read."""
    code, out, err = main_in_process(capsys, ["scene", *argv])
    return SimpleNamespace(returncode=code, stdout=out, stderr=err)


def test_hertz_command_prints_the_default_values():
    r = run_cli("hertz")
    assert r.returncode == 0, r.stderr
    # foundations.md section 3: F_max 13.85 kN, t_c 87.9 us
    assert "13.847 kN" in r.stdout and "87.894 us" in r.stdout


def test_run_hertz_writes_the_output_contract(tmp_path):
    out = tmp_path / "run"
    r = run_cli("run", "paper-rig", "--method", "hertz", "--out", str(out), "-q")
    assert r.returncode == 0, r.stderr
    s = json.loads((out / "summary.json").read_text())
    for key in ("scene", "method", "peak_contact_force_N", "contact_duration_s", "max_approach_m",
                "restitution", "hertz", "wall_time_s", "model"):
        assert key in s
    # the Hertz run reproduces its own closed form: duration from F^(2/3) edge extrapolation
    assert s["peak_contact_force_N"] == pytest.approx(s["hertz"]["F_max_N"], rel=1e-4)
    assert s["contact_duration_s"] == pytest.approx(s["hertz"]["t_c_s"], rel=1e-4)
    header = (out / "timeseries.csv").read_text().splitlines()[0].split(",")
    assert header[0] == "time_s" and "contact_force_N" in header
    ts = TimeSeries.read_csv(out / "timeseries.csv")
    # impulse of an elastic rebound = 2 m v
    assert np.trapz(ts["contact_force_N"], ts.time) == pytest.approx(2 * s["hertz"]["mass_kg"] * 3.0, rel=1e-3)
    for f in ("contact_force.png", "contact_point.png", "energy.png", "timeseries.h5", "scene.toml"):
        assert (out / f).stat().st_size > 0


@pytest.mark.parametrize("args,field", [
    (["run", "--method", "hertz", "--set", "ball.radius=-0.01"], "ball.radius"),
    (["run", "--method", "hertz", "--set", "block.material.poisson=0.5"], "block.material.poisson"),
    (["run", "--method", "hertz", "--set", "impact.gap=-1e-4"], "impact.gap"),
    (["run", "--method", "hertz", "--set", "impact.velocity=[0.0, 3.0, 0.0]"], "impact.velocity"),
    (["run", "no-such-scene", "--method", "hertz"], "scene"),
    (["run", "--method", "teleport"], "--method"),
    (["hertz", "--bogus"], "--bogus"),
    (["run", "--method", "improved", "-recovery", "psychic"], "recovery"),
    (["run", "--method", "improved", "--modes", "-3"], "--modes"),
    (["run", "--method", "traditional", "--f-cut", "0"], "--f-cut"),
    (["run", "--method", "full", "--f-cut", "1e5"], "--f-cut"),
])
def test_bad_input_one_line_exit_2(args, field, tmp_path):
    out = tmp_path / "never"
    r = run_cli(*args, "--out", str(out)) if args[0] == "run" else run_cli(*args)
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and field in lines[0] and "Traceback" not in r.stderr
    assert not out.exists()  # nothing half-written


def test_unknown_key_in_scene_file(tmp_path):
    p = tmp_path / "s.toml"
    p.write_text("[ball]\nradius = 0.01\ncolour = 'red'\n")
    r = run_cli("run", str(p), "--method", "hertz", "--out", str(tmp_path / "o"))
    assert r.returncode == 2 and "ball.colour" in r.stderr and len(r.stderr.strip().splitlines()) == 1


def test_scene_export_and_show(tmp_path, capsys):
    r = scene_cli(capsys, "export", "paper-rig")
    assert r.returncode == 0
    p = tmp_path / "my.toml"
    p.write_text(r.stdout.replace("radius = 0.015", "radius = 0.02"))
    r = scene_cli(capsys, "show", str(p))
    assert r.returncode == 0 and "radius 20 mm" in r.stdout and "h_contact" in r.stdout


def test_petsc_options_are_separated():
    from millimpact.cli import split_petsc_options

    rest, opts = split_petsc_options(["run", "-impact_ksp_type", "gmres", "--out", "x", "-log_view", "-q",
                                      "-impact_ksp_rtol", "1e-10"])
    assert rest == ["run", "--out", "x", "-q"]
    assert opts == {"impact_ksp_type": "gmres", "log_view": "", "impact_ksp_rtol": "1e-10"}


def test_version_unknown_option_and_verbose_after_the_command():
    """--version names the stack; an unknown top-level option is exit 2 in one line (it printed the
    help with exit 0); -v is accepted after the command as before it."""
    r = run_cli("--version")
    assert r.returncode == 0
    for part in ("millimpact ", "DOLFINx 0.5", "PETSc 3.18", "SLEPc 3.18", "gmsh 4."):
        assert part in r.stdout
    r = run_cli("--bogus")
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "--bogus" in r.stderr
    r = run_cli("scene", "list", "-v")
    assert r.returncode == 0 and "paper-rig" in r.stdout


def test_verbose_run_logs_the_stages_details(tmp_path):
    """-v logs the package's INFO lines (the reduction's modes and eigensolver); it logged none:
    FFCx configures logging when imported, and the CLI's own configuration was then a no-op."""
    # the small rig mesh (~10.6k P2 dofs against 67k): the same stages, the same logging
    small = [a for k, v in SMALL_RIG.items() for a in ("--set", f"{k}={v!r}")]
    r = run_cli("run", "--set", "time.end=1e-5", *small, "-v", "--out", str(tmp_path / "r"))
    assert r.returncode == 0, r.stderr
    assert "millimpact.reduction.craig_bampton: reduction block:" in r.stderr, r.stderr[-2000:]
    r = run_cli("run", "--set", "time.end=1e-5", *small, "--out", str(tmp_path / "q"), "--force")
    assert r.returncode == 0 and "millimpact.reduction" not in r.stderr


def test_run_help_lists_every_method():
    from millimpact.methods.registry import DEFAULT_METHOD, METHODS

    r = run_cli("run", "--help")
    assert r.returncode == 0
    text = " ".join(r.stdout.split())
    for m in METHODS:  # each summary whole: a % in one was read as a format and printed argparse's internals
        assert f"{m.name}: {' '.join(m.summary.split())}" in text, m.name
    assert f"default {DEFAULT_METHOD}" in text and "when available" not in text
    assert "option_strings" not in text


@pytest.mark.parametrize("command", ["run", "hertz", "scene", "mesh", "study", "table", "bench", "stability",
                                     "compare", "export", "mill", "damage", "repeat"])
def test_every_help_is_its_text(command):
    """Every command's --help is its help text, not argparse's internals (a lone % in a help string
    made argparse print its action's dict instead)."""
    r = run_cli(command, "--help")
    assert r.returncode == 0, r.stderr[-2000:]
    assert "option_strings" not in r.stdout and "Traceback" not in r.stderr


def test_the_reference_is_the_converged_degree():
    """``--method full`` at its default degree (the plan's P1) is ~3 % stiff on hertz-halfspace
    (F_max +3.06 %, t_c -2.99 % against Hertz; P2 within 2 %: docs/methods.md): the method list
    calls "the reference" only the P2 model (before: "full ...: the reference" at P1)."""
    from millimpact.methods.registry import method_entry
    from millimpact.scene.builtin import builtin_scene

    assert builtin_scene("hertz-halfspace").model.degree == 1
    summary = method_entry("full").summary
    assert "reference" in summary and "--degree 2" in summary.split("reference", 1)[1][:20], summary


def test_scene_show_of_the_hertz_model_shows_no_mesh(capsys):
    """``scene show --method hertz``: a 1-DOF model, no contact zone and no P1 accuracy note (they
    are the FE methods')."""
    from output_lock import main_in_process

    code, stdout, _ = main_in_process(capsys, ["scene", "show", "--method", "hertz"])
    assert code == 0 and "dt_contact" in stdout and "gap" in stdout
    assert "zone_radius" not in stdout and "P1 (default)" not in stdout and "h_contact" not in stdout


@pytest.mark.parametrize("args", [("repeat", "--impacts", "x"), ("run", "--degree", "3"), ("damage",),
                                  ("table", "--ranks-per-case", "y"), ("bogus",)])
def test_argument_errors_are_one_line_with_one_prefix(args):
    """argparse's errors as millimpact's own: one line ``millimpact: error: ...`` naming the
    command and its --help, exit 2 (before: a usage block and a different prefix per command)."""
    r = run_cli(*args)
    lines = r.stderr.strip().splitlines()
    assert r.returncode == 2 and len(lines) == 1 and lines[0].startswith("millimpact: error: "), r.stderr
    assert "--help'" in lines[0] and (args[0] == "bogus" or f"error: {args[0]}: " in lines[0])


#: a Ctrl-C that lands inside a ``__del__`` (pyparsing's ``Forward.__del__`` while the start-up
#: imports run): Python cannot raise it there, prints "Exception ignored in ..." with a traceback
#: and goes on; the command's hook interrupts the main thread again after the ``__del__``
DEL_CHILD = """
import os, signal, time
from millimpact.interrupts import command_signals

class Slow:
    def __del__(self):
        os.kill(os.getpid(), signal.SIGINT)
        time.sleep(0.5)

try:
    with command_signals():
        Slow()
        for _ in range(100):
            time.sleep(0.02)
        print("not interrupted")
except KeyboardInterrupt:
    print("interrupted")
"""


def test_a_ctrl_c_inside_a_finalizer_is_not_lost_nor_printed():
    import subprocess
    import sys

    from conftest import ROOT, default_sigint, mpi_env

    r = subprocess.run([sys.executable, "-c", DEL_CHILD], cwd=ROOT, env=mpi_env(), capture_output=True, text=True,
                       timeout=120, preexec_fn=default_sigint)
    assert r.stdout.strip() == "interrupted" and "Exception ignored" not in r.stderr, (r.stdout, r.stderr)


#: a SIGTERM the main thread answers by itself (raise_if_interrupted between two time steps sees
#: the waiter's record) while the waiter is still in its hooks (under mpirun: the interrupt line and
#: the lock's release, here a 0.3 s sleep); then the command either goes on a while in its own
#: cleanup ("stay") or ends at once ("leave"). Prints what each exception was and where.
ANSWERED_CHILD = """
import os, signal, sys, time
from millimpact import interrupts
from millimpact.interrupts import command_signals, raise_if_interrupted

interrupts.ON_SIGNAL.append(lambda signum: time.sleep(0.3))
seen = []
try:
    with command_signals():
        os.kill(os.getpid(), signal.SIGTERM)
        try:
            for _ in range(500):
                raise_if_interrupted()
                time.sleep(0.001)
        except KeyboardInterrupt as exc:
            seen.append("step " + type(exc).__name__)
        if sys.argv[1] == "stay":
            for _ in range(100):              # 1 s of cleanup
                time.sleep(0.01)
except KeyboardInterrupt as exc:
    seen.append("again " + type(exc).__name__)
time.sleep(0.5)                              # the waiter, had it gone on, would have delivered by now
print(" | ".join(seen), flush=True)
"""


@pytest.mark.parametrize("then", ["stay", "leave"])
def test_a_signal_the_main_thread_answered_raises_once(then):
    """One SIGTERM, one exception: before, the waiter interrupted the main thread again after its
    hooks, in the command's cleanup ("stay") or while the command's end joined it ("leave"); under
    ``mpirun -n 2`` that printed a traceback of a second Terminated (1 of 3 suite runs)."""
    import subprocess
    import sys

    from conftest import ROOT, mpi_env

    r = subprocess.run([sys.executable, "-c", ANSWERED_CHILD, then], cwd=ROOT, env=mpi_env(), capture_output=True,
                       text=True, timeout=120)
    assert r.returncode == 0 and r.stdout.strip() == "step Terminated", (r.stdout, r.stderr[-2000:])


def test_every_registered_method_resolves():
    """The registry's table is the only list of methods: each row names a real runner."""
    from millimpact.methods.registry import METHODS, method_runner

    for m in METHODS:
        assert callable(method_runner(m.name)), m.name


def test_first_run_form_compilation_is_one_line(tmp_path):
    """On a fresh form cache (~/.cache/fenics under a new HOME) the C build's gcc lines are not
    shown: one 'compiling forms' line instead (issue 18)."""
    import subprocess
    import sys

    from conftest import ROOT, mpi_env

    # FFCx's cache follows XDG_CACHE_HOME when it is set: drop it so the new HOME decides
    env = {k: v for k, v in {**mpi_env(), "HOME": str(tmp_path)}.items() if k != "XDG_CACHE_HOME"}
    r = subprocess.run([sys.executable, "-m", "millimpact.cli", "run", "-q", "--method", "full",
                        "--set", "time.end=2e-6", "--out", str(tmp_path / "out")],
                       capture_output=True, text=True, env=env, cwd=ROOT, timeout=600)
    assert r.returncode == 0, r.stderr[-2000:]
    assert (tmp_path / ".cache" / "fenics").is_dir()              # it really compiled
    assert "gcc" not in r.stdout + r.stderr
    assert (r.stdout + r.stderr).count("compiling forms") == 1


@pytest.mark.parametrize("bad", ["ball.radius", "=0.02", "ball.radius="])
def test_set_without_value_is_one_line(bad):
    r = run_cli("run", "--method", "hertz", "--set", bad, "--out", "out/never")
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "expected FIELD=VALUE" in r.stderr


@pytest.mark.parametrize("option, value", [("-impact_fieldsplit_u_ksp_type", "nosuch"), ("-impact_pc_type", "lux"),
                                           ("-impact_reduction_block_pc_factor_mat_solver_type", "mumpsy")])
def test_unknown_petsc_type_is_one_line(option, value):
    """A misspelled KSP / PC / factorization type is refused before any work, naming the option
    (PETSc failed later with 'PETSc error 86' and a stack)."""
    r = run_cli("run", "--method", "hertz", option, value, "--out", "out/never")
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and f"{option} {value}: unknown" in r.stderr


@pytest.mark.parametrize("value", ["abc", "-3", "2.5"])
def test_bad_block_krylov_size_is_one_line(value):
    """A block size that is not an integer >= 0 is refused before any work ('abc' was a PETSc
    error and a stack after the meshing; '-3' silently chose Krylov-Schur)."""
    option = "-impact_reduction_block_block_krylov_size"
    r = run_cli("run", "--method", "hertz", option, value, "--out", "out/never")
    assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
    assert f"{option} {value}: " in r.stderr and "integer >= 0" in r.stderr


@pytest.mark.parametrize("suffix, value, words", [
    ("substructures", "-2", "integer >= 0"), ("substructures", "two", "integer >= 0"),
    ("substructure_f_factor", "0.5", "number >= 1"), ("substructure_trace_density", "-1", "number >= 0"),
    ("substructure_margin", "x", "number >= 0"), ("substructure_compress", "1", "number in [0, 1)"),
    ("substructure_zone_degree", "-1", "integer >= 0"), ("substructure_zone_degree", "2.5", "integer >= 0"),
    ("substructure_eps_tol", "0", "number in [1e-15, 1)"), ("substructure_eps_tol", "2", "number in [1e-15, 1)")])
def test_bad_substructure_settings_are_one_line(suffix, value, words):
    """The substructuring settings out of range are refused before any work, one line, exit 2."""
    option = f"-impact_reduction_block_{suffix}"
    r = run_cli("run", "--method", "hertz", option, value, "--out", "out/never")
    assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
    assert f"{option} {value}: " in r.stderr and words in r.stderr


@pytest.mark.parametrize("command", ["study", "table"])
def test_bad_petsc_option_of_a_study_is_one_line(command, tmp_path):
    """`study` and `table` --option values get the checks of `run` (they reached the cases
    unchecked: a PETSc error in every case)."""
    args = (["study", "velocity"] if command == "study" else ["table", "--velocity", "2"])
    r = run_cli(*args, "--option", "reduction_block_substructures=-2", "--out", str(tmp_path / "never"))
    assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
    assert "reduction_block_substructures -2: " in r.stderr and not (tmp_path / "never").exists()


def test_scene_show_prints_the_plan_of_the_method_that_runs(tmp_path, capsys):
    """`scene show` printed the full P1 plan (zone 4.64 mm) while the default improved run uses P2
    and 2.90 mm: it now shows the plan of --method (default the run's default), as the run notes."""
    r = scene_cli(capsys, "show")
    assert r.returncode == 0 and "plan of --method improved" in r.stdout
    zone = [l for l in r.stdout.splitlines() if l.strip().startswith("zone_radius")][0]
    assert "2.898 mm" in zone and "P2" in [l for l in r.stdout.splitlines() if l.strip().startswith("degree")][0]
    r = scene_cli(capsys, "show", "--method", "full")
    assert "4.637 mm" in [l for l in r.stdout.splitlines() if l.strip().startswith("zone_radius")][0]
    # the run's notes say the zone `scene show` printed: on the rig's mesh coarsened (h_contact
    # 0.8 mm, h_far 8 mm: ~10.6k P2 dofs against 67k), where the reduced zone is another size
    p = tmp_path / "coarse.toml"
    p.write_text(scene_cli(capsys, "export", "paper-rig").stdout.replace("[model]\n", "[model]\nh_contact = 0.0008\n"
                                                                                 "h_far = 0.008\n"))
    shown = scene_cli(capsys, "show", str(p))
    zone = [l for l in shown.stdout.splitlines() if l.strip().startswith("zone_radius")][0].split()[1]
    assert zone != "2.898", shown.stdout
    run = run_cli("run", str(p), "--set", "time.end=1e-5", "-q", "--out", str(tmp_path / "r"))
    assert run.returncode == 0, run.stderr[-2000:]
    assert f"contact zone radius {zone} mm" in run.stdout, run.stdout


@pytest.mark.parametrize("args, words", [
    (["--set", "ball.radius=10"], "ball.radius = 10.0: must lie in [0.0001, 1] m"),
    (["--set", "ball.radius=1e-9"], "ball.radius = 1e-09: must lie in"),
    (["--set", "impact.velocity=[0,-1000,0]"], "its speed 1000 m/s must be at most 100 m/s"),
])
def test_out_of_range_scene_names_what_the_user_gave(args, words):
    """A 10 m ball or a 1000 m/s impact named model.zone_radius (a field the user never set); a 1 nm
    ball ran silently. Now the field the user gave, its range, one line; `hertz` says the same."""
    r = run_cli("run", "--method", "hertz", *args, "--out", "out/never")
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and words in r.stderr


def test_empty_scene_file_and_one_value_study_are_refused(tmp_path):
    empty = tmp_path / "empty.toml"
    empty.write_text("")
    r = run_cli("run", str(empty), "--method", "hertz", "--out", str(tmp_path / "never"))
    assert r.returncode == 2 and "is empty" in r.stderr and r.stderr.count("\n") == 1
    r = run_cli("study", "--param", "ball.radius=0.02", "--out", str(tmp_path / "never2"))
    assert r.returncode == 2 and "at least two values" in r.stderr and r.stderr.count("\n") == 1


def test_options_nothing_used_are_warned(tmp_path):
    """A misspelled PETSc option or one for a solver the method does not have is named in a
    warning; options a solver or the method did read are not (PetscOptionsUsed, method settings)."""
    used = ["-impact_fieldsplit_u_pc_factor_mat_solver_type", "mumps",   # the effective-matrix solver
            "-impact_gap_rtol", "1e-9",                                  # read by the integrator
            "-candidate_radius", "0.002"]                                # a setting of method full
    # a coarse mesh (h_contact 0.8 mm, h_far 15 mm): the same solvers read the same options
    r = run_cli("run", "hertz-halfspace", "--method", "full", "--set", "time.end=2e-5", "--set", "model.h_contact=8e-4",
                "--set", "model.h_far=0.015", "--out", str(tmp_path / "r"), "-impact_nonsense", "3", *used)
    assert r.returncode == 0, r.stderr[-2000:]
    line = [l for l in r.stdout.splitlines() if "nothing in this run used" in l]
    assert len(line) == 1 and "-impact_nonsense" in line[0], r.stdout
    assert not any(o in line[0] for o in used[::2]), line[0]
    r = run_cli("study", "velocity", "--method", "hertz", "--option", "nosuch=3", "-q", "--no-case-figures",
                "--out", str(tmp_path / "s"))
    assert r.returncode == 0, r.stderr[-2000:]
    assert r.stderr.count("nothing in this run used") == 1 and "-nosuch" in r.stderr, r.stderr
