"""One package list: the README's commands (./dev), CI and the Dockerfile all install packages.txt."""
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _packages():
    return [l.split("#")[0].strip() for l in (ROOT / "packages.txt").read_text().splitlines()
            if l.split("#")[0].strip()]


def test_package_list_has_the_stack():
    pk = _packages()
    for name in ("python3-dolfinx", "python3-petsc4py", "python3-slepc4py", "python3-gmsh", "python3-meshio",
                 "python3-mpi4py", "python3-scipy", "python3-matplotlib", "python3-h5py", "python3-pytest",
                 "openmpi-bin"):
        assert name in pk


def test_dockerfile_installs_the_same_list_the_same_way():
    docker = (ROOT / "Dockerfile").read_text()
    assert docker.splitlines()[[l.startswith("FROM") for l in docker.splitlines()].index(True)].split()[1] \
        == "debian:bookworm-slim"
    assert "COPY packages.txt" in docker and "./dev install" in docker
    assert 'ENTRYPOINT ["millimpact"]' in docker and "OMPI_ALLOW_RUN_AS_ROOT=1" in docker
    dev = (ROOT / "dev").read_text()
    assert "packages.txt" in dev and "apt-get install" in dev
    assert "/usr/bin/python3 -m venv --system-site-packages" in dev


def test_readme_and_ci_use_the_dev_script():
    readme = (ROOT / "README.md").read_text()
    assert "./dev run" in readme and "./dev test" in readme
    assert "./dev test" in (ROOT / ".ci" / "run").read_text()


# docker/build-image.sh builds the image with podman and runs it (docs/docker.md); these checks are
# cheap and build nothing (a build downloads ~450 MB and takes minutes)
SCRIPT = ROOT / "docker" / "build-image.sh"


def _dockerfile_copies():
    """Sources of the Dockerfile's COPY lines (the last word of each is the destination)."""
    copied = []
    for line in (ROOT / "Dockerfile").read_text().splitlines():
        words = line.split()
        if words and words[0] == "COPY":
            copied += [w.rstrip("/") for w in words[1:-1] if not w.startswith("--")]
    return copied


def test_build_script_is_an_executable_bash_script():
    import os
    import subprocess

    assert SCRIPT.is_file() and os.access(SCRIPT, os.X_OK)
    assert SCRIPT.read_text().startswith("#!/usr/bin/env bash\n")
    subprocess.run(["bash", "-n", str(SCRIPT)], check=True)


def test_dockerfile_copies_what_dev_install_needs():
    import fnmatch
    import tomllib

    copied = _dockerfile_copies()
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())
    # ./dev reads packages.txt and pip-installs the project: pyproject.toml, its readme, its packages
    needed = {"dev", "packages.txt", "pyproject.toml", project["project"]["readme"]}
    needed |= {p.rstrip("*") for p in project["tool"]["setuptools"]["packages"]["find"]["include"]}
    assert needed <= set(copied), needed - set(copied)
    dev = (ROOT / "dev").read_text()
    assert "done < packages.txt" in dev and "pip install -q --no-build-isolation --no-deps -e ." in dev
    # .dockerignore leaves out none of it
    ignored = [l.strip() for l in (ROOT / ".dockerignore").read_text().splitlines()
               if l.strip() and not l.startswith("#")]
    for name in copied:
        assert (ROOT / name).exists(), name
        assert not any(fnmatch.fnmatch(name, p.rstrip("/")) for p in ignored), name


def test_build_script_matches_the_dockerfile():
    script = SCRIPT.read_text()
    docker = (ROOT / "Dockerfile").read_text()
    base = next(l.split()[1] for l in docker.splitlines() if l.startswith("FROM"))
    assert f"base=docker.io/library/{base}\n" in script      # the base it makes when podman has none
    assert 'ENTRYPOINT ["millimpact"]' in docker and '[ "$entrypoint" = millimpact ]' in script
    assert "ARG PIP_CERT" in docker and "--build-arg PIP_CERT=" in script
    assert '-f "$repo/Dockerfile" "$repo"' in script
    # build artefacts (debootstrap tree, podman storage) stay outside the repository
    assert "MILLIMPACT_BUILD_DIR:-/var/tmp/" in script and "must be outside the repository" in script


