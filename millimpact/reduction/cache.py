"""On-disk cache of a body's Craig-Bampton data: constraint modes Psi, fixed-interface modes Phi.

The offline reduction of a body's interior (:func:`millimpact.reduction.craig_bampton.reduce_model`)
costs a sparse factorization of K_ii, a multi-right-hand-side solve for Psi = -K_ii^-1 K_iz G and
a shift-and-invert eigensolve for Phi (on the rig ~6 of the ~15 s of an improved setup). They
depend only on the matrices K_ii, M_ii, C = K_iz G, D = M_iz G (so on the mesh, the materials,
the supports, the zone basis and the partition over ranks), on the cutoff (f_cut or a mode
count) and on the solver options. The key is a SHA-1 of exactly those: each rank hashes its local
rows of the four matrices (values rounded to float32, so that round-off differences between runs
under MPI do not change it) with the settings, and the ranks' digests are hashed together, so any
real change in what the modes depend on changes the key (nothing to invalidate by hand).

Under ``mpirun`` the graph partitioner can split the mesh differently from one run to the next,
and with it each rank's rows: the key then differs and the body is reduced again (two runs of the
same scene on 2 ranks here reused one body or none). Serial runs, and a contact table's groups of
one rank, reuse.

Each rank keeps its own rows in ``<dir>/<key>.<rank>of<size>.npz`` (written to a temporary name
and renamed: an interrupted write leaves nothing that looks complete). A body is used from the
cache only when every rank has its file; otherwise all ranks compute. The folder is
``$MILLIMPACT_REDUCTION_CACHE`` ("off" disables it), else ``reductions/`` in the mesh cache
(:func:`millimpact.geometry.mesh.default_cache_dir`). Data above
:data:`MAX_BYTES_PER_RANK` per rank are not stored (Psi is n_i x n_b doubles: 76 MB for the rig's
two bodies). With augmentation vectors nothing is cached. Deleting the folder is always safe.
"""

from __future__ import annotations

import hashlib
import logging
import os
from pathlib import Path
from typing import Any

import numpy as np
from mpi4py import MPI

log = logging.getLogger(__name__)

CACHE_ENV = "MILLIMPACT_REDUCTION_CACHE"
#: bump when what reduce_model computes for the same matrices changes
CACHE_VERSION = 3  # 2: a substructured body's wide slab is cut again across (substructure_across)
# 3: its slabs' modes to substructure_eps_tol (1e-4, was the body's 1e-10)
#: a rank's files above this are not written (the disk is not a second memory)
MAX_BYTES_PER_RANK = 2e9


def cache_dir() -> Path | None:
    """The cache folder, or None (the default, and "off"): the cache is opt-in,
    ``MILLIMPACT_REDUCTION_CACHE=on`` (``reductions/`` in the mesh cache) or a folder. Off by
    default: a body's files reach gigabytes (Psi is interior x interface doubles), and a study
    of many scenes would fill the disk unasked. (It was first switched off while CI runs had
    processes die without a word; that was gmsh, geometry.builders.gmsh_session.)"""
    env = os.environ.get(CACHE_ENV, "")
    if env.lower() in ("", "off", "0", "no", "false"):
        return None
    if env.lower() in ("on", "1", "yes", "true"):
        from ..geometry.mesh import default_cache_dir

        return default_cache_dir() / "reductions"
    if env:
        return Path(env).expanduser()
    from ..geometry.mesh import default_cache_dir

    return default_cache_dir() / "reductions"


def body_key(comm: MPI.Comm, mats: list, settings: dict[str, Any]) -> str:
    """The key of one body's reduction: the ranks' local CSR rows of ``mats`` (PETSc AIJ) and the
    ``settings``, hashed together (collective)."""
    h = hashlib.sha1(repr((CACHE_VERSION, sorted(settings.items()), comm.size)).encode())
    for A in mats:
        indptr, indices, values = A.getValuesCSR()
        h.update(repr((A.getSize(), A.getOwnershipRange())).encode())
        # values to float32: under MPI a product's entries can differ in the last bits from run to
        # run (the order of a parallel sum), which must not change the key; a real change does
        for x in (indptr, indices, np.asarray(values, dtype=np.float32)):
            h.update(np.ascontiguousarray(x).tobytes())
    return hashlib.sha1("".join(comm.allgather(h.hexdigest())).encode()).hexdigest()[:24]


def _path(folder: Path, key: str, comm: MPI.Comm) -> Path:
    return folder / f"{key}.{comm.rank}of{comm.size}.npz"


def load(comm: MPI.Comm, key: str) -> dict[str, np.ndarray] | None:
    """This rank's arrays of ``key`` when every rank has them, else None (collective)."""
    folder = cache_dir()
    data = None
    if folder is not None:
        try:
            with np.load(_path(folder, key, comm)) as f:
                data = {k: f[k] for k in f.files}
        except (OSError, ValueError, KeyError):
            data = None
    if not comm.allreduce(data is not None, op=MPI.LAND):
        return None
    return data


def store(comm: MPI.Comm, key: str, arrays: dict[str, np.ndarray]) -> bool:
    """Write this rank's ``arrays`` under ``key`` (tmp + rename); False (and nothing written) when
    the cache is off, the data are too large on some rank, or the folder is not writable."""
    folder = cache_dir()
    size = sum(a.nbytes for a in arrays.values())
    if folder is None or comm.allreduce(size, op=MPI.MAX) > MAX_BYTES_PER_RANK:
        return False
    path = _path(folder, key, comm)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp.npz")
    try:
        folder.mkdir(parents=True, exist_ok=True)
        np.savez(tmp, **arrays)
        os.replace(tmp, path)
        return True
    except OSError as exc:
        log.warning("reduction cache %s not written (%s)", folder, exc)
        tmp.unlink(missing_ok=True)
        return False
