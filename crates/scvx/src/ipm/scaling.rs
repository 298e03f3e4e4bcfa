//! Nesterov–Todd scaling of the cone part and the cone arithmetic the interior point needs:
//! step lengths to the boundary, the Jordan product's inverse, shifts into the interior.
//!
//! For a nonnegative row, `W = √(s/z)` and `λ = √(sz)`. For a second-order cone
//! 𝒬^d = {(t, u) : ‖u‖ ≤ t} (Vandenberghe 2010, §4):
//!
//! ```text
//! s̄ = s/√det s,  z̄ = z/√det z,  γ = √((1 + s̄ᵀz̄)/2),  w̄ = (s̄ + Jz̄)/(2γ),  η = (det s/det z)^¼
//! W = η [w̄₀  w̄₁ᵀ; w̄₁  I + w̄₁w̄₁ᵀ/(1 + w̄₀)],   W⁻¹ = η⁻¹ J W̄ J,   λ = Wz = W⁻¹s
//! ```
//!
//! with `det v = v₀² − ‖v₁‖²` and `J = diag(1, −I)`. W⁻² is applied as W⁻¹(W⁻¹v), never
//! formed: its small eigenvalue, (w̄₀ − ‖w̄₁‖)²/η², is lost to cancellation in
//! `2(Jw̄)(Jw̄)ᵀ − J` once w̄₀ is large, which happens as s and z approach the boundary.

use super::{Cones, MAX_SOC, dot};

/// The scaling of the cone rows (equality rows excluded), allocated once per pattern.
#[derive(Debug, Clone)]
pub(super) struct Scaling {
    nonneg: usize,
    soc: Vec<usize>,
    /// Offset of each cone's d×d blocks in `w`/`winv` (after the `nonneg` diagonal entries).
    soc_off: Vec<usize>,
    /// z/s per nonnegative row (the diagonal of W⁻²).
    pub(super) weights: Vec<f64>,
    /// W and W⁻¹: the nonnegative diagonal, then each cone's dense block (row-major).
    w: Vec<f64>,
    winv: Vec<f64>,
    /// λ = Wz, per cone row.
    pub(super) lambda: Vec<f64>,
}

impl Scaling {
    pub(super) fn new(cones: &Cones) -> Scaling {
        let mut soc_off = Vec::with_capacity(cones.soc.len());
        let mut off = cones.nonneg;
        for &d in &cones.soc {
            soc_off.push(off);
            off += d * d;
        }
        let rows = cones.nonneg + cones.soc.iter().sum::<usize>();
        Scaling {
            nonneg: cones.nonneg,
            soc: cones.soc.clone(),
            soc_off,
            weights: vec![0.0; cones.nonneg],
            w: vec![0.0; off],
            winv: vec![0.0; off],
            lambda: vec![0.0; rows],
        }
    }

    /// W = I (the cold start's least-squares system).
    pub(super) fn identity(&mut self) {
        self.weights.fill(1.0);
        self.w.fill(0.0);
        self.w[..self.nonneg].fill(1.0);
        for (k, &d) in self.soc.iter().enumerate() {
            for i in 0..d {
                self.w[self.soc_off[k] + i * d + i] = 1.0;
            }
        }
        self.winv.copy_from_slice(&self.w);
    }

    /// The scaling at the cone parts `s`, `z` (both strictly inside their cones).
    pub(super) fn compute(&mut self, s: &[f64], z: &[f64]) {
        for i in 0..self.nonneg {
            self.weights[i] = z[i] / s[i];
            self.w[i] = (s[i] / z[i]).sqrt();
            self.winv[i] = 1.0 / self.w[i];
            self.lambda[i] = (s[i] * z[i]).sqrt();
        }
        let mut r = self.nonneg;
        for (k, &d) in self.soc.iter().enumerate() {
            let o = self.soc_off[k];
            nt_scaling(
                &s[r..r + d],
                &z[r..r + d],
                &mut self.w[o..o + d * d],
                &mut self.winv[o..o + d * d],
                &mut self.lambda[r..r + d],
            );
            r += d;
        }
    }

    /// Cone `k`'s W⁻¹ block (d×d, row-major).
    pub(super) fn winv_block(&self, k: usize) -> &[f64] {
        let d = self.soc[k];
        &self.winv[self.soc_off[k]..self.soc_off[k] + d * d]
    }

    /// out = W·v.
    pub(super) fn apply_w(&self, v: &[f64], out: &mut [f64]) {
        self.apply(&self.w, v, out);
    }

