"""Mesh: build (or load from the cache) the gmsh model on rank 0 and distribute it with DOLFINx.

:func:`create_mesh` is the entry point: it keys a cache by a sha256 of every geometry and mesh
parameter, builds the model with :mod:`millimpact.geometry` on a miss (writing
``<key>.msh`` + ``<key>.json`` atomically on rank 0), ``gmsh.merge``-s the cached file on a hit,
and converts with ``dolfinx.io.gmshio.model_to_mesh`` (gmsh initialized on every rank; the
``read_from_msh`` of this DOLFINx build is broken). The result is a :class:`MeshData` with the
mesh, the cell and facet tags of :mod:`millimpact.geometry` and a :class:`MeshInfo` summary
(global counts, identical on every rank).

Cache directory: the ``cache_dir`` argument, else ``$MILLIMPACT_MESH_CACHE``, else
``<repo>/meshes/cache`` when running from a source tree, else ``~/.cache/millimpact/meshes``.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import logging
import math
import os
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, NamedTuple

import dolfinx
import gmsh
import numpy as np
from dolfinx.io import XDMFFile, gmshio
from mpi4py import MPI

from ..errors import MeshError
from ..scene.liner_shape import LinerShape, vec3
from ..scene.plan import SIZE_GROWTH_ZONE_RADII, Plan
from ..scene.schema import Scene, Vec3
from . import builders as geo
from .block import build_impact_model
from .builders import CELL_TAG_NAMES, FACET_TAG_NAMES, MeshSizes, ModelInfo
from .liner import build_liner_model

logger = logging.getLogger(__name__)

#: environment variable overriding the default cache directory
CACHE_ENV = "MILLIMPACT_MESH_CACHE"


@dataclass(frozen=True)
class MeshInfo:
    """Summary of a mesh (global values, the same on every rank; lengths in m, volumes in m^3).

    ``n_cells`` / ``n_facets``: element counts per cell / facet tag; ``n_vertices``: mesh
    vertices; ``h_contact_measured``: longest edge of the block's cells touching its contact point
    (``h_contact_mean`` their mean edge; ``h_contact_surface`` the longest edge of the block's
    contact facets within ``fine_radius``; ``h_contact_ball_measured`` the longest edge at the
    ball's contact point, nan without a ball); ``min_quality``: the
    smallest signed inverse condition number (SICN, 1 for a regular tetrahedron, <= 0 inverted);
    ``meshing_time``: gmsh generation time (s) when the mesh was built; ``setup_time``: wall time
    of this :func:`create_mesh` call (s); ``cached``: loaded from the cache; ``volumes``: exact
    geometric volume of each cell tag (OCC).
    """

    n_cells: dict[int, int]
    n_facets: dict[int, int]
    n_vertices: int
    h_contact: float
    h_far: float
    zone_radius: float
    h_contact_measured: float
    h_contact_mean: float
    h_contact_surface: float
    h_contact_ball_measured: float
    min_quality: float
    meshing_time: float
    cache_key: str
    symmetry: str
    symmetry_planes: tuple[str, ...]
    contact_point_block: Vec3
    contact_point_ball: Vec3 | None
    volumes: dict[int, float] = field(default_factory=dict)
    cached: bool = False
    setup_time: float = 0.0

    @property
    def n_cells_total(self) -> int:
        """Number of tetrahedra."""
        return int(sum(self.n_cells.values()))

    def to_json(self) -> dict:
        """Plain JSON-able data (integer keys become strings)."""
        d = dataclasses.asdict(self)
        for k in ("n_cells", "n_facets", "volumes"):
            d[k] = {str(t): v for t, v in d[k].items()}
        return d

    @classmethod
    def from_json(cls, d: dict) -> MeshInfo:
        """Inverse of :meth:`to_json`."""
        d = dict(d)
        for k in ("n_cells", "n_facets", "volumes"):
            d[k] = {int(t): v for t, v in d[k].items()}
        d["symmetry_planes"] = tuple(d["symmetry_planes"])
        d["contact_point_block"] = tuple(d["contact_point_block"])
        if d["contact_point_ball"] is not None:
            d["contact_point_ball"] = tuple(d["contact_point_ball"])
        names = {f.name for f in dataclasses.fields(cls)}
        return cls(**{k: v for k, v in d.items() if k in names})


class MeshData(NamedTuple):
    """The distributed mesh with its cell and facet tags (see :mod:`millimpact.geometry`) and info."""

    mesh: dolfinx.mesh.Mesh
    cell_tags: dolfinx.cpp.mesh.MeshTags_int32
    facet_tags: dolfinx.cpp.mesh.MeshTags_int32
    info: MeshInfo


# --- cache ---------------------------------------------------------------------------------------
def default_cache_dir() -> Path:
    """``$MILLIMPACT_MESH_CACHE``, else ``<repo>/meshes/cache`` in a source tree (the package's
    parent holds ``pyproject.toml``), else ``$XDG_CACHE_HOME`` or ``~/.cache``/millimpact/meshes."""
    env = os.environ.get(CACHE_ENV)
    if env:
        return Path(env).expanduser()
    repo = Path(__file__).resolve().parents[2]
    if (repo / "pyproject.toml").is_file():
        return repo / "meshes" / "cache"
    base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return base / "millimpact" / "meshes"


def mesh_parameters(scene: Scene, plan: Plan) -> dict[str, Any]:
    """Every parameter the impact mesh depends on (SI units): the cache key hashes these."""
    blk = scene.block
    return {
        "kind": "impact",
        **_builder_parameters(),
        "ball_radius": scene.ball.radius,
        "ball_centre": list(scene.ball_centre(plan.gap)),
        "block": {"length": blk.length, "thickness": blk.thickness, "height": blk.height, "support": blk.support},
        "impact_point": list(scene.impact_point),
        "gap": plan.gap,
        "sizes": dataclasses.asdict(MeshSizes.from_plan(plan)),
        "symmetry_planes": list(plan.symmetry_planes),
    }


def cache_key(params: dict[str, Any]) -> str:
    """sha256 (hex) of the canonical JSON of ``params``."""
    text = json.dumps(params, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()


def _builder_parameters() -> dict[str, Any]:
    return {
        "builder_version": geo.BUILDER_VERSION,
        "gmsh": gmsh.__version__,
        "algorithm_2d": geo.MESH_ALGORITHM_2D,
        "algorithm_3d": geo.MESH_ALGORITHM_3D,
        "growth_zone_radii": SIZE_GROWTH_ZONE_RADII,
    }


# --- creation ------------------------------------------------------------------------------------
def create_mesh(
    scene: Scene,
    plan: Plan,
    comm: MPI.Comm = MPI.COMM_WORLD,
    cache_dir: Path | str | None = None,
    *,
    use_cache: bool = True,
    export: Path | str | None = None,
) -> MeshData:
    """The impact mesh (ball + block) of a scene and its plan, distributed over ``comm``.

    Built by :func:`millimpact.geometry.block.build_impact_model` on rank 0 or loaded from the cache
    (see the module docstring for the directory; ``use_cache=False`` neither reads nor writes it).
    Raises :class:`MeshError` on every rank if the build fails. ``export``: also write the gmsh
    model (with its physical groups: the mesh contract, meshes/README.md) to this .msh file.
    """
    if scene.liner is not None:
        ln = scene.liner
        # an impact off the lifter face adds its place (a face impact keeps the cache key it had)
        place = {} if ln.impact_place == "lifter_face" else {"place": ln.impact_place, "arc": ln.impact_arc}
        return create_liner_mesh(
            ln,
            MeshSizes.from_plan(plan),
            comm,
            cache_dir,
            use_cache=use_cache,
            lifter=ln.impact_lifter,
            face=ln.impact_face,
            height_fraction=ln.impact_height,
            x=ln.impact_x,
            ball_radius=scene.ball.radius,
            gap=plan.gap,
            symmetry_planes=tuple(plan.symmetry_planes),
            export=export,
            **place,
        )
    params = mesh_parameters(scene, plan)
    return _create(params, lambda: build_impact_model(scene, plan), plan.symmetry, comm, cache_dir, use_cache, export)


def create_liner_mesh(
    liner: LinerShape,
    sizes: MeshSizes,
    comm: MPI.Comm = MPI.COMM_WORLD,
    cache_dir: Path | str | None = None,
    *,
    use_cache: bool = True,
    export: Path | str | None = None,
    **placement: Any,
) -> MeshData:
    """A liner segment mesh (tagged as the block), optionally with a ball; ``placement`` goes to
    :func:`millimpact.geometry.liner.build_liner_model` (lifter, face, height_fraction, x, ball_radius,
    gap, symmetry_planes). Cached like :func:`create_mesh`."""
    shape = {f.name: getattr(liner, f.name) for f in dataclasses.fields(LinerShape)}
    for name, default in LinerShape.OPTIONAL_DEFAULTS.items():  # no holes, clamped: the key as before them
        if shape[name] == default:
            del shape[name]
        elif isinstance(shape[name], tuple):
            shape[name] = list(shape[name])
    params = {
        "kind": "liner",
        **_builder_parameters(),
        "liner": shape,
        "sizes": dataclasses.asdict(sizes),
        "placement": {k: list(v) if isinstance(v, tuple) else v for k, v in sorted(placement.items())},
    }
    planes = tuple(placement.get("symmetry_planes", ()))
    symmetry = "half" if planes else "full"
    return _create(
        params, lambda: build_liner_model(liner, sizes, **placement), symmetry, comm, cache_dir, use_cache, export
    )


def _create(
    params: dict,
    build: Callable[[], ModelInfo],
    symmetry: str,
    comm: MPI.Comm,
    cache_dir: Path | str | None,
    use_cache: bool,
    export: Path | str | None = None,
) -> MeshData:
    t0 = time.perf_counter()
    key = cache_key(params)
    directory = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    with geo.gmsh_session(f"millimpact-{key[:12]}"):
        status: tuple[str, Any] = ("error", "rank 0 did not report")
        if comm.rank == 0:
            try:
                info = _load_cached(directory, key, params) if use_cache else None
                if info is None:
                    info = _build(build, key, symmetry)
                    if use_cache:
                        _store(directory, key, params, info)
                if export is not None:
                    gmsh.write(str(export))
                status = ("ok", info)
            except MeshError as exc:
                status = ("error", str(exc))
            except Exception as exc:  # gmsh or file errors: one sentence for every rank
                status = ("error", f"meshing failed: {exc}")
        status = comm.bcast(status, root=0)
        if status[0] != "ok":
            raise MeshError(status[1])
        info = status[1]
        mesh, cell_tags, facet_tags = gmshio.model_to_mesh(gmsh.model, comm, 0, gdim=3)
    info = dataclasses.replace(info, setup_time=time.perf_counter() - t0)
    if comm.rank == 0:
        logger.info(
            "mesh %s: %d cells, %d vertices, h_c %.4g m (measured %.4g m), min SICN %.3f, %s in %.2f s",
            key[:12],
            info.n_cells_total,
            info.n_vertices,
            info.h_contact,
            info.h_contact_measured,
            info.min_quality,
            "loaded" if info.cached else "built",
            info.setup_time,
        )
    return MeshData(mesh, cell_tags, facet_tags, info)


#: the physical groups a mesh must have for millimpact (meshes/README.md): every cell group and the
#: facet groups the model and contact read
REQUIRED_CELL_TAGS = tuple(CELL_TAG_NAMES)
REQUIRED_FACET_TAGS = (geo.BALL_CONTACT, geo.BLOCK_CONTACT, geo.BALL_INTERFACE, geo.BLOCK_INTERFACE, geo.SUPPORT)


def load_msh(path: Path | str, comm: MPI.Comm = MPI.COMM_WORLD):
    """Read a gmsh .msh file that follows the mesh contract (meshes/README.md) and distribute it:
    returns (mesh, cell_tags, facet_tags). A missing physical group is a :class:`MeshError` naming
    it (one line). (``gmshio.read_from_msh`` is broken in this DOLFINx build: gmsh.merge on rank 0.)"""
    path = Path(path)
    if comm.rank == 0 and not path.is_file():
        raise MeshError(f"mesh file {path}: no such file")
    with geo.gmsh_session(f"millimpact-load-{path.stem}"):
        if comm.rank == 0:
            gmsh.merge(str(path))
        mesh, cell_tags, facet_tags = gmshio.model_to_mesh(gmsh.model, comm, 0, gdim=3)
    have_c = set().union(*comm.allgather(set(int(v) for v in np.unique(cell_tags.values))))
    have_f = set().union(*comm.allgather(set(int(v) for v in np.unique(facet_tags.values))))
    missing = [f"cell group {t} ({CELL_TAG_NAMES[t]})" for t in REQUIRED_CELL_TAGS if t not in have_c] + [
        f"facet group {t} ({FACET_TAG_NAMES[t]})" for t in REQUIRED_FACET_TAGS if t not in have_f
    ]
    if missing:
        raise MeshError(f"mesh file {path}: missing physical {', '.join(missing)} (see meshes/README.md)")
    return mesh, cell_tags, facet_tags


def _build(build: Callable[[], ModelInfo], key: str, symmetry: str) -> MeshInfo:
    """Run the builder in the current gmsh model and measure the mesh (rank 0)."""
    model = build()
    return _measure(model, key, symmetry)


def _load_cached(directory: Path, key: str, params: dict) -> MeshInfo | None:
    """Merge the cached mesh into the current gmsh model; None on a miss or a broken entry."""
    msh, meta = directory / f"{key}.msh", directory / f"{key}.json"
    if not (msh.is_file() and meta.is_file()):
        return None
    try:
        data = json.loads(meta.read_text())
        if data.get("params") != json.loads(json.dumps(params)):
            logger.warning("mesh cache %s: parameters differ from its key; rebuilding", meta)
            return None
        info = MeshInfo.from_json(data["info"])
    except (OSError, UnicodeDecodeError, ValueError, KeyError, TypeError, AttributeError) as exc:
        # the metadata, not the mesh: say which file is broken
        logger.warning(
            "mesh cache entry %s: its metadata %s is unreadable (%s: %s); rebuilding",
            key,
            meta.name,
            type(exc).__name__,
            exc,
        )
        return None
    try:
        gmsh.merge(str(msh))
    except Exception as exc:
        logger.warning("mesh cache entry %s unreadable (%s); rebuilding", msh, exc)
        name = gmsh.model.getCurrent()
        gmsh.model.remove()
        gmsh.model.add(name)
        return None
    logger.info("mesh loaded from cache %s", msh)
    return dataclasses.replace(info, cached=True)


def _store(directory: Path, key: str, params: dict, info: MeshInfo) -> None:
    """Write ``<key>.msh`` then ``<key>.json`` (the json marks a complete entry), each atomically."""
    try:
        directory.mkdir(parents=True, exist_ok=True)
        tmp = directory / f".{key}.{os.getpid()}.tmp.msh"
        gmsh.option.setNumber("Mesh.MshFileVersion", 4.1)
        gmsh.option.setNumber("Mesh.Binary", 1)
        gmsh.write(str(tmp))
        os.replace(tmp, directory / f"{key}.msh")
        tmp_json = directory / f".{key}.{os.getpid()}.tmp.json"
        tmp_json.write_text(
            json.dumps({"key": key, "params": params, "info": info.to_json()}, indent=1, sort_keys=True)
        )
        os.replace(tmp_json, directory / f"{key}.json")
    except OSError as exc:
        logger.warning("could not write the mesh cache in %s (%s); continuing without", directory, exc)


# --- measurements (rank 0, on the gmsh mesh) -------------------------------------------------------
def _measure(model: ModelInfo, key: str, symmetry: str) -> MeshInfo:
    tags, coords, _ = gmsh.model.mesh.getNodes()
    x = np.zeros((int(tags.max()) + 1, 3))
    x[tags] = coords.reshape(-1, 3)
    n_cells, n_facets = {}, {}
    cells_by_tag: dict[int, np.ndarray] = {}
    facets_by_tag: dict[int, np.ndarray] = {}
    for dim, tag in gmsh.model.getPhysicalGroups():
        conn = []
        for ent in gmsh.model.getEntitiesForPhysicalGroup(dim, tag):
            types, _, nodes = gmsh.model.mesh.getElements(dim, ent)
            for t, nd in zip(types, nodes):
                npe = gmsh.model.mesh.getElementProperties(t)[3]
                conn.append(np.asarray(nd, dtype=np.int64).reshape(-1, npe))
        c = np.concatenate(conn) if conn else np.zeros((0, 4 if dim == 3 else 3), dtype=np.int64)
        if dim == 3:
            n_cells[tag] = len(c)
            cells_by_tag[tag] = c
        else:
            n_facets[tag] = len(c)
            facets_by_tag[tag] = c
    tets = np.concatenate(list(cells_by_tag.values()))
    block = np.concatenate([cells_by_tag[t] for t in (geo.BLOCK_ZONE, geo.BLOCK_REGION) if t in cells_by_tag])
    ball = [cells_by_tag[t] for t in (geo.BALL_ZONE, geo.BALL_REGION) if t in cells_by_tag]
    h_block, h_mean = _edge_lengths_at(x, block, model.contact_block)
    h_ball = math.nan
    if ball:
        assert model.contact_ball is not None, "a model with ball cells has a ball contact point"
        h_ball = _edge_lengths_at(x, np.concatenate(ball), model.contact_ball)[0]
    sizes = model.sizes
    tri = x[facets_by_tag.get(geo.BLOCK_CONTACT, np.zeros((0, 3), dtype=np.int64))]
    near = tri[np.linalg.norm(tri.mean(axis=1) - np.asarray(model.contact_block), axis=1) < sizes.fine_radius]
    h_surface = (
        max(
            (float(np.linalg.norm(near[:, i] - near[:, j], axis=1).max()) for i, j in ((0, 1), (1, 2), (0, 2))),
            default=math.nan,
        )
        if len(near)
        else math.nan
    )
    return MeshInfo(
        n_cells=n_cells,
        n_facets=n_facets,
        n_vertices=int(np.unique(tets).size),
        h_contact=sizes.h_contact,
        h_far=sizes.h_far,
        zone_radius=sizes.zone_radius,
        h_contact_measured=h_block,
        h_contact_mean=h_mean,
        h_contact_surface=h_surface,
        h_contact_ball_measured=h_ball,
        min_quality=float(tet_quality(x[tets]).min()),
        meshing_time=model.mesh_time,
        cache_key=key,
        symmetry=symmetry,
        symmetry_planes=tuple(model.symmetry_planes),
        contact_point_block=vec3(model.contact_block),
        contact_point_ball=vec3(model.contact_ball) if model.contact_ball else None,
        volumes=dict(model.volumes),
    )


def _edge_lengths_at(x: np.ndarray, cells: np.ndarray, point: Sequence[float]) -> tuple[float, float]:
    """Longest and mean edge (m) of the cells touching the mesh node at ``point``."""
    used = np.unique(cells)
    d = np.linalg.norm(x[used] - np.asarray(point), axis=1)
    node = used[np.argmin(d)]
    if d.min() > 1e-9 * max(1.0, np.ptp(x[used], axis=0).max()):
        raise MeshError(f"no mesh node at the contact point {tuple(point)} (nearest {d.min():.3g} m away)")
    star = cells[np.any(cells == node, axis=1)]
    p = x[star]
    lengths = np.concatenate([np.linalg.norm(p[:, i] - p[:, j], axis=1) for i in range(4) for j in range(i + 1, 4)])
    return float(lengths.max()), float(lengths.mean())


#: maps the reference tetrahedron onto the regular tetrahedron of unit edge (columns: edge vectors)
_REGULAR = np.array([[1.0, 0.5, 0.5], [0.0, math.sqrt(3) / 2, math.sqrt(3) / 6], [0.0, 0.0, math.sqrt(2.0 / 3.0)]])
_REGULAR_INV = np.linalg.inv(_REGULAR)


def tet_quality(p: np.ndarray) -> np.ndarray:
    """Signed inverse condition number (SICN) of tetrahedra ``p`` (n, 4, 3).

    With J the edge matrix and W that of the regular tetrahedron, S = J W^-1 and
    SICN = 3 sign(det S) / (|S|_F |S^-1|_F): 1 for a regular tetrahedron, -> 0 as it flattens,
    negative if inverted (the Frobenius condition number, as gmsh's ICN measure).
    """
    J = np.stack([p[:, 1] - p[:, 0], p[:, 2] - p[:, 0], p[:, 3] - p[:, 0]], axis=2)
    S = J @ _REGULAR_INV
    det = np.linalg.det(S)
    q = np.zeros(len(p))
    ok = np.abs(det) > 0
    Sinv = np.linalg.inv(S[ok])
    q[ok] = 3.0 * np.sign(det[ok]) / (np.linalg.norm(S[ok], axis=(1, 2)) * np.linalg.norm(Sinv, axis=(1, 2)))
    return q


# --- output and helpers ----------------------------------------------------------------------------
def write_mesh_xdmf(meshdata: MeshData, path: Path | str) -> Path:
    """Write the mesh with its cell and facet tags to an XDMF file (collective). Returns the path."""
    path = Path(path)
    comm = meshdata.mesh.comm
    if comm.rank == 0:
        path.parent.mkdir(parents=True, exist_ok=True)
    comm.barrier()
    mesh = meshdata.mesh
    mesh.topology.create_connectivity(mesh.topology.dim - 1, mesh.topology.dim)
    with XDMFFile(comm, str(path), "w") as xdmf:
        xdmf.write_mesh(mesh)
        xdmf.write_meshtags(meshdata.cell_tags)
        xdmf.write_meshtags(meshdata.facet_tags)
    return path


def _as_tags(tag: int | Iterable[int]) -> list[int]:
    return [int(tag)] if isinstance(tag, (int, np.integer)) else [int(t) for t in tag]


def locate_cells(meshdata: MeshData, tag: int | Iterable[int]) -> np.ndarray:
    """Local indices (int32, sorted) of the cells with cell tag ``tag`` (or any of several tags)."""
    ct = meshdata.cell_tags
    return np.sort(ct.indices[np.isin(ct.values, _as_tags(tag))]).astype(np.int32)


def facet_indices(meshdata: MeshData, tag: int | Iterable[int]) -> np.ndarray:
    """Local indices (int32, sorted) of the facets with facet tag ``tag`` (or any of several tags)."""
    ft = meshdata.facet_tags
    return np.sort(ft.indices[np.isin(ft.values, _as_tags(tag))]).astype(np.int32)


def mesh_report(meshdata: MeshData) -> list[tuple[str, str]]:
    """(name, value) rows describing the mesh, for printing."""
    i = meshdata.info
    rows = [
        ("symmetry", f"{i.symmetry} (cut planes: {', '.join(i.symmetry_planes) or 'none'})"),
        ("tetrahedra", f"{i.n_cells_total}"),
        ("vertices", f"{i.n_vertices}"),
    ]
    for tag, name in CELL_TAG_NAMES.items():
        if tag in i.n_cells:
            rows.append((f"  {name}", f"{i.n_cells[tag]} cells, {i.volumes.get(tag, math.nan) * 1e9:.4g} mm^3"))
    for tag, name in FACET_TAG_NAMES.items():
        if tag in i.n_facets:
            rows.append((f"  {name}", f"{i.n_facets[tag]} facets"))
    rows += [
        ("zone radius", f"{i.zone_radius * 1e3:.4g} mm"),
        (
            "h_contact",
            f"{i.h_contact * 1e3:.4g} mm target; at the block's contact point: longest edge "
            f"{i.h_contact_measured * 1e3:.4g} mm, mean {i.h_contact_mean * 1e3:.4g} mm; "
            f"contact face {i.h_contact_surface * 1e3:.4g} mm",
        ),
        ("h_far", f"{i.h_far * 1e3:.4g} mm"),
        ("min quality", f"{i.min_quality:.3f} (SICN; 1 = regular tetrahedron)"),
        (
            "meshing",
            f"{i.meshing_time:.2f} s gmsh"
            + (" (loaded from cache)" if i.cached else "")
            + f"; {i.setup_time:.2f} s this call",
        ),
        ("cache key", i.cache_key[:16]),
    ]
    return rows


# --- whole bodies in the zone ----------------------------------------------------------------------
#: the plan's names of the bodies (``Plan.plastic_whole``) and their (region, zone) cell tags
_WHOLE_BODY_TAGS = {"ball": (geo.BALL_REGION, geo.BALL_ZONE), "struck": (geo.BLOCK_REGION, geo.BLOCK_ZONE)}


def with_whole_bodies_in_zone(md: MeshData, bodies: Iterable[str]) -> MeshData:
    """The mesh data with the region cells of ``bodies`` ("ball", "struck") tagged as their contact
    zone's: such a body is finite elements throughout (no region left to reduce, the plastic zone
    its every cell) on the same mesh and its same sizes. The facet tags are kept (the zone-region
    interface facets, now inside the zone, tag nothing that the zone's methods read)."""
    swap = dict(_WHOLE_BODY_TAGS[b] for b in bodies)
    if not swap:
        return md
    values = md.cell_tags.values.copy()
    for region, zone in swap.items():
        values[values == region] = zone
    tags = dolfinx.mesh.meshtags(md.mesh, md.mesh.topology.dim, md.cell_tags.indices.copy(), values)
    tags.name = md.cell_tags.name  # type: ignore[attr-defined]
    return md._replace(cell_tags=tags)
