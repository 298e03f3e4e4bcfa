"""The seed tutorial's 7-DOF pick-and-place in OpenSCvx 0.5.2, assembled verbatim from the
tutorial (../shared/seed/), for a wall-time comparison with `armature demo`.

One change: the tour visits pre_grasp twice and the tutorial names both waypoint
Parameters `waypoint_pre_grasp`, which OpenSCvx rejects as a duplicate name; the second is
`waypoint_lift` (the same position).

Run: python3 bench/openscvx/seed_pick_and_place.py   (after `pip install openscvx==0.5.2 jaxlie`)
"""

import time

T_START = time.perf_counter()

import numpy as np  # noqa: E402
import openscvx as ox  # noqa: E402

T_IMPORT = time.perf_counter()

N_JOINTS = 7
d1 = 0.340
a2 = 0.300
a3 = 0.250
a4 = 0.150
screw_axes = np.array([
    [0.0, 0.0, 0.0, 0.0, 0.0, 1.0],
    [-d1, 0.0, 0.0, 0.0, 1.0, 0.0],
    [0.0, -a2, 0.0, 0.0, 0.0, 1.0],
    [-d1, 0.0, a2, 0.0, 1.0, 0.0],
    [0.0, -(a2 + a3), 0.0, 0.0, 0.0, 1.0],
    [-d1, 0.0, a2 + a3, 0.0, 1.0, 0.0],
    [0.0, -(a2 + a3 + a4), 0.0, 0.0, 0.0, 1.0],
])
T_home = np.eye(4)
T_home[:3, 3] = [a2 + a3 + a4, 0.0, d1]

angle = ox.State("angle", shape=(N_JOINTS,))
angle.max = np.deg2rad([170, 120, 170, 120, 170, 120, 175])
angle.min = -angle.max
angle.initial = np.zeros(N_JOINTS)
angle.final = [("free", 0.0)] * N_JOINTS
velocity = ox.State("velocity", shape=(N_JOINTS,))
velocity.max = np.full(N_JOINTS, 3.0)
velocity.min = -velocity.max
velocity.initial = np.zeros(N_JOINTS)
velocity.final = np.zeros(N_JOINTS)
torque = ox.Control("torque", shape=(N_JOINTS,))
torque.max = np.array([8.0, 8.0, 4.0, 4.0, 2.0, 1.0, 0.5])
torque.min = -torque.max

joint_names = ["base", "shoulder", "elbow", "wrist", "ee"]
keypoint_after_joint = [0, 1, 2, 4, 7]
T_chain = ox.Constant(np.eye(4))
joint_idx = 0
joint_transforms = {}
for name, n_joints in zip(joint_names, keypoint_after_joint):
    while joint_idx < n_joints:
        xi = ox.Constant(screw_axes[joint_idx])
        T_chain = T_chain @ ox.lie.SE3Exp(xi * angle[joint_idx])
        joint_idx += 1
    joint_transforms[name] = T_chain
T_ee = T_chain @ ox.Constant(T_home)
p_ee = T_ee[:3, 3]
R_ee = T_ee[:3, :3]

inertia = np.array([0.08, 0.06, 0.05, 0.04, 0.02, 0.01, 0.005])
I_inv = ox.Constant(1.0 / inertia)
dynamics = {"angle": velocity, "velocity": I_inv * torque}

q_down = np.array([np.cos(np.pi / 4), 0.0, np.sin(np.pi / 4), 0.0])
q_identity = np.array([1.0, 0.0, 0.0, 0.0])
pre_height = 0.15
grasp_pos = np.array([0.35, -0.25, 0.05])
place_pos = np.array([0.35, 0.25, 0.05])
home_pos = np.array([a2 + a3 + a4 - 0.01, 0.0, d1])
pre_grasp_pos = grasp_pos + np.array([0.0, 0.0, pre_height])
pre_place_pos = place_pos + np.array([0.0, 0.0, pre_height])
waypoint_names = ["home", "pre_grasp", "grasp", "lift", "pre_place", "place"]
waypoint_positions = [home_pos, pre_grasp_pos, grasp_pos, pre_grasp_pos, pre_place_pos, place_pos]
waypoint_orientations = [q_identity, q_down, q_down, q_down, q_down, q_down]
nodes_per_segment = 2
n_segments = len(waypoint_positions) - 1
n = nodes_per_segment * n_segments + 1
waypoint_nodes = [i * nodes_per_segment for i in range(len(waypoint_positions))]

