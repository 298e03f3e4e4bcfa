//! The curvature of one segment's propagation map, `yᵀ ∂²x_prop/∂z²`, by the second-order
//! adjoint on the recorded integration grid.
//!
//! # Math
//! On segment k, `dx/dτ = g(x, p, τ) = s·f(x, u(τ))` with the parameters
//! `z = [x_k | u_k | s_k | u_{k+1}]` (`n + 2m + 1` of them), `u(τ) = α(τ)u_k + β(τ)u_{k+1}`
//! on first-order-hold entries (`u_k` on zero-order-hold ones). With `W(τ) = ∂(x, u, s)/∂z`
//! (its state rows the sensitivities `[Φ | B⁻ | B⁺]` the grid records, its control rows
//! `α`, `β`, its dilation row `e_s`) and the adjoint `λ(τ)ᵀ = yᵀΦ(Δτ)Φ(τ)⁻¹` (so
//! `λ(Δτ) = y`), the Hessian of `yᵀx(Δτ)` is
//!
//! ```text
//! H = ∫₀^Δτ W(τ)ᵀ G(τ) W(τ) dτ,   G = ∇²_{(x,u,s)} (s·λᵀf) = [ s∇²(λᵀf)   ∇(λᵀf) ]
//!                                                            [ ∇(λᵀf)ᵀ     0      ]
//! ```
//!
//! — the exact flow's Hessian, evaluated here by Simpson's rule on the grid (the trapezoid
//! rule for an odd number of steps) along the integrated trajectory. The RK4 map's own
//! Hessian differs from it by the integration error, O(h⁴) (the tests check the agreement
//! with finite differences of the map's Jacobians and its convergence as the grid refines).
//! Gated rows (a CTCS integrand outside its interval) have `f_r = 0` on the segment.
//!
//! A weight `c_i` on an intermediate grid state, `c_iᵀx(τ_i)`, has the same Hessian over
//! `[0, τ_i]` with `λ_i(τ)ᵀ = c_iᵀΦ(τ_i)Φ(τ)⁻¹`
//! ([`segment_hessian_along`](Dynamics::segment_hessian_along)). `G` is linear in `λ`, so
//! every weighted point shares one evaluation per grid point: at point `j` the adjoint
//! solves `Φ(τ_j)ᵀλ_j = Σ_i q_j⁽ⁱ⁾ Φ(τ_i)ᵀc_i`, with `q⁽ⁱ⁾` the quadrature weights of
//! `[0, τ_i]` (Simpson's composite rule, closed by Simpson's 3/8 rule on an odd number of
//! steps, the trapezoid on one step).

use armature_symbolic::HessianWorkspace;

use super::*;

/// Scratch of [`Dynamics::segment_hessian`] (allocated once).
#[derive(Debug, Clone)]
pub struct SegmentHessianWorkspace {
    hws: HessianWorkspace,
    input: Vec<f64>,
    values: Vec<f64>,
    jac: Vec<f64>,
    hess: Vec<f64>,
    /// `Σ_i q_j⁽ⁱ⁾Φ(τ_i)ᵀc_i` at one grid point, the adjoint and the gated weights.
    mu: Vec<f64>,
    /// Per grid point `i`: `Φ(τ_i)ᵀc_i` (grown to the grid on first use).
    nu: Vec<f64>,
    /// Per grid point: whether it carries a weight.
    weighted: Vec<bool>,
    lam: Vec<f64>,
    weights: Vec<f64>,
    /// LU scratch (`n×n`).
    lu: Vec<f64>,
    /// `W` (`(n+m+1) × nz`), `G` (`(n+m+1)²`), `G·W` and which of its rows are nonzero.
    w: Vec<f64>,
    g: Vec<f64>,
    gw: Vec<f64>,
    touched: Vec<bool>,
}

impl Dynamics {
    /// A workspace for [`segment_hessian`](Self::segment_hessian).
    pub fn segment_hessian_workspace(&self) -> SegmentHessianWorkspace {
        let (n, mu) = (self.n_x, self.n_u);
        let (nv, nz) = (n + mu + 1, n + 2 * mu + 1);
        SegmentHessianWorkspace {
            hws: self.f.hessian_workspace(),
            input: vec![0.0; n + mu],
            values: vec![0.0; n],
            jac: vec![0.0; self.f.jacobian_pattern().nnz()],
            hess: vec![0.0; self.f.hessian_pattern().nnz()],
            mu: vec![0.0; n],
            nu: Vec::new(),
            weighted: Vec::new(),
            lam: vec![0.0; n],
            weights: vec![0.0; n],
            lu: vec![0.0; n * n],
            w: vec![0.0; nv * nz],
            g: vec![0.0; nv * nv],
            gw: vec![0.0; nv * nz],
            touched: vec![false; nv],
        }
    }