def test_build_script_reads_f_max_from_a_summary(tmp_path):
    """The script's fmax() (sed, no Python on the host) on a summary.json written the way runs write it."""
    import json
    import subprocess

    from millimpact.results.timeseries import jsonable

    summary = tmp_path / "summary.json"
    summary.write_text(json.dumps(jsonable({"scene": "paper-rig", "peak_contact_force_N": 13438.191882743053,
                                            "hertz": {"peak_contact_force_N": 1.0}}), indent=2) + "\n")
    lines = SCRIPT.read_text().splitlines()
    start = lines.index(next(l for l in lines if l.startswith("fmax()")))
    end = lines.index("}", start)
    fn = "\n".join(lines[start:end + 1])
    out = subprocess.run(["bash", "-c", f'{fn}\nfmax "$1"', "_", str(summary)], check=True,
                         capture_output=True, text=True).stdout
    assert out.strip() == "13438.191882743053"


def test_slim_image_keeps_what_the_form_compiler_needs():
    """FFCx compiles forms with gcc at run time (cffi): the C toolchain, libc's, gcc's and Python's
    headers and the archives a shared object links with (libc6-dev's, gcc's) stay in the image."""
    pk = _packages()
    assert "build-essential" in pk and "python3-dev" in pk
    docker = (ROOT / "Dockerfile").read_text()
    excluded = [l for l in docker.splitlines() if "path-exclude" in l or "rm -" in l or "-delete" in l]
    for kept in ("/usr/include/python", "/usr/include/x86_64-linux-gnu", "/usr/lib/gcc/*'", "/usr/bin"):
        assert not any(kept in l and "! -path" not in l for l in excluded), kept
    assert "! -path '/usr/lib/gcc/*'" in docker and "dpkg -L libc6-dev" in docker


def test_an_mpi_singleton_starts_no_helper_daemon():
    """A process not launched by mpirun (``millimpact run``, a study worker) initialises MPI with no
    ``orted`` child (millimpact/__init__.py: a singleton whose daemon dies ends without a word).
    Without the setting Open MPI 4.1 forks one, so the count below is 1 then."""
    import os
    import subprocess
    import sys

    code = ("import glob, os, millimpact\nfrom mpi4py import MPI\nMPI.COMM_WORLD.Barrier()\n"
            "kids = [c for f in glob.glob(f'/proc/{os.getpid()}/task/*/children') for c in open(f).read().split()]\n"
            "print(sum('orted' in open(f'/proc/{c}/cmdline').read() for c in kids))")
    env = {k: v for k, v in os.environ.items() if k != "OMPI_MCA_ess_singleton_isolated"}
    env.update(OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120)
    assert r.returncode == 0, r.stderr[-2000:]
    assert r.stdout.split()[-1] == "0"


#: what decides a process's BLAS threads: the value, and the marker of millimpact's own choice
BLAS_VARS = ("OPENBLAS_NUM_THREADS", "MILLIMPACT_BLAS_THREADS_AUTO")


def _without_blas_choice(env: dict, **extra: str) -> dict:
    """``env`` with no BLAS thread choice in it (the suite's conftest sets one), plus ``extra``."""
    return {**{k: v for k, v in env.items() if k not in BLAS_VARS}, **extra}


def _blas_threads_seen(env_extra: dict, cores=None):
    """(OPENBLAS_NUM_THREADS after ``import millimpact``, the threads OpenBLAS itself runs, the
    process's cores) in a fresh interpreter, on ``cores`` if given."""
    code = ("import os, ctypes, millimpact, numpy\n"
            "n = ctypes.CDLL('libopenblas.so.0').openblas_get_num_threads()\n"
            "print(os.environ['OPENBLAS_NUM_THREADS'], n, len(os.sched_getaffinity(0)))")
    env = _without_blas_choice(dict(os.environ), **env_extra)
    pin = (lambda: os.sched_setaffinity(0, cores)) if cores else None
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env,
                       timeout=120, preexec_fn=pin)
    assert r.returncode == 0, r.stderr[-2000:]
    return tuple(int(w) for w in r.stdout.split()[-3:])