states = [angle, velocity]
controls = [torque]
constraints = []
for state in states:
    constraints.extend([ox.ctcs(state <= state.max), ox.ctcs(state.min <= state)])
constraints.append(ox.ctcs(p_ee[2] >= 0.0))
ee_tolerance = 0.01
for name, wp, node in zip(waypoint_names, waypoint_positions, waypoint_nodes):
    wp_param = ox.Parameter(f"waypoint_{name}", shape=(3,), value=wp)
    constraints.append((ox.linalg.Norm(p_ee - wp_param, ord=2) <= ee_tolerance).at([node]))
w, x, y, z = q_down
R_des = np.array([
    [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
    [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
    [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
])
ori_error = ox.lie.SO3Log(R_des.T @ R_ee)
ori_norm = ox.linalg.Norm(ori_error, ord=2)
constraints.append((ori_norm <= np.deg2rad(5.0)).over((waypoint_nodes[1], waypoint_nodes[-1])))
constraints.append((ori_norm <= np.deg2rad(0.1)).over((waypoint_nodes[1], waypoint_nodes[3])))
constraints.append((ori_norm <= np.deg2rad(0.1)).over((waypoint_nodes[4], waypoint_nodes[5])))

angle.guess = ox.init.ik_interpolation(
    keyframes=list(zip(waypoint_positions, waypoint_orientations)),
    nodes=waypoint_nodes,
    screw_axes=screw_axes,
    T_home=T_home,
    angles_init=angle.initial,
    angles_min=angle.min,
    angles_max=angle.max,
    sequential=True,
)
angle.initial = np.clip(angle.guess[0], angle.min, angle.max)
velocity.guess = np.zeros((n, N_JOINTS))
torque.guess = np.zeros((n, N_JOINTS))

total_time = 4.0
time_ = ox.Time(initial=0.0, final=ox.Minimize(total_time), min=0.0, max=total_time)
problem = ox.Problem(
    dynamics=dynamics,
    states=states,
    controls=controls,
    time=time_,
    constraints=constraints,
    N=n,
    algorithm={"lam_vb": 1e0},
    algebraic_prop={
        "ee_position": p_ee,
        **{f"T_{name}": T for name, T in joint_transforms.items()},
    },
)
problem.settings.prp.dt = 0.01
T_BUILT = time.perf_counter()
problem.initialize()
T_INIT = time.perf_counter()
results = problem.solve()
T_SOLVE = time.perf_counter()
results = problem.post_process()
T_POST = time.perf_counter()

print(
    "openscvx 0.5.2 seed pick-and-place: "
    f"import {T_IMPORT - T_START:.1f} s, build + IK {T_BUILT - T_IMPORT:.1f} s, "
    f"initialize {T_INIT - T_BUILT:.1f} s, solve {T_SOLVE - T_INIT:.1f} s, "
    f"post_process {T_POST - T_SOLVE:.1f} s, total {T_POST - T_START:.1f} s"
)


def report(label, value):
    """One result line; a field this version lacks is reported, not fatal."""
    try:
        print(f"  {label}: {value()}")
    except Exception as e:  # noqa: BLE001
        print(f"  {label}: n/a ({type(e).__name__}: {e})")


report("converged", lambda: results.converged)
report("iterations (acceptance-ratio records)", lambda: len(results.acceptance_ratio_history))
report("final time", lambda: f"{float(np.asarray(results.t_final).ravel()[-1]):.4f} s")
report("largest CTCS violation", lambda: f"{float(np.max(np.asarray(results.ctcs_violation))):.3g}")
