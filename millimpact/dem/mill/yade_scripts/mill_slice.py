# A slice of a tumbling mill in Yade: run as  yade -n -j1 -x mill_slice.py INPUT.json
#
# Written by millimpact (millimpact/dem/mill/setup.py writes INPUT.json; millimpact/dem/mill/log.py
# reads what this leaves). It runs inside Yade's own Python: no millimpact imports here.
#
# The liner: the profile's segments (x0, y0, x1, y1 in the mill's cross-section, axis on z through
# the origin) swept over the slice's thickness 0 <= z <= L, two triangular facets a segment, all
# members of one clump that RotationEngine turns about z at omega (rad/s, counter-clockwise).
# Frictionless walls close the slice at z = 0 and z = L. Balls: Hertz-Mindlin
# (Law2_ScGeom_MindlinPhys_Mindlin), restitution parameter en_yade, Coulomb friction mu with the
# liner and between balls; or, with "law" in INPUT.json, an exported law (contact_law_yade.py of
# millimpact export --to yade): its materials' labels, millimpact_ip2() and its per-contact runner
# every law["every"] steps. Gravity -g along y.
#
# Every `check_every` steps, each ball-liner interaction made real since the previous check, with
# a part of the liner (a plate between two lifters, a lifter face, a lifter top) the ball was not
# touching at the previous check, is written to impacts_raw.csv with the ball's velocity before
# the contact (at the previous check, plus gravity's pull since), the contact point and normal,
# the overlap and the Hertz coefficient kno when found. Every `power_every` steps the charge's
# torque on the liner about the axis is summed into the drive's work; snapshots of the balls go to
# charge.csv, energies to energy.csv (evenly spaced samples and one at the warm-up's end), traced
# balls to trace.csv. Lines starting with "PROGRESS "
# report progress.
import csv
import json
import math
import sys
import time

from yade import utils

cfg = json.load(open(sys.argv[1]))
wall0, cpu0 = time.time(), time.process_time()
L = cfg["thickness_m"]
g = cfg["gravity_m_s2"]
omega = cfg["omega_rad_s"]
ball = cfg["ball"]
liner = cfg["liner"]
r = ball["radius_m"]

law_cfg = cfg.get("law")
if law_cfg:
    # an exported law (millimpact export --to yade): its file defines MILLIMPACT_LAW and the runtime
    # (millimpact_ip2, millimpact_update, ...); its moduli are scaled as the scene's would be (the
    # restitution depends on the damping ratio alone), the materials carry its labels
    exec(open(law_cfg["file"]).read())
    _k = law_cfg["stiffness_scale"]
    MILLIMPACT_LAW["e_star_Pa"] = [[_k * x for x in row] for row in MILLIMPACT_LAW["e_star_Pa"]]
    liner_label, ball_label = MILLIMPACT_LAW["yade"]["liner_material"], MILLIMPACT_LAW["yade"]["ball_material"]
else:
    liner_label, ball_label = "liner", "ball"
O.materials.append(
    FrictMat(
        young=liner["young_Pa"],
        poisson=liner["poisson"],
        density=liner["density_kg_m3"],
        frictionAngle=math.atan(cfg["friction"]),
        label=liner_label,
    )
)
O.materials.append(
    FrictMat(
        young=ball["young_Pa"],
        poisson=ball["poisson"],
        density=ball["density_kg_m3"],
        frictionAngle=math.atan(cfg["friction"]),
        label=ball_label,
    )
)
O.materials.append(
    FrictMat(
        young=liner["young_Pa"],
        poisson=liner["poisson"],
        density=liner["density_kg_m3"],
        frictionAngle=0.0,
        label="end",
    )
)

# --- the liner: one clump of facets (one body to turn and to sum the torque on) ---------------
facets, facet_part = [], []
for x0, y0, x1, y1, part in cfg["segments"]:
    a, b, c, d = (x0, y0, 0.0), (x1, y1, 0.0), (x1, y1, L), (x0, y0, L)
    for tri in ((a, b, c), (a, c, d)):
        f = utils.facet(tri, material=liner_label, fixed=True)
        # a clump needs members with mass; the clump is not dynamic, so these values do not act
        f.state.mass, f.state.inertia = 1.0, (1.0, 1.0, 1.0)
        facets.append(f)
        facet_part.append(part)
clump_id, member_ids = O.bodies.appendClumped(facets)
O.bodies[clump_id].dynamic = False
part_of = dict(zip(member_ids, facet_part))
end_ids = [
    O.bodies.append(utils.wall(0.0, axis=2, sense=1, material="end")),
    O.bodies.append(utils.wall(L, axis=2, sense=-1, material="end")),
]

ball_ids = [O.bodies.append(utils.sphere(tuple(p), r, material=ball_label)) for p in cfg["ball_positions"]]
mass = O.bodies[ball_ids[0]].state.mass
inertia = O.bodies[ball_ids[0]].state.inertia[0]
is_ball = set(ball_ids)

