#!/usr/bin/env python3
"""T_ref: the suite's tasks solved by direct transcription with CasADi + IPOPT.

An optimal-control reference that shares no code with armature: the robot's forward
kinematics written out from its published description, the task's continuous-time problem
transcribed on a fine grid, solved from several starts, the best start that passes a dense
check kept. Its output, `t_ref.json`, is committed; the suite (`bench/suite`) re-verifies every
stored trajectory with its own verification before it uses its final time as T_ref.

The transcription. Time is split into phases at the task's event nodes (the waypoints' nodes
and the orientation ranges' ends), each phase of free duration with K uniform intervals. The
states are the joint angles q and velocities v at the grid points, the control the joint
accelerations a = tau / I at the grid points, held first-order between them, so the
dynamics q'' = tau / I is integrated exactly (q cubic, v quadratic in each interval). Joint and
velocity limits hold on the whole arc (the Bernstein control points of each interval's cubic
and quadratic inside the limits: sufficient, and tight where the arc touches a limit with zero
slope); the table, the orientation ranges and the ball against the capsules (with the task's
margin) at every grid point and interval midpoint; waypoints at their phase boundaries; the arm
starts at rest at the task's start configuration and ends at rest. The objective is the final
time. A solution that leaves an orientation range between the samples by more than the
tolerance is solved again with the range tightened by 1.5x the excess (stored as `backoff`). Starts: armature's solution and the IK guess at armature's guess durations; the best
that passes the dense check (1 ms, 1e-4) is kept (with --first: the first, guess first).
T_ref is therefore the best local optimum found, not a certificate of global optimality.
Rigid-body tasks (M(q) q'' + C(q, q') q' + g(q) = tau): the accelerations stay the control
(first-order hold, integrated exactly), free, and the torques are what the recursive
Newton-Euler algorithm (written out here on the robot's DH frames, checked against Pinocchio
when it is installed) asks for the motion: bounded at every grid point and at the quarter
points of each interval, with a small margin that the dense check backs off further where the
torque between the samples needs it (stored as `torque_margin`); a tiny weight on the
accelerations' changes keeps a joint of small inertia from chattering between grid points.
Not modelled: self-collision (the suite's verification checks it on armature's solutions;
leaving it out can only lower T_ref, so the ratios T / T_ref stay conservative).

Usage:
    cargo run --release -p armature-suite -- --export /tmp/tasks.json
    python3 bench/reference/t_ref.py /tmp/tasks.json bench/reference/t_ref.json [--jobs 2]
        [--filter NAME] [--intervals 30] [--first] [--start armature|guess] [--keep-best]

Needs `pip install casadi numpy` (IPOPT is bundled with casadi); `pip install pin` for the
rigid-body dynamics' check against Pinocchio.
"""

import argparse
import json
import math
import multiprocessing
import os
import sys
import time

import casadi as ca
import numpy as np

# Intervals per phase.
INTERVALS = 30
# The dense check's step (s) and tolerance (the suite's).
DENSE_DT = 1e-3
TOLERANCE = 1e-4
# Re-solves with the orientation tolerances backed off, per start.
BACKOFF_ROUNDS = 3
# IPOPT's time budget per start, seconds.
MAX_SECONDS = 300
# `--local`: IPOPT's barrier starts this small and the start is pushed this little inside its
# bounds, so a start at a local optimum stays in its basin (the default barrier, 0.1, first
# pushes a start at its bounds far inside them, from where it may reach another optimum).
LOCAL_OPTIONS = {"ipopt.mu_init": 1e-7, "ipopt.bound_push": 1e-9, "ipopt.bound_frac": 1e-9,
                 "ipopt.mu_strategy": "monotone"}
