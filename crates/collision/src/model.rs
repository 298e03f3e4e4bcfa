//! The collision model: capsule links between keypoints, obstacles, and the pairs to check.

use armature_kinematics::{Chain, FkWorkspace};
use armature_lie::SE3;
use nalgebra::{Matrix3xX, Vector3};
use serde::Serialize;

use crate::CollisionError;
use crate::geometry::{Closest, capsule_box, capsule_capsule, capsule_halfspace, capsule_sphere};

/// A capsule around the segment between two keypoints.
#[derive(Debug, Clone, PartialEq)]
pub struct Link {
    /// Name, `start-end` by default (e.g. `shoulder-elbow`).
    pub name: String,
    /// Keypoint index of the segment start.
    pub start: usize,
    /// Keypoint index of the segment end.
    pub end: usize,
    /// Radius (m).
    pub radius: f64,
}

/// The geometry of a static obstacle.
#[derive(Debug, Clone, PartialEq)]
pub enum ObstacleShape {
    /// A ball.
    Sphere {
        /// Centre.
        center: Vector3<f64>,
        /// Radius.
        radius: f64,
    },
    /// A box with its centre pose.
    Box {
        /// Pose of the box centre.
        pose: SE3,
        /// Half side lengths.
        half_extents: Vector3<f64>,
    },
    /// A capsule.
    Capsule {
        /// Segment start.
        a: Vector3<f64>,
        /// Segment end.
        b: Vector3<f64>,
        /// Radius.
        radius: f64,
    },
    /// The half-space `{x : normal·x ≤ offset}` (e.g. the table: `normal = +z`,
    /// `offset` = its height).
    HalfSpace {
        /// Unit normal pointing into free space.
        normal: Vector3<f64>,
        /// Offset along the normal.
        offset: f64,
    },
}

/// A named obstacle.
#[derive(Debug, Clone, PartialEq)]
pub struct Obstacle {
    /// Name.
    pub name: String,
    /// Geometry.
    pub shape: ObstacleShape,
}

/// What a pair is made of.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PairKind {
    /// Two links (self-collision).
    Links(usize, usize),
    /// A link and an obstacle.
    LinkObstacle(usize, usize),
}

/// One checked pair.
#[derive(Debug, Clone, PartialEq)]
pub struct Pair {
    /// What it is made of.
    pub kind: PairKind,
    /// Name of A (a link).
    pub a: String,
    /// Name of B (a link or an obstacle).
    pub b: String,
}

/// Which pairs to check beyond "every link with every obstacle".
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PairOptions {
    /// Check non-adjacent link pairs (adjacent links share a keypoint and always touch).
    pub self_collision: bool,
    /// Pairs to skip, by name (either order).
    pub allowed: Vec<(String, String)>,
    /// Link pairs to add (e.g. adjacent links with a known clearance), by name.
    pub extra: Vec<(String, String)>,
}

/// Distance, witness points and gradient of one pair at one configuration.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PairResult {
    /// Signed surface distance (m), negative when penetrating.
    pub distance: f64,
    /// Witness point on A.
    pub point_a: [f64; 3],
    /// Witness point on B.
    pub point_b: [f64; 3],
    /// ∂distance/∂q (n entries).
    pub gradient: Vec<f64>,
}

/// Capsule links of a chain, obstacles, and the pairs between them.
///
/// # Example
/// ```
/// use armature_collision::CollisionModel;
/// use armature_kinematics::robots;
/// let arm = robots::arm7();
/// let model = CollisionModel::seed_arm7(&arm).unwrap();
/// assert_eq!(model.pairs().len(), 3 + 4);
/// let mut ws = model.workspace(&arm);
/// let r = model.evaluate(&arm, &[0.0; 7], &mut ws, true).unwrap();
/// // The outstretched arm (axis at z = 0.34, radius 0.04) dips 1 cm into the ball at
/// // (0.35, 0, 0.25), r = 0.06: the signed distance is negative.
/// let ball = r.iter().zip(model.pairs()).find(|(_, p)| p.a == "elbow-wrist").unwrap().0;
/// assert!((ball.distance - (0.09 - 0.06 - 0.04)).abs() < 1e-12 && ball.distance < 0.0);
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct CollisionModel {
    links: Vec<Link>,
    obstacles: Vec<Obstacle>,
    pairs: Vec<Pair>,
    n_keypoints: usize,
}