if law_cfg:
    ip2 = millimpact_ip2()
    # the law's update right after the InteractionLoop (its notes), every law_cfg["every"] steps
    law_runner = [millimpact_law_runner()]
    law_runner[0].iterPeriod = int(law_cfg["every"])
else:
    ip2 = Ip2_FrictMat_FrictMat_MindlinPhys(en=MatchMaker(algo="val", val=cfg["en_yade"]))
    law_runner = []
O.engines = [
    ForceResetter(),
    InsertionSortCollider([Bo1_Sphere_Aabb(), Bo1_Facet_Aabb(), Bo1_Wall_Aabb()], label="collider"),
    InteractionLoop(
        [Ig2_Sphere_Sphere_ScGeom(), Ig2_Facet_Sphere_ScGeom(), Ig2_Wall_Sphere_ScGeom()],
        [ip2],
        [Law2_ScGeom_MindlinPhys_Mindlin(calcEnergy=True, label="law")],
    ),
    *law_runner,
    RotationEngine(
        rotateAroundZero=True,
        zeroPoint=(0, 0, 0),
        rotationAxis=(0, 0, 1),
        angularVelocity=omega,
        ids=[clump_id],
        label="turn",
    ),
    # no numerical damping (Yade's default is 0.2): the contact law's en is then the restitution
    NewtonIntegrator(damping=0.0, gravity=(0, -g, 0), label="newton"),
    PyRunner(iterPeriod=int(cfg["power_every"]), command="every_step()", label="stepper"),
]
O.dt = cfg["dt_s"]
O.trackEnergy = False

t_end = cfg["warmup_s"] + cfg["run_s"]
check_every = int(cfg["check_every"])
power_every = int(cfg["power_every"])
trace_every = int(cfg.get("trace_every", 0))
trace_ids = [ball_ids[i] for i in cfg.get("trace_balls", [])]
snap_times = [
    cfg["warmup_s"] + k * cfg["snapshot_every_s"] for k in range(int(cfg["run_s"] / cfg["snapshot_every_s"] + 1e-9) + 1)
]
# evenly from the start, and one at the warm-up's end: the measured window's drive work starts there
energy_times = sorted({t_end * k / cfg["energy_samples"] for k in range(cfg["energy_samples"])} | {cfg["warmup_s"]})

impacts_fh = open("impacts_raw.csv", "w", newline="")
impacts = csv.writer(impacts_fh)
impacts.writerow(
    ["time_s", "ball", "part", "vx", "vy", "vz", "cx", "cy", "cz", "nx", "ny", "nz", "overlap_m", "kno", "age_steps"]
)
charge_fh = open("charge.csv", "w", newline="")
charge = csv.writer(charge_fh)
charge.writerow(["snapshot", "time_s", "ball", "x_m", "y_m", "z_m", "vx_m_s", "vy_m_s"])
energy_fh = open("energy.csv", "w", newline="")
energy = csv.writer(energy_fh)
energy.writerow(
    [
        "time_s",
        "drive_work_J",
        "kinetic_J",
        "potential_J",
        "elastic_normal_J",
        "elastic_shear_J",
        "damping_normal_J",
        "damping_shear_J",
        "friction_J",
    ]
)
trace_fh = open("trace.csv", "w", newline="")
trace = csv.writer(trace_fh)
trace.writerow(["time_s", "ball", "x_m", "y_m", "z_m", "vx_m_s", "vy_m_s", "vz_m_s", "liner_contacts"])

vel_prev = [Vector3(0.0, 0.0, 0.0) for b in ball_ids]
state = {"last_check": 0, "drive_work": 0.0, "snap": 0, "esample": 0, "progress": -1, "n_impacts": 0, "touching": set()}


def check_impacts():
    """Ball-liner interactions made real since the previous check that start a contact of the ball
    with a part of the liner it was not touching at the previous check (the two facets of a segment,
    or a ball rolling from one chord of the plate to the next, make no new impact)."""
    last = state["last_check"]
    now = O.iter
    touching = set()
    new = []
    for i in O.interactions:
        if not i.isReal:
            continue
        id1, id2 = i.id1, i.id2
        part, b, sign = part_of.get(id1), id2, 1.0
        if part is None:
            part, b, sign = part_of.get(id2), id1, -1.0
        if part is None or b not in is_ball:
            continue
        touching.add((b, part))
        if i.iterMadeReal > last:
            new.append((i, b, part, sign))
    before = state["touching"]
    logged = {}
    for i, b, part, sign in new:
        if (b, part) in before:
            continue
        before.add((b, part))  # one impact even if both facets of a segment were hit
        c = i.geom.contactPoint
        # a ball striking an edge or a corner (face and top, or lifter and plate) touches two parts at
        # one point: one impact
        if any((c - q).norm() < 0.25 * r for q in logged.get(b, ())):
            continue
        logged.setdefault(b, []).append(c)
        # the ball's velocity before the contact: at the previous check, plus gravity's pull until the
        # step before the contact became real (a flight's velocity exactly; a ball in the bed may also
        # have been pushed by other balls in those few steps)
        v = vel_prev[b - ball_ids[0]] + Vector3(0.0, -g * O.dt * max(i.iterMadeReal - 1 - last, 0), 0.0)
        # the normal points from id1 to id2: turned to point from the liner into the ball
        n = i.geom.normal * sign
        impacts.writerow(
            [
                O.time,
                b - ball_ids[0],
                part,
                v[0],
                v[1],
                v[2],
                c[0],
                c[1],
                c[2],
                n[0],
                n[1],
                n[2],
                i.geom.penetrationDepth,
                i.phys.kno,
                now - i.iterMadeReal,
            ]
        )
        state["n_impacts"] += 1
    state["touching"] = touching
    state["last_check"] = now
    vel_prev[:] = [Vector3(O.bodies[b].state.vel) for b in ball_ids]  # copies, not views