# Rigid-body tasks: the torque rows (at the grid points and TORQUE_SAMPLES) keep this fraction
# of each limit in reserve, so that the torque between the samples (a nonlinear function of
# the motion there) stays inside the limit on the dense check.
TORQUE_MARGIN = 1e-3
# Where in each interval the torque rows sit besides its start (fractions of it): the torque
# is a nonlinear function of the motion, and with the midpoint alone it left the limits by up
# to 0.6 % between the samples.
TORQUE_SAMPLES = (0.25, 0.5, 0.75)
# Rigid-body tasks: a joint of small inertia (the UR5e's last wrist, 1.3e-4 kg m^2) can switch
# its acceleration between +-2000 rad/s^2 from one grid point to the next at no cost in time,
# and the torque of the joints it couples to then leaves the limits between the samples. This
# weight on the squared changes of the accelerations (per 1000 rad/s^2) picks the smooth
# motion among those of the same final time; it moves the final time by about 1e-6 s.
SMOOTHING = 1e-6

ARM7 = (0.340, 0.300, 0.250, 0.150)
UR5E_DH = [
    (0.1625, 0.0, math.pi / 2),
    (0.0, -0.425, 0.0),
    (0.0, -0.3922, 0.0),
    (0.1333, 0.0, math.pi / 2),
    (0.0997, 0.0, -math.pi / 2),
    (0.0996, 0.0, 0.0),
]
IIWA7_DH = [
    (0.34, 0.0, -math.pi / 2),
    (0.0, 0.0, math.pi / 2),
    (0.4, 0.0, math.pi / 2),
    (0.0, 0.0, -math.pi / 2),
    (0.4, 0.0, -math.pi / 2),
    (0.0, 0.0, math.pi / 2),
    (0.126, 0.0, 0.0),
]
ARM7_CAPSULE_RADII = (0.06, 0.05, 0.04, 0.035)


def rot(axis, a):
    c, s = ca.cos(a), ca.sin(a)
    if axis == "x":
        return ca.vertcat(ca.horzcat(1, 0, 0), ca.horzcat(0, c, -s), ca.horzcat(0, s, c))
    if axis == "y":
        return ca.vertcat(ca.horzcat(c, 0, s), ca.horzcat(0, 1, 0), ca.horzcat(-s, 0, c))
    return ca.vertcat(ca.horzcat(c, -s, 0), ca.horzcat(s, c, 0), ca.horzcat(0, 0, 1))


def then(frame, r, t):
    """Composes (R, p) with a rotation then a translation in the moving frame."""
    rr = ca.mtimes(frame[0], r)
    return (rr, frame[1] + ca.mtimes(rr, ca.DM(t)))


def frames(robot, q):
    """Keypoint frames (arm7: base, shoulder, elbow, wrist, ee) or DH frames 0..n."""
    f = (ca.DM.eye(3), ca.DM.zeros(3))
    out = [f]
    if robot == "arm7":
        d1, a2, a3, a4 = ARM7
        f = then(f, rot("z", q[0]), [0, 0, d1])
        out.append(f)
        f = then(f, rot("y", q[1]), [a2, 0, 0])
        out.append(f)
        f = then(f, rot("z", q[2]), [0, 0, 0])
        f = then(f, rot("y", q[3]), [a3, 0, 0])
        out.append(f)
        f = then(f, rot("z", q[4]), [0, 0, 0])
        f = then(f, rot("y", q[5]), [a4, 0, 0])
        f = then(f, rot("z", q[6]), [0, 0, 0])
        out.append(f)
        return out
    table = UR5E_DH if robot == "ur5e" else IIWA7_DH
    for i, (d, a, alpha) in enumerate(table):
        f = then(f, rot("z", q[i]), [a, 0, d])
        f = (ca.mtimes(f[0], rot("x", alpha)), f[1])
        out.append(f)
    return out


def quat_matrix(w, x, y, z):
    n = math.sqrt(w * w + x * x + y * y + z * z)
    w, x, y, z = w / n, x / n, y / n, z / n
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def segment_distance_sq(c, a, b):
    ab = b - a
    t = ca.fmin(ca.fmax(ca.dot(c - a, ab) / (ca.dot(ab, ab) + 1e-12), 0), 1)
    d = a + t * ab - c
    return ca.dot(d, d)


