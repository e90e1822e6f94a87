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
# balls to trace.csv. With rolling resistance, every rolling_every checks the contacts' bending
# moments' power -M . (w2 - w1) is summed into rolling_J (Yade's law does not count it). Lines starting with "PROGRESS "
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
rock = cfg.get("rock")
if rock:
    O.materials.append(
        FrictMat(
            young=rock["young_Pa"],
            poisson=rock["poisson"],
            density=rock["density_kg_m3"],
            frictionAngle=math.atan(rock["friction"]),
            label="rock",
        )
    )
mat_id = {m.label: k for k, m in enumerate(O.materials)}

# --- the liner: one clump of facets (one body to turn and to sum the torque on) ---------------
facets, facet_part, facet_seg = [], [], []
for k_seg, (x0, y0, x1, y1, part) in enumerate(cfg["segments"]):
    a, b, c, d = (x0, y0, 0.0), (x1, y1, 0.0), (x1, y1, L), (x0, y0, L)
    for tri in ((a, b, c), (a, c, d)):
        f = utils.facet(tri, material=liner_label, fixed=True)
        # a clump needs members with mass; the clump is not dynamic, so these values do not act
        f.state.mass, f.state.inertia = 1.0, (1.0, 1.0, 1.0)
        facets.append(f)
        facet_part.append(part)
        facet_seg.append(k_seg)
clump_id, member_ids = O.bodies.appendClumped(facets)
O.bodies[clump_id].dynamic = False
part_of = dict(zip(member_ids, facet_part))
seg_of = dict(zip(member_ids, facet_seg))
end_ids = [
    O.bodies.append(utils.wall(0.0, axis=2, sense=1, material="end")),
    O.bodies.append(utils.wall(L, axis=2, sense=-1, material="end")),
]

# the particles: balls, then rock (ids consecutive: particle index = id - first id)
ball_ids = [O.bodies.append(utils.sphere(tuple(p), r, material=ball_label)) for p in cfg["ball_positions"]]
rock_ids = []
if rock:
    rock_ids = [
        O.bodies.append(utils.sphere(tuple(p), rr, material="rock")) for p, rr in zip(rock["positions"], rock["radii"])
    ]
# starting velocities (the tests' exact cases; a mill run starts at rest)
for b, v in zip(ball_ids, cfg.get("ball_velocities", [])):
    O.bodies[b].state.vel = Vector3(*v)
for b, v, w in zip(rock_ids, (rock or {}).get("velocities", []), (rock or {}).get("angular_velocities", [])):
    O.bodies[b].state.vel, O.bodies[b].state.angVel = Vector3(*v), Vector3(*w)
part_ids = ball_ids + rock_ids
first_id = part_ids[0]
masses = [O.bodies[b].state.mass for b in part_ids]
inertias = [O.bodies[b].state.inertia[0] for b in part_ids]
is_particle = set(part_ids)  # a ball or a rock
is_rock = set(rock_ids)
rolling = bool(rock) and rock["eta"] > 0.0

if law_cfg:
    ip2 = millimpact_ip2()
    # the law's update right after the InteractionLoop (its notes), every law_cfg["every"] steps
    law_runner = [millimpact_law_runner()]
    law_runner[0].iterPeriod = int(law_cfg["every"])
else:
    ip2 = Ip2_FrictMat_FrictMat_MindlinPhys(en=MatchMaker(algo="val", val=cfg["en_yade"]))
    law_runner = []
if rock:
    # every contact with rock: its restitution and friction; rolling resistance M <= eta R_mean F_n
    # at stiffness krot (contacts without rock get kr = 0 at the first check, check_impacts)
    others = [mat_id[x] for x in (liner_label, ball_label, "rock")]
    ip2.en = MatchMaker(matches=[(mat_id["rock"], j, rock["en_yade"]) for j in others], algo="val", val=cfg["en_yade"])
    ip2.frictAngle = MatchMaker(matches=[(mat_id["rock"], j, math.atan(rock["friction"])) for j in others], algo="min")
    if rolling:
        ip2.krot, ip2.eta, ip2.ktwist = rock["krot"], rock["eta"], 0.0
