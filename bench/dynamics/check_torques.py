#!/usr/bin/env python3
"""Independent check of a rigid-body result: the dense trajectory's torques recomputed by
Pinocchio's inverse dynamics (pip `pin`), which shares no code with armature.

  python3 bench/dynamics/check_torques.py result.json ROBOT.urdf [--tol 1e-3]
      [--payload MASS CX CY CZ --tip LINK]

For each dense sample: q and q̇ from the result, q̈ by central differences of q̇ (one-sided at
the ends), τ_pin = RNEA(q, q̇, q̈). Prints the largest |τ_pin| / limit and the largest
|τ_pin − τ| / limit (τ: the result's torque), and exits 1 if a limit is exceeded by more than
the relative tolerance. Limits are the URDF's efforts; gravity is read from --gravity
(default 0 0 -9.81, the example's); a point payload (kg, centre in the tip link's frame) is
added to the last joint's body. For `armature demo ur5e-rigid-body`:

  python3 bench/dynamics/check_torques.py result.json \
      crates/kinematics/tests/fixtures/dynamics/ur5e.urdf --payload 3 0 0 0.05 --tip tool0
"""
import argparse
import json
import sys

import numpy as np
import pinocchio as pin


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("result")
    ap.add_argument("urdf")
    ap.add_argument("--tol", type=float, default=1e-3)
    ap.add_argument("--gravity", type=float, nargs=3, default=[0.0, 0.0, -9.81])
    ap.add_argument("--payload", type=float, nargs=4, metavar=("MASS", "CX", "CY", "CZ"))
    ap.add_argument("--tip", default="tool0")
    a = ap.parse_args()
    model = pin.buildModelFromUrdf(a.urdf)
    if a.payload:
        frame = model.frames[model.getFrameId(a.tip)]
        m, com = a.payload[0], np.array(a.payload[1:])
        model.appendBodyToJoint(frame.parentJoint, pin.Inertia(m, com, np.zeros((3, 3))), frame.placement)
    model.gravity.linear = np.array(a.gravity)
    data = model.createData()
    traj = json.load(open(a.result))["trajectory"]
    t = np.array(traj["time"]).reshape(-1)
    q, qd, tau = (np.array(traj[k]) for k in ("angle", "velocity", "torque"))
    qdd = np.gradient(qd, t, axis=0, edge_order=2)
    limit = model.effortLimit
    worst_use, worst_gap = 0.0, 0.0
    for k in range(len(t)):
        tp = pin.rnea(model, data, q[k], qd[k], qdd[k])
        worst_use = max(worst_use, float(np.max(np.abs(tp) / limit)))
        worst_gap = max(worst_gap, float(np.max(np.abs(tp - tau[k]) / limit)))
    print(f"samples {len(t)}, final time {t[-1]:.4f} s")
    print(f"largest |tau_pinocchio| / limit: {worst_use:.6f}")
    print(f"largest |tau_pinocchio - tau| / limit: {worst_gap:.3e} (finite-difference q̈)")
    ok = worst_use <= 1.0 + a.tol
    print("within limits" if ok else "LIMIT EXCEEDED")
    sys.exit(0 if ok else 1)


if __name__ == "__main__":
    main()
