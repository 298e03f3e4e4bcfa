//! Numeric forward kinematics: all keypoint frames, the end effector and the Jacobians in
//! one pass over the joints, into a caller-owned workspace.

use armature_lie::{SE3, SO3};
use nalgebra::{Matrix3, Matrix3xX, Matrix6xX, Vector3};

use crate::{Chain, KinematicsError};

/// Results and scratch of [`Chain::forward`]; create once per chain with
/// [`Chain::fk_workspace`] and reuse (no allocation per call).
#[derive(Debug, Clone)]
pub struct FkWorkspace {
    /// `partial[i] = exp(ξ₁q₁)·…·exp(ξᵢqᵢ)` as (R, t), `partial[0] = I`.
    partial: Vec<(Matrix3<f64>, Vector3<f64>)>,
    keypoint_positions: Vec<Vector3<f64>>,
    ee: (Matrix3<f64>, Vector3<f64>),
    space_jacobian: Matrix6xX<f64>,
}

fn to_se3(rt: &(Matrix3<f64>, Vector3<f64>)) -> SE3 {
    SE3::from_parts(SO3::from_matrix_unchecked(&rt.0), rt.1)
}

impl FkWorkspace {
    /// The accumulated product of the first `i` joint exponentials (the seed's snapshot
    /// `T_chain` after `i` joints).
    pub fn partial(&self, i: usize) -> SE3 {
        to_se3(&self.partial[i])
    }

    /// [`partial`](Self::partial) as rotation matrix and translation (no conversion).
    pub fn partial_matrix(&self, i: usize) -> (Matrix3<f64>, Vector3<f64>) {
        self.partial[i]
    }

    /// Frame of keypoint `k`: the partial product after its joints (as the seed snapshots it).
    pub fn keypoint_frame(&self, chain: &Chain, k: usize) -> SE3 {
        self.partial(chain.keypoints()[k].after)
    }

    /// World position of keypoint `k`.
    pub fn keypoint_position(&self, k: usize) -> Vector3<f64> {
        self.keypoint_positions[k]
    }

    /// End-effector pose `T_ee(q)`.
    pub fn ee(&self) -> SE3 {
        to_se3(&self.ee)
    }

    /// [`ee`](Self::ee) as rotation matrix and translation (no conversion).
    pub fn ee_matrix(&self) -> (Matrix3<f64>, Vector3<f64>) {
        self.ee
    }

    /// Space Jacobian of the end effector (6×n, twist rows `[v; ω]` in the base frame):
    /// column `i` is `Ad(partial(i)) ξᵢ`.
    pub fn space_jacobian(&self) -> &Matrix6xX<f64> {
        &self.space_jacobian
    }

    /// Body Jacobian `Ad(T_ee⁻¹) J_s` (twists in the end-effector frame) into `out` (6×n).
    ///
    /// # Errors
    /// [`KinematicsError::WrongJointCount`] if `out` does not have n columns.
    pub fn body_jacobian(&self, out: &mut Matrix6xX<f64>) -> Result<(), KinematicsError> {
        if out.ncols() != self.space_jacobian.ncols() {
            return Err(KinematicsError::WrongJointCount {
                expected: self.space_jacobian.ncols(),
                got: out.ncols(),
            });
        }
        let ad = self.ee().inverse().adjoint();
        // Column by column with fixed-size products: a dynamic gemm would allocate a buffer.
        for i in 0..out.ncols() {
            let col: nalgebra::Vector6<f64> = ad * self.space_jacobian.fixed_view::<6, 1>(0, i);
            out.set_column(i, &col);
        }
        Ok(())
    }

    /// Jacobian (3×n) of the world point `p` rigidly attached to the frame after `after`
    /// joints: column `i < after` is `ωᵢ' × p + vᵢ'` for the space twist `[vᵢ'; ωᵢ']`, the
    /// rest are zero.
    ///
    /// # Errors
    /// [`KinematicsError::WrongJointCount`] if `out` does not have n columns or `after > n`.
    pub fn point_jacobian(
        &self,
        after: usize,
        p: &Vector3<f64>,
        out: &mut Matrix3xX<f64>,
    ) -> Result<(), KinematicsError> {
        let n = self.space_jacobian.ncols();
        if out.ncols() != n || after > n {
            return Err(KinematicsError::WrongJointCount {
                expected: n,
                got: out.ncols().min(after),
            });
        }
        for i in 0..n {
            let col = if i < after {
                let c = self.space_jacobian.column(i);
                let (v, w) = (Vector3::new(c[0], c[1], c[2]), Vector3::new(c[3], c[4], c[5]));
                w.cross(p) + v
            } else {
                Vector3::zeros()
            };
            out.set_column(i, &col);
        }
        Ok(())
    }

    /// World position of a point given by its home (q = 0) position on the link after
    /// `after` joints.
    pub fn point_on_link(&self, after: usize, home_position: &Vector3<f64>) -> Vector3<f64> {
        let (r, t) = &self.partial[after];
        r * home_position + t
    }
}

impl Chain {
    /// A workspace for [`forward`](Self::forward) (allocates once).
    pub fn fk_workspace(&self) -> FkWorkspace {
        let n = self.dof();
        FkWorkspace {
            partial: vec![(Matrix3::identity(), Vector3::zeros()); n + 1],
            keypoint_positions: vec![Vector3::zeros(); self.keypoints().len()],
            ee: (Matrix3::identity(), Vector3::zeros()),
            space_jacobian: Matrix6xX::zeros(n),
        }
    }

