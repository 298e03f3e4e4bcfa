//! The integrators of one segment: fixed-step RK4 on the variational equations, and
//! Dormand–Prince 5(4) with step control; the right-hand side they integrate.

use super::*;

/// Dormand–Prince 5(4) tableau: nodes `c`, rows of `a`, 5th-order weights `b`, and
/// `b − b*` (the embedded 4th-order difference) for the error estimate.
pub(super) const DP_C: [f64; 7] = [0.0, 1.0 / 5.0, 3.0 / 10.0, 4.0 / 5.0, 8.0 / 9.0, 1.0, 1.0];

pub(super) const DP_A: [[f64; 6]; 7] = [
    [0.0; 6],
    [1.0 / 5.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [3.0 / 40.0, 9.0 / 40.0, 0.0, 0.0, 0.0, 0.0],
    [44.0 / 45.0, -56.0 / 15.0, 32.0 / 9.0, 0.0, 0.0, 0.0],
    [19372.0 / 6561.0, -25360.0 / 2187.0, 64448.0 / 6561.0, -212.0 / 729.0, 0.0, 0.0],
    [9017.0 / 3168.0, -355.0 / 33.0, 46732.0 / 5247.0, 49.0 / 176.0, -5103.0 / 18656.0, 0.0],
    [35.0 / 384.0, 0.0, 500.0 / 1113.0, 125.0 / 192.0, -2187.0 / 6784.0, 11.0 / 84.0],
];

pub(super) const DP_E: [f64; 7] = [
    35.0 / 384.0 - 5179.0 / 57600.0,
    0.0,
    500.0 / 1113.0 - 7571.0 / 16695.0,
    125.0 / 192.0 - 393.0 / 640.0,
    -2187.0 / 6784.0 + 92097.0 / 339200.0,
    11.0 / 84.0 - 187.0 / 2100.0,
    -1.0 / 40.0,
];

/// Scratch of one evaluation of the dynamics `f(x, u)`.
#[derive(Debug, Clone)]
pub(super) struct FEval {
    pub(super) ws: Workspace,
    pub(super) input: Vec<f64>,
    pub(super) fval: Vec<f64>,
    pub(super) jac: Vec<f64>,
    /// The rows whose derivatives the segment needs (its gated rows are not).
    pub(super) needed: Vec<bool>,
}

impl Dynamics {
    /// One segment by Dormand–Prince into `v` (which holds the initial value on entry).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn dormand_prince(
        &self,
        (rtol, atol): (f64, f64),
        first_step: f64,
        dtau: f64,
        (uk, uk1, sk, seg): (&[f64], &[f64], f64, usize),
        ws: &mut Lane,
        full: bool,
        grid: &mut [f64],
    ) -> Result<(), DiscretizationError> {
        let n = self.n_x;
        let len = if full { ws.v.len() } else { n };
        let stride = self.grid_stride();
        let points = grid.len() / stride;
        // The next grid point to land on (steps are clipped to reach it exactly).
        let mut next = 1;
        let Lane { f, v, k, tmp } = ws;
        let mut t = 0.0;
        let mut h = first_step.min(dtau);
        // k[0] = f(t, v) (first same as last: refreshed from k[6] after each accepted step).
        self.rhs(v, 0.0, (uk, uk1, sk, seg), f, &mut k[0], full)?;
        let mut steps = 0;
        while t < dtau * (1.0 - 1e-14) {
            steps += 1;
            if steps > MAX_ADAPTIVE_STEPS {
                return Err(DiscretizationError::Size(format!(
                    "Dormand–Prince: segment {seg} needs more than {MAX_ADAPTIVE_STEPS} steps (tolerances too tight, or stiff dynamics)"
                )));
            }
            h = h.min(dtau - t);
            let mut land = false;
            if next < points {
                let tg = dtau * next as f64 / (points - 1) as f64;
                if t + h >= tg - 1e-14 * dtau {
                    h = tg - t;
                    land = true;
                }
            }
            for stage in 1..7 {
                for i in 0..len {
                    let mut acc = v[i];
                    for (j, a) in DP_A[stage][..stage].iter().enumerate() {
                        if *a != 0.0 {
                            acc += h * a * k[j][i];
                        }
                    }
                    tmp[i] = acc;
                }
                let beta = (t + DP_C[stage] * h) / dtau;
                self.rhs(tmp, beta.min(1.0), (uk, uk1, sk, seg), f, &mut k[stage], full)?;
            }
            // tmp holds the 5th-order solution (stage 7's argument); error on the state part.
            let mut err = 0.0;
            for i in 0..n {
                let e: f64 = h * (0..7).map(|j| DP_E[j] * k[j][i]).sum::<f64>();
                let scale = atol + rtol * v[i].abs().max(tmp[i].abs());
                err += (e / scale) * (e / scale);
            }
            if tmp[..n].iter().any(|x| !x.is_finite()) {
                return Err(DiscretizationError::Size(format!(
                    "Dormand–Prince: non-finite state on segment {seg}"
                )));
            }
            // An overflowing ratio (tolerances far below the state's scale) just rejects.
            let err = (err / n.max(1) as f64).sqrt().min(f64::MAX);
            if h < 1e-12 * dtau {
                return Err(DiscretizationError::Size(format!(
                    "Dormand–Prince: the step on segment {seg} fell below 1e-12·Δτ: the tolerances cannot be met"
                )));
            }
            let factor = if err == 0.0 { 5.0 } else { (0.9 * err.powf(-0.2)).clamp(0.2, 5.0) };
            if err <= 1.0 {
                t += h;
                v[..len].copy_from_slice(&tmp[..len]);
                let (first, last) = k.split_at_mut(6);
                first[0][..len].copy_from_slice(&last[0][..len]);
                if land {
                    grid[next * stride..next * stride + len].copy_from_slice(&v[..len]);
                    next += 1;
                }
            }
            h *= factor;
        }
        Ok(())
    }

    /// Time derivative of the augmented vector `V = [x, Φ, B⁻, B⁺]` at normalised segment
    /// time `beta` (β of the FOH) on segment `seg` (controls `uk`, `uk1`, dilation `s`),
    /// into `dv`; with `full` false, of the state `x` alone (`dv[..n]`).
    pub(super) fn rhs(
        &self,
        v: &[f64],
        beta: f64,
        (uk, uk1, s, seg): (&[f64], &[f64], f64, usize),
        fe: &mut FEval,
        dv: &mut [f64],
        full: bool,
    ) -> Result<(), DiscretizationError> {
        let (n, mu) = (self.n_x, self.n_u);
        let m = mu + 1;
        let FEval { ws: fws, input, fval, jac, needed } = fe;
        input[..n].copy_from_slice(&v[..n]);
        for i in 0..mu {
            input[n + i] = self.held_control(i, (uk, uk1), beta, s);
        }
        if !full {
            // The state alone: no Jacobian, no variational equations.
            self.f.eval(input, fws, fval, None)?;
            for &(row, first, end) in &self.gates {
                if seg < first || seg >= end {
                    fval[row] = 0.0;
                }
            }
            for r in 0..n {
                dv[r] = s * fval[r];
            }
            return Ok(());
        }
        // Gated rows (inactive CTCS integrands on this segment) are not differentiated, nor
        // penalties whose constraints all hold here (their derivatives are zero): see
        // `Function::eval_pruned`.
        needed.fill(true);
        for &(row, first, end) in &self.gates {
            if seg < first || seg >= end {
                needed[row] = false;
            }
        }
        self.f.eval_pruned(input, fws, fval, jac, Some(needed))?;
        for (v, &need) in fval.iter_mut().zip(needed.iter()) {
            if !need {
                *v = 0.0;
            }
        }
        dv.fill(0.0);
        for r in 0..n {
            dv[r] = s * fval[r];
        }
        let (phi0, bm0, bp0) = (n, n + n * n, n + n * n + n * m);
        // A·[Φ | B⁻ | B⁺] through the CSC columns of ∂f/∂x, scaled by s (entries that are zero
        // here, such as an inactive penalty's, are skipped).
        let axpy = |dst: &mut [f64], a: f64, src: &[f64]| {
            for (d, x) in dst.iter_mut().zip(src) {
                *d += a * x;
            }
        };
        for j in 0..n {
            for p in self.col_ptr[j]..self.col_ptr[j + 1] {
                if jac[p] == 0.0 {
                    continue;
                }
                let (r, a) = (self.rows[p], s * jac[p]);
                axpy(&mut dv[phi0 + r * n..][..n], a, &v[phi0 + j * n..][..n]);
                axpy(&mut dv[bm0 + r * m..][..m], a, &v[bm0 + j * m..][..m]);
                axpy(&mut dv[bp0 + r * m..][..m], a, &v[bp0 + j * m..][..m]);
            }
        }
        // Control columns: s ∂f/∂u · diag(α) into B⁻, · diag(β) into B⁺ (∂f/∂u alone for a
        // time-scaled entry: ∂(s f(x, w/s))/∂w = ∂f/∂u).
        for i in 0..mu {
            let (alpha, b) = if self.foh[i] { (1.0 - beta, beta) } else { (1.0, 0.0) };
            let scale = if self.time_scaled[i] { 1.0 } else { s };
            for p in self.col_ptr[n + i]..self.col_ptr[n + i + 1] {
                let (r, d) = (self.rows[p], scale * jac[p]);
                dv[bm0 + r * m + i] += d * alpha;
                dv[bp0 + r * m + i] += d * b;
            }
        }
        // The dilation column: ∂(s f)/∂s = f, zero-order hold; with time-scaled entries
        // (u = w/s) less Σ ∂f/∂u_i · u_i.
        for r in 0..n {
            dv[bm0 + r * m + mu] += fval[r];
        }
        for i in (0..mu).filter(|&i| self.time_scaled[i]) {
            for p in self.col_ptr[n + i]..self.col_ptr[n + i + 1] {
                dv[bm0 + self.rows[p] * m + mu] -= jac[p] * input[n + i];
            }
        }
        Ok(())
    }

    #[allow(clippy::too_many_arguments)]
    pub(super) fn integrate(
        &self,
        x: &[f64],
        u: &[f64],
        s: &[f64],
        settings: &DiscretizationSettings,
        ws: &mut DiscretizationWorkspace,
        out: &mut Discretization,
        full: bool,
    ) -> Result<(), DiscretizationError> {
        let (n, mu) = (self.n_x, self.n_u);
        let nodes = s.len();
        if nodes < 2
            || x.len() != nodes * n
            || u.len() != nodes * mu
            || out.segments != nodes - 1
            || settings.substeps == 0
            || (out.grid_points != 0 && out.grid_points != settings.substeps + 1)
        {
            return Err(DiscretizationError::Size(format!(
                "{nodes} nodes need x of {} (got {}), u of {} (got {}), an output for {} segments (has {}), substeps ≥ 1 and a grid of substeps + 1 points (substeps {}, grid points {})",
                nodes * n,
                x.len(),
                nodes * mu,
                u.len(),
                nodes.saturating_sub(1),
                out.segments,
                settings.substeps,
                out.grid_points
            )));
        }
        let segments = nodes - 1;
        let lanes = if settings.parallel { ws.lanes.len().min(segments) } else { 1 };
        let all = LaneOut {
            first: 0,
            grid_seg: out.grid_points * self.grid_stride(),
            grid: &mut out.grid,
            a: &mut out.a,
            b_minus: &mut out.b_minus,
            b_plus: &mut out.b_plus,
            x_prop: &mut out.x_prop,
            defect: &mut out.defect,
        };
        let plan = (settings.substeps, settings.integrator, full);
        self.discretize_lanes(x, u, s, plan, &mut ws.lanes[..lanes], segments, all)
    }
}