/// Scratch of [`CollisionModel::evaluate`]: FK, keypoint Jacobians and results (no
/// allocation per call).
#[derive(Debug, Clone)]
pub struct CollisionWorkspace {
    pub(crate) fk: FkWorkspace,
    kp: Vec<Vector3<f64>>,
    jac: Vec<Matrix3xX<f64>>,
    results: Vec<PairResult>,
}

/// Whether keypoints `a` and `b` of `chain` are one point of the arm for every `q`: equal,
/// or at one place at `q = 0` (within 1e-9 m) with only revolute joints between them whose
/// axes pass through it (a point on a joint's axis does not move with that joint).
pub(crate) fn same_point(chain: &Chain, a: usize, b: usize) -> bool {
    if a == b {
        return true;
    }
    let (ka, kb) = (&chain.keypoints()[a], &chain.keypoints()[b]);
    let (pa, pb) = (Vector3::from(ka.position), Vector3::from(kb.position));
    if (pa - pb).norm() > 1e-9 {
        return false;
    }
    let (lo, hi) = (ka.after.min(kb.after), ka.after.max(kb.after));
    chain.joints()[lo..hi].iter().all(|j| {
        let s = j.screw_vector();
        let (v, w) = (s.fixed_rows::<3>(0).into_owned(), s.fixed_rows::<3>(3).into_owned());
        // The velocity of the point under the joint's unit twist: zero on a revolute axis.
        j.kind == armature_kinematics::JointKind::Revolute && (v + w.cross(&pa)).norm() < 1e-9
    })
}

impl CollisionModel {
    /// A model for `chain`: links as `(start keypoint, end keypoint, radius)`, obstacles, and
    /// pair options.
    ///
    /// Links are adjacent (and skipped by `self_collision`) when an end of one is the same
    /// point of the arm as an end of the other for every `q`: the same keypoint, or keypoints
    /// at one place at `q = 0` with only revolute joints between them whose axes pass
    /// through it (a URDF's child-link origin on its joint's axis, say).
    ///
    /// # Errors
    /// [`CollisionError`] for an unknown keypoint, a negative or non-finite radius, a
    /// non-unit half-space normal, a bad box, duplicate names, or an unknown name in the
    /// allowed/extra lists.
    pub fn new(
        chain: &Chain,
        links: &[(&str, &str, f64)],
        obstacles: Vec<Obstacle>,
        options: &PairOptions,
    ) -> Result<CollisionModel, CollisionError> {
        let kp = |name: &str| {
            chain.keypoint_index(name).ok_or_else(|| CollisionError::UnknownKeypoint {
                name: name.to_string(),
                valid: chain.keypoint_names().map(str::to_string).collect(),
            })
        };
        let mut ls = Vec::new();
        for &(a, b, r) in links {
            if !(r.is_finite() && r >= 0.0) {
                return Err(CollisionError::Bad(format!(
                    "link {a}-{b}: radius {r} must be finite and ≥ 0"
                )));
            }
            ls.push(Link { name: format!("{a}-{b}"), start: kp(a)?, end: kp(b)?, radius: r });
        }
        for o in &obstacles {
            let bad = |m: String| Err(CollisionError::Bad(format!("obstacle '{}': {m}", o.name)));
            let finite = |v: &Vector3<f64>| v.iter().all(|x| x.is_finite());
            match &o.shape {
                ObstacleShape::Sphere { center, radius }
                | ObstacleShape::Capsule { a: center, radius, .. }
                    if !(radius.is_finite() && *radius >= 0.0 && finite(center)) =>
                {
                    return bad(format!("radius {radius} must be finite and ≥ 0, centre finite"));
                }
                ObstacleShape::Capsule { b, .. } if !finite(b) => {
                    return bad("end point is not finite".into());
                }
                ObstacleShape::Box { half_extents, .. }
                    if !(finite(half_extents) && half_extents.min() > 0.0) =>
                {
                    return bad(format!(
                        "half extents {:?} must be positive",
                        half_extents.as_slice()
                    ));
                }
                ObstacleShape::HalfSpace { normal, offset }
                    if !((normal.norm() - 1.0).abs() < 1e-9 && offset.is_finite()) =>
                {
                    return bad(format!("normal {:?} must be a unit vector", normal.as_slice()));
                }
                _ => {}
            }
        }
        let names: Vec<&str> = ls
            .iter()
            .map(|l| l.name.as_str())
            .chain(obstacles.iter().map(|o| o.name.as_str()))
            .collect();
        for (i, n) in names.iter().enumerate() {
            if names[..i].contains(n) {
                return Err(CollisionError::Bad(format!("duplicate name '{n}'")));
            }
        }
        for (a, b) in options.allowed.iter().chain(&options.extra) {
            for n in [a, b] {
                if !names.contains(&n.as_str()) {
                    return Err(CollisionError::Bad(format!(
                        "unknown link or obstacle '{n}' in the pair list"
                    )));
                }
            }
        }
        let same = |p: &(String, String), a: &str, b: &str| {
            (p.0 == a && p.1 == b) || (p.0 == b && p.1 == a)
        };
        let skip = |a: &str, b: &str| options.allowed.iter().any(|p| same(p, a, b));
        let mut pairs = Vec::new();
        for i in 0..ls.len() {
            for j in i + 1..ls.len() {
                let (a, b) = (&ls[i], &ls[j]);
                let adjacent =
                    [(a.start, b.start), (a.start, b.end), (a.end, b.start), (a.end, b.end)]
                        .iter()
                        .any(|&(p, q)| same_point(chain, p, q));
                let extra = options.extra.iter().any(|p| same(p, &a.name, &b.name));
                if ((options.self_collision && !adjacent) || extra) && !skip(&a.name, &b.name) {
                    pairs.push(Pair {
                        kind: PairKind::Links(i, j),
                        a: a.name.clone(),
                        b: b.name.clone(),
                    });
                }
            }
        }
        for (i, l) in ls.iter().enumerate() {
            for (k, o) in obstacles.iter().enumerate() {
                if !skip(&l.name, &o.name) {
                    pairs.push(Pair {
                        kind: PairKind::LinkObstacle(i, k),
                        a: l.name.clone(),
                        b: o.name.clone(),
                    });
                }
            }
        }
        Ok(CollisionModel { links: ls, obstacles, pairs, n_keypoints: chain.keypoints().len() })
    }

