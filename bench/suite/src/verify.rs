//! Verification that shares no code with the solver: the robot's forward kinematics written
//! out from its published description (the seed tutorial's joint sequence, the UR5e's DH
//! table), the solution's node torques re-integrated (first-order hold, RK4 at 1 ms), and
//! every constraint of the task checked on that trajectory to [`TOLERANCE`].
//!
//! The rigid-body dynamics is the one exception: the re-integration calls
//! `armature_kinematics::RigidBodyModel::aba`, which the solver also uses (through its graph
//! node) and which is itself checked against Pinocchio to 1e-10.

use nalgebra::{Matrix3, Rotation3, Vector3};

/// How far a constraint may be broken for a solution to count as verified (its own units).
pub const TOLERANCE: f64 = 1e-4;

/// The re-integration's step (s).
pub const DT: f64 = 1e-3;

/// Which forward kinematics a robot has.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Robot {
    /// The seed tutorial's 7-DOF arm.
    Arm7,
    /// The UR5e (standard DH).
    Ur5e,
    /// The KUKA LBR iiwa 7 R800 (standard DH).
    Iiwa7,
}

/// A standard DH table: `(d, a, α)` per joint.
type Dh = [(f64, f64, f64)];

/// The UR5e's published DH table.
const UR5E_DH: [(f64, f64, f64); 6] = [
    (0.1625, 0.0, std::f64::consts::FRAC_PI_2),
    (0.0, -0.425, 0.0),
    (0.0, -0.3922, 0.0),
    (0.1333, 0.0, std::f64::consts::FRAC_PI_2),
    (0.0997, 0.0, -std::f64::consts::FRAC_PI_2),
    (0.0996, 0.0, 0.0),
];

/// The LBR iiwa 7 R800's DH table (KUKA's link lengths 0.34, 0.4, 0.4, 0.126 m).
pub const IIWA7_DH: [(f64, f64, f64); 7] = [
    (0.34, 0.0, -std::f64::consts::FRAC_PI_2),
    (0.0, 0.0, std::f64::consts::FRAC_PI_2),
    (0.4, 0.0, std::f64::consts::FRAC_PI_2),
    (0.0, 0.0, -std::f64::consts::FRAC_PI_2),
    (0.4, 0.0, -std::f64::consts::FRAC_PI_2),
    (0.0, 0.0, std::f64::consts::FRAC_PI_2),
    (0.126, 0.0, 0.0),
];

/// The frames 0…n of a standard DH chain: `Tᵢ = Tᵢ₋₁·Rz(qᵢ)·Tz(d)·Tx(a)·Rx(α)`.
fn dh_frames(table: &Dh, q: &[f64]) -> Vec<Frame> {
    let mut f: Frame = (Matrix3::identity(), Vector3::zeros());
    let mut out = vec![f];
    for (&(d, a, alpha), &qi) in table.iter().zip(q) {
        let turned = then(&f, rz(qi), Vector3::new(a, 0.0, d));
        f = (turned.0 * rx(alpha), turned.1);
        out.push(f);
    }
    out
}

/// A pose (rotation, position).
pub type Frame = (Matrix3<f64>, Vector3<f64>);

fn rz(a: f64) -> Matrix3<f64> {
    *Rotation3::from_axis_angle(&Vector3::z_axis(), a).matrix()
}
fn ry(a: f64) -> Matrix3<f64> {
    *Rotation3::from_axis_angle(&Vector3::y_axis(), a).matrix()
}
fn rx(a: f64) -> Matrix3<f64> {
    *Rotation3::from_axis_angle(&Vector3::x_axis(), a).matrix()
}

/// Composes `(r, p)` with a rotation then a translation in the moving frame.
fn then(f: &Frame, rot: Matrix3<f64>, trans: Vector3<f64>) -> Frame {
    let r = f.0 * rot;
    (r, f.1 + r * trans)
}

