//! One symbolic node per collision pair: the exact signed distance as an
//! [`ExternalFunction`] of the keypoint positions.

use std::sync::Arc;

use armature_symbolic::{Expr, ExternalFunction};
use nalgebra::Vector3;

use crate::geometry::{capsule_box, capsule_capsule, capsule_halfspace, capsule_sphere};
use crate::model::{CollisionModel, ObstacleShape, PairKind};

/// The signed distance of one pair as a function of the world positions of its capsules'
/// segment endpoints (`a₀, a₁` and, for link pairs, `b₀, b₁`: 6 or 12 inputs), with the
/// exact gradient `[(1 − s) n, s n, −(1 − t) n, −t n]`.
#[derive(Debug, Clone)]
pub struct PairDistance {
    name: String,
    ra: f64,
    other: Other,
}

#[derive(Debug, Clone)]
enum Other {
    Link(f64),
    Obstacle(ObstacleShape),
}

impl ExternalFunction for PairDistance {
    fn name(&self) -> &str {
        &self.name
    }

    fn n_outputs(&self) -> usize {
        1
    }

    fn eval(&self, x: &[f64], values: &mut [f64], jacobian: &mut [f64]) {
        let v = |k: usize| Vector3::new(x[3 * k], x[3 * k + 1], x[3 * k + 2]);
        let (a0, a1) = (v(0), v(1));
        let c = match &self.other {
            Other::Link(rb) => capsule_capsule(&a0, &a1, self.ra, &v(2), &v(3), *rb),
            Other::Obstacle(ObstacleShape::Sphere { center, radius }) => {
                capsule_sphere(&a0, &a1, self.ra, center, *radius)
            }
            Other::Obstacle(ObstacleShape::Capsule { a, b, radius }) => {
                capsule_capsule(&a0, &a1, self.ra, a, b, *radius)
            }
            Other::Obstacle(ObstacleShape::Box { pose, half_extents }) => {
                capsule_box(&a0, &a1, self.ra, pose, half_extents)
            }
            Other::Obstacle(ObstacleShape::HalfSpace { normal, offset }) => {
                capsule_halfspace(&a0, &a1, self.ra, normal, *offset)
            }
        };
        values[0] = c.distance;
        let weights = [1.0 - c.s, c.s, -(1.0 - c.t), -c.t];
        for (k, w) in weights.iter().enumerate().take(x.len() / 3) {
            for i in 0..3 {
                jacobian[3 * k + i] = w * c.normal[i];
            }
        }
    }
}

impl CollisionModel {
    /// One symbolic expression per pair, `(name "a|b", signed distance)`, from the keypoint
    /// world positions (in chain keypoint order, e.g. `SymbolicFk::positions`). A constraint
    /// "every pair keeps distance ≥ 0" is then `d.ge(0.0)` per pair, nodal or `ctcs()`.
    ///
    /// ```
    /// use armature_collision::CollisionModel;
    /// use armature_kinematics::robots;
    /// use armature_symbolic::{Expr, Function};
    /// let arm = robots::arm7();
    /// let model = CollisionModel::seed_arm7(&arm).unwrap();
    /// let angle = Expr::variable("angle", 7);
    /// let fk = arm.symbolic_fk(&angle).unwrap();
    /// let positions: Vec<Expr> = fk.positions.iter().map(|(_, p)| p.clone()).collect();
    /// let d = model.symbolic_distances(&positions);
    /// assert_eq!(d.len(), 7);
    /// let f = Function::compile(&[d[0].1.clone()], &[&[angle]]).unwrap();
    /// assert!(f.jacobian_pattern().nnz() <= 7);
    /// ```
    pub fn symbolic_distances(&self, keypoint_positions: &[Expr]) -> Vec<(String, Expr)> {
        self.pairs()
            .iter()
            .map(|p| {
                let name = format!("{}|{}", p.a, p.b);
                let (f, inputs) = match p.kind {
                    PairKind::Links(i, j) => {
                        let (a, b) = (&self.links()[i], &self.links()[j]);
                        (
                            PairDistance {
                                name: format!("distance[{name}]"),
                                ra: a.radius,
                                other: Other::Link(b.radius),
                            },
                            vec![
                                keypoint_positions[a.start].clone(),
                                keypoint_positions[a.end].clone(),
                                keypoint_positions[b.start].clone(),
                                keypoint_positions[b.end].clone(),
                            ],
                        )
                    }
                    PairKind::LinkObstacle(i, o) => {
                        let a = &self.links()[i];
                        (
                            PairDistance {
                                name: format!("distance[{name}]"),
                                ra: a.radius,
                                other: Other::Obstacle(self.obstacles()[o].shape.clone()),
                            },
                            vec![
                                keypoint_positions[a.start].clone(),
                                keypoint_positions[a.end].clone(),
                            ],
                        )
                    }
                };
                (name, Expr::external(Arc::new(f), &inputs))
            })
            .collect()
    }
}