O.engines = [
    ForceResetter(),
    InsertionSortCollider([Bo1_Sphere_Aabb(), Bo1_Facet_Aabb(), Bo1_Wall_Aabb()], label="collider"),
    InteractionLoop(
        [Ig2_Sphere_Sphere_ScGeom(), Ig2_Facet_Sphere_ScGeom(), Ig2_Wall_Sphere_ScGeom()],
        [ip2],
        [Law2_ScGeom_MindlinPhys_Mindlin(calcEnergy=True, includeMoment=rolling, label="law")],
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
trace_ids = [part_ids[i] for i in cfg.get("trace_balls", [])]
snap_times = [
    cfg["warmup_s"] + k * cfg["snapshot_every_s"] for k in range(int(cfg["run_s"] / cfg["snapshot_every_s"] + 1e-9) + 1)
]
# evenly from the start, and one at the warm-up's end: the measured window's drive work starts there
energy_times = sorted({t_end * k / cfg["energy_samples"] for k in range(cfg["energy_samples"])} | {cfg["warmup_s"]})

impacts_fh = open("impacts_raw.csv", "w", newline="")
impacts = csv.writer(impacts_fh)
impacts.writerow(
    [
        "time_s",
        "particle",
        "part",
        "vx",
        "vy",
        "vz",
        "cx",
        "cy",
        "cz",
        "nx",
        "ny",
        "nz",
        "overlap_m",
        "kno",
        "age_steps",
    ]
)
charge_fh = open("charge.csv", "w", newline="")
charge = csv.writer(charge_fh)
charge.writerow(["snapshot", "time_s", "particle", "x_m", "y_m", "z_m", "vx_m_s", "vy_m_s"])
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
        "liner_friction_J",
        "rolling_J",
    ]
)
trace_fh = open("trace.csv", "w", newline="")
trace = csv.writer(trace_fh)
trace.writerow(["time_s", "particle", "x_m", "y_m", "z_m", "vx_m_s", "vy_m_s", "vz_m_s", "liner_contacts"])

# the velocities at the previous check of the particles that can reach the liner before the next
# refresh (every REFRESH checks): centres within the tips' circle less the farthest a particle
# travels in that time at v_max (more would cost a Python copy of every particle's velocity a check)
vel_prev = {}
candidates = []
REFRESH = 16
envelope = cfg["arc"]["radius_m"] - cfg["arc"]["lifter_height_m"]
margin = cfg["v_max_m_s"] * REFRESH * int(cfg["check_every"]) * cfg["dt_s"]


def refresh_candidates():
    near = []
    for b in part_ids:
        body = O.bodies[b]
        p = body.state.pos
        if math.hypot(p[0], p[1]) + body.shape.radius >= envelope - margin:
            near.append(b)
    candidates[:] = near


state = {
    "last_check": -1,  # contacts made real at step 0 are new at the first check
    "drive_work": 0.0,
    "snap": 0,
    "esample": 0,
    "progress": -1,
    "n_impacts": 0,
    "touching": set(),
    "liner_friction": 0.0,
    "rolling_work": 0.0,  # the rolling moments' work on the contacts, sampled (check_impacts)
    "checks": 0,
    "last_pair": -1,  # the iteration of the previous pair_pass
}
rolling_every = int(cfg.get("rolling_every", 1))
pair_every = int(cfg.get("pair_every", 1))
liner_spin = Vector3(0.0, 0.0, omega)
# abrasion: per contact with the liner, its plastic slip vector (usTotal - usElastic) at the previous
# check; per (particle kind, part, arc bin) after the warm-up: friction work, normal force x slip, slip
slip_prev = {}
abrasion = {}
arc_cfg = cfg["arc"]
n_balls = len(ball_ids)


def surface_bin(c, seg):
    """The bin of contact point c's surface position on segment seg: the distance along the profile
    from the lifter unit's start (segment_s0), the point turned back by omega t to the liner's frame."""
    cos_t, sin_t = state["turn_back"]
    xl = cos_t * c[0] - sin_t * c[1]
    yl = sin_t * c[0] + cos_t * c[1]
    x0, y0, x1, y1, _ = cfg["segments"][seg]
    dx, dy = x1 - x0, y1 - y0
    length = math.hypot(dx, dy)
    t = min(length, max(0.0, ((xl - x0) * dx + (yl - y0) * dy) / length))
    return int(math.floor((arc_cfg["segment_s0_m"][seg] + t) / arc_cfg["bin_m"]))


def slide(i, b, part, facet, seen, logging):
    """This contact's sliding since the previous check: slip ds = |change of the plastic slip
    vector|, friction work tan(phi) F_n ds (the Coulomb force while it slides), F_n ds; binned by
    place once logging (after the warm-up)."""
    key = (facet, b)
    seen.add(key)
    ph = i.phys
    p = ph.usTotal - ph.usElastic
    prev = slip_prev.get(key)
    ds = (p - prev).norm() if prev is not None else p.norm()
    slip_prev[key] = p  # a new vector (the difference), not a view of the contact's
    if ds <= 0.0:
        return
    fn = ph.normalForce.norm()
    w = ph.tangensOfFrictionAngle * fn * ds
    state["liner_friction"] += w
    if logging:
        k = (0 if b - first_id < n_balls else 1, part % 4, surface_bin(i.geom.contactPoint, seg_of[facet]))
        acc = abrasion.setdefault(k, [0.0, 0.0, 0.0])
        acc[0] += w
        acc[1] += fn * ds
        acc[2] += ds


