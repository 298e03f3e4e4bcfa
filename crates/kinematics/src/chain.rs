//! Serial kinematic chains in product-of-exponentials form.

use armature_lie::{SE3, SO3};
use nalgebra::{Vector3, Vector6};
use serde::{Deserialize, Serialize};

use crate::{Inertial, KinematicsError};

/// Tolerance on unit axes and orthogonality checks of chain data.
pub const AXIS_TOLERANCE: f64 = 1e-6;

/// How a joint moves.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum JointKind {
    /// Rotation about an axis (screw `[v; ω]` with `|ω| = 1`).
    Revolute,
    /// Translation along an axis (screw `[v; 0]` with `|v| = 1`).
    Prismatic,
}

/// Joint limits; any may be absent.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Limits {
    /// Lowest position (rad or m).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lower: Option<f64>,
    /// Highest position (rad or m).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub upper: Option<f64>,
    /// Largest speed magnitude (rad/s or m/s).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub velocity: Option<f64>,
    /// Largest torque or force magnitude (N·m or N).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub effort: Option<f64>,
}

impl Limits {
    /// Symmetric position limits `±position`, with velocity and effort limits.
    pub fn symmetric(position: f64, velocity: f64, effort: f64) -> Self {
        Limits {
            lower: Some(-position),
            upper: Some(position),
            velocity: Some(velocity),
            effort: Some(effort),
        }
    }
}

/// One joint: its screw axis in the base frame at `q = 0`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Joint {
    /// Name (unique in the chain).
    pub name: String,
    /// Revolute or prismatic.
    pub kind: JointKind,
    /// Screw axis `[v; ω]` in the base frame at `q = 0`. A revolute joint through point `p`
    /// about unit axis `ω` has `v = −ω × p`.
    #[serde(deserialize_with = "crate::exact::array")]
    pub screw: [f64; 6],
    /// Limits.
    #[serde(default)]
    pub limits: Limits,
    /// Mass properties of the rigid body this joint moves (every link after it up to the next
    /// joint), in the base frame at `q = 0`; needed by the rigid-body dynamics only.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub inertial: Option<Inertial>,
    /// The link this joint moves, where the source names one (a URDF's child link).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub link: Option<String>,
}

impl Joint {
    /// The same joint with the mass properties of the body it moves (base frame, `q = 0`).
    pub fn with_inertial(mut self, inertial: Inertial) -> Joint {
        self.inertial = Some(inertial);
        self
    }

    /// A revolute joint about the unit `axis` through `point` (base frame, `q = 0`).
    pub fn revolute(name: &str, axis: [f64; 3], point: [f64; 3], limits: Limits) -> Joint {
        let w = Vector3::from(axis);
        let v = -w.cross(&Vector3::from(point));
        Joint {
            name: name.into(),
            kind: JointKind::Revolute,
            screw: [v.x, v.y, v.z, w.x, w.y, w.z],
            limits,
            inertial: None,
            link: None,
        }
    }

    /// A prismatic joint along the unit `axis`.
    pub fn prismatic(name: &str, axis: [f64; 3], limits: Limits) -> Joint {
        Joint {
            name: name.into(),
            kind: JointKind::Prismatic,
            screw: [axis[0], axis[1], axis[2], 0.0, 0.0, 0.0],
            limits,
            inertial: None,
            link: None,
        }
    }

    /// The screw axis as a vector.
    pub fn screw_vector(&self) -> Vector6<f64> {
        Vector6::from_column_slice(&self.screw)
    }
}

/// A named point of interest on the arm: its position at `q = 0` and how many joints
/// precede it (it moves with the frame after those joints).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Keypoint {
    /// Name (unique among keypoints).
    pub name: String,
    /// Number of joints before it (0 = fixed to the base).
    pub after: usize,
    /// Position in the base frame at `q = 0`.
    #[serde(deserialize_with = "crate::exact::array")]
    pub position: [f64; 3],
}

/// A pose given as position and quaternion `[w, x, y, z]` in files.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Pose {
    /// Translation.
    #[serde(deserialize_with = "crate::exact::array")]
    pub position: [f64; 3],
    /// Orientation `[w, x, y, z]`.
    #[serde(default = "identity_wxyz")]
    #[serde(deserialize_with = "crate::exact::array")]
    pub quaternion_wxyz: [f64; 4],
}

