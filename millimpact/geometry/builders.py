"""Geometry: gmsh (OpenCASCADE) models of the ball and the struck body, meshed with tetrahedra.

Stage 3 of a run (foundations.md section 1): what the builders :mod:`.block` (the rig) and :mod:`.liner`
share (tags, sizes, the gmsh instance, zone splitting, size fields, meshing). The builders act on
the current gmsh instance on rank 0; :mod:`millimpact.geometry.mesh` converts the result to DOLFINx
once and caches it. Units are SI (metres) throughout.

One model holds both bodies as disjoint volumes (the ball never touches the block: the plan's gap
separates them). Each body is split into a *contact zone* (the body inside a sphere of radius
``zone_radius`` around its contact point) and the *region* (the rest); the two share a conforming
interface (OCC fragment). A vertex sits exactly at each contact point (the block's impact point
and the ball's lowest point), so contact-point outputs are nodal values. Symmetry cuts keep
``x >= x_p`` (plane ``"x"``) and ``z >= z_p`` (plane ``"z"``).

Element size: ``h_contact`` within ``fine_radius`` of either contact point, growing linearly with
the distance to ``h_far`` at ``fine_radius + SIZE_GROWTH_ZONE_RADII * zone_radius`` (further for a
small ball, :data:`millimpact.scene.plan.MAX_SIZE_GROWTH`), never above ``h_far`` (gmsh Distance +
Threshold fields) nor ``h_ball`` inside a small ball (a Ball field); first-order tetrahedra.

Physical groups (integer tags below, also named with ``setPhysicalName``):

=====================  ====  ==================================================================
cells                  tag
=====================  ====  ==================================================================
``BALL_ZONE``          1     ball inside the zone sphere
``BALL_REGION``        2     rest of the ball
``BLOCK_ZONE``         3     block (or liner) inside the zone sphere
``BLOCK_REGION``       4     rest of the block (or liner)
facets
``BALL_CONTACT``       11    ball sphere surface inside the zone
``BLOCK_CONTACT``      12    block's struck face y = 0 inside the zone (liner: exterior in zone)
``BALL_INTERFACE``     13    ball zone / region interface (interior facets)
``BLOCK_INTERFACE``    14    block zone / region interface (interior facets)
``SUPPORT``            15    clamped face: z = 0 (``support = "base"``), y = -b (``"back"``)
``SYM_X``              16    cut plane x = x_p (both bodies)
``SYM_Z``              17    cut plane z = z_p (both bodies)
``BALL_SURFACE``       18    rest of the ball's surface
``BLOCK_SURFACE``      19    rest of the block's exterior
``BACKING``            20    a liner's back face on a rubber backing (``liner.backing = "rubber"``;
                             clamped it is ``SUPPORT``); a liner's bolt holes are ``SUPPORT``
=====================  ====  ==================================================================
"""

from __future__ import annotations

import contextlib
import dataclasses
import logging
import math
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass

import gmsh
import numpy as np

from ..errors import MeshError
from ..scene.plan import Plan, size_growth_distance
from ..scene.schema import Vec3

logger = logging.getLogger(__name__)


#: bump when the builders change what they produce: part of the mesh cache key
BUILDER_VERSION = 3  # 2: a liner's zone spheres on a plate or lifter top have their poles on the normal;
# 3: the growth to h_far capped at MAX_SIZE_GROWTH, a small ball's own far size h_ball

BALL_ZONE, BALL_REGION, BLOCK_ZONE, BLOCK_REGION = 1, 2, 3, 4
BALL_CONTACT, BLOCK_CONTACT, BALL_INTERFACE, BLOCK_INTERFACE = 11, 12, 13, 14
SUPPORT, SYM_X, SYM_Z, BALL_SURFACE, BLOCK_SURFACE = 15, 16, 17, 18, 19
BACKING = 20

