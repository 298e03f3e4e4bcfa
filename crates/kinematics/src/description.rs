//! Robot description files: a TOML screw table, and one entry point for every robot source.

use std::path::Path;

use serde::Deserialize;
use toml::Spanned;

use crate::chain::{ChainData, Keypoint, Pose};
use crate::{Chain, Joint, KinematicsError};

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ChainFile {
    name: String,
    joints: Vec<Spanned<Joint>>,
    home: Pose,
    #[serde(default)]
    keypoints: Vec<Spanned<Keypoint>>,
}

/// `line:col` (1-based) of a byte offset.
fn line_col(text: &str, offset: usize) -> String {
    let before = &text[..offset.min(text.len())];
    let line = before.matches('\n').count() + 1;
    let col = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    format!("{line}:{col}")
}

/// Parses a TOML screw table (the layout of [`ChainData`]):
///
/// ```toml
/// name = "two-link"
/// home = { position = [0.5, 0.0, 0.0] }          # quaternion_wxyz defaults to identity
///
/// [[joints]]
/// name = "j1"
/// kind = "revolute"
/// screw = [0.0, 0.0, 0.0, 0.0, 0.0, 1.0]         # [v; ω] in the base frame at q = 0
/// limits = { lower = -3.0, upper = 3.0, velocity = 2.0, effort = 10.0 }
///
/// [[keypoints]]
/// name = "tip"
/// after = 1
/// position = [0.5, 0.0, 0.0]
/// ```
///
/// `origin` names the source in error locations (`origin:line:col`).
///
/// # Errors
/// [`KinematicsError::File`] with `origin:line:col` for TOML syntax, unknown keys, wrong types
/// and invalid joints or keypoints (located at the offending table).
pub fn chain_from_toml_str(text: &str, origin: &str) -> Result<Chain, KinematicsError> {
    let file: ChainFile = toml::from_str(text).map_err(|e| KinematicsError::File {
        location: match e.span() {
            Some(s) => format!("{origin}:{}", line_col(text, s.start)),
            None => origin.to_string(),
        },
        message: e.message().to_string(),
    })?;
    let joint_spans: Vec<usize> = file.joints.iter().map(|j| j.span().start).collect();
    let keypoint_spans: Vec<(String, usize)> =
        file.keypoints.iter().map(|k| (k.get_ref().name.clone(), k.span().start)).collect();
    let data = ChainData {
        name: file.name,
        joints: file.joints.into_iter().map(Spanned::into_inner).collect(),
        home: file.home,
        keypoints: file.keypoints.into_iter().map(Spanned::into_inner).collect(),
    };
    Chain::try_from(data).map_err(|e| {
        let at = match &e {
            KinematicsError::BadJoint { index, .. } => joint_spans.get(*index).copied(),
            KinematicsError::BadKeypoint { name, .. }
            | KinematicsError::DuplicateName { name, .. } => {
                keypoint_spans.iter().find(|(n, _)| n == name).map(|(_, s)| *s)
            }
            _ => None,
        };
        KinematicsError::File {
            location: match at {
                Some(s) => format!("{origin}:{}", line_col(text, s)),
                None => origin.to_string(),
            },
            message: e.to_string(),
        }
    })
}

/// Which part of a robot description to load: for a URDF, the base and tip links (default:
/// the root link and the single leaf) and the links to put keypoints at (default: the base,
/// the child link of every movable joint, and the tip).
#[derive(Debug, Clone, Copy, Default)]
pub struct LoadOptions<'a> {
    /// URDF base link.
    pub base: Option<&'a str>,
    /// URDF tip link.
    pub tip: Option<&'a str>,
    /// URDF links to put keypoints at (on the base → tip path), named after them.
    pub keypoint_links: Option<&'a [&'a str]>,
}

/// [`load_robot_with`] with default keypoints.
///
/// # Errors
/// As [`load_robot_with`].
pub fn load_robot(
    spec: &str,
    base: Option<&str>,
    tip: Option<&str>,
) -> Result<Chain, KinematicsError> {
    load_robot_with(spec, &LoadOptions { base, tip, keypoint_links: None })
}

/// Loads a robot from a built-in name (`arm7`, `ur5e`), a `.toml` screw table, or a `.urdf`
/// file (with `base` and `tip` links; by default the URDF's root link and its single leaf).
///
/// # Errors
/// [`KinematicsError::UnknownRobot`], [`KinematicsError::File`], [`KinematicsError::Urdf`];
/// [`KinematicsError::BaseTipNotUrdf`] for URDF options given to another kind of robot.
pub fn load_robot_with(spec: &str, options: &LoadOptions<'_>) -> Result<Chain, KinematicsError> {
    let LoadOptions { base, tip, keypoint_links } = *options;
    let path = Path::new(spec);
    let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    if ext.as_deref() != Some("urdf")
        && (base.is_some() || tip.is_some() || keypoint_links.is_some())
    {
        return Err(KinematicsError::BaseTipNotUrdf(spec.to_string()));
    }
    let read = || {
        crate::read_text_file(path).map_err(|e| {
            let (location, message) = crate::located_read_error(spec, &e);
            KinematicsError::File { location, message }
        })
    };
    match ext.as_deref() {
        Some("toml") => chain_from_toml_str(&read()?, spec),
        Some("urdf") => {
            let xml = read()?;
            let robot = crate::urdf::parse_urdf(&xml)
                .map_err(|e| KinematicsError::Urdf(format!("malformed URDF {spec}: {e}")))?;
            crate::urdf::check_tree(&robot)?;
            let children: Vec<&str> = robot.joints.iter().map(|j| j.child.link.as_str()).collect();
            let parents: Vec<&str> = robot.joints.iter().map(|j| j.parent.link.as_str()).collect();
            let root = robot.links.iter().map(|l| l.name.as_str()).find(|l| !children.contains(l));
            let leaves: Vec<&str> = robot
                .links
                .iter()
                .map(|l| l.name.as_str())
                .filter(|l| !parents.contains(l))
                .collect();
            let base = match (base, root) {
                (Some(b), _) => b,
                (None, Some(r)) => r,
                (None, None) => {
                    return Err(KinematicsError::NoRootLink);
                }
            };
            let tip = match (tip, leaves.as_slice()) {
                (Some(t), _) => t,
                (None, [one]) => one,
                (None, many) => {
                    let leaves = many.iter().map(|l| l.to_string()).collect();
                    return Err(KinematicsError::AmbiguousTip { leaves });
                }
            };
            crate::urdf::chain_from_urdf_str(&xml, base, tip, keypoint_links)
        }
        _ if !spec.contains('.') && !spec.contains('/') => crate::robots::builtin(spec),
        _ => Err(KinematicsError::UnknownRobot(spec.to_string())),
    }
}