fn identity_wxyz() -> [f64; 4] {
    [1.0, 0.0, 0.0, 0.0]
}

impl From<SE3> for Pose {
    fn from(t: SE3) -> Pose {
        let p = t.translation();
        Pose { position: [p.x, p.y, p.z], quaternion_wxyz: t.rotation().quaternion_wxyz() }
    }
}

/// A serial chain in product-of-exponentials form:
/// `T_ee(q) = exp(ξ₁q₁)·…·exp(ξₙqₙ)·M`, with named keypoints snapshotted along the way.
///
/// Plain data, serde-serializable; deserialising validates like [`Chain::new`].
///
/// # Example
/// ```
/// use armature_kinematics::{Chain, robots};
/// let arm = robots::arm7();
/// assert_eq!(arm.dof(), 7);
/// assert_eq!(arm.keypoint_names().collect::<Vec<_>>(), ["base", "shoulder", "elbow", "wrist", "ee"]);
/// let json = serde_json::to_string(&arm).unwrap();
/// let back: Chain = serde_json::from_str(&json).unwrap();
/// assert_eq!(back, arm);
/// ```
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "ChainData", into = "ChainData")]
pub struct Chain {
    name: String,
    joints: Vec<Joint>,
    home: SE3,
    keypoints: Vec<Keypoint>,
    /// Per-joint constants of the FK hot path, derived from `joints` once.
    pub(crate) exp_data: Vec<JointExpData>,
}

/// Constants of `exp(ξ q)` for one joint: `R(q) = I + sin q·W + (1 − cos q)·W²`,
/// `t(q) = (I − R(q))·p + h·q·ω` (revolute), or `t = q·v` (prismatic).
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct JointExpData {
    pub(crate) prismatic: bool,
    pub(crate) w: nalgebra::Vector3<f64>,
    pub(crate) v: nalgebra::Vector3<f64>,
    pub(crate) wh: nalgebra::Matrix3<f64>,
    pub(crate) wh2: nalgebra::Matrix3<f64>,
    /// `ω × v`: the axis point nearest the origin.
    pub(crate) p: nalgebra::Vector3<f64>,
    /// Pitch `ω·v` (zero for a validated revolute joint, kept for exactness).
    pub(crate) h: f64,
    /// `Some((k, σ))` if `ω = σ·e_k` exactly: the joint rotates in the plane of the two other
    /// axes, which the FK hot path exploits.
    pub(crate) aligned: Option<(usize, f64)>,
}

impl JointExpData {
    fn new(j: &Joint) -> Self {
        let s = j.screw_vector();
        let v = Vector3::new(s[0], s[1], s[2]);
        let w = Vector3::new(s[3], s[4], s[5]);
        let wh = SO3::hat(&w);
        let aligned = (0..3).find_map(|k| {
            let others_zero = (0..3).all(|i| i == k || w[i] == 0.0);
            (others_zero && w[k].abs() == 1.0 && j.kind == JointKind::Revolute).then_some((k, w[k]))
        });
        JointExpData {
            prismatic: j.kind == JointKind::Prismatic,
            w,
            v,
            wh,
            wh2: wh * wh,
            p: w.cross(&v),
            h: w.dot(&v),
            aligned,
        }
    }
}

/// The serialized form of a [`Chain`] (also the screw-table robot file's layout).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ChainData {
    /// Robot name.
    pub name: String,
    /// Joints from base to tip.
    pub joints: Vec<Joint>,
    /// End-effector pose at `q = 0`.
    pub home: Pose,
    /// Keypoints.
    #[serde(default)]
    pub keypoints: Vec<Keypoint>,
}

impl TryFrom<ChainData> for Chain {
    type Error = KinematicsError;
    fn try_from(d: ChainData) -> Result<Chain, KinematicsError> {
        let rot = SO3::from_quaternion_wxyz(d.home.quaternion_wxyz)
            .map_err(|e| KinematicsError::BadHome(e.to_string()))?;
        if d.home.position.iter().any(|x| !x.is_finite()) {
            return Err(KinematicsError::BadHome("position is not finite".into()));
        }
        Chain::new(
            &d.name,
            d.joints,
            SE3::from_parts(rot, Vector3::from(d.home.position)),
            d.keypoints,
        )
    }
}

impl From<Chain> for ChainData {
    fn from(c: Chain) -> ChainData {
        ChainData { name: c.name, joints: c.joints, home: c.home.into(), keypoints: c.keypoints }
    }
}