    /// `yᵀ ∂²x_prop_k/∂z²` over `z = [x_k | u_k | s_k | u_{k+1}]` (`nz = n + 2m + 1`,
    /// row-major `nz×nz` into `out`) for segment `k` of a discretization `d` made with a grid
    /// ([`output_with_grid`](Self::output_with_grid)), with the controls `u` (N×m) and the
    /// dilation `s_k` it was made with. See the module's math. Allocation-free.
    ///
    /// # Errors
    /// A discretization without a grid, a segment out of range or buffers of the wrong
    /// length ([`DiscretizationError::Size`]); evaluation errors of the dynamics.
    ///
    /// # Example
    /// ```
    /// use armature_scvx::{DiscretizationSettings, Dynamics};
    /// use armature_symbolic::Expr;
    ///
    /// // v' = a on one segment: v_prop = v_k + s·Δτ·(a_k + a_{k+1})/2, so the only curvature
    /// // of y·v_prop is the dilation times each acceleration, y·Δτ/2 (Δτ = 1).
    /// let (v, a) = (Expr::variable("v", 1), Expr::variable("a", 1));
    /// let d = Dynamics::new(&[v], &[a.clone()], &[a], &[true]).unwrap();
    /// let (u, s) = ([0.3, -0.2], [2.0, 2.0]);
    /// let mut out = d.output_with_grid(2, 10);
    /// let settings = DiscretizationSettings::default();
    /// d.discretize(&[0.0, 0.0], &u, &s, &settings, &mut d.workspace(), &mut out).unwrap();
    /// // z = [v_k, a_k, s_k, a_{k+1}]
    /// let mut h = [0.0; 16];
    /// d.segment_hessian(&out, 0, &u, s[0], &[3.0], &mut d.segment_hessian_workspace(), &mut h)
    ///     .unwrap();
    /// assert!((h[1 * 4 + 2] - 1.5).abs() < 1e-12 && (h[3 * 4 + 2] - 1.5).abs() < 1e-12);
    /// assert!(h[0].abs() < 1e-12 && h[2 * 4 + 2].abs() < 1e-12);
    /// ```
    #[allow(clippy::too_many_arguments)]
    pub fn segment_hessian(
        &self,
        d: &Discretization,
        k: usize,
        u: &[f64],
        s_k: f64,
        y: &[f64],
        ws: &mut SegmentHessianWorkspace,
        out: &mut [f64],
    ) -> Result<(), DiscretizationError> {
        self.segment_hessian_along(d, k, u, s_k, y, &[], ws, out)
    }

