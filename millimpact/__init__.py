"""millimpact: reference-quality 3D impact dynamics of a grinding ball on a SAG mill liner.

The flow of one run, one subpackage per stage (each imports only the stages listed after it;
pyproject.toml's import-linter contract checks this):

- :mod:`millimpact.cli`          the ``millimpact`` command line, on top of everything
- :mod:`millimpact.studies`      sweeps, benchmarks, stability maps, ``compare``
- :mod:`millimpact.methods`      the registry of run methods and one module per method family
- :mod:`millimpact.results`      recorder, time series, fields, reference files, figures
- :mod:`millimpact.reduction`    SLEPc modes, Craig-Bampton, the NMM contact zone
- :mod:`millimpact.integration`  time integrators and PETSc solver set-ups
- :mod:`millimpact.fem`          DOLFINx spaces, mass and stiffness, contact rows, probes
- :mod:`millimpact.geometry`     gmsh builders and the mesh cache
- :mod:`millimpact.scene`        what the user describes (schema, built-in scenes) and the plan
- :mod:`millimpact.theory`       closed-form contact mechanics (Hertz, ...)
- :mod:`millimpact.errors`, :mod:`millimpact.console`  exceptions and rank-0 printing
"""

import os as _os

__version__ = "0.1.0"


def _blas_threads(sharers: int = 1) -> int:
    """OpenBLAS threads for this process: the cores it may run on, shared among the MPI ranks of
    its node (or the ``sharers`` processes started side by side). OpenBLAS (packages.txt) would
    otherwise start a thread per core in every rank (oversubscribing 2 cores under ``mpirun -n 2``,
    where each rank is bound to its own core: 1); a serial run uses its machine's cores, most of
    all in CHOLMOD's supernodal solves and factorizations (the plastic rig's impact-only run, 2
    cores, 3 pairs: time loop 0.86 and process 0.90 of one thread's, docs: plasticity)."""
    local = _os.environ.get("OMPI_COMM_WORLD_LOCAL_SIZE") or _os.environ.get("MPI_LOCALNRANKS") or "1"
    try:
        cores = len(_os.sched_getaffinity(0))
    except AttributeError:  # no affinity call (not Linux)
        cores = _os.cpu_count() or 1
    return max(1, cores // max(1, int(local), sharers))


#: set when millimpact chose OPENBLAS_NUM_THREADS: a millimpact process it starts (an MPI rank, a
#: subprocess) chooses again for itself; a value the user set (this marker absent) is kept
_BLAS_AUTO = "MILLIMPACT_BLAS_THREADS_AUTO"


def share_blas_threads(processes: int) -> None:
    """Before starting ``processes`` serial workers that share this process's cores: each gets
    its share of BLAS threads (their environment), unless the user set OPENBLAS_NUM_THREADS."""
    if _os.environ.get(_BLAS_AUTO) == "1":
        _os.environ["OPENBLAS_NUM_THREADS"] = str(_blas_threads(processes))
        del _os.environ[_BLAS_AUTO]


if "OPENBLAS_NUM_THREADS" not in _os.environ or _os.environ.get(_BLAS_AUTO) == "1":
    _os.environ["OPENBLAS_NUM_THREADS"] = str(_blas_threads())
    _os.environ[_BLAS_AUTO] = "1"

#: the CPU features (/proc/cpuinfo flags) of OpenBLAS's kernel families, the widest first
_BLAS_CORES = (("SkylakeX", {"avx512f", "avx512dq", "avx512cd", "avx512bw", "avx512vl"}), ("Haswell", {"avx2", "fma"}))


def _blas_coretype(cpuinfo: str = "/proc/cpuinfo"):
    """The OpenBLAS kernel family the CPU's features allow (OPENBLAS_CORETYPE), or None.

    Debian 12's OpenBLAS 0.3.21 (DYNAMIC_ARCH) picks its kernels by the CPU's family and model
    number, and a model it does not know falls back to "Prescott", SSE3 kernels: the 2-core cloud
    machines here (family 6, model 207, AVX-512) ran numpy's dgemm at 16.6 GFLOPS against 137 with
    SkylakeX's kernels, and the liner panel's dense Rayleigh-Ritz (4,368 columns) in 42 s against
    18 s. Choosing by the features, as newer OpenBLAS releases do, gives the kernels the CPU runs;
    on a CPU OpenBLAS knows it names the family it would pick or one as wide."""
    try:
        with open(cpuinfo) as f:
            flags = next((set(line.split(":", 1)[1].split()) for line in f if line.startswith("flags")), set())
    except OSError:
        return None
    return next((name for name, need in _BLAS_CORES if need <= flags), None)


if "OPENBLAS_CORETYPE" not in _os.environ:
    _core = _blas_coretype()
    if _core:
        _os.environ["OPENBLAS_CORETYPE"] = _core

# Open MPI starts every process not launched by mpirun (a "singleton": `millimpact run`, a study's
# worker, the test process) with a helper daemon, `orted --hnp --set-sid`, in its own process group (setsid). A
# singleton whose daemon is gone ends at its next runtime call without a word (kill -9 of the
# daemon: exit 195, nothing on stderr). (The exit-1 deaths of CI runs once blamed on it were gmsh's:
# millimpact.geometry.builders.gmsh_session.) millimpact needs nothing the
# daemon gives (no MPI_Comm_spawn, no name publishing), so a singleton runs without one
# (ess_singleton_isolated, Open MPI 4.1; no effect under mpirun). Set before mpi4py initialises MPI.
_os.environ.setdefault("OMPI_MCA_ess_singleton_isolated", "1")