CELL_TAG_NAMES: dict[int, str] = {
    BALL_ZONE: "ball_zone",
    BALL_REGION: "ball_region",
    BLOCK_ZONE: "block_zone",
    BLOCK_REGION: "block_region",
}
FACET_TAG_NAMES: dict[int, str] = {
    BALL_CONTACT: "ball_contact",
    BLOCK_CONTACT: "block_contact",
    BALL_INTERFACE: "ball_interface",
    BLOCK_INTERFACE: "block_interface",
    SUPPORT: "support",
    SYM_X: "sym_x",
    SYM_Z: "sym_z",
    BALL_SURFACE: "ball_surface",
    BLOCK_SURFACE: "block_surface",
    BACKING: "backing",
}

#: the size reaches h_far SIZE_GROWTH_ZONE_RADII zone radii beyond fine_radius (a growth rate
#: (h_far - h_contact) / (3 zone_radius) ~ 0.25 at the default scene keeps the tetrahedra well
#: shaped), or further: :func:`millimpact.scene.plan.size_growth_distance`
#: gmsh 3D algorithm: 1 = Delaunay, deterministic (HXT, 10, is faster but its counts vary run to run)
MESH_ALGORITHM_3D = 1
#: gmsh 2D algorithm: 6 = Frontal-Delaunay
MESH_ALGORITHM_2D = 6