    /// out = W⁻¹·v.
    pub(super) fn apply_winv(&self, v: &[f64], out: &mut [f64]) {
        self.apply(&self.winv, v, out);
    }

    /// out = W⁻²·v = W⁻¹(W⁻¹v), through `scratch`.
    pub(super) fn apply_winv2(&self, v: &[f64], out: &mut [f64], scratch: &mut [f64]) {
        self.apply(&self.winv, v, scratch);
        self.apply(&self.winv, scratch, out);
    }

    fn apply(&self, mat: &[f64], v: &[f64], out: &mut [f64]) {
        for i in 0..self.nonneg {
            out[i] = mat[i] * v[i];
        }
        let mut r = self.nonneg;
        for (k, &d) in self.soc.iter().enumerate() {
            let o = self.soc_off[k];
            for i in 0..d {
                out[r + i] = (0..d).map(|j| mat[o + i * d + j] * v[r + j]).sum();
            }
            r += d;
        }
    }

    /// u = λ⁻¹∘ξ with ξ = −λ∘λ + σμe − a∘b (the corrector's complementarity term), where
    /// x∘y is the elementwise product on nonnegative rows and (xᵀy, x₀y₁ + y₀x₁) on a cone.
    pub(super) fn corrector(&self, sigma_mu: f64, a: &[f64], b: &[f64], u: &mut [f64]) {
        let l = &self.lambda;
        for i in 0..self.nonneg {
            u[i] = (-l[i] * l[i] + sigma_mu - a[i] * b[i]) / l[i];
        }
        let mut r = self.nonneg;
        for &d in &self.soc {
            let l = &self.lambda[r..r + d];
            let mut xi = [0.0; MAX_SOC];
            let xi = &mut xi[..d];
            xi[0] = -dot(l, l) + sigma_mu - dot(&a[r..r + d], &b[r..r + d]);
            for j in 1..d {
                xi[j] = -2.0 * l[0] * l[j] - (a[r] * b[r + j] + b[r] * a[r + j]);
            }
            soc_inv_prod(l, xi, &mut u[r..r + d]);
            r += d;
        }
    }
}

/// Largest α with `x + α·dx` and `y + α·dy` in the cones (x, y strictly inside).
pub(super) fn step_length(cones: &Cones, x: &[f64], dx: &[f64], y: &[f64], dy: &[f64]) -> f64 {
    let mut alpha = f64::INFINITY;
    for (v, d) in [(x, dx), (y, dy)] {
        for i in 0..cones.nonneg {
            if d[i] < 0.0 {
                alpha = alpha.min(-v[i] / d[i]);
            }
        }
    }
    let mut r = cones.nonneg;
    for &d in &cones.soc {
        alpha = alpha.min(soc_step(&x[r..r + d], &dx[r..r + d]));
        alpha = alpha.min(soc_step(&y[r..r + d], &dy[r..r + d]));
        r += d;
    }
    alpha
}

/// Shift a cone vector into the interior: v += (1 + α)e when its smallest "eigenvalue" −α is
/// not positive.
pub(super) fn shift_into_cone(v: &mut [f64], cones: &Cones) {
    let nn = cones.nonneg;
    let mut alpha = v[..nn].iter().fold(f64::NEG_INFINITY, |m, x| m.max(-x));
    let mut r = nn;
    for &d in &cones.soc {
        alpha = alpha.max(-(v[r] - norm(&v[r + 1..r + d])));
        r += d;
    }
    if alpha >= 0.0 {
        let shift = 1.0 + alpha;
        v[..nn].iter_mut().for_each(|x| *x += shift);
        let mut r = nn;
        for &d in &cones.soc {
            v[r] += shift;
            r += d;
        }
    }
}

/// Push every block at least `theta` inside its cone (nonnegative entries to ≥ θ, cone
/// heads to ≥ ‖tail‖ + θ): the warm start.
pub(super) fn push_inside(v: &mut [f64], cones: &Cones, theta: f64) {
    for x in &mut v[..cones.nonneg] {
        *x = x.max(theta);
    }
    push_inside_socs(&mut v[cones.nonneg..], &cones.soc, theta);
}

/// [`push_inside`] for second-order cones of dimensions `socs` only (`v` their rows).
pub(super) fn push_inside_socs(v: &mut [f64], socs: &[usize], theta: f64) {
    let mut r = 0;
    for &d in socs {
        let tail = norm(&v[r + 1..r + d]);
        if v[r] - tail < theta {
            v[r] = tail + theta;
        }
        r += d;
    }
}

fn norm(v: &[f64]) -> f64 {
    v.iter().map(|x| x * x).sum::<f64>().sqrt()
}

