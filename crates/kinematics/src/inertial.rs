//! Mass properties of a rigid body: mass, centre of mass and rotational inertia.

use armature_lie::SE3;
use nalgebra::{Matrix3, Vector3};
use serde::{Deserialize, Serialize};

/// The mass properties of one rigid body, as URDF's `<inertial>` gives them: mass `m` (kg),
/// centre of mass `c` (m) and the rotational inertia about the centre of mass,
/// `[ixx, ixy, ixz, iyy, iyz, izz]` (kg·m²), both in one frame (for a joint's body in a
/// [`Chain`](crate::Chain): the base frame at `q = 0`).
///
/// The spatial inertia about the frame's origin, in twist order `[v; ω]`, is
/// `[[m·I, −m·ĉ], [m·ĉ, I_c − m·ĉĉ]]`.
///
/// # Example
/// ```
/// use armature_kinematics::Inertial;
/// let a = Inertial::point(1.0, [1.0, 0.0, 0.0]);
/// let b = Inertial::point(1.0, [-1.0, 0.0, 0.0]);
/// let ab = a.combined(&b);
/// assert_eq!(ab.com, [0.0, 0.0, 0.0]);
/// assert_eq!(ab.inertia, [0.0, 0.0, 0.0, 2.0, 0.0, 2.0]); // two unit masses 1 m from the y and z axes
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Inertial {
    /// Mass (kg).
    pub mass: f64,
    /// Centre of mass (m).
    #[serde(deserialize_with = "crate::exact::array")]
    pub com: [f64; 3],
    /// Rotational inertia about the centre of mass, `[ixx, ixy, ixz, iyy, iyz, izz]` (kg·m²).
    #[serde(deserialize_with = "crate::exact::array")]
    pub inertia: [f64; 6],
}

impl Inertial {
    /// No mass.
    pub const ZERO: Inertial = Inertial { mass: 0.0, com: [0.0; 3], inertia: [0.0; 6] };

    /// A point mass at `com`.
    pub fn point(mass: f64, com: [f64; 3]) -> Inertial {
        Inertial { mass, com, inertia: [0.0; 6] }
    }

    /// The inertia tensor about the centre of mass as a symmetric matrix.
    pub fn inertia_matrix(&self) -> Matrix3<f64> {
        let [xx, xy, xz, yy, yz, zz] = self.inertia;
        Matrix3::new(xx, xy, xz, xy, yy, yz, xz, yz, zz)
    }

    fn from_matrix(mass: f64, com: Vector3<f64>, i: &Matrix3<f64>) -> Inertial {
        let s = 0.5 * (i + i.transpose());
        Inertial {
            mass,
            com: com.into(),
            inertia: [s[(0, 0)], s[(0, 1)], s[(0, 2)], s[(1, 1)], s[(1, 2)], s[(2, 2)]],
        }
    }

    /// The same body seen from another frame: `t` maps this frame's coordinates into the new
    /// one (`x' = R·x + p`), so `c' = R·c + p` and `I_c' = R·I_c·Rᵀ`.
    pub fn transformed(&self, t: &SE3) -> Inertial {
        let r = t.rotation().matrix();
        let c = r * Vector3::from(self.com) + t.translation();
        Inertial::from_matrix(self.mass, c, &(r * self.inertia_matrix() * r.transpose()))
    }

    /// Two bodies rigidly joined (both in the same frame): masses add, the centre of mass is
    /// the weighted mean, inertias move to it by the parallel-axis theorem.
    pub fn combined(&self, other: &Inertial) -> Inertial {
        let m = self.mass + other.mass;
        if m <= 0.0 {
            let i = self.inertia_matrix() + other.inertia_matrix();
            return Inertial::from_matrix(0.0, Vector3::from(self.com), &i);
        }
        let (ca, cb) = (Vector3::from(self.com), Vector3::from(other.com));
        let c = (self.mass * ca + other.mass * cb) / m;
        let shift = |mass: f64, p: Vector3<f64>| {
            let d = p - c;
            mass * (Matrix3::identity() * d.norm_squared() - d * d.transpose())
        };
        let i = self.inertia_matrix()
            + other.inertia_matrix()
            + shift(self.mass, ca)
            + shift(other.mass, cb);
        Inertial::from_matrix(m, c, &i)
    }

    /// Whether the body has neither mass nor rotational inertia.
    pub fn is_zero(&self) -> bool {
        self.mass == 0.0 && self.inertia.iter().all(|&x| x == 0.0)
    }

    /// Why these mass properties are not physical, if they are not: a non-finite entry, a
    /// negative mass, or an inertia tensor that is not positive semi-definite or breaks the
    /// triangle inequality of its principal moments (beyond a relative 1e-9).
    pub fn check(&self) -> Result<(), String> {
        let all = [self.mass].into_iter().chain(self.com).chain(self.inertia);
        if let Some(x) = all.into_iter().find(|x| !x.is_finite()) {
            return Err(format!("mass properties contain {x}"));
        }
        if self.mass < 0.0 {
            return Err(format!("mass {} is negative", self.mass));
        }
        let eig = self.inertia_matrix().symmetric_eigenvalues();
        let scale = eig.iter().fold(0.0f64, |a, &b| a.max(b.abs()));
        let tol = 1e-9 * scale;
        if eig.iter().any(|&l| l < -tol) {
            return Err(format!(
                "inertia tensor {:?} is not positive semi-definite (principal moments {:.3e}, {:.3e}, {:.3e})",
                self.inertia, eig[0], eig[1], eig[2]
            ));
        }
        for k in 0..3 {
            let (a, b, c) = (eig[k], eig[(k + 1) % 3], eig[(k + 2) % 3]);
            if a > b + c + tol {
                return Err(format!(
                    "principal moments {:.3e}, {:.3e}, {:.3e} break the triangle inequality",
                    eig[0], eig[1], eig[2]
                ));
            }
        }
        Ok(())
    }
}