impl Robot {
    /// The frames along the arm: the arm7 keypoints (base, shoulder, elbow, wrist, ee) or the
    /// DH frames 0…n of the others; the last is the end effector.
    pub fn frames(self, q: &[f64]) -> Vec<Frame> {
        let mut f: Frame = (Matrix3::identity(), Vector3::zeros());
        let mut out = vec![f];
        match self {
            Robot::Arm7 => {
                let (d1, a2, a3, a4) = (0.340, 0.300, 0.250, 0.150);
                f = then(&f, rz(q[0]), Vector3::new(0.0, 0.0, d1));
                out.push(f);
                f = then(&f, ry(q[1]), Vector3::new(a2, 0.0, 0.0));
                out.push(f);
                f = then(&f, rz(q[2]), Vector3::zeros());
                f = then(&f, ry(q[3]), Vector3::new(a3, 0.0, 0.0));
                out.push(f);
                f = then(&f, rz(q[4]), Vector3::zeros());
                f = then(&f, ry(q[5]), Vector3::new(a4, 0.0, 0.0));
                f = then(&f, rz(q[6]), Vector3::zeros());
                out.push(f);
            }
            Robot::Ur5e => return dh_frames(&UR5E_DH, q),
            Robot::Iiwa7 => return dh_frames(&IIWA7_DH, q),
        }
        out
    }

    /// The end effector's pose.
    pub fn ee(self, q: &[f64]) -> Frame {
        *self.frames(q).last().expect("frames end at the end effector")
    }

    /// The capsule axes of the seed's collision variant (arm7: base–shoulder, shoulder–elbow,
    /// elbow–wrist, wrist–ee with radii 0.06, 0.05, 0.04, 0.035).
    pub fn capsules(self, q: &[f64]) -> Vec<(Vector3<f64>, Vector3<f64>, f64)> {
        let f = self.frames(q);
        match self {
            Robot::Arm7 => [0.06, 0.05, 0.04, 0.035]
                .iter()
                .enumerate()
                .map(|(i, &r)| (f[i].1, f[i + 1].1, r))
                .collect(),
            Robot::Ur5e | Robot::Iiwa7 => Vec::new(),
        }
    }
}

/// The rotation angle between two rotations (rad), from the trace.
pub fn angle_between(a: &Matrix3<f64>, b: &Matrix3<f64>) -> f64 {
    let c = ((a.transpose() * b).trace() - 1.0) / 2.0;
    c.clamp(-1.0, 1.0).acos()
}

