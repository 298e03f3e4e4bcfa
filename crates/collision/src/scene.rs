//! Scene files: capsule links, obstacles and pair options in TOML.

use armature_kinematics::Chain;
use armature_lie::{SE3, SO3};
use nalgebra::Vector3;
use serde::Deserialize;

use crate::{CollisionError, CollisionModel, Obstacle, ObstacleShape, PairOptions};

/// A scene file:
///
/// ```toml
/// self_collision = true               # default true
/// allowed = [["base-shoulder", "ball"]]
///
/// [[links]]
/// start = "base"
/// end = "shoulder"
/// radius = 0.06
///
/// [[obstacles]]
/// name = "ball"
/// sphere = { center = [0.35, 0.0, 0.25], radius = 0.06 }
/// # or: box = { center = [...], quaternion_wxyz = [...], half_extents = [...] }
/// #     capsule = { a = [...], b = [...], radius = ... }
/// #     halfspace = { normal = [0, 0, 1], offset = 0.0 }
/// ```
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    /// Check non-adjacent link pairs.
    #[serde(default = "yes")]
    pub self_collision: bool,
    /// Pairs to skip.
    #[serde(default)]
    pub allowed: Vec<(String, String)>,
    /// Link pairs to add.
    #[serde(default)]
    pub extra: Vec<(String, String)>,
    /// Capsule links.
    #[serde(default)]
    pub links: Vec<LinkSpec>,
    /// Obstacles.
    #[serde(default)]
    pub obstacles: Vec<ObstacleSpec>,
}

fn yes() -> bool {
    true
}

/// A capsule link in a scene file.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LinkSpec {
    /// Start keypoint.
    pub start: String,
    /// End keypoint.
    pub end: String,
    /// Radius (m).
    pub radius: f64,
}

/// An obstacle in a scene file: a name and exactly one shape.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObstacleSpec {
    /// Name.
    pub name: String,
    /// A ball.
    pub sphere: Option<SphereSpec>,
    /// A box.
    #[serde(rename = "box")]
    pub cuboid: Option<BoxSpec>,
    /// A capsule.
    pub capsule: Option<CapsuleSpec>,
    /// A half-space.
    pub halfspace: Option<HalfSpaceSpec>,
}

/// Ball data.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SphereSpec {
    /// Centre.
    #[serde(deserialize_with = "armature_kinematics::exact::array")]
    pub center: [f64; 3],
    /// Radius.
    pub radius: f64,
}

/// Box data.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BoxSpec {
    /// Centre.
    #[serde(deserialize_with = "armature_kinematics::exact::array")]
    pub center: [f64; 3],
    /// Orientation `[w, x, y, z]` (default identity).
    #[serde(default = "identity")]
    #[serde(deserialize_with = "armature_kinematics::exact::array")]
    pub quaternion_wxyz: [f64; 4],
    /// Half side lengths.
    #[serde(deserialize_with = "armature_kinematics::exact::array")]
    pub half_extents: [f64; 3],
}

fn identity() -> [f64; 4] {
    [1.0, 0.0, 0.0, 0.0]
}

/// Capsule data.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CapsuleSpec {
    /// Segment start.
    #[serde(deserialize_with = "armature_kinematics::exact::array")]
    pub a: [f64; 3],
    /// Segment end.
    #[serde(deserialize_with = "armature_kinematics::exact::array")]
    pub b: [f64; 3],
    /// Radius.
    pub radius: f64,
}

/// Half-space data: free space is `normal·x ≥ offset`.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HalfSpaceSpec {
    /// Unit normal into free space.
    #[serde(deserialize_with = "armature_kinematics::exact::array")]
    pub normal: [f64; 3],
    /// Offset along the normal.
    pub offset: f64,
}

impl Scene {
    /// Builds the collision model for `chain`.
    ///
    /// # Errors
    /// As [`CollisionModel::new`]; an obstacle with zero or several shapes; a bad quaternion.
    pub fn model(&self, chain: &Chain) -> Result<CollisionModel, CollisionError> {
        let links: Vec<(&str, &str, f64)> =
            self.links.iter().map(|l| (l.start.as_str(), l.end.as_str(), l.radius)).collect();
        let mut obstacles = Vec::new();
        for o in &self.obstacles {
            let bad = |m: &str| CollisionError::Bad(format!("obstacle '{}': {m}", o.name));
            let count = [
                o.sphere.is_some(),
                o.cuboid.is_some(),
                o.capsule.is_some(),
                o.halfspace.is_some(),
            ]
            .iter()
            .filter(|x| **x)
            .count();
            if count != 1 {
                return Err(bad("give exactly one of sphere, box, capsule, halfspace"));
            }
            let shape = if let Some(s) = &o.sphere {
                ObstacleShape::Sphere { center: s.center.into(), radius: s.radius }
            } else if let Some(b) = &o.cuboid {
                let r = SO3::from_quaternion_wxyz(b.quaternion_wxyz)
                    .map_err(|e| bad(&e.to_string()))?;
                ObstacleShape::Box {
                    pose: SE3::from_parts(r, Vector3::from(b.center)),
                    half_extents: b.half_extents.into(),
                }
            } else if let Some(c) = &o.capsule {
                ObstacleShape::Capsule { a: c.a.into(), b: c.b.into(), radius: c.radius }
            } else {
                let h = o.halfspace.as_ref().expect("counted");
                ObstacleShape::HalfSpace { normal: h.normal.into(), offset: h.offset }
            };
            obstacles.push(Obstacle { name: o.name.clone(), shape });
        }
        let options = PairOptions {
            self_collision: self.self_collision,
            allowed: self.allowed.clone(),
            extra: self.extra.clone(),
        };
        CollisionModel::new(chain, &links, obstacles, &options)
    }
}

/// Parses a scene file; `origin` names it in error locations (`origin:line:col`).
///
/// # Errors
/// [`CollisionError::File`] for syntax, unknown keys and wrong types.
pub fn scene_from_toml_str(text: &str, origin: &str) -> Result<Scene, CollisionError> {
    toml::from_str(text).map_err(|e| {
        let location = match e.span() {
            Some(s) => {
                let before = &text[..s.start];
                let line = before.matches('\n').count() + 1;
                let col = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
                format!("{origin}:{line}:{col}")
            }
            None => origin.to_string(),
        };
        CollisionError::File { location, message: e.message().to_string() }
    })
}