def rnea_function(spec):
    """tau(q, v, a) of the rigid-body model, by the recursive Newton-Euler algorithm written
    out here on the robot's own DH frames (world-frame form): link i moves with DH frame i, its
    joint turns about z of frame i-1. The links' mass properties come with the task (mass,
    centre of mass and inertia about it, in the base frame at q = 0) and are moved into their
    frames once."""
    n = len(spec["q_lo"])
    links = spec["links"]
    gravity = np.array(spec["gravity"], dtype=float)
    zero = frames(spec["robot"], ca.DM.zeros(n))
    local = []
    for i, link in enumerate(links):
        r0 = np.array(zero[i + 1][0])
        p0 = np.array(zero[i + 1][1]).ravel()
        xx, xy, xz, yy, yz, zz = link["inertia"]
        inertia_w = np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])
        com = r0.T @ (np.array(link["com"]) - p0)
        local.append((link["mass"], com, r0.T @ inertia_w @ r0))
    q, v, a = ca.SX.sym("q", n), ca.SX.sym("v", n), ca.SX.sym("a", n)
    fs = frames(spec["robot"], q)
    w, dw, acc = ca.SX.zeros(3), ca.SX.zeros(3), ca.SX(-gravity)
    kin = []
    for i in range(n):
        z = fs[i][0][:, 2]
        r, o = fs[i + 1]
        dw = dw + z * a[i] + ca.cross(w, z * v[i])
        w = w + z * v[i]
        # The joint's axis passes through o_{i-1}: the body turns about it.
        d = o - fs[i][1]
        acc = acc + ca.cross(dw, d) + ca.cross(w, ca.cross(w, d))
        m, com, inertia = local[i]
        c = ca.mtimes(r, ca.DM(com))
        acc_c = acc + ca.cross(dw, c) + ca.cross(w, ca.cross(w, c))
        iw = ca.mtimes([r, ca.DM(inertia), r.T])
        kin.append((z, fs[i][1], o, o + c, m * acc_c, ca.mtimes(iw, dw) + ca.cross(w, ca.mtimes(iw, w))))
    force, moment = ca.SX.zeros(3), ca.SX.zeros(3)
    tau = [None] * n
    for i in reversed(range(n)):
        z, o_prev, o, pc, f_c, n_c = kin[i]
        # Moment about o_{i-1}: the link's own, its force at the centre of mass, and what
        # the next link passes on at o_i.
        moment = n_c + ca.cross(pc - o_prev, f_c) + moment + ca.cross(o - o_prev, force)
        force = f_c + force
        tau[i] = ca.dot(z, moment)
    return ca.Function("rnea", [q, v, a], [ca.vertcat(*tau)])


def check_rnea(spec, rnea, samples=20, seed=0):
    """The largest difference between `rnea` and Pinocchio's RNEA on the same robot (built
    here from the DH table and the links' mass properties), at random states; None without
    Pinocchio (`pip install pin`)."""
    try:
        import pinocchio as pin
    except ImportError:
        return None
    n = len(spec["q_lo"])
    table = UR5E_DH if spec["robot"] == "ur5e" else IIWA7_DH
    model = pin.Model()
    model.gravity.linear = np.array(spec["gravity"], dtype=float)
    zero = frames(spec["robot"], ca.DM.zeros(n))
    parent, placement = 0, pin.SE3.Identity()
    for i, (d, a, alpha) in enumerate(table):
        joint = model.addJoint(parent, pin.JointModelRZ(), placement, f"j{i}")
        # Frame i is the joint's frame moved by D_i = Tz(d) Tx(a) Rx(alpha).
        rx = np.array(rot("x", alpha))
        dh = pin.SE3(rx, np.array([a, 0.0, d]))
        r0, p0 = np.array(zero[i + 1][0]), np.array(zero[i + 1][1]).ravel()
        link = spec["links"][i]
        xx, xy, xz, yy, yz, zz = link["inertia"]
        inertia_w = np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])
        com_local, inertia_local = r0.T @ (np.array(link["com"]) - p0), r0.T @ inertia_w @ r0
        com_joint = dh.rotation @ com_local + dh.translation
        inertia_joint = dh.rotation @ inertia_local @ dh.rotation.T
        model.appendBodyToJoint(joint, pin.Inertia(link["mass"], com_joint, inertia_joint),
                                pin.SE3.Identity())
        parent, placement = joint, dh
    data = model.createData()
    rng = np.random.default_rng(seed)
    worst = 0.0
    for _ in range(samples):
        q, v, a = rng.uniform(-3, 3, n), rng.uniform(-3, 3, n), rng.uniform(-20, 20, n)
        ours = np.array(rnea(q, v, a)).ravel()
        worst = max(worst, float(np.max(np.abs(ours - pin.rnea(model, data, q, v, a)))))
    return worst