def count_contact(i, id1, id2):
    """A new contact between two particles after the warm-up, counted by the kinds' pair, and
    again when they approached at >= 1 m/s along its normal. The approach speed is the normal
    relative speed v_n now with the Hertz spring's energy (2/5) k_no delta^(5/2) given back,
    v_0^2 = v_n^2 + (4/5) k_no delta^(5/2) / m*, m* = m1 m2 / (m1 + m2) (Johnson 1985, sec. 11.1:
    the undamped Hertz impact; the damping's loss in the steps since contact is not given back)."""
    if O.time < cfg["warmup_s"]:
        return
    j1, j2 = id1 - first_id, id2 - first_id
    k1, k2 = sorted((0 if j1 < n_balls else 1, 0 if j2 < n_balls else 1))
    key = ("ball", "rock")[k1] + "-" + ("ball", "rock")[k2]
    c = contacts.setdefault(key, [0, 0])
    c[0] += 1
    vn = (O.bodies[id2].state.vel - O.bodies[id1].state.vel).dot(i.geom.normal)
    m_eff = masses[j1] * masses[j2] / (masses[j1] + masses[j2])
    delta = max(i.geom.penetrationDepth, 0.0)
    if vn * vn + 0.8 * i.phys.kno * delta**2.5 / m_eff >= 1.0:
        c[1] += 1


contacts = {}


def pair_pass(sample):
    """Every pair_every checks, over every contact: those between two particles (or a particle and
    an end wall) made real since the previous pass (every contact lasts more than a pass's
    interval: pair_every * check_every steps < STEPS_PER_CONTACT), counted (count_contact) and
    without rolling resistance when neither is rock; with sample, the rolling moments' power
    -M . (w2 - w1) on every contact (the torque on id2 is +M, on id1 -M), returned."""
    last = state["last_pair"]
    power = 0.0
    for i in O.interactions:
        if not i.isReal:
            continue
        id1, id2 = i.id1, i.id2
        if i.iterMadeReal > last and id1 not in part_of and id2 not in part_of:
            if rolling and id1 not in is_rock and id2 not in is_rock:
                i.phys.kr = 0.0
                i.phys.momentBend = Vector3(0.0, 0.0, 0.0)
            if id1 in is_particle and id2 in is_particle:
                count_contact(i, id1, id2)
        if sample and i.phys.kr > 0:
            w1 = liner_spin if id1 in part_of else O.bodies[id1].state.angVel
            w2 = liner_spin if id2 in part_of else O.bodies[id2].state.angVel
            power -= i.phys.momentBend.dot(w2 - w1)
    state["last_pair"] = O.iter
    return power


