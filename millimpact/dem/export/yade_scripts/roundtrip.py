# millimpact export --check: one ball on a wall in Yade for each of a contact table's (speed, angle).
# Run by millimpact as `yade -n -x roundtrip.py INPUT.json` in a folder of its own; writes the JSON
# file the input names. Input: the exported law file (law mode) or a naive constant input (naive
# mode: Ip2(en=...) with the materials' Young's modulus and Yade's default NewtonIntegrator, as a
# new user would set it up). The wall is the plane z = 0; the ball arrives with
# v = V (sin(a), 0, -cos(a)) and no spin. Measured after separation: e_n = v_z,out / v_z,in,
# e_t = u_x,out / u_x,in with u_x = v_x - R omega_y the contact point's tangential velocity, and the
# peak of the wall's force on the ball (its z component).
import json
import math
import sys

from yade import utils

inp = json.load(open(sys.argv[-1]))
mode = inp["mode"]
if mode == "law":
    exec(open(inp["law_file"]).read(), globals())
R, rho = inp["radius_m"], inp["density_kg_m3"]
results = []
for k, case in enumerate(inp["cases"]):
    O.reset()
    if mode == "law":
        ball_mat = O.materials.append(millimpact_ball_material())
        liner_mat = O.materials.append(millimpact_liner_material())
        ip2 = millimpact_ip2()
        extra = [millimpact_law_runner()]
        newton = NewtonIntegrator(gravity=(0, 0, 0), damping=0.0)
    else:
        nv = inp["naive"]
        ball_mat = liner_mat = O.materials.append(
            FrictMat(young=nv["young_Pa"], poisson=nv["poisson"], density=rho, frictionAngle=math.atan(nv["friction"]))
        )
        ip2 = Ip2_FrictMat_FrictMat_MindlinPhys(en=MatchMaker(algo="val", val=nv["en"]))
        extra = []
        newton = NewtonIntegrator(gravity=(0, 0, 0))  # Yade's default local damping (0.2)
    O.bodies.append(utils.wall(0, axis=2, sense=1, material=liner_mat))
    b = O.bodies.append(utils.sphere((0, 0, R * (1 + 1e-6)), R, material=ball_mat))
    a = math.radians(case["angle_deg"])
    v0 = case["speed_m_s"]
    O.bodies[b].state.vel = (v0 * math.sin(a), 0, -v0 * math.cos(a))
    O.engines = [
        ForceResetter(),
        InsertionSortCollider([Bo1_Sphere_Aabb(), Bo1_Wall_Aabb()]),
        InteractionLoop([Ig2_Wall_Sphere_ScGeom()], [ip2], [Law2_ScGeom_MindlinPhys_Mindlin()]),
        *extra,
        newton,
    ]
    O.dt = case["dt_s"]
    st = O.bodies[b].state
    vz_in, ux_in = st.vel[2], st.vel[0] - R * st.angVel[1]
    f_max, touched = 0.0, False
    for i in range(int(case["max_steps"])):  # noqa: B007 (the step count is reported below)
        O.step()
        f_max = max(f_max, O.forces.f(b)[2])
        real = any(x.isReal for x in O.interactions)
        touched = touched or real
        if touched and not real and st.vel[2] > 0:
            break
    else:
        raise RuntimeError(f"case {k}: contact not ended after {case['max_steps']} steps")
    e_n = -st.vel[2] / vz_in
    ux = st.vel[0] - R * st.angVel[1]
    e_t = ux / ux_in if abs(ux_in) > 1e-12 * v0 else float("nan")
    results.append(
        {
            "speed_m_s": v0,
            "angle_deg": case["angle_deg"],
            "restitution_normal": e_n,
            "restitution_tangential": e_t,
            "peak_normal_force_N": f_max,
            "steps": i + 1,
        }
    )
    print(
        f"PROGRESS case {k + 1}/{len(inp['cases'])}: v = {v0:g} m/s, {case['angle_deg']:g} deg: e_n {e_n:.4f}, "
        f"F_max {f_max:.4g} N",
        flush=True,
    )
json.dump({"yade_version": version, "results": results}, open(inp["results_file"], "w"), indent=1)