class Task:
    """The task's constraint functions of q, built once."""

    def __init__(self, spec, backoff=0.0, torque_margin=TORQUE_MARGIN):
        self.spec = spec
        self.n = len(spec["q_lo"])
        q = ca.SX.sym("q", self.n)
        fs = frames(spec["robot"], q)
        r, p = fs[-1]
        self.ee = ca.Function("ee", [q], [p])
        # Orientation: (3 - tr(Rd^T R)) / (2 (1 - cos tol)) <= 1, i.e. angle <= tol.
        rows = []
        for o in spec["orientation"]:
            rd = quat_matrix(*o["quaternion_wxyz"])
            tol = math.radians(o["tolerance_deg"])
            bound = 2 * (1 - math.cos(max(tol - backoff, 0.5 * tol)))
            rows.append((3 - ca.trace(ca.mtimes(ca.DM(rd).T, r))) / bound)
        self.orient = ca.Function("orient", [q], [ca.vertcat(*rows) if rows else ca.DM.zeros(0)])
        self.angle = ca.Function("angle", [q], [r])
        self.rnea = rnea_function(spec) if spec["rigid_body"] else None
        self.torque_margin = torque_margin
        # Ball clearance, squared, scaled: d^2 / (rc + rb + margin)^2 >= 1; and without the
        # margin, for the dense check: d - rc - rb.
        clear, plain = [], []
        if spec["balls"] and spec["robot"] == "arm7":
            for i, rc in enumerate(ARM7_CAPSULE_RADII):
                a, b = fs[i][1], fs[i + 1][1]
                for ball in spec["balls"]:
                    d2 = segment_distance_sq(ca.DM(ball["centre"]), a, b)
                    clear.append(d2 / (rc + ball["radius"] + spec["margin"]) ** 2)
                    plain.append(ca.sqrt(d2) - rc - ball["radius"])
        self.clear = ca.Function("clear", [q], [ca.vertcat(*clear) if clear else ca.DM.zeros(0)])
        self.plain_clear = ca.Function(
            "plain", [q], [ca.vertcat(*plain) if plain else ca.DM.zeros(0)]
        )


def foh(q0, v0, a0, a1, h, s):
    """State at s in [0, h] of q'' = a, a linear from a0 to a1 over h."""
    da = (a1 - a0) / h
    v = v0 + a0 * s + da * s * s / 2
    q = q0 + v0 * s + a0 * s * s / 2 + da * s**3 / 6
    return q, v


