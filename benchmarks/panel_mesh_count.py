import sys, time
from mpi4py import MPI
import gmsh
from millimpact.scene.builtin import builtin_scene
from millimpact.scene.plan import make_plan
from millimpact.geometry.builders import MeshSizes, gmsh_session, FACET_TAG_NAMES
from millimpact.geometry.liner import build_liner_model
import os
scene = builtin_scene(os.environ.get("SCENE", "liner-panel"))
for a in sys.argv[1:]:
    k, v = a.split("=")
    scene = scene.with_value(k, float(v))
plan = make_plan(scene)
ln = scene.liner
t0 = time.perf_counter()
with gmsh_session():
    info = build_liner_model(ln, MeshSizes.from_plan(plan), lifter=ln.impact_lifter, face=ln.impact_face,
                             height_fraction=ln.impact_height, x=ln.impact_x, ball_radius=scene.ball.radius,
                             gap=plan.gap, symmetry_planes=plan.symmetry_planes)
    nodes = gmsh.model.mesh.getNodes()[0]
    gmsh.model.mesh.createEdges()
    etypes, etags, enodes = gmsh.model.mesh.getElements(3)
    ntet = sum(len(t) for t in etags)
    edges = gmsh.model.mesh.getAllEdges()[0] if hasattr(gmsh.model.mesh, "getAllEdges") else None
    import numpy as np
    tets = np.concatenate(enodes).reshape(-1, 4)
    e = np.sort(np.vstack([tets[:, [i, j]] for i in range(4) for j in range(i + 1, 4)]), axis=1)
    n_edges = len(np.unique(e, axis=0))
    n_vert = len(np.unique(tets))
    groups = {FACET_TAG_NAMES.get(t, t): len(gmsh.model.getEntitiesForPhysicalGroup(d, t)) for d, t in gmsh.model.getPhysicalGroups(2)}
print(f"h_contact {plan.h_contact:.4g} h_far {plan.h_far:.4g} zone {plan.zone_radius:.4g}: tets {ntet} vertices {n_vert} edges {n_edges} "
      f"P1 dofs {3*n_vert} P2 dofs {3*(n_vert+n_edges)} mesh time {info.mesh_time:.1f} s total {time.perf_counter()-t0:.1f} s")
print(groups)
from millimpact.scene.sizing import estimate_mesh
est = estimate_mesh(scene, plan)
print(f"estimate: vertices {est.vertices} (measured {n_vert}, ratio {n_vert/est.vertices:.3f}) edges {est.edges} "
      f"(measured {n_edges}) P2 dofs {est.dofs(2)} (measured {3*(n_vert+n_edges)}, ratio {3*(n_vert+n_edges)/est.dofs(2):.3f})")
