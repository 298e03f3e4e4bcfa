//! Rigid-body dynamics of a chain, `M(q)·q̈ + C(q, q̇)·q̇ + g(q) = τ`: inverse dynamics (RNEA),
//! the mass matrix (CRBA), forward dynamics (ABA) and the exact first derivatives of the
//! inverse and forward dynamics.
//!
//! Every algorithm runs in the base frame (the chain's product-of-exponentials form gives
//! each joint's screw there directly): body `i`'s pose is `gᵢ = exp(ξ₁q₁)…exp(ξᵢqᵢ)`, its
//! joint's screw `Sᵢ = Ad(gᵢ₋₁)·ξᵢ`, and its inertia is its home inertia moved by `gᵢ`.
//! Gravity enters as the base's acceleration `a₀ = [−g; 0]`.

mod aba;
mod crba;
mod derivatives;
mod node;
mod rnea;
pub(crate) mod spatial;

use nalgebra::{DMatrix, Matrix3, Matrix6, Vector3};

use crate::{Chain, KinematicsError};
pub use derivatives::DynamicsPartials;
use spatial::{SpatialInertia, Sv};

/// Standard gravity along −z (m/s²), the default of [`RigidBodyModel::new`].
pub const STANDARD_GRAVITY: [f64; 3] = [0.0, 0.0, -9.80665];

/// A body's home mass properties (base frame, `q = 0`).
#[derive(Debug, Clone, PartialEq)]
struct Body {
    mass: f64,
    com: Vector3<f64>,
    inertia: Matrix3<f64>,
}

/// The rigid-body model of a [`Chain`]: its joints and the mass properties of the body each
/// joint moves, plus gravity. Immutable and shareable; the numeric work happens in a
/// [`DynamicsWorkspace`] (one per thread, no allocation per call).
///
/// # Example
/// ```
/// use armature_kinematics::{Inertial, RigidBodyModel, robots};
/// // The seed arm with a 1 kg point mass at the tip of each link.
/// let mut chain = robots::arm7();
/// let mut joints = chain.joints().to_vec();
/// let tips = [[0.0, 0.0, 0.34], [0.3, 0.0, 0.34], [0.3, 0.0, 0.34], [0.55, 0.0, 0.34],
///             [0.55, 0.0, 0.34], [0.7, 0.0, 0.34], [0.7, 0.0, 0.34]];
/// for (j, c) in joints.iter_mut().zip(tips) {
///     j.inertial = Some(Inertial { mass: 1.0, com: c, inertia: [1e-3, 0.0, 0.0, 1e-3, 0.0, 1e-3] });
/// }
/// let chain = armature_kinematics::Chain::new("arm", joints, chain.home(), vec![]).unwrap();
/// let model = RigidBodyModel::new(&chain, [0.0, 0.0, -9.81]).unwrap();
/// let mut ws = model.workspace();
/// let (q, qd) = ([0.1, 0.5, -0.2, -1.0, 0.3, 1.2, 0.0], [0.2; 7]);
/// // Inverse then forward dynamics give back the acceleration.
/// let qdd = [1.0, -0.5, 0.3, 0.0, 2.0, -1.0, 0.5];
/// let mut tau = [0.0; 7];
/// model.rnea(&mut ws, &q, &qd, &qdd, &mut tau).unwrap();
/// let mut back = [0.0; 7];
/// model.aba(&mut ws, &q, &qd, &tau, &mut back).unwrap();
/// for (a, b) in qdd.iter().zip(back) { assert!((a - b).abs() < 1e-9); }
/// ```
#[derive(Debug, Clone)]
pub struct RigidBodyModel {
    chain: Chain,
    bodies: Vec<Body>,
    gravity: Vector3<f64>,
}

/// Scratch and results of the dynamics algorithms for one [`RigidBodyModel`]; made once by
/// [`RigidBodyModel::workspace`] and reused.
#[derive(Debug, Clone)]
pub struct DynamicsWorkspace {
    /// Joint screws in the base frame at the current `q`.
    s: Vec<Sv>,
    /// Body inertias in the base frame at the current `q`.
    inertia: Vec<SpatialInertia>,
    /// Body velocities, accelerations, and forces (RNEA) or bias forces (ABA).
    v: Vec<Sv>,
    a: Vec<Sv>,
    f: Vec<Sv>,
    /// RNEA: each body's momentum `Iᵢ·vᵢ`; ABA: the velocity-product accelerations `vᵢ × Sᵢq̇ᵢ`.
    h: Vec<Sv>,
    /// ABA: articulated inertias, `Uᵢ = IAᵢ·Sᵢ`, `Dᵢ`, `uᵢ`.
    ia: Vec<Matrix6<f64>>,
    u: Vec<Sv>,
    d: Vec<f64>,
    uu: Vec<f64>,
    /// Composite inertias (CRBA) and derivative scratch.
    composite: Vec<SpatialInertia>,
    df: Vec<Sv>,
    /// n×n scratch: the mass matrix and its Cholesky factor.
    mass: DMatrix<f64>,
    scratch: Vec<f64>,
}