def transcribe(task, k):
    """The NLP: variables, constraints with bounds, objective."""
    spec, n = task.spec, task.n
    events = spec["events"]
    phases = len(events) - 1
    g_count = phases * k + 1
    tau_max = np.array(spec["tau_max"])
    # Decoupled: a = tau / I, bounded directly. Rigid-body: tau = RNEA(q, v, a) bounded by
    # rows at the grid points and interval midpoints, a itself free.
    a_max = tau_max / np.array(spec["inertia"]) if task.rnea is None else np.full(n, np.inf)
    qv, vv, av = ca.MX.sym("q", n, g_count), ca.MX.sym("v", n, g_count), ca.MX.sym("a", n, g_count)
    hv = ca.MX.sym("h", phases)
    g, lb, ub = [], [], []

    def add(expr, lo, hi):
        g.append(expr)
        size = expr.shape[0]
        lb.append(np.broadcast_to(lo, size).astype(float))
        ub.append(np.broadcast_to(hi, size).astype(float))

    def torque(qe, ve, ae):
        if task.rnea is not None:
            bound = 1 - task.torque_margin
            add(task.rnea(qe, ve, ae) / ca.DM(tau_max), -bound, bound)

    def path(qe, phase):
        node_lo, node_hi = events[phase], events[phase + 1]
        if spec["table"] is not None:
            add(task.ee(qe)[2], spec["table"], np.inf)
        active = [
            i
            for i, o in enumerate(spec["orientation"])
            if o["first"] <= node_lo and node_hi <= o["last"]
        ]
        if active:
            rows = task.orient(qe)
            add(ca.vertcat(*[rows[i] for i in active]), -np.inf, 1.0)
        if task.clear.size1_out(0) > 0:
            add(task.clear(qe), 1.0, np.inf)

    for p in range(phases):
        dt = hv[p] / k
        for i in range(k):
            j = p * k + i
            q1, v1 = foh(qv[:, j], vv[:, j], av[:, j], av[:, j + 1], dt, dt)
            add(qv[:, j + 1] - q1, 0, 0)
            add(vv[:, j + 1] - v1, 0, 0)
            # Joint angles are cubic and velocities quadratic on the interval: their
            # Bernstein control points inside the limits keep the whole arc inside.
            q_ctrl = ca.vertcat(qv[:, j] + vv[:, j] * dt / 3, q1 - v1 * dt / 3)
            add(q_ctrl, np.tile(spec["q_lo"], 2), np.tile(spec["q_hi"], 2))
            add(vv[:, j] + av[:, j] * dt / 2, -np.array(spec["qd_max"]), np.array(spec["qd_max"]))
            qm, _ = foh(qv[:, j], vv[:, j], av[:, j], av[:, j + 1], dt, dt / 2)
            path(qm, p)
            path(qv[:, j], p)
            torque(qv[:, j], vv[:, j], av[:, j])
            for frac in TORQUE_SAMPLES:
                qs, vs = foh(qv[:, j], vv[:, j], av[:, j], av[:, j + 1], dt, frac * dt)
                torque(qs, vs, (1 - frac) * av[:, j] + frac * av[:, j + 1])
        path(qv[:, (p + 1) * k], p)
    torque(qv[:, -1], vv[:, -1], av[:, -1])
    for w in spec["waypoints"]:
        j = events.index(w["node"]) * k
        d = task.ee(qv[:, j]) - ca.DM(w["position"])
        add(ca.dot(d, d) / w["tolerance"] ** 2, -np.inf, 1.0)
    add(ca.sum1(hv), 0, spec["t_max"])
    x = ca.vertcat(ca.vec(qv), ca.vec(vv), ca.vec(av), hv)
    q_lo = np.tile(spec["q_lo"], g_count)
    q_hi = np.tile(spec["q_hi"], g_count)
    v_lo, v_hi = -np.tile(spec["qd_max"], g_count), np.tile(spec["qd_max"], g_count)
    q0 = np.array(spec["q0"])
    q_lo[:n], q_hi[:n] = q0, q0
    v_lo[:n] = v_hi[:n] = 0
    v_lo[-n:] = v_hi[-n:] = 0
    x_lo = np.concatenate([q_lo, v_lo, -np.tile(a_max, g_count), np.full(phases, 1e-3)])
    x_hi = np.concatenate([q_hi, v_hi, np.tile(a_max, g_count), np.full(phases, spec["t_max"])])
    f = ca.sum1(hv)
    if task.rnea is not None:
        da = (av[:, 1:] - av[:, :-1]) / 1000.0
        f = f + SMOOTHING * ca.sumsqr(da)
    nlp = {"x": x, "f": f, "g": ca.vertcat(*g)}
    return nlp, (x_lo, x_hi), (np.concatenate(lb), np.concatenate(ub)), g_count


def interp_start(spec, times, angles, accel, k):
    """A start on the grid: angles (and accelerations) interpolated at the phase grid times."""
    events = spec["events"]
    times, angles = np.asarray(times), np.asarray(angles)
    node_t = times
    grid_t = []
    for p in range(len(events) - 1):
        t0, t1 = node_t[events[p]], node_t[events[p + 1]]
        grid_t.extend(np.linspace(t0, t1, k + 1)[:-1] if p < len(events) - 2 else np.linspace(t0, t1, k + 1))
    grid_t = np.array(grid_t)
    q = np.stack([np.interp(grid_t, node_t, angles[:, j]) for j in range(angles.shape[1])], 1)
    v = np.gradient(q, grid_t, axis=0) if len(grid_t) > 2 else np.zeros_like(q)
    v[0] = v[-1] = 0
    if accel is None:
        a = np.gradient(v, grid_t, axis=0)
    else:
        accel = np.asarray(accel)
        a = np.stack([np.interp(grid_t, node_t, accel[:, j]) for j in range(accel.shape[1])], 1)
    h = np.array([node_t[events[p + 1]] - node_t[events[p]] for p in range(len(events) - 1)])
    return q, v, a, np.maximum(h, 1e-3)