impl Chain {
    /// A validated chain.
    ///
    /// # Errors
    /// [`KinematicsError::BadJoint`] for a non-unit rotation axis (revolute) or translation
    /// axis (prismatic), a revolute screw with pitch, non-finite data or disordered / non-
    /// positive limits; [`KinematicsError::BadKeypoint`] for a keypoint after more joints than
    /// the chain has, or out of order; [`KinematicsError::DuplicateName`].
    pub fn new(
        name: &str,
        joints: Vec<Joint>,
        home: SE3,
        keypoints: Vec<Keypoint>,
    ) -> Result<Chain, KinematicsError> {
        for (index, j) in joints.iter().enumerate() {
            let bad =
                |reason: String| KinematicsError::BadJoint { index, name: j.name.clone(), reason };
            if j.screw.iter().any(|x| !x.is_finite()) {
                return Err(bad(format!("screw {:?} is not finite", j.screw)));
            }
            let s = j.screw_vector();
            let (v, w) = (s.fixed_rows::<3>(0), s.fixed_rows::<3>(3));
            match j.kind {
                JointKind::Revolute => {
                    if (w.norm() - 1.0).abs() > AXIS_TOLERANCE {
                        return Err(bad(format!(
                            "rotation axis {:?} has norm {:.9}, not 1",
                            [w.x, w.y, w.z],
                            w.norm()
                        )));
                    }
                    if w.dot(&v).abs() > AXIS_TOLERANCE {
                        return Err(bad(format!(
                            "screw has pitch ω·v = {:.3e}; a revolute joint needs v ⊥ ω",
                            w.dot(&v)
                        )));
                    }
                }
                JointKind::Prismatic => {
                    if w.norm() > AXIS_TOLERANCE || (v.norm() - 1.0).abs() > AXIS_TOLERANCE {
                        return Err(bad(format!(
                            "a prismatic screw is [unit axis; 0], got {:?}",
                            j.screw
                        )));
                    }
                }
            }
            let l = &j.limits;
            for (what, x) in [
                ("lower", l.lower),
                ("upper", l.upper),
                ("velocity", l.velocity),
                ("effort", l.effort),
            ] {
                if let Some(x) = x
                    && !x.is_finite()
                {
                    return Err(bad(format!("{what} limit is {x}")));
                }
            }
            if let (Some(lo), Some(hi)) = (l.lower, l.upper)
                && lo > hi
            {
                return Err(bad(format!("lower limit {lo} exceeds upper limit {hi}")));
            }
            for (what, x) in [("velocity", l.velocity), ("effort", l.effort)] {
                if let Some(x) = x
                    && x <= 0.0
                {
                    return Err(bad(format!("{what} limit {x} is not positive")));
                }
            }
            if let Some(inertial) = &j.inertial {
                inertial.check().map_err(|r| bad(format!("inertial: {r}")))?;
            }
            if joints[..index].iter().any(|o| o.name == j.name) {
                return Err(KinematicsError::DuplicateName { what: "joint", name: j.name.clone() });
            }
        }
        let mut last = 0;
        for (i, k) in keypoints.iter().enumerate() {
            let bad =
                |reason: String| KinematicsError::BadKeypoint { name: k.name.clone(), reason };
            if k.after > joints.len() {
                return Err(bad(format!(
                    "comes after {} joints but the chain has {}",
                    k.after,
                    joints.len()
                )));
            }
            if k.after < last {
                return Err(bad(format!(
                    "comes after {} joints, fewer than the keypoint before it ({last})",
                    k.after
                )));
            }
            if k.position.iter().any(|x| !x.is_finite()) {
                return Err(bad("position is not finite".into()));
            }
            if keypoints[..i].iter().any(|o| o.name == k.name) {
                return Err(KinematicsError::DuplicateName {
                    what: "keypoint",
                    name: k.name.clone(),
                });
            }
            last = k.after;
        }
        let exp_data = joints.iter().map(JointExpData::new).collect();
        Ok(Chain { name: name.into(), joints, home, keypoints, exp_data })
    }

    /// The robot's name.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Number of joints.
    pub fn dof(&self) -> usize {
        self.joints.len()
    }

    /// The joints, base to tip.
    pub fn joints(&self) -> &[Joint] {
        &self.joints
    }

    /// End-effector pose at `q = 0`.
    pub fn home(&self) -> SE3 {
        self.home
    }