/// Largest α ≥ 0 with x + αd in the second-order cone (x in its interior): the smallest
/// positive root of (x₀ + αd₀)² − ‖x₁ + αd₁‖² (∞ when there is none).
fn soc_step(x: &[f64], d: &[f64]) -> f64 {
    let qa = d[0] * d[0] - d[1..].iter().map(|v| v * v).sum::<f64>();
    let qb = x[0] * d[0] - x[1..].iter().zip(&d[1..]).map(|(a, b)| a * b).sum::<f64>();
    let qc = (x[0] * x[0] - x[1..].iter().map(|v| v * v).sum::<f64>()).max(0.0);
    let mut best = f64::INFINITY;
    let disc = qb * qb - qa * qc;
    if qa.abs() < 1e-300 {
        if qb < 0.0 {
            best = -qc / (2.0 * qb);
        }
    } else if disc >= 0.0 {
        let qq = -(qb + qb.signum() * disc.sqrt());
        for root in [qq / qa, if qq != 0.0 { qc / qq } else { f64::INFINITY }] {
            if root > 0.0 {
                best = best.min(root);
            }
        }
    }
    best
}

/// u with λ∘u = ξ in the second-order cone's Jordan algebra.
fn soc_inv_prod(l: &[f64], xi: &[f64], u: &mut [f64]) {
    let d = l.len();
    let l1l1: f64 = l[1..].iter().map(|v| v * v).sum();
    let l1x1: f64 = l[1..].iter().zip(&xi[1..]).map(|(a, b)| a * b).sum();
    let det = l[0] * l[0] - l1l1;
    u[0] = (l[0] * xi[0] - l1x1) / det;
    for j in 1..d {
        u[j] = (xi[j] - u[0] * l[j]) / l[0];
    }
}

