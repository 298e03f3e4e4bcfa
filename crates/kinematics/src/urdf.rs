//! URDF import: a serial chain between two links, converted to screw axes and a home pose.

use std::collections::HashMap;

use armature_lie::{SE3, SO3};
use nalgebra::{UnitQuaternion, Vector3};

use crate::{Chain, Inertial, Joint, JointKind, Keypoint, KinematicsError, Limits};

fn origin(p: &urdf_rs::Pose) -> SE3 {
    let [r, pi, y] = p.rpy.0;
    SE3::from_parts(SO3::from(UnitQuaternion::from_euler_angles(r, pi, y)), Vector3::from(p.xyz.0))
}

fn err(msg: impl Into<String>) -> KinematicsError {
    KinematicsError::Urdf(msg.into())
}

/// Builds a chain from URDF text: the joints on the path from link `base` to link `tip`
/// (revolute, continuous, prismatic; fixed joints fold into the geometry), with the home pose
/// of `tip` as end effector and keypoints at `keypoint_links` (default: `base`, the child
/// link of every movable joint, and `tip`), named after the links.
///
/// Limits: URDF cannot tell a missing `<limit>` from zeros, so a revolute/prismatic joint with
/// `lower = upper = 0` gets no position limits, and zero velocity/effort mean absent;
/// continuous joints have no position limits.
///
/// # Errors
/// [`KinematicsError::Urdf`] for malformed XML, a missing link, a tip not below the base, a
/// keypoint link off the base→tip path, a floating/planar/spherical joint on the path, or a
/// zero joint axis.
pub fn chain_from_urdf_str(
    xml: &str,
    base: &str,
    tip: &str,
    keypoint_links: Option<&[&str]>,
) -> Result<Chain, KinematicsError> {
    let robot = parse_urdf(xml).map_err(|e| err(format!("malformed URDF: {e}")))?;
    check_tree(&robot)?;
    for l in [base, tip] {
        if !robot.links.iter().any(|k| k.name == l) {
            let names: Vec<&str> = robot.links.iter().map(|k| k.name.as_str()).collect();
            return Err(err(format!("no link named '{l}' (links: {})", names.join(", "))));
        }
    }
    let by_child: HashMap<&str, &urdf_rs::Joint> =
        robot.joints.iter().map(|j| (j.child.link.as_str(), j)).collect();
    // Walk up from the tip to the base.
    let mut path = Vec::new();
    let mut link = tip;
    while link != base {
        if path.len() > robot.joints.len() {
            return Err(err(format!("the joints form a loop through link '{link}'")));
        }
        match by_child.get(link) {
            Some(j) => {
                path.push(*j);
                link = j.parent.link.as_str();
            }
            None => {
                return Err(err(format!(
                    "link '{tip}' is not below link '{base}' (walking up from the tip ends at '{link}')"
                )));
            }
        }
    }
    path.reverse();
    // Links on the path, each with the movable-joint count before it and its home frame.
    let mut t = SE3::identity();
    let mut joints = Vec::new();
    let mut links: Vec<(String, usize, SE3)> = vec![(base.to_string(), 0, t)];
    for j in &path {
        let frame = t * origin(&j.origin);
        let kind = match j.joint_type {
            urdf_rs::JointType::Revolute | urdf_rs::JointType::Continuous => {
                Some(JointKind::Revolute)
            }
            urdf_rs::JointType::Prismatic => Some(JointKind::Prismatic),
            urdf_rs::JointType::Fixed => None,
            ref other => {
                return Err(err(format!(
                    "joint '{}' is {other:?}: only revolute, continuous, prismatic and fixed joints are supported",
                    j.name
                )));
            }
        };
        if let Some(kind) = kind {
            let a = Vector3::from(j.axis.xyz.0);
            if a.norm() < 1e-12 {
                return Err(err(format!("joint '{}' has a zero axis", j.name)));
            }
            let axis = frame.act_vector(&a.normalize());
            let l = &j.limit;
            let continuous = j.joint_type == urdf_rs::JointType::Continuous;
            let has_pos = !(continuous || (l.lower == 0.0 && l.upper == 0.0));
            let limits = Limits {
                lower: has_pos.then_some(l.lower),
                upper: has_pos.then_some(l.upper),
                velocity: (l.velocity > 0.0).then_some(l.velocity),
                effort: (l.effort > 0.0).then_some(l.effort),
            };
            let mut joint = match kind {
                JointKind::Revolute => {
                    Joint::revolute(&j.name, axis.into(), frame.translation().into(), limits)
                }
                JointKind::Prismatic => Joint::prismatic(&j.name, axis.into(), limits),
            };
            joint.link = Some(j.child.link.clone());
            joints.push(joint);
        }
        t = frame;
        links.push((j.child.link.clone(), joints.len(), t));
        if let Some(body) = joints.last_mut() {
            let on_path = |name: &str| path.iter().any(|p| p.child.link == name);
            let mass = carried_mass(&robot, &j.child.link, &frame, &on_path);
            let sum = body.inertial.unwrap_or(Inertial::ZERO).combined(&mass);
            body.inertial = (!sum.is_zero()).then_some(sum);
        }
    }
    let wanted: Vec<String> = match keypoint_links {
        Some(v) => v.iter().map(|s| s.to_string()).collect(),
        None => {
            let mut v = vec![base.to_string()];
            for j in &path {
                if j.joint_type != urdf_rs::JointType::Fixed {
                    v.push(j.child.link.clone());
                }
            }
            if v.last().map(String::as_str) != Some(tip) {
                v.push(tip.to_string());
            }
            v
        }
    };
    let mut keypoints = Vec::new();
    for w in &wanted {
        let (_, after, frame) = links.iter().find(|(n, _, _)| n == w).ok_or_else(|| {
            if robot.links.iter().any(|l| &l.name == w) {
                let names: Vec<&str> = links.iter().map(|(n, _, _)| n.as_str()).collect();
                err(format!(
                    "keypoint link '{w}' is not on the path {base} → {tip} (it is on another branch; the path's links: {})",
                    names.join(", ")
                ))
            } else {
                let names: Vec<&str> = links.iter().map(|(n, _, _)| n.as_str()).collect();
                err(format!(
                    "no link named '{w}' for a keypoint (links on the path {base} → {tip}: {})",
                    names.join(", ")
                ))
            }
        })?;
        keypoints.push(Keypoint {
            name: w.clone(),
            after: *after,
            position: frame.translation().into(),
        });
    }
    keypoints.sort_by_key(|k| k.after);
    Chain::new(&robot.name, joints, t, keypoints)
}