# --- parameters --------------------------------------------------------------------------------
@dataclass(frozen=True)
class MeshSizes:
    """Element sizes and the contact-zone radius, all in m (see :class:`millimpact.scene.plan.Plan`)."""

    h_contact: float
    h_far: float
    zone_radius: float
    fine_radius: float
    h_ball: float = 0.0  #: the ball's far size when smaller than h_far (a small ball); 0: h_far
    ball_zone_radius: float = 0.0  #: the zone's radius in the ball when smaller (a small ball); 0: zone_radius

    @classmethod
    def from_plan(cls, plan: Plan) -> MeshSizes:
        """The sizes a plan chose."""
        return cls(plan.h_contact, plan.h_far, plan.zone_radius, plan.fine_radius, plan.h_ball, plan.ball_zone_radius)

    @property
    def ball_zone(self) -> float:
        """The contact zone's radius in the ball, m."""
        return self.ball_zone_radius or self.zone_radius

    def validate(self) -> None:
        """Refuse non-positive or inconsistent sizes with a :class:`MeshError` naming the field."""
        for name in ("h_contact", "h_far", "zone_radius", "fine_radius"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise MeshError(f"mesh size {name} = {v!r}: must be a finite number > 0 m")
        if self.h_far < self.h_contact:
            raise MeshError(f"mesh size h_far = {self.h_far:g} m: must be >= h_contact = {self.h_contact:g} m")
        if self.h_ball != 0 and not (self.h_contact <= self.h_ball <= self.h_far):
            raise MeshError(
                f"mesh size h_ball = {self.h_ball!r}: must be 0 (h_far) or between h_contact "
                f"= {self.h_contact:g} m and h_far = {self.h_far:g} m"
            )
        if self.zone_radius < 2.0 * self.h_contact:
            raise MeshError(
                f"zone_radius = {self.zone_radius:g} m: must be at least 2 h_contact "
                f"= {2 * self.h_contact:g} m (two elements across the zone)"
            )


@dataclass(frozen=True)
class ModelInfo:
    """What a builder made (rank 0): contact points (m), exact OCC volumes per cell tag (m^3),
    the symmetry planes and the element sizes."""

    contact_block: Vec3
    contact_ball: Vec3 | None
    volumes: dict[int, float]
    symmetry_planes: tuple[str, ...]
    sizes: MeshSizes
    contact_vertices: tuple[int, ...] = ()  #: gmsh point tags at the contact points
    block_volumes: tuple[int, ...] = ()  #: gmsh volume tags of the block (liner)
    ball_volumes: tuple[int, ...] = ()
    mesh_time: float = 0.0  #: gmsh generate time, s (0 if not meshed)


# --- gmsh instance ---------------------------------------------------------------------------------
#: open :func:`gmsh_session` calls that initialized gmsh or run inside one that did. gmsh 4.8 has no
#: "is initialized" query, and its API must not be asked: a call before ``gmsh.initialize()`` goes
#: to gmsh's Msg::Error, which at random ends the process with exit(1) and no message (an
#: LD_PRELOAD hook on exit() caught it in a CI run: gmshModelList -> Msg::Error -> exit(1), from the
#: earlier ``gmsh.model.list()`` probe here; the "silent deaths" of runs, study workers and MPI
#: ranks). So the state is kept here.
_open_sessions = [0]


@contextlib.contextmanager
def gmsh_session(name: str = "millimpact") -> Iterator[None]:
    """Initialize gmsh (quiet) if needed, make a fresh current model ``name``, and clean up.

    Finalizes gmsh on exit only if this call initialized it (the calls nest). Use on every rank
    before :func:`dolfinx.io.gmshio.model_to_mesh` (it needs gmsh initialized everywhere). gmsh is
    initialized through here only: a caller's own ``gmsh.initialize()`` is not seen, and a
    call would finalize it.
    """
    owned = _open_sessions[0] == 0
    if owned:
        gmsh.initialize(readConfigFiles=False)  # no user gmshrc: meshes depend on our options only
    _open_sessions[0] += 1
    try:
        previous = gmsh.model.getCurrent()
        terminal = gmsh.option.getNumber("General.Terminal")
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add(name)
        try:
            yield
        finally:
            if not owned:
                with contextlib.suppress(Exception):
                    gmsh.model.setCurrent(name)
                    gmsh.model.remove()
                    gmsh.model.setCurrent(previous)
                gmsh.option.setNumber("General.Terminal", terminal)
    finally:
        _open_sessions[0] -= 1
        if owned:
            gmsh.finalize()


# --- shared pieces ---------------------------------------------------------------------------------
def positive_size(name: str, v: object) -> None:
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v <= 0:
        raise MeshError(f"{name} = {v!r}: must be a finite number > 0 m")


def check_zone_fits(body: str, zone_radius: float, size: float) -> None:
    # the plan keeps the zone below 0.45 of the smallest size; refuse only what cannot be built
    if zone_radius >= 0.5 * size:
        raise MeshError(
            f"zone_radius = {zone_radius:g} m: the contact zone is larger than the {body} "
            f"(must be below half its smallest size, {0.5 * size:g} m)"
        )


def run_gmsh(build: Callable[[], ModelInfo]) -> ModelInfo:
    """Run a builder, turning gmsh's exceptions into one-sentence :class:`MeshError`."""
    try:
        return build()
    except MeshError:
        raise
    except Exception as exc:  # gmsh raises bare Exception with its last error message
        raise MeshError(f"gmsh failed to build or mesh the model: {exc}") from exc


def polygon_face(points: Sequence[tuple[float, float, float]], x0: float) -> int:
    """A plane surface in x = x0 through (_, y, z) points (the first coordinate is ignored)."""
    occ = gmsh.model.occ
    tags = [occ.addPoint(x0, y, z) for _, y, z in points]
    lines = [occ.addLine(tags[i], tags[(i + 1) % len(tags)]) for i in range(len(tags))]
    return occ.addPlaneSurface([occ.addCurveLoop(lines)])


def keep_box(
    planes: Sequence[str], x_p: float, z_p: float, scale: float, lo: Sequence[float], hi: Sequence[float]
) -> int | None:
    """A box holding the kept side of the symmetry planes (x >= x_p, z >= z_p), None if no plane."""
    if not planes:
        return None
    x0 = x_p if "x" in planes else lo[0] - scale
    z0 = z_p if "z" in planes else lo[2] - scale
    x1, y0, y1, z1 = hi[0] + scale, lo[1] - scale, hi[1] + scale, hi[2] + scale
    return gmsh.model.occ.addBox(x0, y0, z0, x1 - x0, y1 - y0, z1 - z0)


#: a zone sphere keeps OCC's z axis as its polar axis when its poles are at least this far (deg)
#: from the struck surface's tangent plane (|n_z| >= sin of it: a lifter face, n_z ~ 0.94 for
#: liner-segment, keeps the mesh it had); nearer, its poles are turned onto the normal (:func:`zone_axis`)
ZONE_POLE_MIN_ANGLE = 45.0


def zone_axis(normal: Vec3) -> Vec3 | None:
    """The polar axis for a zone sphere on a surface of unit outward ``normal``: None (OCC's z) if
    the z poles are at least :data:`ZONE_POLE_MIN_ANGLE` from the tangent plane (asin |n_z|),
    else the normal (the poles 90 deg from it: :func:`orient_poles`)."""
    norm = math.sqrt(sum(c * c for c in normal))
    if abs(normal[2]) >= math.sin(math.radians(ZONE_POLE_MIN_ANGLE)) * norm:
        return None
    return normal


def orient_poles(sphere: int, centre: Vec3, axis: Vec3) -> None:
    """Rotate the OCC sphere ``sphere`` about its ``centre`` so that its poles lie on ``axis``.

    An OCC sphere is parametrized by longitude and latitude about the z axis; its poles (centre +-
    r e_z) are singular points of that map. A zone sphere centred on a surface whose normal is
    nearly perpendicular to z (a liner's plate: n ~ e_y) has a pole next to that surface: the
    surface cuts a sliver off the sphere's cap (at a plate impact 0.175 m from the lifter of
    liner-segment, with a zone of 24.2 mm, a 0.82 mm edge beside the pole) and gmsh's 2D mesher
    aborted the process ("The 1D mesh seems not to be forming a closed loop", a C++ exception
    Python cannot catch). With the poles on the contact normal the surface cuts the
    sphere near its equator, as far from both poles as it can be. The sphere itself is unchanged.
    """
    ex, ey, ez = axis
    norm = math.sqrt(ex * ex + ey * ey + ez * ez)
    if not norm > 0:
        raise MeshError(f"zone sphere axis {tuple(axis)}: must be a nonzero vector")
    ex, ey, ez = ex / norm, ey / norm, ez / norm
    # rotation taking e_z to the axis: about e_z x axis = (-ey, ex, 0), by angle acos(ez)
    kx, ky = -ey, ex
    angle = math.atan2(math.hypot(kx, ky), ez)
    if math.hypot(kx, ky) < 1e-12:
        if ez > 0:
            return
        kx, ky = 1.0, 0.0  # the axis is -z: half a turn about x (the poles swap)
    gmsh.model.occ.rotate([(3, sphere)], *centre, kx, ky, 0.0, angle)


def split_body(
    body: int, point: Vec3, zone_radius: float, keep: int | None, name: str, axis: Vec3 | None = None
) -> tuple[list[int], list[int], int]:
    """Cut ``body`` by the symmetry box ``keep``, then fragment it with the zone sphere (radius m,
    centred at the contact ``point``) and the point itself. Returns (zone volumes, region volumes,
    the point's gmsh tag). Pieces are identified through OCC's fragment history (which input each
    output came from) and checked by their OCC volumes.

    ``axis``: the zone sphere's polar axis (:func:`orient_poles`; None keeps OCC's z axis):
    :func:`zone_axis` of the contact normal keeps the poles away from the body's surface."""
    occ = gmsh.model.occ
    if keep is not None:
        out, _ = occ.intersect([(3, body)], [(3, keep)])
        vols = [t for d, t in out if d == 3]
        if len(vols) != 1:
            raise MeshError(f"the symmetry cut of the {name} left {len(vols)} pieces (expected one)")
        body = vols[0]
    full = occ.getMass(3, body)
    sphere = occ.addSphere(*point, zone_radius)
    if axis is not None:
        orient_poles(sphere, point, axis)
    pt = occ.addPoint(*point)
    out, children = occ.fragment([(3, body)], [(3, sphere), (0, pt)])
    from_body = {t for d, t in children[0] if d == 3}
    from_sphere = {t for d, t in children[1] if d == 3}
    zone = sorted(from_body & from_sphere)
    region = sorted(from_body - from_sphere)
    outside = [(3, t) for t in sorted(from_sphere - from_body)]
    if outside:
        occ.remove(outside, recursive=True)
    points = [t for d, t in children[2] if d == 0]
    if len(points) != 1:
        raise MeshError(f"the {name}'s contact point {point} is not on its surface")
    v_zone = sum(occ.getMass(3, t) for t in zone)
    v_region = sum(occ.getMass(3, t) for t in region)
    if not zone or v_zone <= 1e-12 * full:
        raise MeshError(f"the {name}'s contact zone is empty (the zone sphere misses the {name})")
    if not region or v_region <= 1e-12 * full:
        raise MeshError(f"zone larger than the body: the contact zone holds the whole {name}")
    return zone, region, points[0]


def surface_samples(s: int) -> np.ndarray:
    """Points on the underlying surface of gmsh surface ``s`` (a 3 x 3 grid in its parameters)."""
    lo, hi = gmsh.model.getParametrizationBounds(2, s)
    uv = [
        lo[i] + f * (hi[i] - lo[i]) for fu in (0.2, 0.5, 0.8) for fv in (0.2, 0.5, 0.8) for i, f in ((0, fu), (1, fv))
    ]
    return np.asarray(gmsh.model.getValue(2, s, uv)).reshape(-1, 3)


def on_plane(s: int, axis: int, value: float, tol: float) -> bool:
    """Whether surface ``s`` lies in the plane x[axis] = value (m)."""
    if gmsh.model.getType(2, s) != "Plane":
        return False
    return bool(np.all(np.abs(surface_samples(s)[:, axis] - value) < tol))


def symmetry_tag(s: int, planes: Sequence[str], x_p: float, z_p: float, tol: float) -> int:
    if "x" in planes and on_plane(s, 0, x_p, tol):
        return SYM_X
    if "z" in planes and on_plane(s, 2, z_p, tol):
        return SYM_Z
    return 0


def tag_groups(
    block_zone: list[int],
    block_region: list[int],
    ball_zone: list[int],
    ball_region: list[int],
    block_facet: Callable[[int, bool], int],
    ball_facet: Callable[[int, bool], int],
) -> dict[int, float]:
    """Add the physical groups. Interfaces are surfaces bounding a zone and a region volume; each
    exterior surface is classified by the body's ``*_facet(surface, in_zone)``. Returns the OCC
    volume (m^3) of each cell group."""
    cells = {BALL_ZONE: ball_zone, BALL_REGION: ball_region, BLOCK_ZONE: block_zone, BLOCK_REGION: block_region}
    owner = {v: tag for tag, vols in cells.items() for v in vols}
    facets: dict[int, list[int]] = {tag: [] for tag in FACET_TAG_NAMES}
    for _, s in gmsh.model.getEntities(2):
        up, _ = gmsh.model.getAdjacencies(2, s)
        kinds = sorted({owner[v] for v in up if v in owner})
        if not kinds:
            continue  # a leftover not bounding any kept volume
        if kinds == [BALL_ZONE, BALL_REGION]:
            facets[BALL_INTERFACE].append(s)
        elif kinds == [BLOCK_ZONE, BLOCK_REGION]:
            facets[BLOCK_INTERFACE].append(s)
        elif len(up) == 1 and kinds[0] in (BALL_ZONE, BALL_REGION):
            facets[ball_facet(s, kinds[0] == BALL_ZONE)].append(s)
        elif len(up) == 1:
            facets[block_facet(s, kinds[0] == BLOCK_ZONE)].append(s)
        else:
            continue  # internal to one group (not expected)
    volumes = {}
    for tag, vols in cells.items():
        if vols:
            gmsh.model.addPhysicalGroup(3, vols, tag)
            gmsh.model.setPhysicalName(3, tag, CELL_TAG_NAMES[tag])
        volumes[tag] = float(sum(gmsh.model.occ.getMass(3, v) for v in vols))
    for tag, surfs in facets.items():
        if surfs:
            gmsh.model.addPhysicalGroup(2, surfs, tag)
            gmsh.model.setPhysicalName(2, tag, FACET_TAG_NAMES[tag])
    return volumes


#: elements around a bolt hole's circumference (at most; never coarser than h_far): its lateral
#: area, the clamped support, is then within 1 - sin(pi/n)/(pi/n) = 0.6 % of the cylinder's
HOLE_ELEMENTS_AROUND = 16


def hole_size(diameter: float, h_far: float) -> float:
    """Element size (m) on a bolt hole of ``diameter`` (m): pi d / HOLE_ELEMENTS_AROUND, at most h_far."""
    return min(h_far, math.pi * diameter / HOLE_ELEMENTS_AROUND)


def size_field(
    points: Sequence[int],
    sizes: MeshSizes,
    holes: Sequence[tuple[int, float]] = (),
    ball: tuple[Vec3, float] | None = None,
) -> None:
    """h = h_contact within fine_radius of the contact points, linear growth to h_far at
    fine_radius + :func:`size_growth_distance`, capped at h_far; first-order tets.
    ``holes``: (gmsh curve tag, hole diameter m) of the bolt holes' edges: h = :func:`hole_size` on
    them, growing linearly to h_far one diameter away (the smaller of the two fields wins).
    ``ball``: (centre, radius m) of the ball, capped at ``sizes.h_ball`` when that is set."""
    f = gmsh.model.mesh.field
    dist = f.add("Distance")
    f.setNumbers(dist, "PointsList", list(points))
    thr = f.add("Threshold")
    f.setNumber(thr, "InField", dist)
    f.setNumber(thr, "SizeMin", sizes.h_contact)
    f.setNumber(thr, "SizeMax", sizes.h_far)
    f.setNumber(thr, "DistMin", sizes.fine_radius)
    f.setNumber(
        thr,
        "DistMax",
        sizes.fine_radius
        + size_growth_distance(sizes.h_contact, sizes.h_far, sizes.zone_radius, small_ball=sizes.h_ball > 0),
    )
    background = thr
    fields = [thr]
    if ball is not None and 0 < sizes.h_ball < sizes.h_far:
        centre, radius = ball
        cap = f.add("Ball")
        for key, value in zip(("XCenter", "YCenter", "ZCenter"), centre):
            f.setNumber(cap, key, value)
        f.setNumber(cap, "Radius", radius * 1.01)  # the sphere's faceted surface inside
        f.setNumber(cap, "VIn", sizes.h_ball)
        f.setNumber(cap, "VOut", sizes.h_far)
        fields.append(cap)
    if holes:
        for curve, diameter in holes:
            d_h = f.add("Distance")
            f.setNumbers(d_h, "CurvesList", [curve])
            f.setNumber(d_h, "NumPointsPerCurve", 100)
            t_h = f.add("Threshold")
            f.setNumber(t_h, "InField", d_h)
            f.setNumber(t_h, "SizeMin", hole_size(diameter, sizes.h_far))
            f.setNumber(t_h, "SizeMax", sizes.h_far)
            f.setNumber(t_h, "DistMin", 0.0)
            f.setNumber(t_h, "DistMax", diameter)
            fields.append(t_h)
    if len(fields) > 1:
        background = f.add("Min")
        f.setNumbers(background, "FieldsList", fields)
    f.setAsBackgroundMesh(background)
    opt = gmsh.option.setNumber
    opt("Mesh.MeshSizeExtendFromBoundary", 0)
    opt("Mesh.MeshSizeFromPoints", 0)
    opt("Mesh.MeshSizeFromCurvature", 0)
    opt("Mesh.MeshSizeMax", sizes.h_far)
    opt("Mesh.Algorithm", MESH_ALGORITHM_2D)
    opt("Mesh.Algorithm3D", MESH_ALGORITHM_3D)
    opt("Mesh.ElementOrder", 1)
    opt("Mesh.Optimize", 1)


def generate_mesh(info: ModelInfo) -> ModelInfo:
    """Mesh the current model in 3D; refuse empty groups; renumber nodes contiguously."""
    t0 = time.perf_counter()
    gmsh.model.mesh.generate(3)
    gmsh.model.mesh.renumberNodes()
    gmsh.model.mesh.renumberElements()
    elapsed = time.perf_counter() - t0
    for dim, tag in gmsh.model.getPhysicalGroups(3):
        n = sum(
            len(e)
            for v in gmsh.model.getEntitiesForPhysicalGroup(dim, tag)
            for e in gmsh.model.mesh.getElements(3, v)[1]
        )
        if n == 0:
            raise MeshError(
                f"gmsh produced an empty mesh for {CELL_TAG_NAMES.get(tag, tag)} "
                "(element sizes too large for the body?)"
            )
    logger.info("gmsh meshed the model in %.2f s", elapsed)
    return dataclasses.replace(info, mesh_time=elapsed)