def dense_check(task, times, q_grid, v_grid, a_grid):
    """The largest violation on the exact trajectory sampled every DENSE_DT."""
    spec = task.spec
    worst = [-np.inf, "nothing"]

    def note(value, what):
        if value > worst[0]:
            worst[0], worst[1] = float(value), what

    q_lo, q_hi, vmax = map(np.array, (spec["q_lo"], spec["q_hi"], spec["qd_max"]))
    tau_max = np.array(spec["tau_max"])
    events = spec["events"]
    k = (len(times) - 1) // (len(events) - 1)
    node_times = {}
    for p, e in enumerate(events):
        node_times[e] = times[p * k]
    for j in range(len(times) - 1):
        h = times[j + 1] - times[j]
        steps = max(1, math.ceil(h / DENSE_DT))
        for s in np.linspace(0, h, steps + 1):
            q, v = foh(q_grid[j], v_grid[j], a_grid[j], a_grid[j + 1], h, s)
            t = times[j] + s
            note(max(np.max(q - q_hi), np.max(q_lo - q)), f"joint limits at t={t:.3f}")
            note(np.max(np.abs(v) - vmax), f"velocity limits at t={t:.3f}")
            if task.rnea is not None:
                a = a_grid[j] + (a_grid[j + 1] - a_grid[j]) * s / h
                tau = np.array(task.rnea(q, v, a)).ravel()
                note(np.max(np.abs(tau) - tau_max), f"torque limits at t={t:.3f}")
            p_ee = np.array(task.ee(q)).ravel()
            if spec["table"] is not None:
                note(spec["table"] - p_ee[2], f"table at t={t:.3f}")
            r = np.array(task.angle(q))
            for o in spec["orientation"]:
                if node_times[o["first"]] - 1e-12 <= t <= node_times[o["last"]] + 1e-12:
                    rd = quat_matrix(*o["quaternion_wxyz"])
                    c = np.clip((np.trace(rd.T @ r) - 1) / 2, -1, 1)
                    note(math.acos(c) - math.radians(o["tolerance_deg"]), f"orientation at t={t:.3f}")
            if task.plain_clear.size1_out(0) > 0:
                note(float(np.max(-np.array(task.plain_clear(q)))), f"clearance at t={t:.3f}")
    for w in spec["waypoints"]:
        j = events.index(w["node"]) * k
        p_ee = np.array(task.ee(q_grid[j])).ravel()
        note(np.linalg.norm(p_ee - np.array(w["position"])) - w["tolerance"], f"waypoint {w['node']}")
    note(float(np.max(np.abs(v_grid[-1]))), "end at rest")
    return worst[0], worst[1]


def starts(spec, k):
    """Armature's solution, its IK guess at its guess durations, and those scaled."""
    out = []
    if spec.get("armature"):
        s = spec["armature"]
        # Rigid-body: the accelerations from the interpolated angles (no forward dynamics
        # here).
        accel = None if spec["rigid_body"] else np.array(s["torques"]) / np.array(spec["inertia"])
        out.append(("armature", interp_start(spec, s["times"], s["angles"], accel, k)))
    if spec.get("guess"):
        d = np.array(spec["guess"]["durations"])
        for scale in (1.0,):
            t = np.concatenate([[0.0], np.cumsum(d[:-1] * scale)])
            out.append((f"guess x{scale}", interp_start(spec, t, spec["guess"]["angles"], None, k)))
    return out