/// The mass properties (base frame at `q = 0`) of link `name`, at home pose `frame`, and of
/// every link hanging below it through fixed joints off the path (a flange, a camera).
fn carried_mass(
    robot: &urdf_rs::Robot,
    name: &str,
    frame: &SE3,
    on_path: &dyn Fn(&str) -> bool,
) -> Inertial {
    let mut total = Inertial::ZERO;
    // An explicit stack: the tree check ran first, so the walk ends.
    let mut stack = vec![(name.to_string(), *frame)];
    while let Some((link, frame)) = stack.pop() {
        if let Some(l) = robot.links.iter().find(|l| l.name == link) {
            let i = &l.inertial;
            let local = Inertial {
                mass: i.mass.value,
                com: [0.0; 3],
                inertia: [
                    i.inertia.ixx,
                    i.inertia.ixy,
                    i.inertia.ixz,
                    i.inertia.iyy,
                    i.inertia.iyz,
                    i.inertia.izz,
                ],
            };
            if !local.is_zero() {
                total = total.combined(&local.transformed(&(frame * origin(&i.origin))));
            }
        }
        for j in &robot.joints {
            if j.parent.link == link
                && j.joint_type == urdf_rs::JointType::Fixed
                && !on_path(&j.child.link)
            {
                stack.push((j.child.link.clone(), frame * origin(&j.origin)));
            }
        }
    }
    total
}

/// [`chain_from_urdf_str`] on a file.
///
/// # Errors
/// As [`chain_from_urdf_str`], plus [`KinematicsError::File`] if the file cannot be read.
pub fn chain_from_urdf_file(
    path: &std::path::Path,
    base: &str,
    tip: &str,
    keypoint_links: Option<&[&str]>,
) -> Result<Chain, KinematicsError> {
    let xml = crate::read_text_file(path).map_err(|e| {
        let (location, message) = crate::located_read_error(&path.display().to_string(), &e);
        KinematicsError::File { location, message }
    })?;
    chain_from_urdf_str(&xml, base, tip, keypoint_links)
}

/// The URDF's links and joints form a tree: names are unique, every joint joins two known,
/// different links, and no link has two parent joints. (A loop is then found by the walk.)
///
/// # Errors
/// [`KinematicsError::Urdf`] naming the first offending link or joint.
pub(crate) fn check_tree(robot: &urdf_rs::Robot) -> Result<(), KinematicsError> {
    let mut links = std::collections::HashSet::new();
    for l in &robot.links {
        if !links.insert(l.name.as_str()) {
            return Err(err(format!("link '{}' is defined twice", l.name)));
        }
    }
    let mut joints = std::collections::HashSet::new();
    let mut parent_of: HashMap<&str, &str> = HashMap::new();
    for j in &robot.joints {
        let (parent, child) = (j.parent.link.as_str(), j.child.link.as_str());
        if !joints.insert(j.name.as_str()) {
            return Err(err(format!("joint '{}' is defined twice", j.name)));
        }
        if parent == child {
            return Err(err(format!("joint '{}' joins link '{parent}' to itself", j.name)));
        }
        for l in [parent, child] {
            if !links.contains(l) {
                return Err(err(format!("joint '{}' names no link '{l}'", j.name)));
            }
        }
        if let Some(other) = parent_of.insert(child, j.name.as_str()) {
            return Err(err(format!(
                "link '{child}' has two parent joints ('{other}' and '{}')",
                j.name
            )));
        }
    }
    Ok(())
}

/// Parses URDF text. The XML parser underneath panics on some malformed documents (an
/// attribute with an unbound namespace prefix beside a default namespace, found by fuzzing): such a panic is caught and
/// reported as a malformed document, without the panic message on standard error.
///
/// # Errors
/// What is wrong with the document.
pub(crate) fn parse_urdf(xml: &str) -> Result<urdf_rs::Robot, String> {
    static HOOK: std::sync::Mutex<()> = std::sync::Mutex::new(());
    let _guard = HOOK.lock().unwrap_or_else(std::sync::PoisonError::into_inner);
    let previous = std::panic::take_hook();
    std::panic::set_hook(Box::new(|_| {}));
    let parsed = std::panic::catch_unwind(|| urdf_rs::read_from_string(xml));
    std::panic::set_hook(previous);
    match parsed {
        Ok(r) => r.map_err(|e| e.to_string()),
        Err(_) => Err("the XML parser rejected the document (e.g. an attribute with an empty namespace prefix)".into()),
    }
}