def test_blas_threads_follow_the_cores_a_process_may_use():
    """A serial process runs OpenBLAS on the cores it may run on (millimpact/__init__.py), an MPI
    rank on its share of its node's, a value the user set stays, and a millimpact parent's choice
    is made again by the child."""
    env_value, blas, cores = _blas_threads_seen({})
    assert env_value == blas == cores
    assert _blas_threads_seen({}, cores={0})[:2] == (1, 1)
    # OpenBLAS runs at most a thread per core, whatever is asked
    assert _blas_threads_seen({"OPENBLAS_NUM_THREADS": "3"})[:2] == (3, min(3, cores))
    # the parent's choice (the marker set) is not the user's: the child takes its own cores
    assert _blas_threads_seen({"OPENBLAS_NUM_THREADS": "5", "MILLIMPACT_BLAS_THREADS_AUTO": "1"},
                              cores={0})[:2] == (1, 1)
    # two ranks of mpirun on this node share its cores
    shared = max(1, cores // 2)
    assert _blas_threads_seen({"OMPI_COMM_WORLD_LOCAL_SIZE": "2"})[:2] == (shared, shared)


def test_blas_kernels_follow_the_cpu_features(tmp_path):
    """OPENBLAS_CORETYPE from the CPU's features (millimpact/__init__.py): AVX-512 gives SkylakeX,
    AVX2 with FMA Haswell, older or unreadable none; and OpenBLAS runs the kernels chosen, or the
    ones the user named."""
    from millimpact import _blas_coretype

    def cpu(flags: str) -> str:
        path = tmp_path / f"cpuinfo{len(flags)}"
        path.write_text(f"processor\t: 0\nvendor_id\t: GenuineIntel\nflags\t\t: {flags}\n\n")
        return str(path)

    assert _blas_coretype(cpu("fpu sse2 avx2 fma avx512f avx512dq avx512cd avx512bw avx512vl")) == "SkylakeX"
    assert _blas_coretype(cpu("fpu sse2 avx2 fma avx512f")) == "Haswell"
    assert _blas_coretype(cpu("fpu sse2 avx avx2")) is None
    assert _blas_coretype(str(tmp_path / "absent")) is None
    code = ("import os, ctypes, millimpact, numpy\n"
            "lib = ctypes.CDLL('libopenblas.so.0'); lib.openblas_get_corename.restype = ctypes.c_char_p\n"
            "print(os.environ.get('OPENBLAS_CORETYPE'), lib.openblas_get_corename().decode())")
    base = {k: v for k, v in os.environ.items() if k != "OPENBLAS_CORETYPE"}
    for extra in ({}, {"OPENBLAS_CORETYPE": "Prescott"}):
        r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env={**base, **extra},
                           timeout=120)
        assert r.returncode == 0, r.stderr[-2000:]
        chosen, running = r.stdout.split()
        expect = extra.get("OPENBLAS_CORETYPE") or _blas_coretype()
        assert chosen == str(expect)
        if expect is not None:
            assert running == expect


def test_study_workers_share_the_blas_threads():
    """``share_blas_threads(n)`` before n side-by-side workers gives each its share, once (the
    marker goes: the workers keep it), and leaves a user's value alone."""
    code = ("import os, millimpact\nmillimpact.share_blas_threads(2)\n"
            "print(os.environ['OPENBLAS_NUM_THREADS'], 'MILLIMPACT_BLAS_THREADS_AUTO' in os.environ,"
            " len(os.sched_getaffinity(0)))")
    for extra, expect in (({}, None), ({"OPENBLAS_NUM_THREADS": "3"}, "3")):
        r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                           env=_without_blas_choice(dict(os.environ), **extra), timeout=120)
        assert r.returncode == 0, r.stderr[-2000:]
        value, marker, cores = r.stdout.split()
        assert value == (expect or str(max(1, int(cores) // 2))) and marker == "False"


def test_mpi_ranks_share_their_nodes_cores():
    """Under ``mpirun -n 2`` on one node each rank runs OpenBLAS on its share of the cores (bound
    to one core each by default: 1 thread), not on every core of the machine."""
    import shutil

    import pytest
    from conftest import mpi_env
    if shutil.which("mpirun") is None:
        pytest.skip("mpirun not installed")
    # rank 0 prints the gathered rows: two ranks printing themselves interleave their characters
    # under an unbuffered stdout (PYTHONUNBUFFERED: print writes each field on its own), e.g.
    # "1 1" and "1 1" arriving as "11 1" and " 1"
    code = ("import os, ctypes, millimpact, numpy\n"
            "from mpi4py import MPI\n"
            "row = (ctypes.CDLL('libopenblas.so.0').openblas_get_num_threads(), len(os.sched_getaffinity(0)))\n"
            "rows = MPI.COMM_WORLD.gather(row)\n"
            "if MPI.COMM_WORLD.rank == 0:\n"
            "    print('\\n'.join(f'{a} {b}' for a, b in rows), flush=True)\n")
    env = _without_blas_choice(mpi_env())
    r = subprocess.run(["mpirun", "-n", "2", sys.executable, "-c", code], capture_output=True, text=True,
                       env=env, timeout=300)
    assert r.returncode == 0, (r.returncode, r.stdout[-1000:], r.stderr[-2000:])
    rows = [tuple(map(int, line.split())) for line in r.stdout.split("\n") if line.strip()]
    cores = len(os.sched_getaffinity(0))
    assert len(rows) == 2 and all(n == max(1, min(c, cores // 2)) for n, c in rows), (rows, r.stderr[-2000:])