/// Distance from point `c` to segment `a`–`b`.
pub fn point_segment(c: &Vector3<f64>, a: &Vector3<f64>, b: &Vector3<f64>) -> f64 {
    let ab = b - a;
    let t = if ab.norm_squared() > 0.0 {
        ((c - a).dot(&ab) / ab.norm_squared()).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (a + t * ab - c).norm()
}

/// Distance between segments `a0`–`a1` and `b0`–`b1`: the least of the distances at the
/// interior critical point of `|a(s) − b(t)|²` (when the segments are not parallel and it lies
/// in the unit square) and of the four endpoint-to-segment distances, which cover every
/// boundary minimum. Degenerate (point) segments reduce to [`point_segment`].
pub fn segment_segment(
    a0: &Vector3<f64>,
    a1: &Vector3<f64>,
    b0: &Vector3<f64>,
    b1: &Vector3<f64>,
) -> f64 {
    let mut best = point_segment(a0, b0, b1)
        .min(point_segment(a1, b0, b1))
        .min(point_segment(b0, a0, a1))
        .min(point_segment(b1, a0, a1));
    let (u, v, w) = (a1 - a0, b1 - b0, a0 - b0);
    let (a, b, c, d, e) = (u.dot(&u), u.dot(&v), v.dot(&v), u.dot(&w), v.dot(&w));
    let den = a * c - b * b;
    if den > 1e-12 * a * c {
        let s = (b * e - c * d) / den;
        let t = (a * e - b * d) / den;
        if (0.0..=1.0).contains(&s) && (0.0..=1.0).contains(&t) {
            best = best.min((a0 + s * u - b0 - t * v).norm());
        }
    }
    best
}

/// The arm's accelerations for the verification's re-integration.
pub trait Accelerations {
    /// `q̈` at `(q, q̇, τ)`.
    fn qdd(&mut self, q: &[f64], qd: &[f64], tau: &[f64], out: &mut [f64]);
}

/// `q̈ = τ / I`.
#[derive(Debug, Clone)]
pub struct Decoupled(pub Vec<f64>);

impl Accelerations for Decoupled {
    fn qdd(&mut self, _: &[f64], _: &[f64], tau: &[f64], out: &mut [f64]) {
        for ((o, t), i) in out.iter_mut().zip(tau).zip(&self.0) {
            *o = t / i;
        }
    }
}

/// Rigid-body forward dynamics (ABA).
#[derive(Debug)]
pub struct RigidBody(
    pub armature_kinematics::RigidBodyModel,
    pub armature_kinematics::DynamicsWorkspace,
);

impl Accelerations for RigidBody {
    fn qdd(&mut self, q: &[f64], qd: &[f64], tau: &[f64], out: &mut [f64]) {
        if self.0.aba(&mut self.1, q, qd, tau, out).is_err() {
            out.fill(f64::NAN);
        }
    }
}

/// A dense trajectory: times, angles, velocities, torques.
#[derive(Debug, Clone, Default)]
pub struct Dense {
    /// Times (s).
    pub t: Vec<f64>,
    /// Angles per sample.
    pub q: Vec<Vec<f64>>,
    /// Velocities per sample.
    pub qd: Vec<Vec<f64>>,
    /// Torques per sample (at a node: where the segment before it ends).
    pub tau: Vec<Vec<f64>>,
    /// The torques where each segment starts (they jump at a node where a time-scaled
    /// solution's segments change duration).
    pub segment_starts: Vec<Vec<f64>>,
}

/// Re-integrates from `(q0, q̇0)` under the torques at the node times, held first-order
/// between them (segment k from `torques[k]` to `ends[k]`, or to `torques[k + 1]` without
/// `ends`), with RK4 steps of at most [`DT`].
pub fn reintegrate(
    dyn_: &mut dyn Accelerations,
    times: &[f64],
    (torques, ends): (&[Vec<f64>], Option<&[Vec<f64>]>),
    q0: &[f64],
    qd0: &[f64],
) -> Dense {
    let n = q0.len();
    let (mut q, mut qd) = (q0.to_vec(), qd0.to_vec());
    let mut out = Dense::default();
    let push = |out: &mut Dense, t: f64, q: &[f64], qd: &[f64], tau: Vec<f64>| {
        out.t.push(t);
        out.q.push(q.to_vec());
        out.qd.push(qd.to_vec());
        out.tau.push(tau);
    };
    push(&mut out, times[0], &q, &qd, torques[0].clone());
    let mut acc = vec![0.0; n];
    for k in 0..times.len() - 1 {
        let (t0, h) = (times[k], times[k + 1] - times[k]);
        let steps = (h / DT).ceil().max(1.0) as usize;
        let dt = h / steps as f64;
        let tau_at = |s: f64| -> Vec<f64> {
            let w = ((s - t0) / h).clamp(0.0, 1.0);
            let end = ends.map_or(&torques[k + 1], |e| &e[k]);
            torques[k].iter().zip(end).map(|(a, b)| (1.0 - w) * a + w * b).collect()
        };
        out.segment_starts.push(torques[k].clone());
        for i in 0..steps {
            let s = t0 + i as f64 * dt;
            let mut deriv = |q: &[f64], qd: &[f64], s: f64| -> (Vec<f64>, Vec<f64>) {
                dyn_.qdd(q, qd, &tau_at(s), &mut acc);
                (qd.to_vec(), acc.clone())
            };
            let add = |x: &[f64], d: &[f64], c: f64| -> Vec<f64> {
                x.iter().zip(d).map(|(x, d)| x + c * d).collect()
            };
            let (k1q, k1v) = deriv(&q, &qd, s);
            let (k2q, k2v) =
                deriv(&add(&q, &k1q, dt / 2.0), &add(&qd, &k1v, dt / 2.0), s + dt / 2.0);
            let (k3q, k3v) =
                deriv(&add(&q, &k2q, dt / 2.0), &add(&qd, &k2v, dt / 2.0), s + dt / 2.0);
            let (k4q, k4v) = deriv(&add(&q, &k3q, dt), &add(&qd, &k3v, dt), s + dt);
            for j in 0..n {
                q[j] += dt / 6.0 * (k1q[j] + 2.0 * k2q[j] + 2.0 * k3q[j] + k4q[j]);
                qd[j] += dt / 6.0 * (k1v[j] + 2.0 * k2v[j] + 2.0 * k3v[j] + k4v[j]);
            }
            push(&mut out, s + dt, &q, &qd, tau_at(s + dt));
        }
    }
    out
}

/// What a task asks, as the verification reads it (copied out of the task, not the problem).
#[derive(Debug, Clone)]
pub struct Checks {
    /// The robot's FK.
    pub robot: Robot,
    /// Position limits.
    pub q_lo: Vec<f64>,
    /// Position limits.
    pub q_hi: Vec<f64>,
    /// Velocity limits.
    pub qd_max: Vec<f64>,
    /// Torque limits.
    pub tau_max: Vec<f64>,
    /// Waypoints: (node, position, tolerance).
    pub waypoints: Vec<(usize, Vector3<f64>, f64)>,
    /// Orientation ranges: (rotation, tolerance in rad, first node, last node).
    pub orientation: Vec<(Matrix3<f64>, f64, usize, usize)>,
    /// Table height.
    pub table: Option<f64>,
    /// Ball obstacles: (centre, radius).
    pub balls: Vec<(Vector3<f64>, f64)>,
    /// The non-adjacent capsule pairs (indices into [`Robot::capsules`]) that must keep the
    /// clearance from each other (self-collision).
    pub link_pairs: Vec<(usize, usize)>,
    /// The clearance the task keeps from every ball and between the capsules of every
    /// pair in `link_pairs` (m).
    pub margin: f64,
}

/// The largest violation found: its size (in the constraint's units) and what it is.
#[derive(Debug, Clone, PartialEq)]
pub struct Worst {
    /// How far beyond its bound (≤ 0: holds).
    pub value: f64,
    /// Which constraint, and when.
    pub what: String,
}

/// Checks the re-integrated trajectory (and the waypoints at the node times).
pub fn check(c: &Checks, dense: &Dense, node_times: &[f64]) -> Worst {
    let mut worst = Worst { value: f64::NEG_INFINITY, what: String::new() };
    let mut note = |v: f64, what: &dyn Fn() -> String| {
        if v > worst.value {
            worst = Worst { value: v, what: what() };
        }
    };
    let node_at = |t: f64| node_times.iter().rposition(|&s| s <= t + 1e-12).unwrap_or(0);
    for (k, tau) in dense.segment_starts.iter().enumerate() {
        let t = node_times.get(k).copied().unwrap_or(f64::NAN);
        for j in 0..tau.len() {
            note(tau[j].abs() - c.tau_max[j], &|| format!("joint {j} torque at t = {t:.3}"));
        }
    }
    for (s, &t) in dense.t.iter().enumerate() {
        let (q, qd, tau) = (&dense.q[s], &dense.qd[s], &dense.tau[s]);
        for j in 0..q.len() {
            note(q[j] - c.q_hi[j], &|| format!("joint {j} upper limit at t = {t:.3}"));
            note(c.q_lo[j] - q[j], &|| format!("joint {j} lower limit at t = {t:.3}"));
            note(qd[j].abs() - c.qd_max[j], &|| format!("joint {j} velocity at t = {t:.3}"));
            note(tau[j].abs() - c.tau_max[j], &|| format!("joint {j} torque at t = {t:.3}"));
        }
        let (r, p) = c.robot.ee(q);
        if let Some(h) = c.table {
            note(h - p.z, &|| format!("table at t = {t:.3}"));
        }
        let k = node_at(t);
        for &(rd, tol, first, last) in &c.orientation {
            // Held over [t_first, t_last].
            if t >= node_times[first] - 1e-12 && t <= node_times[last] + 1e-12 {
                note(angle_between(&r, &rd) - tol, &|| {
                    format!("orientation nodes {first}..{last} at t = {t:.3} (node {k})")
                });
            }
        }
        let capsules = c.robot.capsules(q);
        for (ci, (a, b, rc)) in capsules.iter().enumerate() {
            for (bc, rb) in &c.balls {
                let clearance = point_segment(bc, a, b) - rc - rb - c.margin;
                note(-clearance, &|| format!("capsule {ci} against the ball at t = {t:.3}"));
            }
        }
        for &(i, j) in &c.link_pairs {
            let ((a0, a1, ra), (b0, b1, rb)) = (&capsules[i], &capsules[j]);
            let clearance = segment_segment(a0, a1, b0, b1) - ra - rb - c.margin;
            note(-clearance, &|| format!("capsules {i} and {j} at t = {t:.3}"));
        }
    }
    for &(node, w, tol) in &c.waypoints {
        let t = node_times[node];
        let s = dense.t.iter().position(|&u| (u - t).abs() < 1e-9).unwrap_or_else(|| {
            dense
                .t
                .iter()
                .enumerate()
                .min_by(|a, b| (a.1 - t).abs().total_cmp(&(b.1 - t).abs()))
                .map_or(0, |(i, _)| i)
        });
        let (_, p) = c.robot.ee(&dense.q[s]);
        note((p - w).norm() - tol, &|| format!("waypoint at node {node}"));
    }
    // At rest at the end.
    if let Some(last) = dense.qd.last() {
        let v = last.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        note(v, &|| "velocity at the end".to_string());
    }
    worst
}