def ball_energies():
    ke = pe = 0.0
    for b in ball_ids:
        st = O.bodies[b].state
        v, w = st.vel, st.angVel
        ke += 0.5 * mass * v.squaredNorm() + 0.5 * inertia * w.squaredNorm()
        pe += mass * g * st.pos[1]
    return ke, pe


def shear_elastic_energy():
    """Energy stored in the contacts' tangential springs now, sum |F_s|^2 / (2 k_s) (J)."""
    w = 0.0
    for i in O.interactions:
        ks = i.phys.ks
        if ks > 0:
            w += i.phys.shearElastic.squaredNorm() / (2.0 * ks)
    return w


def write_energy():
    ke, pe = ball_energies()
    # the law's functor knows its scene only once it has run (calling it before the first step crashes)
    elastic = law.normElastEnergy() if O.iter > 0 else 0.0
    energy.writerow(
        [
            O.time,
            state["drive_work"],
            ke,
            pe,
            elastic,
            shear_elastic_energy(),
            law.normDampDissip,
            law.shearDampDissip,
            law.frictionDissipation,
        ]
    )


def write_snapshot():
    k = state["snap"]
    for j, b in enumerate(ball_ids):
        st = O.bodies[b].state
        charge.writerow([k, O.time, j, st.pos[0], st.pos[1], st.pos[2], st.vel[0], st.vel[1]])
    state["snap"] += 1


def write_trace():
    for b in trace_ids:
        st = O.bodies[b].state
        n = sum(1 for i in O.bodies[b].intrs() if i.isReal and (i.id1 in part_of or i.id2 in part_of))
        trace.writerow([O.time, b - ball_ids[0], st.pos[0], st.pos[1], st.pos[2], st.vel[0], st.vel[1], st.vel[2], n])


def every_step():
    it = O.iter
    # the charge's torque on the liner about the axis (this step's forces); the drive supplies -T omega
    torque = utils.sumTorques([clump_id], (0, 0, 1), (0, 0, 0))
    state["drive_work"] += -torque * omega * O.dt * power_every
    if it % check_every == 0:
        check_impacts()
    if trace_every and it % trace_every == 0:
        write_trace()
    t = O.time
    if state["snap"] < len(snap_times) and t >= snap_times[state["snap"]] - 0.5 * O.dt:
        write_snapshot()
    if state["esample"] < len(energy_times) and t >= energy_times[state["esample"]] - 0.5 * O.dt:
        write_energy()
        state["esample"] += 1
    pct = int(100 * t / t_end)
    if pct != state["progress"]:
        state["progress"] = pct
        rev = omega * max(t - cfg["warmup_s"], 0.0) / (2 * math.pi)
        print(
            f"PROGRESS {t / t_end:.4f} t={t:.3f} s revolutions={rev:.2f} impacts={state['n_impacts']} "
            f"wall={time.time() - wall0:.0f} s",
            flush=True,
        )


if check_every % power_every:
    raise SystemExit("check_every must be a multiple of power_every")
write_energy()
state["esample"] = 1
n_steps = int(math.ceil(t_end / O.dt / power_every)) * power_every
O.run(n_steps, True)
check_impacts()
write_energy()
for fh in (impacts_fh, charge_fh, energy_fh, trace_fh):
    fh.close()
json.dump(
    {
        "steps": O.iter,
        "time_s": O.time,
        "dt_s": O.dt,
        "wall_s": time.time() - wall0,
        "cpu_s": time.process_time() - cpu0,
        "balls": len(ball_ids),
        "facets": len(member_ids),
        "impacts_logged": state["n_impacts"],
        "ball_mass_kg": mass,
        "power_every": power_every,
        "check_every": check_every,
        "law_every": int(law_cfg["every"]) if law_cfg else 0,
    },
    open("run.json", "w"),
    indent=1,
)
print("PROGRESS 1.0000 done", flush=True)
