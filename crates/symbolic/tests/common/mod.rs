//! Helpers shared by the integration tests: the seed arm, and a finite-difference checker.
#![allow(dead_code)]

use armature_symbolic::{Expr, Function};

pub(crate) mod tree;

pub(crate) const D1: f64 = 0.340;
pub(crate) const A2: f64 = 0.300;
pub(crate) const A3: f64 = 0.250;
pub(crate) const A4: f64 = 0.150;

pub(crate) fn screws() -> [[f64; 6]; 7] {
    [
        [0.0, 0.0, 0.0, 0.0, 0.0, 1.0],
        [-D1, 0.0, 0.0, 0.0, 1.0, 0.0],
        [0.0, -A2, 0.0, 0.0, 0.0, 1.0],
        [-D1, 0.0, A2, 0.0, 1.0, 0.0],
        [0.0, -(A2 + A3), 0.0, 0.0, 0.0, 1.0],
        [-D1, 0.0, A2 + A3, 0.0, 1.0, 0.0],
        [0.0, -(A2 + A3 + A4), 0.0, 0.0, 0.0, 1.0],
    ]
}

/// The tutorial's symbolic FK: keypoint frames after 0/1/2/4/7 joints, and T_ee.
pub(crate) fn seed_fk(angle: &Expr) -> (Vec<Expr>, Expr) {
    let s = screws();
    let mut chain = Expr::identity(4);
    let mut frames = Vec::new();
    let mut j = 0;
    for after in [0, 1, 2, 4, 7] {
        while j < after {
            chain = chain.matmul(&(Expr::constant_vector(&s[j]) * angle.at(j)).se3_exp());
            j += 1;
        }
        frames.push(chain.clone());
    }
    let home = Expr::constant_matrix(&[
        [1.0, 0.0, 0.0, A2 + A3 + A4],
        [0.0, 1.0, 0.0, 0.0],
        [0.0, 0.0, 1.0, D1],
        [0.0, 0.0, 0.0, 1.0],
    ]);
    let t_ee = chain.matmul(&home);
    (frames, t_ee)
}

/// Dense Jacobian (row-major) by central differences of `f`'s values.
pub(crate) fn fd_jacobian(f: &Function, x: &[f64], h: f64) -> Vec<f64> {
    let (n, m) = (f.n_inputs(), f.n_outputs());
    let mut ws = f.workspace();
    let (mut vp, mut vm) = (vec![0.0; m], vec![0.0; m]);
    let mut jac = vec![0.0; m * n];
    let mut xp = x.to_vec();
    for c in 0..n {
        xp[c] = x[c] + h;
        f.eval(&xp, &mut ws, &mut vp, None).unwrap();
        xp[c] = x[c] - h;
        f.eval(&xp, &mut ws, &mut vm, None).unwrap();
        xp[c] = x[c];
        for r in 0..m {
            jac[r * n + c] = (vp[r] - vm[r]) / (2.0 * h);
        }
    }
    jac
}

/// Analytic dense Jacobian (row-major) from the sparse one.
pub(crate) fn dense_jacobian(f: &Function, x: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let mut ws = f.workspace();
    let mut v = vec![0.0; f.n_outputs()];
    let mut nz = vec![0.0; f.jacobian_pattern().nnz()];
    f.eval(x, &mut ws, &mut v, Some(&mut nz)).unwrap();
    (v, f.jacobian_pattern().to_dense(&nz))
}

/// Max |analytic − FD| / max(1, |analytic|) entrywise, and whether every FD-nonzero entry is
/// in the pattern.
pub(crate) fn check_against_fd(f: &Function, x: &[f64], h: f64) -> (f64, bool) {
    let (_, a) = dense_jacobian(f, x);
    let d = fd_jacobian(f, x, h);
    let n = f.n_inputs();
    let mut err: f64 = 0.0;
    let mut covered = true;
    for (k, (ai, di)) in a.iter().zip(&d).enumerate() {
        err = err.max((ai - di).abs() / ai.abs().max(1.0));
        if di.abs() > 1e-7 && !f.jacobian_pattern().contains(k / n, k % n) {
            covered = false;
        }
    }
    (err, covered)
}

/// A splitmix64 generator: random expression trees reproducible from one seed.
pub(crate) struct Rng(pub(crate) u64);

impl Rng {
    pub(crate) fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in `0..n`.
    pub(crate) fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }

    /// Uniform in [−1, 1).
    pub(crate) fn f(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    }
}
