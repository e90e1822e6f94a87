"""millimpact: reference-quality 3D impact dynamics of a grinding ball on a SAG mill liner.

The flow of one run (see README): scene -> plan -> geometry -> model -> reduction -> contact ->
integrator -> solvers -> results -> plots.
"""
import os as _os

__version__ = "0.1.0"

# OpenBLAS (packages.txt) would start a thread per core in every MPI rank (oversubscribing 2 cores
# under mpirun -n 2): one BLAS thread per process unless the user says otherwise
_os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