impl RigidBodyModel {
    /// The model of `chain` under `gravity` (m/s², base frame; [`STANDARD_GRAVITY`] is the
    /// usual choice).
    ///
    /// # Errors
    /// [`KinematicsError::NoInertial`] naming the first joint (and its link, where known) whose
    /// body has no mass properties; [`KinematicsError::SingularMassMatrix`] if the mass matrix
    /// at `q = 0` is not positive definite (a joint that moves no inertia about its axis);
    /// [`KinematicsError::BadJoint`] for non-finite gravity.
    pub fn new(chain: &Chain, gravity: [f64; 3]) -> Result<RigidBodyModel, KinematicsError> {
        if gravity.iter().any(|g| !g.is_finite()) {
            return Err(KinematicsError::BadGravity(gravity));
        }
        let mut bodies = Vec::with_capacity(chain.dof());
        for j in chain.joints() {
            let Some(i) = j.inertial else {
                return Err(KinematicsError::NoInertial {
                    joint: j.name.clone(),
                    link: j.link.clone(),
                });
            };
            bodies.push(Body {
                mass: i.mass,
                com: Vector3::from(i.com),
                inertia: i.inertia_matrix(),
            });
        }
        let model =
            RigidBodyModel { chain: chain.clone(), bodies, gravity: Vector3::from(gravity) };
        let mut ws = model.workspace();
        let zeros = vec![0.0; chain.dof()];
        model.kinematics(&mut ws, &zeros);
        model.composite_mass_matrix(&mut ws);
        if let Some(index) = ws.factor_mass_matrix() {
            return Err(KinematicsError::SingularMassMatrix {
                joint: chain.joints()[index].name.clone(),
            });
        }
        Ok(model)
    }

    /// The chain.
    pub fn chain(&self) -> &Chain {
        &self.chain
    }

    /// Number of joints.
    pub fn dof(&self) -> usize {
        self.bodies.len()
    }

    /// Gravity (m/s², base frame).
    pub fn gravity(&self) -> [f64; 3] {
        self.gravity.into()
    }

    /// A workspace for this model (allocates once).
    pub fn workspace(&self) -> DynamicsWorkspace {
        let n = self.dof();
        DynamicsWorkspace {
            s: vec![Sv::ZERO; n],
            inertia: vec![SpatialInertia::ZERO; n],
            v: vec![Sv::ZERO; n],
            a: vec![Sv::ZERO; n],
            f: vec![Sv::ZERO; n],
            h: vec![Sv::ZERO; n],
            ia: vec![Matrix6::zeros(); n],
            u: vec![Sv::ZERO; n],
            d: vec![0.0; n],
            uu: vec![0.0; n],
            composite: vec![SpatialInertia::ZERO; n],
            df: vec![Sv::ZERO; n],
            mass: DMatrix::zeros(n, n),
            scratch: vec![0.0; n],
        }
    }

    /// The base's acceleration that stands for gravity.
    fn a0(&self) -> Sv {
        Sv::new(-self.gravity, Vector3::zeros())
    }

    /// Joint screws and body inertias at `q` in the base frame.
    fn kinematics(&self, ws: &mut DynamicsWorkspace, q: &[f64]) {
        let (mut r, mut p) = (Matrix3::identity(), Vector3::zeros());
        for (i, body) in self.bodies.iter().enumerate() {
            let xi = &self.chain.joints()[i].screw;
            let (v, w) = (Vector3::new(xi[0], xi[1], xi[2]), Vector3::new(xi[3], xi[4], xi[5]));
            let rw = r * w;
            ws.s[i] = Sv::new(r * v + p.cross(&rw), rw);
            let (re, te) = self.chain.joint_exp_matrix(i, q[i]);
            p += r * te;
            r *= re;
            ws.inertia[i] = SpatialInertia::moved(&body.com, &body.inertia, body.mass, &r, &p);
        }
    }

    fn check(&self, args: &[&[f64]], outs: &[usize]) -> Result<(), KinematicsError> {
        let n = self.dof();
        for a in args {
            self.chain.check_q(a)?;
        }
        if let Some(&got) = outs.iter().find(|&&len| len != n) {
            return Err(KinematicsError::WrongJointCount { expected: n, got });
        }
        Ok(())
    }

    fn check_square(&self, m: &DMatrix<f64>) -> Result<(), KinematicsError> {
        let n = self.dof();
        if m.nrows() != n || m.ncols() != n {
            return Err(KinematicsError::WrongJointCount {
                expected: n,
                got: m.nrows().max(m.ncols()),
            });
        }
        Ok(())
    }
}

impl DynamicsWorkspace {
    /// Factors `self.mass` in place as `L·Lᵀ` (lower triangle); the index of the first
    /// non-positive pivot if it is not positive definite.
    fn factor_mass_matrix(&mut self) -> Option<usize> {
        let m = &mut self.mass;
        let n = m.nrows();
        for j in 0..n {
            let mut d = m[(j, j)];
            for k in 0..j {
                d -= m[(j, k)] * m[(j, k)];
            }
            if d.is_nan() || d <= 1e-14 * (1.0 + m[(j, j)].abs()) {
                return Some(j);
            }
            let d = d.sqrt();
            m[(j, j)] = d;
            for i in j + 1..n {
                let mut x = m[(i, j)];
                for k in 0..j {
                    x -= m[(i, k)] * m[(j, k)];
                }
                m[(i, j)] = x / d;
            }
        }
        None
    }

    /// Solves `L·Lᵀ·x = b` in place with the factor in `self.mass`.
    fn solve_in_place(&self, b: &mut [f64]) {
        let l = &self.mass;
        let n = b.len();
        for i in 0..n {
            let mut x = b[i];
            for k in 0..i {
                x -= l[(i, k)] * b[k];
            }
            b[i] = x / l[(i, i)];
        }
        for i in (0..n).rev() {
            let mut x = b[i];
            for k in i + 1..n {
                x -= l[(k, i)] * b[k];
            }
            b[i] = x / l[(i, i)];
        }
    }
}