    /// `yᵀ ∂²x_prop/∂z² + Σ_i c_iᵀ ∂²x(τ_i)/∂z²`: [`segment_hessian`](Self::segment_hessian)
    /// with weights `c_i` (`points`, `grid_points × n` row-major, or empty for none) on the
    /// states at the segment's grid points `τ_i` too — the curvature of constraints imposed
    /// between the nodes through the flow. The weight on the first point (`x_k` itself,
    /// linear in `z`) adds nothing; one on the last adds to `y`. See the module's math.
    /// Allocation-free after its first call with a grid of this size.
    ///
    /// # Errors
    /// As [`segment_hessian`](Self::segment_hessian), and `points` of another length.
    ///
    /// # Example
    /// ```
    /// use armature_scvx::{DiscretizationSettings, Dynamics};
    /// use armature_symbolic::Expr;
    ///
    /// // p' = v, v' = a on one segment of 4 steps. A weight on the midpoint's position,
    /// // p(½) = p_k + s·v_k/2 + s²(5a_k + a_{k+1})/48, curves it in s·v_k, s² and s·a.
    /// let (p, v, a) = (Expr::variable("p", 1), Expr::variable("v", 1), Expr::variable("a", 1));
    /// let d = Dynamics::new(&[p, v.clone()], &[a.clone()], &[v, a], &[true]).unwrap();
    /// let (x, u, s) = ([0.0, 0.5, 0.0, 0.0], [0.3, -0.2], [2.0, 2.0]);
    /// let mut out = d.output_with_grid(2, 4);
    /// let mut settings = DiscretizationSettings::default();
    /// settings.substeps = 4;
    /// d.discretize(&x, &u, &s, &settings, &mut d.workspace(), &mut out).unwrap();
    /// // z = [p_k, v_k, a_k, s_k, a_{k+1}]; weight 1 on p at the midpoint.
    /// let mut points = [0.0; 10];
    /// points[2 * 2] = 1.0;
    /// let mut h = [0.0; 25];
    /// let mut ws = d.segment_hessian_workspace();
    /// d.segment_hessian_along(&out, 0, &u, s[0], &[0.0, 0.0], &points, &mut ws, &mut h)
    ///     .unwrap();
    /// // ∂²p(½)/∂s∂v_k = 1/2, ∂²/∂s² = (5a_k + a_{k+1})/24, ∂²/∂s∂a_k = 5s/24.
    /// assert!((h[1 * 5 + 3] - 0.5).abs() < 1e-12);
    /// assert!((h[3 * 5 + 3] - (5.0 * 0.3 - 0.2) / 24.0).abs() < 1e-12);
    /// assert!((h[2 * 5 + 3] - 5.0 * 2.0 / 24.0).abs() < 1e-12);
    /// ```
    #[allow(clippy::too_many_arguments)]
    pub fn segment_hessian_along(
        &self,
        d: &Discretization,
        k: usize,
        u: &[f64],
        s_k: f64,
        y: &[f64],
        points: &[f64],
        ws: &mut SegmentHessianWorkspace,
        out: &mut [f64],
    ) -> Result<(), DiscretizationError> {
        let (n, mu) = (self.n_x, self.n_u);
        let (nv, nz, pts) = (n + mu + 1, n + 2 * mu + 1, d.grid_points);
        if pts < 2
            || k >= d.segments
            || y.len() != n
            || !(points.is_empty() || points.len() == pts * n)
            || out.len() != nz * nz
            || u.len() != (d.segments + 1) * mu
            || ws.w.len() != nv * nz
        {
            return Err(DiscretizationError::Size(format!(
                "segment_hessian: segment {k} of {}, {pts} grid points (need ≥ 2), y of {} (need {n}), points of {} (need 0 or {}), out of {} (need {}), u of {} (need {})",
                d.segments,
                y.len(),
                points.len(),
                pts * n,
                out.len(),
                nz * nz,
                u.len(),
                (d.segments + 1) * mu
            )));
        }
        out.fill(0.0);
        let stride = self.grid_stride();
        let block = |j: usize| &d.grid[(k * pts + j) * stride..][..stride];
        self.point_adjoints(y, points, pts, |j| &block(j)[n..n + n * n], ws);
        let steps = pts - 1;
        let hq = 1.0 / (d.segments * steps) as f64;
        for j in 0..pts {
            // μ_j = h Σ_{i ≥ j} q_j⁽ⁱ⁾ ν_i.
            ws.mu.fill(0.0);
            let mut any = false;
            for i in j.max(1)..pts {
                if ws.weighted[i] {
                    let q = quadrature_weight(j, i) * hq;
                    for (m, nu) in ws.mu.iter_mut().zip(&ws.nu[i * n..(i + 1) * n]) {
                        *m += q * nu;
                    }
                    any = true;
                }
            }
            if !any {
                continue;
            }
            let beta = j as f64 / steps as f64;
            self.adjoint_at(block(j), ws);
            self.fill_w(block(j), beta, ws);
            self.fill_g(
                block(j),
                beta,
                (&u[k * mu..(k + 1) * mu], &u[(k + 1) * mu..][..mu]),
                s_k,
                k,
                ws,
            )?;
            accumulate(ws, nv, nz, 1.0, out);
        }
        Ok(())
    }