    /// `exp(ξᵢ q)` of joint `i` as (R, t): one `sin_cos` and precomputed `W = ω^`, `W²`:
    /// `R = I + sin q·W + (1 − cos q)·W²`, `t = (I − R)·p⊥ + h·q·ω` with `p⊥ = ω × v` the
    /// axis point nearest the origin and pitch `h = ω·v`; a translation for prismatic joints.
    #[inline]
    pub fn joint_exp_matrix(&self, i: usize, q: f64) -> (Matrix3<f64>, Vector3<f64>) {
        let d = &self.exp_data[i];
        if d.prismatic {
            return (Matrix3::identity(), d.v * q);
        }
        let (s, c) = q.sin_cos();
        let r = Matrix3::identity() + d.wh * s + d.wh2 * (1.0 - c);
        let t = d.p - r * d.p + d.w * (d.h * q);
        (r, t)
    }

    /// `exp(ξᵢ q)` of joint `i` as an [`SE3`].
    pub fn joint_exp(&self, i: usize, q: f64) -> SE3 {
        to_se3(&self.joint_exp_matrix(i, q))
    }

    /// Forward kinematics of every keypoint, the end effector and the space Jacobian, in one
    /// pass over the joints. Allocation-free.
    ///
    /// # Errors
    /// [`KinematicsError::WrongJointCount`] / [`KinematicsError::NonFiniteJoint`] for bad `q`;
    /// a workspace from another chain is reported as a wrong joint count.
    ///
    /// ```
    /// use armature_kinematics::robots;
    /// let arm = robots::arm7();
    /// let mut ws = arm.fk_workspace();
    /// arm.forward(&[0.0; 7], &mut ws).unwrap();
    /// assert!((ws.ee().translation() - nalgebra::Vector3::new(0.7, 0.0, 0.34)).norm() < 1e-15);
    /// ```
    pub fn forward(&self, q: &[f64], ws: &mut FkWorkspace) -> Result<(), KinematicsError> {
        self.forward_impl::<true>(q, ws)
    }

    /// Like [`forward`](Self::forward) but only the end effector and the space Jacobian:
    /// keypoint positions and partial frames are left as they were (the IK inner loop).
    ///
    /// # Errors
    /// As [`forward`](Self::forward).
    pub fn forward_ee(&self, q: &[f64], ws: &mut FkWorkspace) -> Result<(), KinematicsError> {
        self.forward_impl::<false>(q, ws)
    }

    fn forward_impl<const FULL: bool>(
        &self,
        q: &[f64],
        ws: &mut FkWorkspace,
    ) -> Result<(), KinematicsError> {
        self.check_q(q)?;
        let n = self.dof();
        if ws.partial.len() != n + 1 || ws.keypoint_positions.len() != self.keypoints().len() {
            return Err(KinematicsError::WrongJointCount {
                expected: n,
                got: ws.partial.len().saturating_sub(1),
            });
        }
        let kps = self.keypoints();
        let mut k = 0;
        let (mut r, mut t) = (Matrix3::identity(), Vector3::zeros());
        while FULL && k < kps.len() && kps[k].after == 0 {
            ws.keypoint_positions[k] = Vector3::from(kps[k].position);
            k += 1;
        }
        for i in 0..n {
            // Column i of the space Jacobian: Ad(T) ξ_i with T the product so far.
            let d = &self.exp_data[i];
            let w = r * d.w;
            let v = r * d.v + t.cross(&w);
            let mut col = ws.space_jacobian.column_mut(i);
            col[0] = v.x;
            col[1] = v.y;
            col[2] = v.z;
            col[3] = w.x;
            col[4] = w.y;
            col[5] = w.z;
            if let Some((ax, sign)) = d.aligned {
                // Rotation by φ = σq about e_ax: only the other two columns of R mix, and
                // (I − Rⱼ)p⊥ lies in their plane.
                let (a, b) = ((ax + 1) % 3, (ax + 2) % 3);
                let (s, c) = (sign * q[i]).sin_cos();
                let (pa, pb) = (d.p[a], d.p[b]);
                let (ta, tb) = ((1.0 - c) * pa + s * pb, (1.0 - c) * pb - s * pa);
                let (ca, cb) = (r.column(a).into_owned(), r.column(b).into_owned());
                t += ca * ta + cb * tb + r.column(ax) * (d.h * q[i] * sign);
                r.set_column(a, &(ca * c + cb * s));
                r.set_column(b, &(cb * c - ca * s));
            } else {
                let (rj, tj) = self.joint_exp_matrix(i, q[i]);
                t += r * tj;
                r *= rj;
            }
            if FULL {
                ws.partial[i + 1] = (r, t);
            }
            while FULL && k < kps.len() && kps[k].after == i + 1 {
                ws.keypoint_positions[k] = r * Vector3::from(kps[k].position) + t;
                k += 1;
            }
        }
        let home = self.home();
        let (rm, tm) = (home.rotation().matrix(), home.translation());
        ws.ee = (r * rm, r * tm + t);
        Ok(())
    }
}