    /// The seed tutorial's collision variant on [`arm7`](armature_kinematics::robots::arm7):
    /// capsules base–shoulder 0.06, shoulder–elbow 0.05, elbow–wrist 0.04, wrist–ee 0.035,
    /// non-adjacent self-collision, and a ball of radius 0.06 at (0.35, 0, 0.25).
    ///
    /// # Errors
    /// If `chain` lacks the seed's keypoints.
    pub fn seed_arm7(chain: &Chain) -> Result<CollisionModel, CollisionError> {
        CollisionModel::new(
            chain,
            &[
                ("base", "shoulder", 0.06),
                ("shoulder", "elbow", 0.05),
                ("elbow", "wrist", 0.04),
                ("wrist", "ee", 0.035),
            ],
            vec![Obstacle {
                name: "sphere".into(),
                shape: ObstacleShape::Sphere {
                    center: Vector3::new(0.35, 0.0, 0.25),
                    radius: 0.06,
                },
            }],
            &PairOptions { self_collision: true, ..PairOptions::default() },
        )
    }

    /// The links.
    pub fn links(&self) -> &[Link] {
        &self.links
    }

    /// The obstacles.
    pub fn obstacles(&self) -> &[Obstacle] {
        &self.obstacles
    }

    /// The checked pairs, in result order.
    pub fn pairs(&self) -> &[Pair] {
        &self.pairs
    }

    /// A workspace for [`evaluate`](Self::evaluate).
    pub fn workspace(&self, chain: &Chain) -> CollisionWorkspace {
        CollisionWorkspace {
            fk: chain.fk_workspace(),
            kp: vec![Vector3::zeros(); self.n_keypoints],
            jac: vec![Matrix3xX::zeros(chain.dof()); self.n_keypoints],
            results: self
                .pairs
                .iter()
                .map(|_| PairResult {
                    distance: 0.0,
                    point_a: [0.0; 3],
                    point_b: [0.0; 3],
                    gradient: vec![0.0; chain.dof()],
                })
                .collect(),
        }
    }