class Transcription:
    """The NLP of a task with its orientation tolerances backed off by `backoff` rad, and
    IPOPT on it."""

    def __init__(self, spec, k, backoff=0.0, torque_margin=TORQUE_MARGIN, local=False):
        self.task = Task(spec, backoff, torque_margin)
        self.k = k
        nlp, self.x_bounds, self.g_bounds, self.g_count = transcribe(self.task, k)
        options = {
            "ipopt.print_level": 0, "print_time": False, "ipopt.max_iter": 3000,
            "ipopt.tol": 1e-9, "ipopt.constr_viol_tol": 1e-9, "ipopt.mu_strategy": "adaptive",
            "expand": self.task.rnea is None, "ipopt.max_cpu_time": MAX_SECONDS,
        }
        if local:
            options.update(LOCAL_OPTIONS)
        self.solver = ca.nlpsol("s", "ipopt", nlp, options)

    def torques(self, x, accelerations):
        """The torques at the grid points: tau = I a, or RNEA(q, v, a)."""
        if self.task.rnea is None:
            return accelerations * np.array(self.task.spec["inertia"])
        m = self.task.n * self.g_count
        qs, vs = (x[i * m:(i + 1) * m].reshape(self.g_count, self.task.n) for i in range(2))
        return np.array([np.array(self.task.rnea(q, v, a)).ravel()
                         for q, v, a in zip(qs, vs, accelerations)])

    def solve(self, x0):
        """IPOPT from x0: (converged, x, final time, grid times, q, v, a, worst, what)."""
        (x_lo, x_hi), (g_lo, g_hi) = self.x_bounds, self.g_bounds
        sol = self.solver(x0=np.clip(x0, x_lo, x_hi), lbx=x_lo, ubx=x_hi, lbg=g_lo, ubg=g_hi)
        status = self.solver.stats()["return_status"]
        x = np.array(sol["x"]).ravel()
        m = self.task.n * self.g_count
        qs, vs, as_ = (x[i * m:(i + 1) * m].reshape(self.g_count, self.task.n) for i in range(3))
        hs = x[3 * m:]
        times = np.concatenate([[0.0], np.cumsum(np.repeat(hs / self.k, self.k))])
        ok = status in ("Solve_Succeeded", "Solved_To_Acceptable_Level")
        worst, what = dense_check(self.task, times, qs, vs, as_) if ok else (math.inf, "not solved")
        return status, ok, x, float(np.sum(hs)), times, as_, worst, what


