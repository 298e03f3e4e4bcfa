//! Forward kinematics as symbolic expressions (the seed tutorial's `SE3Exp` chain).

use armature_symbolic::{Expr, Shape};

use crate::{Chain, KinematicsError};

/// The seed's symbolic kinematics: keypoint frames snapshotted along the accumulated chain,
/// keypoint world positions and `T_ee`, all expressions of one joint-angle vector.
#[derive(Debug, Clone)]
pub struct SymbolicFk {
    /// `(keypoint name, 4×4 frame)`: the partial product after the keypoint's joints.
    pub frames: Vec<(String, Expr)>,
    /// `(keypoint name, vector(3))`: `frame · [home position; 1]`.
    pub positions: Vec<(String, Expr)>,
    /// End-effector pose, 4×4.
    pub t_ee: Expr,
}

impl SymbolicFk {
    /// End-effector position `T_ee[0:3, 3]`.
    pub fn ee_position(&self) -> Expr {
        self.t_ee.block(0, 3, 3, 4)
    }

    /// End-effector rotation `T_ee[0:3, 0:3]`.
    pub fn ee_rotation(&self) -> Expr {
        self.t_ee.block(0, 3, 0, 3)
    }

    /// The position of a keypoint by name.
    pub fn position(&self, name: &str) -> Option<&Expr> {
        self.positions.iter().find(|(n, _)| n == name).map(|(_, e)| e)
    }

    /// The frame of a keypoint by name.
    pub fn frame(&self, name: &str) -> Option<&Expr> {
        self.frames.iter().find(|(n, _)| n == name).map(|(_, e)| e)
    }
}

impl Chain {
    /// Builds the symbolic FK of this chain for the joint-angle expression `angle`
    /// (`vector(n)`, or a scalar for one joint): `T = I`, then for each joint
    /// `T = T @ se3_exp(ξᵢ · angle[i])`, snapshotting `T` at each keypoint, and
    /// `T_ee = T @ M`. Compiles to the tape's product-of-exponentials fast path.
    ///
    /// # Errors
    /// [`KinematicsError::WrongJointCount`] if `angle` has another size.
    pub fn symbolic_fk(&self, angle: &Expr) -> Result<SymbolicFk, KinematicsError> {
        let n = self.dof();
        let size = angle.shape().map(|s| s.numel()).unwrap_or(0);
        if size != n || matches!(angle.shape(), Ok(Shape::Matrix(..))) {
            return Err(KinematicsError::WrongJointCount { expected: n, got: size });
        }
        let mut t = Expr::identity(4);
        let mut frames = Vec::new();
        let mut positions = Vec::new();
        let mut j = 0;
        let snapshot = |t: &Expr,
                        k: &crate::Keypoint,
                        frames: &mut Vec<(String, Expr)>,
                        positions: &mut Vec<(String, Expr)>| {
            let p = &k.position;
            let hom = Expr::constant_vector(&[p[0], p[1], p[2], 1.0]);
            frames.push((k.name.clone(), t.clone()));
            positions.push((k.name.clone(), t.matmul(&hom).slice(0, 3)));
        };
        for k in self.keypoints() {
            while j < k.after {
                t = t.matmul(
                    &(Expr::constant_vector(&self.joints()[j].screw) * angle.at(j)).se3_exp(),
                );
                j += 1;
            }
            snapshot(&t, k, &mut frames, &mut positions);
        }
        while j < n {
            t = t.matmul(&(Expr::constant_vector(&self.joints()[j].screw) * angle.at(j)).se3_exp());
            j += 1;
        }
        let t_ee = t.matmul(&Expr::from_matrix(&self.home().matrix()));
        Ok(SymbolicFk { frames, positions, t_ee })
    }
}
