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

# OpenBLAS (packages.txt) would start a thread per core in every MPI rank (oversubscribing 2 cores
# under mpirun -n 2): one BLAS thread per process unless the user says otherwise
_os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

# Open MPI starts every process not launched by mpirun (a "singleton": `millimpact run`, a study's
# worker, the test process) with a helper daemon, `orted --hnp --set-sid`, in its own session. A
# singleton whose daemon is gone ends at its next runtime call without a word (kill -9 of the
# daemon: exit 195, nothing on stderr). (The exit-1 deaths of CI runs once blamed on it were gmsh's:
# millimpact.geometry.builders.gmsh_session.) millimpact needs nothing the
# daemon gives (no MPI_Comm_spawn, no name publishing), so a singleton runs without one
# (ess_singleton_isolated, Open MPI 4.1; no effect under mpirun). Set before mpi4py initialises MPI.
_os.environ.setdefault("OMPI_MCA_ess_singleton_isolated", "1")
