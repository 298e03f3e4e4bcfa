//! What the 3D view draws besides the trajectory: the robot's keypoints and links, the
//! obstacles, the table, the waypoints with their tolerances, and the limits the readout
//! divides by. Built from a task's [`Plan`] and stored in the result JSON under `scene`, so
//! `armature view result.json` needs nothing else.

use armature_collision::ObstacleShape;
use armature_lie::SO3;
use serde::{Deserialize, Serialize};

use crate::pipeline::Plan;

/// Radius of the thin capsules drawn between keypoints when the task has no collision links (m).
pub const THIN_LINK_RADIUS: f64 = 0.01;

/// The geometry and limits of a task, as the view reads them.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Scene {
    /// Robot name.
    pub robot: String,
    /// Joints with their limits (the readout's denominators).
    pub joints: Vec<JointLimits>,
    /// Keypoints in chain order: the world position is `frame · [offset; 1]`, with `frame`
    /// the 4×4 series of that name in the trajectory.
    pub keypoints: Vec<SceneKeypoint>,
    /// Capsules between keypoints (the collision links, or thin ones when there are none).
    pub links: Vec<SceneLink>,
    /// Static obstacles.
    pub obstacles: Vec<SceneObstacle>,
    /// The table's height, if the task has one.
    pub table_height: Option<f64>,
    /// Waypoints in order.
    pub waypoints: Vec<SceneWaypoint>,
    /// The end-effector axis the gripper points along, in the end-effector frame (drawn as
    /// the axis of the orientation cones).
    pub tool_axis: [f64; 3],
    /// The collision pairs, in the order of the trajectory's `clearance` series.
    pub clearance: Option<SceneClearance>,
}

/// One joint's name and limits.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct JointLimits {
    /// Joint name.
    pub name: String,
    /// Lower and upper position limit (rad or m).
    pub angle: [f64; 2],
    /// Velocity limit (rad/s or m/s).
    pub velocity: f64,
    /// Torque limit (N·m or N).
    pub torque: f64,
}

/// A keypoint: where its frame is in the trajectory and where it sits in that frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SceneKeypoint {
    /// Keypoint name.
    pub name: String,
    /// Name of its 4×4 frame series (`T_<name>`).
    pub frame: String,
    /// Its position in that frame (its position at `q = 0`).
    pub offset: [f64; 3],
}

/// A capsule around the segment between two keypoints.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SceneLink {
    /// Link name.
    pub name: String,
    /// Index of the start keypoint.
    pub start: usize,
    /// Index of the end keypoint.
    pub end: usize,
    /// Radius (m).
    pub radius: f64,
    /// Whether it is a collision link (otherwise a thin drawing aid).
    pub collision: bool,
}

/// A named obstacle.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SceneObstacle {
    /// Obstacle name.
    pub name: String,
    /// Its geometry.
    #[serde(flatten)]
    pub shape: SceneShape,
}

/// Obstacle geometry (tagged by `kind` in the JSON).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum SceneShape {
    /// A ball.
    Sphere {
        /// Centre (m).
        center: [f64; 3],
        /// Radius (m).
        radius: f64,
    },
    /// A box.
    Box {
        /// Centre (m).
        center: [f64; 3],
        /// Rotation matrix, row-major.
        rotation: [f64; 9],
        /// Half side lengths (m).
        half_extents: [f64; 3],
    },
    /// A capsule.
    Capsule {
        /// Segment start (m).
        a: [f64; 3],
        /// Segment end (m).
        b: [f64; 3],
        /// Radius (m).
        radius: f64,
    },
    /// The half-space `{x : normal·x ≤ offset}`.
    HalfSpace {
        /// Unit normal pointing into free space.
        normal: [f64; 3],
        /// Offset along the normal (m).
        offset: f64,
    },
}

/// A waypoint with its tolerance ball and, where an orientation range covers its node, the
/// tightest such range.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SceneWaypoint {
    /// Waypoint name.
    pub name: String,
    /// Its node.
    pub node: usize,
    /// Position (m).
    pub position: [f64; 3],
    /// Radius of its ball (m).
    pub tolerance: f64,
    /// The orientation constraint at its node, if any.
    pub orientation: Option<SceneOrientation>,
}

/// An orientation tolerance: the rotation stays within `tolerance_deg` of `rotation`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SceneOrientation {
    /// The range's name (`from..to`).
    pub range: String,
    /// Desired rotation, row-major.
    pub rotation: [f64; 9],
    /// Largest rotation angle away from it (degrees).
    pub tolerance_deg: f64,
}

/// The collision pairs and the clearance they keep.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SceneClearance {
    /// Pair names (`a|b`), in the order of the `clearance` series.
    pub pairs: Vec<String>,
    /// Required clearance (m).
    pub margin: f64,
}

fn row_major(m: &nalgebra::Matrix3<f64>) -> [f64; 9] {
    std::array::from_fn(|i| m[(i / 3, i % 3)])
}