    /// The keypoints in chain order.
    pub fn keypoints(&self) -> &[Keypoint] {
        &self.keypoints
    }

    /// Keypoint names in order.
    pub fn keypoint_names(&self) -> impl Iterator<Item = &str> {
        self.keypoints.iter().map(|k| k.name.as_str())
    }

    /// Index of a keypoint by name.
    pub fn keypoint_index(&self, name: &str) -> Option<usize> {
        self.keypoints.iter().position(|k| k.name == name)
    }

    /// Checks a joint vector's length and finiteness.
    ///
    /// # Errors
    /// [`KinematicsError::WrongJointCount`], [`KinematicsError::NonFiniteJoint`].
    pub fn check_q(&self, q: &[f64]) -> Result<(), KinematicsError> {
        if q.len() != self.dof() {
            return Err(KinematicsError::WrongJointCount { expected: self.dof(), got: q.len() });
        }
        if let Some(index) = q.iter().position(|x| !x.is_finite()) {
            return Err(KinematicsError::NonFiniteJoint { index, value: q[index] });
        }
        Ok(())
    }

    /// The same chain with a tool centre point: the end effector moves by `offset` (in the
    /// current end-effector frame), and a keypoint named `tool` marks it (after every joint;
    /// an existing `tool` keypoint is replaced).
    ///
    /// # Errors
    /// [`KinematicsError::BadHome`] for an offset that is not a finite rigid transform.
    ///
    /// # Example
    /// ```
    /// use armature_kinematics::{Pose, robots};
    /// let arm = robots::arm7();
    /// let tcp = arm.with_tool(&Pose { position: [0.0, 0.0, 0.1], quaternion_wxyz: [1.0, 0.0, 0.0, 0.0] }).unwrap();
    /// let p = tcp.home().translation();
    /// assert!((p - arm.home().translation()).norm() - 0.1 < 1e-12);
    /// assert_eq!(tcp.keypoint_names().last(), Some("tool"));
    /// ```
    pub fn with_tool(&self, offset: &Pose) -> Result<Chain, KinematicsError> {
        let rot = SO3::from_quaternion_wxyz(offset.quaternion_wxyz)
            .map_err(|e| KinematicsError::BadHome(format!("tool: {e}")))?;
        if offset.position.iter().any(|x| !x.is_finite()) {
            return Err(KinematicsError::BadHome("tool: position is not finite".into()));
        }
        let home = self.home * SE3::from_parts(rot, Vector3::from(offset.position));
        let mut keypoints: Vec<Keypoint> =
            self.keypoints.iter().filter(|k| k.name != "tool").cloned().collect();
        keypoints.push(Keypoint {
            name: "tool".into(),
            after: self.dof(),
            position: home.translation().into(),
        });
        Chain::new(&self.name, self.joints.clone(), home, keypoints)
    }

    /// The same chain carrying a payload rigidly attached to the end effector: `payload` is
    /// given in the end-effector frame and joins the mass properties of the last joint's
    /// body (for the rigid-body dynamics).
    ///
    /// # Errors
    /// [`KinematicsError::BadJoint`] for a payload that is not physical (see
    /// [`Inertial::check`]); [`KinematicsError::WrongJointCount`] for a chain without joints.
    pub fn with_payload(&self, payload: &Inertial) -> Result<Chain, KinematicsError> {
        let mut joints = self.joints.clone();
        let Some(last) = joints.last_mut() else {
            return Err(KinematicsError::WrongJointCount { expected: 1, got: 0 });
        };
        payload.check().map_err(|reason| KinematicsError::BadJoint {
            index: self.dof() - 1,
            name: last.name.clone(),
            reason: format!("payload: {reason}"),
        })?;
        let carried = payload.transformed(&self.home);
        last.inertial = Some(last.inertial.unwrap_or(Inertial::ZERO).combined(&carried));
        Chain::new(&self.name, joints, self.home, self.keypoints.clone())
    }

    /// Lower and upper position limits as vectors (`±∞` where absent).
    pub fn position_limits(&self) -> (Vec<f64>, Vec<f64>) {
        (
            self.joints.iter().map(|j| j.limits.lower.unwrap_or(f64::NEG_INFINITY)).collect(),
            self.joints.iter().map(|j| j.limits.upper.unwrap_or(f64::INFINITY)).collect(),
        )
    }
}