    /// `ν_i = Φ(τ_i)ᵀc_i` per grid point (`y` added to the last point's weight) into
    /// `ws.nu`, and which points carry a weight into `ws.weighted`.
    fn point_adjoints<'a>(
        &self,
        y: &[f64],
        points: &[f64],
        pts: usize,
        phi: impl Fn(usize) -> &'a [f64],
        ws: &mut SegmentHessianWorkspace,
    ) {
        let n = self.n_x;
        ws.nu.resize(pts * n, 0.0);
        ws.weighted.resize(pts, false);
        for i in 0..pts {
            let c = |r: usize| {
                let point = if points.is_empty() { 0.0 } else { points[i * n + r] };
                if i == pts - 1 { point + y[r] } else { point }
            };
            ws.weighted[i] = i > 0 && (0..n).any(|r| c(r) != 0.0);
            if !ws.weighted[i] {
                continue;
            }
            let phi = phi(i);
            for col in 0..n {
                ws.nu[i * n + col] = (0..n).map(|r| phi[r * n + col] * c(r)).sum();
            }
        }
    }

    /// The adjoint at a grid point: solves `Φ(τ)ᵀλ = μ`.
    fn adjoint_at(&self, v: &[f64], ws: &mut SegmentHessianWorkspace) {
        let n = self.n_x;
        let phi = &v[n..n + n * n];
        for r in 0..n {
            for c in 0..n {
                ws.lu[r * n + c] = phi[c * n + r];
            }
        }
        ws.lam.copy_from_slice(&ws.mu);
        lu_solve(&mut ws.lu, &mut ws.lam, n);
    }

    /// `W = ∂(x, u, s)/∂z` at a grid point.
    fn fill_w(&self, v: &[f64], beta: f64, ws: &mut SegmentHessianWorkspace) {
        let (n, mu) = (self.n_x, self.n_u);
        let (m, nz) = (mu + 1, n + 2 * mu + 1);
        let (phi, bm, bp) = (&v[n..], &v[n + n * n..], &v[n + n * n + n * m..]);
        ws.w.fill(0.0);
        for r in 0..n {
            let row = &mut ws.w[r * nz..(r + 1) * nz];
            row[..n].copy_from_slice(&phi[r * n..(r + 1) * n]);
            row[n..n + m].copy_from_slice(&bm[r * m..(r + 1) * m]);
            row[n + m..].copy_from_slice(&bp[r * m..r * m + mu]);
        }
        for i in 0..mu {
            let (alpha, b) = if self.foh[i] { (1.0 - beta, beta) } else { (1.0, 0.0) };
            ws.w[(n + i) * nz + n + i] = alpha;
            ws.w[(n + i) * nz + n + m + i] = b;
        }
        ws.w[(n + mu) * nz + n + mu] = 1.0;
    }

    /// `G = ∇²_{(x,u,s)}(s·λᵀf)` at a grid point (gated rows weigh nothing).
    fn fill_g(
        &self,
        v: &[f64],
        beta: f64,
        (uk, uk1): (&[f64], &[f64]),
        s: f64,
        seg: usize,
        ws: &mut SegmentHessianWorkspace,
    ) -> Result<(), DiscretizationError> {
        let (n, mu) = (self.n_x, self.n_u);
        let nv = n + mu + 1;
        ws.weights.copy_from_slice(&ws.lam);
        for &(row, first, end) in &self.gates {
            if seg < first || seg >= end {
                ws.weights[row] = 0.0;
            }
        }
        ws.input[..n].copy_from_slice(&v[..n]);
        for i in 0..mu {
            ws.input[n + i] = self.held_control(i, (uk, uk1), beta, s);
        }
        let SegmentHessianWorkspace { hws, input, values, jac, hess, weights, g, .. } = ws;
        self.f.eval_hessian(input, weights, hws, values, Some(jac), hess)?;
        g.fill(0.0);
        for ((r, c), &h) in self.f.hessian_pattern().lower().entries().zip(hess.iter()) {
            g[r * nv + c] += h;
            if r != c {
                g[c * nv + r] += h;
            }
        }
        // With H = ∇²(λᵀf), ∇(λᵀf) and the chain factors c_a = s (states, plain controls)
        // or 1 (time-scaled controls, u = w/s):
        //   G_ab = c_a c_b H_ab / s,
        //   G_as = [a plain]·∇_a(λᵀf) − (c_a/s) Σ_{i scaled} H_{a,u_i} u_i,
        //   G_ss = (1/s) Σ_{i,l scaled} u_i H_{u_i,u_l} u_l
        // (without time-scaled entries: s·H, ∇(λᵀf) and 0).
        let scaled = |a: usize| a >= n && self.time_scaled[a - n];
        let c_of = |a: usize| if scaled(a) { 1.0 } else { s };
        let hu = |g: &[f64], a: usize| -> f64 {
            (0..mu).filter(|&i| self.time_scaled[i]).map(|i| g[a * nv + n + i] * input[n + i]).sum()
        };
        let mut g_ss = 0.0;
        for i in (0..mu).filter(|&i| self.time_scaled[i]) {
            g_ss += input[n + i] * hu(g, n + i) / s;
        }
        for a in 0..n + mu {
            let grad: f64 = (self.col_ptr[a]..self.col_ptr[a + 1])
                .map(|p| weights[self.rows[p]] * jac[p])
                .sum();
            let plain = if scaled(a) { 0.0 } else { grad };
            let g_as = plain - c_of(a) / s * hu(g, a);
            g[a * nv + nv - 1] = g_as;
            g[(nv - 1) * nv + a] = g_as;
        }
        g[nv * nv - 1] = g_ss;
        for a in 0..n + mu {
            for b in 0..n + mu {
                g[a * nv + b] *= c_of(a) * c_of(b) / s;
            }
        }
        Ok(())
    }
}