fn obstacle(o: &armature_collision::Obstacle) -> SceneObstacle {
    let shape = match &o.shape {
        ObstacleShape::Sphere { center, radius } => {
            SceneShape::Sphere { center: (*center).into(), radius: *radius }
        }
        ObstacleShape::Box { pose, half_extents } => SceneShape::Box {
            center: pose.translation().into(),
            rotation: row_major(&pose.rotation().matrix()),
            half_extents: (*half_extents).into(),
        },
        ObstacleShape::Capsule { a, b, radius } => {
            SceneShape::Capsule { a: (*a).into(), b: (*b).into(), radius: *radius }
        }
        ObstacleShape::HalfSpace { normal, offset } => {
            SceneShape::HalfSpace { normal: (*normal).into(), offset: *offset }
        }
    };
    SceneObstacle { name: o.name.clone(), shape }
}

/// The end-effector axis that points from the previous keypoint towards the end effector at
/// `q = 0` (the gripper's approach axis), as a unit vector of the end-effector frame; `x`
/// when the chain has a single keypoint.
fn tool_axis(plan: &Plan) -> [f64; 3] {
    let chain = &plan.chain;
    let home = chain.home();
    let kp = chain.keypoints();
    let from = match kp.len() {
        0 | 1 => return [1.0, 0.0, 0.0],
        n => nalgebra::Vector3::from(kp[n - 2].position),
    };
    let dir = home.translation() - from;
    let local = home.rotation().matrix().transpose() * dir;
    let best = (0..3).max_by(|&a, &b| local[a].abs().total_cmp(&local[b].abs())).unwrap_or(0);
    let mut axis = [0.0; 3];
    axis[best] = if local[best] < 0.0 { -1.0 } else { 1.0 };
    axis
}

impl Scene {
    /// The scene of a planned task.
    pub fn from_plan(plan: &Plan) -> Scene {
        let chain = &plan.chain;
        let (lo, hi) = chain.position_limits();
        let joints = chain
            .joints()
            .iter()
            .enumerate()
            .map(|(j, joint)| JointLimits {
                name: joint.name.clone(),
                angle: [lo[j], hi[j]],
                velocity: plan.velocity_limit[j],
                torque: plan.torque_limit[j],
            })
            .collect();
        let keypoints = chain
            .keypoints()
            .iter()
            .map(|k| SceneKeypoint {
                name: k.name.clone(),
                frame: format!("T_{}", k.name),
                offset: k.position,
            })
            .collect();
        let links = links(plan);
        Scene {
            robot: chain.name().to_string(),
            joints,
            keypoints,
            links,
            obstacles: plan
                .collision
                .as_ref()
                .map_or_else(Vec::new, |m| m.obstacles().iter().map(obstacle).collect()),
            table_height: plan.table_height,
            waypoints: plan.waypoints.iter().map(|w| waypoint(plan, w)).collect(),
            tool_axis: tool_axis(plan),
            clearance: plan.collision.as_ref().filter(|m| !m.pairs().is_empty()).map(|m| {
                SceneClearance {
                    pairs: m.pairs().iter().map(|p| format!("{}|{}", p.a, p.b)).collect(),
                    margin: plan.margin,
                }
            }),
        }
    }
}

/// The collision links with their radii, then a thin link between each pair of consecutive
/// keypoints that no collision link joins (so the whole chain is drawn).
fn links(plan: &Plan) -> Vec<SceneLink> {
    let kp = plan.chain.keypoints();
    let mut links: Vec<SceneLink> = plan
        .collision
        .as_ref()
        .map_or(&[][..], |m| m.links())
        .iter()
        .map(|l| SceneLink {
            name: l.name.clone(),
            start: l.start,
            end: l.end,
            radius: l.radius,
            collision: true,
        })
        .collect();
    for i in 1..kp.len() {
        let joined = links.iter().any(|l| (l.start.min(l.end), l.start.max(l.end)) == (i - 1, i));
        if !joined {
            links.push(SceneLink {
                name: format!("{}-{}", kp[i - 1].name, kp[i].name),
                start: i - 1,
                end: i,
                radius: THIN_LINK_RADIUS,
                collision: false,
            });
        }
    }
    links
}

fn waypoint(plan: &Plan, w: &crate::pipeline::PlannedWaypoint) -> SceneWaypoint {
    let orientation = plan
        .orientation
        .iter()
        .filter(|o| (o.first..=o.last).contains(&w.node))
        .min_by(|a, b| a.tolerance_deg.total_cmp(&b.tolerance_deg))
        .and_then(|o| {
            let r = SO3::from_quaternion_wxyz(o.quaternion_wxyz).ok()?;
            Some(SceneOrientation {
                range: o.name.clone(),
                rotation: row_major(&r.matrix()),
                tolerance_deg: o.tolerance_deg,
            })
        });
    SceneWaypoint {
        name: w.name.clone(),
        node: w.node,
        position: w.position,
        tolerance: w.tolerance,
        orientation,
    }
}
