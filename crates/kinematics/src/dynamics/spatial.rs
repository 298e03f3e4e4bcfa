//! Spatial vectors and inertias in one fixed frame (the base), twist order `[v; ω]`.
//!
//! A motion `[v; ω]` is the velocity of the body point at the frame's origin and the angular
//! velocity; a force `[f; n]` is the force and the moment about the origin. Their cross
//! products: `m₁ × m₂ = [ω₁ × v₂ + v₁ × ω₂; ω₁ × ω₂]` and `m ×* f = [ω × f; v × f + ω × n]`.

use nalgebra::{Matrix3, Matrix6, Vector3};

/// A spatial motion or force vector as its linear and angular halves.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub(crate) struct Sv {
    pub(crate) lin: Vector3<f64>,
    pub(crate) ang: Vector3<f64>,
}

impl Sv {
    pub(crate) const ZERO: Sv =
        Sv { lin: Vector3::new(0.0, 0.0, 0.0), ang: Vector3::new(0.0, 0.0, 0.0) };

    pub(crate) fn new(lin: Vector3<f64>, ang: Vector3<f64>) -> Sv {
        Sv { lin, ang }
    }

    /// Motion cross product `self × m`.
    #[inline]
    pub(crate) fn cross_motion(&self, m: &Sv) -> Sv {
        Sv { lin: self.ang.cross(&m.lin) + self.lin.cross(&m.ang), ang: self.ang.cross(&m.ang) }
    }

    /// Force cross product `self ×* f`.
    #[inline]
    pub(crate) fn cross_force(&self, f: &Sv) -> Sv {
        Sv { lin: self.ang.cross(&f.lin), ang: self.lin.cross(&f.lin) + self.ang.cross(&f.ang) }
    }

    /// The pairing of a motion with a force (power).
    #[inline]
    pub(crate) fn dot(&self, f: &Sv) -> f64 {
        self.lin.dot(&f.lin) + self.ang.dot(&f.ang)
    }

    #[inline]
    pub(crate) fn scale(&self, s: f64) -> Sv {
        Sv { lin: self.lin * s, ang: self.ang * s }
    }

    /// As a 6-vector `[lin; ang]`.
    pub(crate) fn to_vector(self) -> nalgebra::Vector6<f64> {
        nalgebra::Vector6::new(
            self.lin.x, self.lin.y, self.lin.z, self.ang.x, self.ang.y, self.ang.z,
        )
    }

    pub(crate) fn from_vector(v: &nalgebra::Vector6<f64>) -> Sv {
        Sv { lin: Vector3::new(v[0], v[1], v[2]), ang: Vector3::new(v[3], v[4], v[5]) }
    }
}

impl core::ops::Add for Sv {
    type Output = Sv;
    #[inline]
    fn add(self, o: Sv) -> Sv {
        Sv { lin: self.lin + o.lin, ang: self.ang + o.ang }
    }
}

impl core::ops::Sub for Sv {
    type Output = Sv;
    #[inline]
    fn sub(self, o: Sv) -> Sv {
        Sv { lin: self.lin - o.lin, ang: self.ang - o.ang }
    }
}

impl core::ops::AddAssign for Sv {
    #[inline]
    fn add_assign(&mut self, o: Sv) {
        self.lin += o.lin;
        self.ang += o.ang;
    }
}

impl core::ops::Neg for Sv {
    type Output = Sv;
    #[inline]
    fn neg(self) -> Sv {
        Sv { lin: -self.lin, ang: -self.ang }
    }
}

/// A rigid body's spatial inertia about the frame's origin: mass `m`, first moment `h = m·c`
/// and the rotational inertia about the origin `Ī = I_c − m·ĉĉ`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct SpatialInertia {
    pub(crate) m: f64,
    pub(crate) h: Vector3<f64>,
    pub(crate) ibar: Matrix3<f64>,
}

impl SpatialInertia {
    pub(crate) const ZERO: SpatialInertia = SpatialInertia {
        m: 0.0,
        h: Vector3::new(0.0, 0.0, 0.0),
        ibar: Matrix3::new(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0),
    };

    /// From mass, centre of mass and the inertia about it (all in this frame).
    pub(crate) fn from_com(m: f64, c: &Vector3<f64>, ic: &Matrix3<f64>) -> SpatialInertia {
        let ch = c.cross_matrix();
        SpatialInertia { m, h: m * c, ibar: ic - m * ch * ch }
    }

    /// `I·m = [m·v − h × ω; h × v + Ī·ω]` (the momentum of motion `m`).
    #[inline]
    pub(crate) fn apply(&self, v: &Sv) -> Sv {
        Sv {
            lin: self.m * v.lin - self.h.cross(&v.ang),
            ang: self.h.cross(&v.lin) + self.ibar * v.ang,
        }
    }

    /// The same body moved rigidly by `(R, p)`.
    #[inline]
    pub(crate) fn moved(
        home_c: &Vector3<f64>,
        home_ic: &Matrix3<f64>,
        m: f64,
        r: &Matrix3<f64>,
        p: &Vector3<f64>,
    ) -> SpatialInertia {
        let c = r * home_c + p;
        SpatialInertia::from_com(m, &c, &(r * home_ic * r.transpose()))
    }

    pub(crate) fn add(&mut self, o: &SpatialInertia) {
        self.m += o.m;
        self.h += o.h;
        self.ibar += o.ibar;
    }

    /// As a 6×6 matrix `[[m·I, −ĥ], [ĥ, Ī]]`.
    pub(crate) fn to_matrix(self) -> Matrix6<f64> {
        let hh = self.h.cross_matrix();
        let mut out = Matrix6::zeros();
        out.fixed_view_mut::<3, 3>(0, 0).copy_from(&(Matrix3::identity() * self.m));
        out.fixed_view_mut::<3, 3>(0, 3).copy_from(&(-hh));
        out.fixed_view_mut::<3, 3>(3, 0).copy_from(&hh);
        out.fixed_view_mut::<3, 3>(3, 3).copy_from(&self.ibar);
        out
    }
}