    /// Closest features of pair `k` given keypoint world positions.
    pub fn closest(&self, k: usize, keypoints: &[Vector3<f64>]) -> Closest {
        match self.pairs[k].kind {
            PairKind::Links(i, j) => {
                let (a, b) = (&self.links[i], &self.links[j]);
                capsule_capsule(
                    &keypoints[a.start],
                    &keypoints[a.end],
                    a.radius,
                    &keypoints[b.start],
                    &keypoints[b.end],
                    b.radius,
                )
            }
            PairKind::LinkObstacle(i, o) => {
                let l = &self.links[i];
                let (a0, a1) = (&keypoints[l.start], &keypoints[l.end]);
                match &self.obstacles[o].shape {
                    ObstacleShape::Sphere { center, radius } => {
                        capsule_sphere(a0, a1, l.radius, center, *radius)
                    }
                    ObstacleShape::Capsule { a, b, radius } => {
                        capsule_capsule(a0, a1, l.radius, a, b, *radius)
                    }
                    ObstacleShape::Box { pose, half_extents } => {
                        capsule_box(a0, a1, l.radius, pose, half_extents)
                    }
                    ObstacleShape::HalfSpace { normal, offset } => {
                        capsule_halfspace(a0, a1, l.radius, normal, *offset)
                    }
                }
            }
        }
    }

    /// Distances, witness points and (with `gradients`) exact gradients w.r.t. `q` of every
    /// pair, into the workspace. Allocation-free.
    ///
    /// The gradient is `nᵀ[(1 − s) J(a₀) + s J(a₁) − (1 − t) J(b₀) − t J(b₁)]` with the keypoint
    /// point Jacobians `J` (obstacles are fixed): exact wherever the closest points are
    /// unique; at ties (parallel axes, zero-length capsules) it is the gradient for the
    /// reported witness pair, and where the axes touch it uses the documented fallback normal.
    ///
    /// # Errors
    /// Bad `q` ([`CollisionError::Kinematics`]).
    pub fn evaluate<'w>(
        &self,
        chain: &Chain,
        q: &[f64],
        ws: &'w mut CollisionWorkspace,
        gradients: bool,
    ) -> Result<&'w [PairResult], CollisionError> {
        chain.forward(q, &mut ws.fk).map_err(|e| CollisionError::Kinematics(e.to_string()))?;
        let n = chain.dof();
        if ws.kp.len() != chain.keypoints().len() || ws.results.len() != self.pairs.len() {
            return Err(CollisionError::Bad("workspace belongs to another model or chain".into()));
        }
        let CollisionWorkspace { fk, kp, jac, results } = ws;
        for (k, slot) in kp.iter_mut().enumerate() {
            *slot = fk.keypoint_position(k);
        }
        if gradients {
            for (k, j) in jac.iter_mut().enumerate() {
                let after = chain.keypoints()[k].after;
                fk.point_jacobian(after, &kp[k], j)
                    .map_err(|e| CollisionError::Kinematics(e.to_string()))?;
            }
        }
        for (k, pair) in self.pairs.iter().enumerate() {
            let c = self.closest(k, kp);
            let r = &mut results[k];
            r.distance = c.distance;
            r.point_a = c.point_a.into();
            r.point_b = c.point_b.into();
            if gradients {
                let terms: [(usize, f64); 4] = match pair.kind {
                    PairKind::Links(i, j) => {
                        let (a, b) = (&self.links[i], &self.links[j]);
                        [(a.start, 1.0 - c.s), (a.end, c.s), (b.start, -(1.0 - c.t)), (b.end, -c.t)]
                    }
                    PairKind::LinkObstacle(i, _) => {
                        let a = &self.links[i];
                        [(a.start, 1.0 - c.s), (a.end, c.s), (0, 0.0), (0, 0.0)]
                    }
                };
                for (col, g) in r.gradient.iter_mut().enumerate().take(n) {
                    let mut acc = 0.0;
                    for &(kpi, w) in &terms {
                        if w != 0.0 {
                            acc += w * c.normal.dot(&jac[kpi].column(col));
                        }
                    }
                    *g = acc;
                }
            }
        }
        Ok(results)
    }
}