/// Nesterov–Todd scaling of one second-order cone: W (= Wᵀ) and W⁻¹ (dense, row-major) and
/// λ = Wz = W⁻¹s.
fn nt_scaling(s: &[f64], z: &[f64], w: &mut [f64], winv: &mut [f64], lambda: &mut [f64]) {
    let d = s.len();
    let det =
        |v: &[f64]| (v[0] * v[0] - v[1..].iter().map(|x| x * x).sum::<f64>()).max(1e-300).sqrt();
    let (sd, zd) = (det(s), det(z));
    let mut sb = [0.0; MAX_SOC];
    let mut zb = [0.0; MAX_SOC];
    for i in 0..d {
        sb[i] = s[i] / sd;
        zb[i] = z[i] / zd;
    }
    let gamma = ((1.0 + dot(&sb[..d], &zb[..d])) / 2.0).sqrt();
    let mut wb = [0.0; MAX_SOC];
    wb[0] = (sb[0] + zb[0]) / (2.0 * gamma);
    for i in 1..d {
        wb[i] = (sb[i] - zb[i]) / (2.0 * gamma);
    }
    let eta = (sd / zd).sqrt();
    for i in 0..d {
        for j in 0..d {
            let v = if i == 0 && j == 0 {
                wb[0]
            } else if i == 0 {
                wb[j]
            } else if j == 0 {
                wb[i]
            } else {
                f64::from(u8::from(i == j)) + wb[i] * wb[j] / (1.0 + wb[0])
            };
            w[i * d + j] = eta * v;
            let sign = if (i == 0) != (j == 0) { -1.0 } else { 1.0 };
            winv[i * d + j] = sign * v / eta;
        }
    }
    for i in 0..d {
        lambda[i] = (0..d).map(|j| w[i * d + j] * z[j]).sum();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// A point strictly inside a d-dimensional second-order cone.
    fn interior(d: usize) -> impl Strategy<Value = Vec<f64>> {
        (prop::collection::vec(-1.0..1.0f64, d - 1), 1e-3..2.0f64).prop_map(|(u, margin)| {
            let n = norm(&u);
            std::iter::once(n + margin).chain(u).collect()
        })
    }

    fn mat_vec(m: &[f64], v: &[f64]) -> Vec<f64> {
        let d = v.len();
        (0..d).map(|i| (0..d).map(|j| m[i * d + j] * v[j]).sum()).collect()
    }

    proptest! {
        /// Nesterov–Todd: Wz = W⁻¹s = λ and W·W⁻¹ = I.
        #[test]
        fn nt_scaling_maps_z_and_s_to_the_same_point(
            (s, z) in (2usize..=5).prop_flat_map(|d| (interior(d), interior(d))),
        ) {
            let d = s.len();
            let (mut w, mut wi, mut l) = (vec![0.0; d * d], vec![0.0; d * d], vec![0.0; d]);
            nt_scaling(&s, &z, &mut w, &mut wi, &mut l);
            let wz = mat_vec(&w, &z);
            let wis = mat_vec(&wi, &s);
            for i in 0..d {
                prop_assert!((wz[i] - l[i]).abs() < 1e-9 * (1.0 + l[i].abs()));
                prop_assert!((wis[i] - l[i]).abs() < 1e-9 * (1.0 + l[i].abs()));
                for j in 0..d {
                    let id: f64 = (0..d).map(|k| w[i * d + k] * wi[k * d + j]).sum();
                    prop_assert!((id - f64::from(u8::from(i == j))).abs() < 1e-9);
                }
            }
        }

        /// λ∘u = ξ for the returned u, with x∘y = (xᵀy, x₀y₁ + y₀x₁).
        #[test]
        fn inverse_product_solves_the_jordan_product(
            l in interior(4),
            xi in prop::collection::vec(-2.0..2.0f64, 4),
        ) {
            let mut u = [0.0; 4];
            soc_inv_prod(&l, &xi, &mut u);
            // The inverse's conditioning is λ₀/(λ₀ − ‖λ₁‖).
            let cond = l[0] / (l[0] - norm(&l[1..]));
            prop_assert!((dot(&l, &u) - xi[0]).abs() < 1e-8 * (1.0 + xi[0].abs()) * cond);
            for j in 1..4 {
                let p = l[0] * u[j] + u[0] * l[j];
                prop_assert!((p - xi[j]).abs() < 1e-6 * (1.0 + u[0].abs() + u[j].abs()));
            }
        }

        /// The step to the cone boundary lands on it, and shorter steps stay inside.
        #[test]
        fn soc_step_stops_at_the_boundary(
            x in interior(4),
            d in prop::collection::vec(-3.0..3.0f64, 4),
        ) {
            let a = soc_step(&x, &d);
            let gap = |t: f64| {
                let p: Vec<f64> = x.iter().zip(&d).map(|(x, d)| x + t * d).collect();
                p[0] - norm(&p[1..])
            };
            prop_assert!(gap(0.5 * a.min(1e6)) > 0.0);
            if a.is_finite() {
                prop_assert!(gap(a).abs() < 1e-8 * (1.0 + x[0] + a * d[0].abs()));
            } else {
                prop_assert!(gap(1e6) >= 0.0);
            }
        }

        /// Over a whole cone part (a nonnegative row and two cones): W⁻¹λ = z and Wλ = s.
        #[test]
        fn scaling_blocks_invert_each_other(
            (s4, z4, s3, z3) in (interior(4), interior(4), interior(3), interior(3)),
            (ns, nz) in (0.1..3.0f64, 0.1..3.0f64),
        ) {
            let cones = Cones { zero: 0, nonneg: 1, soc: vec![4, 3] };
            // Each vector is [nonnegative row | cone of 4 | cone of 3].
            let sv: Vec<f64> = [vec![ns], s4, s3].concat();
            let zv: Vec<f64> = [vec![nz], z4, z3].concat();
            let mut sc = Scaling::new(&cones);
            sc.compute(&sv, &zv);
            let (mut a, mut b) = (vec![0.0; 8], vec![0.0; 8]);
            sc.apply_winv(&sc.lambda.clone(), &mut a);
            for (x, y) in a.iter().zip(&zv) {
                prop_assert!((x - y).abs() < 1e-8 * (1.0 + y.abs()));
            }
            sc.apply_w(&sc.lambda.clone(), &mut b);
            for (x, y) in b.iter().zip(&sv) {
                prop_assert!((x - y).abs() < 1e-8 * (1.0 + y.abs()));
            }
            prop_assert!((sc.weights[0] - nz / ns).abs() < 1e-12 * (nz / ns));
        }
    }

    #[test]
    fn shifting_puts_vectors_inside_each_cone() {
        let cones = Cones { zero: 0, nonneg: 2, soc: vec![3] };
        let mut v = vec![-1.0, 0.5, 0.0, 2.0, 0.0];
        shift_into_cone(&mut v, &cones);
        // The worst "eigenvalue" was −2 (the cone), so every block moved by 3.
        assert_eq!(v, vec![2.0, 3.5, 3.0, 2.0, 0.0]);
        assert!(v[2] > norm(&v[3..]));
        let mut w = vec![0.0, 5.0, 1.0, 3.0, 4.0];
        push_inside(&mut w, &cones, 0.01);
        assert_eq!(w, vec![0.01, 5.0, 5.01, 3.0, 4.0]);
    }
}