def check_impacts(sample_rolling=True):
    """Particle-liner interactions made real since the previous check that start a contact of the
    particle with a part of the liner it was not touching at the previous check (the two facets of a
    segment, or a particle rolling from one chord of the plate to the next, make no new impact); the
    sliding of every particle-liner contact (slide); rolling resistance on new liner contacts: none
    without rock, M <= mu_r r F_n with rock; every pair_every checks the contacts between particles
    (pair_pass), and every rolling_every checks the rolling moments' work (rolling_work)."""
    last = state["last_check"]
    now = O.iter
    state["turn_back"] = (math.cos(-omega * O.time), math.sin(-omega * O.time))  # the liner's frame, once a check
    touching = set()
    seen = set()
    new = []
    logging = O.time >= cfg["warmup_s"]
    # the liner's contacts from its facets' own lists: a pass over a few hundred, not the thousands
    # between particles
    for facet in member_ids:
        for i in O.interactions.withBody(facet):
            id1 = i.id1
            b, sign = (i.id2, 1.0) if id1 == facet else (id1, -1.0)
            if b not in is_particle:
                continue
            part = part_of[facet]
            fresh = i.iterMadeReal > last
            if fresh and rolling:
                if b not in is_rock:
                    i.phys.kr = 0.0
                    i.phys.momentBend = Vector3(0.0, 0.0, 0.0)
                else:
                    # Yade takes a facet as a sphere of twice the particle's radius (R_mean = 1.5 r):
                    # the rock's own radius instead, M <= mu_r r F_n on the liner
                    i.phys.maxBendPl = rock["eta"] * O.bodies[b].shape.radius
            touching.add((b, part))
            slide(i, b, part, facet, seen, logging)
            if fresh:
                new.append((i, b, part, sign))
    if state["checks"] % pair_every == 0:
        sample = sample_rolling and rolling and state["checks"] % rolling_every == 0
        power = pair_pass(sample)
        if sample:
            # the rectangle rule over the sampling period: Yade's law does not count this dissipation
            state["rolling_work"] += power * check_every * rolling_every * O.dt
    for key in [k for k in slip_prev if k not in seen]:
        del slip_prev[key]
    before = state["touching"]
    logged = {}
    for i, b, part, sign in new:
        if (b, part) in before:
            continue
        before.add((b, part))  # one impact even if both facets of a segment were hit
        c = i.geom.contactPoint
        # a particle striking an edge or a corner (face and top, or lifter and plate) touches two
        # parts at one point: one impact
        if any((c - q).norm() < 0.25 * O.bodies[b].shape.radius for q in logged.get(b, ())):
            continue
        logged.setdefault(b, []).append(c)
        # the particle's velocity before the contact: at the previous check, plus gravity's pull until
        # the step before the contact became real (a flight's velocity exactly; a particle in the bed
        # may also have been pushed by others in those few steps)
        v0 = vel_prev.get(b)
        v0 = Vector3(O.bodies[b].state.vel) if v0 is None else v0  # none faster than v_max: never
        v = v0 + Vector3(0.0, -g * O.dt * max(i.iterMadeReal - 1 - last, 0), 0.0)
        # the normal points from id1 to id2: turned to point from the liner into the particle
        n = i.geom.normal * sign
        impacts.writerow(
            [
                O.time,
                b - first_id,
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
    state["checks"] += 1
    if state["checks"] % REFRESH == 1:
        refresh_candidates()
    vel_prev.clear()
    for b in candidates:
        vel_prev[b] = Vector3(O.bodies[b].state.vel)  # copies, not views


def ball_energies():
    ke = pe = 0.0
    for j, b in enumerate(part_ids):
        st = O.bodies[b].state
        v, w = st.vel, st.angVel
        ke += 0.5 * masses[j] * v.squaredNorm() + 0.5 * inertias[j] * w.squaredNorm()
        pe += masses[j] * g * st.pos[1]
    return ke, pe


def shear_elastic_energy():
    """Energy stored in the contacts' tangential springs now, sum |F_s|^2 / (2 k_s) (J)."""
    w = 0.0
    for i in O.interactions:
        ks = i.phys.ks
        if ks > 0:
            w += i.phys.shearElastic.squaredNorm() / (2.0 * ks)
        if rolling and i.phys.kr > 0:
            w += i.phys.momentBend.squaredNorm() / (2.0 * i.phys.kr)
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
            state["liner_friction"],
            state["rolling_work"],
        ]
    )


def write_snapshot():
    k = state["snap"]
    for j, b in enumerate(part_ids):
        st = O.bodies[b].state
        charge.writerow([k, O.time, j, st.pos[0], st.pos[1], st.pos[2], st.vel[0], st.vel[1]])
    state["snap"] += 1


def write_trace():
    for b in trace_ids:
        st = O.bodies[b].state
        n = sum(1 for i in O.bodies[b].intrs() if i.isReal and (i.id1 in part_of or i.id2 in part_of))
        trace.writerow([O.time, b - first_id, st.pos[0], st.pos[1], st.pos[2], st.vel[0], st.vel[1], st.vel[2], n])


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
if rolling_every % pair_every:
    raise SystemExit("rolling_every must be a multiple of pair_every")
write_energy()
state["esample"] = 1
n_steps = int(math.ceil(t_end / O.dt / power_every)) * power_every
O.run(n_steps, True)
check_impacts(sample_rolling=False)
write_energy()
for fh in (impacts_fh, charge_fh, energy_fh, trace_fh):
    fh.close()
with open("abrasion_raw.csv", "w", newline="") as fh:
    rows = csv.writer(fh)
    rows.writerow(["kind", "unit_part", "surface_bin", "friction_work_J", "normal_force_slip_N_m", "slip_m"])
    for (kind, part, k), (w, fs, ds) in sorted(abrasion.items()):
        rows.writerow([kind, part, k, w, fs, ds])
json.dump(
    {
        "steps": O.iter,
        "time_s": O.time,
        "dt_s": O.dt,
        "wall_s": time.time() - wall0,
        "cpu_s": time.process_time() - cpu0,
        "balls": len(ball_ids),
        "rocks": len(rock_ids),
        "velocity_candidates_last": len(candidates),
        "particle_contacts_after_warmup": {k: {"all": v[0], "at_1_m_s_or_more": v[1]} for k, v in contacts.items()},
        "facets": len(member_ids),
        "impacts_logged": state["n_impacts"],
        "ball_mass_kg": masses[0] if ball_ids else None,
        "power_every": power_every,
        "check_every": check_every,
        "law_every": int(law_cfg["every"]) if law_cfg else 0,
    },
    open("run.json", "w"),
    indent=1,
)
print("PROGRESS 1.0000 done", flush=True)