/// The weight of grid point `j` in a quadrature of `[0, i]` steps (in units of the step):
/// Simpson's composite rule on an even number of steps; on an odd number ≥ 3, Simpson's on
/// the first `i − 3` and Simpson's 3/8 rule on the last three; the trapezoid on one step.
fn quadrature_weight(j: usize, i: usize) -> f64 {
    let simpson = |j: usize, steps: usize| {
        if j == 0 || j == steps {
            1.0 / 3.0
        } else if j % 2 == 1 {
            4.0 / 3.0
        } else {
            2.0 / 3.0
        }
    };
    match i {
        _ if j > i => 0.0,
        0 => 0.0,
        1 => 0.5,
        _ if i.is_multiple_of(2) => simpson(j, i),
        _ if j + 3 < i => simpson(j, i - 3),
        _ => {
            // Simpson's 3/8 rule on the last three steps, joined to Simpson's before them.
            let t = j + 3 - i;
            let three_eighths = if t == 0 || t == 3 { 3.0 / 8.0 } else { 9.0 / 8.0 };
            if t == 0 && i > 3 { simpson(j, i - 3) + three_eighths } else { three_eighths }
        }
    }
}

/// `out += q·WᵀGW`, through the nonzero entries of `G`.
fn accumulate(ws: &mut SegmentHessianWorkspace, nv: usize, nz: usize, q: f64, out: &mut [f64]) {
    ws.gw.fill(0.0);
    ws.touched.fill(false);
    for a in 0..nv {
        for b in 0..nv {
            let gab = ws.g[a * nv + b];
            if gab != 0.0 {
                ws.touched[a] = true;
                for c in 0..nz {
                    ws.gw[a * nz + c] += gab * ws.w[b * nz + c];
                }
            }
        }
    }
    for a in (0..nv).filter(|&a| ws.touched[a]) {
        for r in 0..nz {
            let wr = q * ws.w[a * nz + r];
            if wr != 0.0 {
                for c in 0..nz {
                    out[r * nz + c] += wr * ws.gw[a * nz + c];
                }
            }
        }
    }
}

/// Solves `M x = b` in place (`m` row-major `n×n`, overwritten by its LU factors with
/// partial pivoting; `b` becomes `x`). A zero pivot leaves that component at zero (a
/// fundamental matrix is never singular; this only guards against non-finite input).
fn lu_solve(m: &mut [f64], b: &mut [f64], n: usize) {
    for c in 0..n {
        let p =
            (c..n).max_by(|&i, &j| m[i * n + c].abs().total_cmp(&m[j * n + c].abs())).unwrap_or(c);
        if p != c {
            for j in 0..n {
                m.swap(c * n + j, p * n + j);
            }
            b.swap(c, p);
        }
        let d = m[c * n + c];
        if d == 0.0 || !d.is_finite() {
            continue;
        }
        for r in c + 1..n {
            let f = m[r * n + c] / d;
            if f != 0.0 {
                m[r * n + c] = f;
                for j in c + 1..n {
                    m[r * n + j] -= f * m[c * n + j];
                }
                b[r] -= f * b[c];
            }
        }
    }
    for c in (0..n).rev() {
        let d = m[c * n + c];
        let s: f64 = (c + 1..n).map(|j| m[c * n + j] * b[j]).sum();
        b[c] = if d == 0.0 || !d.is_finite() { 0.0 } else { (b[c] - s) / d };
    }
}
