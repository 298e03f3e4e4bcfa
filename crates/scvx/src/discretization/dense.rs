//! Dense single-shooting propagation with the first-order-hold controls.

use super::*;

impl Dynamics {
    /// Dense propagation for post-processing: integrates `ẋ = f(x, u)` from `x0` through all
    /// segments with the FOH controls `u` (N×m) and per-segment durations `s_k·Δτ`, in RK4
    /// steps no longer than `dt` (each segment is split evenly). Returns `(times, states)`,
    /// states row-major, starting with `(0, x0)`. Gated rows follow their segment windows.
    ///
    /// # Errors
    /// Sizes that do not match, `dt ≤ 0`, evaluation errors.
    pub fn propagate(
        &self,
        x0: &[f64],
        u: &[f64],
        s: &[f64],
        dt: f64,
    ) -> Result<(Vec<f64>, Vec<f64>), DiscretizationError> {
        self.propagate_dense(x0, u, s, dt).map(|d| (d.time, d.x))
    }

    /// [`propagate`](Self::propagate) with the first-order-hold controls at every sample
    /// (what the dynamics saw there) and each sample's segment.
    ///
    /// # Errors
    /// As [`propagate`](Self::propagate).
    pub fn propagate_dense(
        &self,
        x0: &[f64],
        u: &[f64],
        s: &[f64],
        dt: f64,
    ) -> Result<DenseTrajectory, DiscretizationError> {
        let (n, mu) = (self.n_x, self.n_u);
        let nodes = s.len();
        if nodes < 2 || x0.len() != n || u.len() != nodes * mu || dt.is_nan() || dt <= 0.0 {
            return Err(DiscretizationError::Size(format!(
                "propagate: x0 of {n} (got {}), u of {} (got {}), ≥ 2 nodes and dt > 0",
                x0.len(),
                nodes * mu,
                u.len()
            )));
        }
        let dtau = 1.0 / (nodes - 1) as f64;
        let mut ws = self.lane();
        let (mut times, mut states) = (vec![0.0], x0.to_vec());
        let mut controls: Vec<f64> =
            (0..mu).map(|i| self.physical_control(i, u[i], s[0])).collect();
        let mut segment = vec![0];
        let mut x = x0.to_vec();
        let (mut k0, mut k1, mut k2, mut k3, mut tmp) =
            (vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        let mut t = 0.0;
        for seg in 0..nodes - 1 {
            let (uk, uk1) = (&u[seg * mu..(seg + 1) * mu], &u[(seg + 1) * mu..(seg + 2) * mu]);
            let duration = s[seg] * dtau;
            let steps = (duration / dt).ceil().max(1.0) as usize;
            let h = duration / steps as f64;
            let mut f =
                |x: &[f64], beta: f64, out: &mut [f64]| -> Result<(), DiscretizationError> {
                    let FEval { ws: fws, input, fval, .. } = &mut ws.f;
                    input[..n].copy_from_slice(x);
                    for i in 0..mu {
                        input[n + i] = self.held_control(i, (uk, uk1), beta, s[seg]);
                    }
                    self.f.eval(input, fws, fval, None)?;
                    for &(row, first, end) in &self.gates {
                        if seg < first || seg >= end {
                            fval[row] = 0.0;
                        }
                    }
                    out.copy_from_slice(fval);
                    Ok(())
                };
            for step in 0..steps {
                let b0 = step as f64 / steps as f64;
                let bh = (step as f64 + 0.5) / steps as f64;
                let b1 = (step as f64 + 1.0) / steps as f64;
                f(&x, b0, &mut k0)?;
                for i in 0..n {
                    tmp[i] = x[i] + 0.5 * h * k0[i];
                }
                f(&tmp, bh, &mut k1)?;
                for i in 0..n {
                    tmp[i] = x[i] + 0.5 * h * k1[i];
                }
                f(&tmp, bh, &mut k2)?;
                for i in 0..n {
                    tmp[i] = x[i] + h * k2[i];
                }
                f(&tmp, b1, &mut k3)?;
                for i in 0..n {
                    x[i] += h / 6.0 * (k0[i] + 2.0 * k1[i] + 2.0 * k2[i] + k3[i]);
                }
                t += h;
                times.push(t);
                states.extend_from_slice(&x);
                segment.push(seg);
                for i in 0..mu {
                    controls.push(self.held_control(i, (uk, uk1), b1, s[seg]));
                }
            }
        }
        Ok(DenseTrajectory { time: times, x: states, u: controls, segment })
    }
}