def solve_task(spec, k=INTERVALS, first=False, only="", local=False):
    """Solves one task from each start; the best start that passes the dense check.

    A start that converges but breaks an orientation range between the grid points by more
    than the tolerance is solved again from its solution with that range's tolerance backed
    off by 1.5x the excess (at most BACKOFF_ROUNDS times): the reference then stays inside
    the task's constraints on the dense trajectory, at a cost of a fraction of a degree.
    With `first`, the starts are tried guess first and the first that passes is kept. With
    `local`, IPOPT starts with a small barrier (`LOCAL_OPTIONS`): from armature's solution it
    then says whether that solution is a local optimum of this transcription.
    """
    result = {"status": "no start", "final_time": None, "starts": [], "times": [], "torques": [],
              "q0": spec.get("q0") or [], "backoff": 0.0, "torque_margin": 0.0}
    if spec["infeasible"] or not spec.get("q0"):
        result["status"] = "skipped"
        return spec["name"], result
    plain = Transcription(spec, k, local=local)
    if plain.task.rnea is not None:
        off = check_rnea(spec, plain.task.rnea)
        if off is not None and off > 1e-8:
            raise SystemExit(f"{spec['name']}: the RNEA differs from Pinocchio's by {off:.1e}")
    best = None
    tries = [t for t in starts(spec, k) if t[0].startswith(only)]
    if first:
        tries.reverse()
    for name, (q, v, a, h) in tries:
        if first and best is not None:
            break
        tr, backoff, margin = plain, 0.0, TORQUE_MARGIN if spec["rigid_body"] else 0.0
        status, ok, x, final, times, as_, worst, what = tr.solve(
            np.concatenate([q.ravel(), v.ravel(), a.ravel(), h]))
        # IPOPT's iterations from this start, the backed-off re-solves included.
        iterations = tr.solver.stats()["iter_count"]
        for _ in range(BACKOFF_ROUNDS):
            if not (ok and worst > TOLERANCE):
                break
            if what.startswith("orientation"):
                backoff += 1.5 * worst
            elif what.startswith("torque"):
                # The excess as a fraction of the smallest limit: enough for every joint.
                margin += 1.5 * worst / min(spec["tau_max"])
            else:
                break
            tr = Transcription(spec, k, backoff, margin, local)
            status, ok, x, final, times, as_, worst, what = tr.solve(x)
            iterations += tr.solver.stats()["iter_count"]
        result["starts"].append(final if ok and worst <= TOLERANCE else None)
        print(f"  {spec['name']}: {name}: {status} T {final:.4f} worst {worst:.1e} ({what})"
              f" backoff {backoff:.1e} torque margin {margin:.1e},"
              f" {iterations} IPOPT iterations", file=sys.stderr)
        if ok and worst <= TOLERANCE and (best is None or final < best[0]):
            best = (final, status, times, tr.torques(x, as_), as_, backoff, margin)
    if best is not None:
        rows = lambda t: [[float(f"{x:.12g}") for x in row] for row in t]
        result.update(status=best[1], final_time=best[0], times=[round(t, 12) for t in best[2]],
                      torques=rows(best[3]), backoff=best[5], torque_margin=best[6])
        if spec["rigid_body"]:
            # The suite verifies a rigid-body reference on its own parametrization: the
            # accelerations, first-order hold, integrated exactly, and the torques RNEA asks
            # along the way.
            result["accelerations"] = rows(best[4])
    else:
        result["status"] = "no start converged and verified"
    return spec["name"], result


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("tasks")
    ap.add_argument("out")
    ap.add_argument("--filter", default="", help="tasks whose name contains one of these (comma-separated)")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--intervals", type=int, default=INTERVALS)
    ap.add_argument("--first", action="store_true",
                    help="keep the first start that passes (guess first) instead of the best")
    ap.add_argument("--start", default="",
                    help="only the starts whose name begins with this (armature, guess)")
    ap.add_argument("--local", action="store_true",
                    help="a small initial barrier: the start's own basin (with --start armature)")
    ap.add_argument("--keep-best", action="store_true",
                    help="keep a stored entry whose final time is lower than the new one's")
    args = ap.parse_args()
    words = args.filter.split(",")
    specs = [s for s in json.load(open(args.tasks)) if any(w in s["name"] for w in words)]
    # Cheapest first (no ball), each result saved as it arrives.
    specs.sort(key=lambda s: len(s.get("balls") or []))
    t0 = time.time()
    results = {}
    with multiprocessing.Pool(args.jobs) as pool:
        for name, result in pool.imap_unordered(
            solve_task_star, [(s, args.intervals, args.first, args.start, args.local) for s in specs],
            chunksize=1,
        ):
            results[name] = result
            save(args.out, {name: result}, args.keep_best)
    done = [r["final_time"] for r in results.values() if r["final_time"]]
    print(f"{len(done)} of {len(results)} tasks with a verified reference, {time.time() - t0:.0f} s",
          file=sys.stderr)


def solve_task_star(args):
    return solve_task(*args)


def save(path, results, keep_best=False):
    """Merges results into the JSON at path, atomically (a temporary file renamed); with
    `keep_best`, a stored entry with a lower final time stays, the new starts' times added to
    its list."""
    try:
        with open(path) as f:
            old = json.load(f)
    except (OSError, ValueError):
        old = {}
    for name, new in results.items():
        stored = old.get(name)
        if keep_best and stored and stored.get("final_time") and (
            not new["final_time"] or stored["final_time"] <= new["final_time"]
        ):
            stored["starts"] = stored.get("starts", []) + new["starts"]
        else:
            if keep_best and stored:
                new["starts"] = stored.get("starts", []) + new["starts"]
            old[name] = new
    tmp = path + ".tmp"
    with open(tmp, "w") as f:
        json.dump(old, f, indent=0, sort_keys=True)
    os.replace(tmp, path)


if __name__ == "__main__":
    main()
