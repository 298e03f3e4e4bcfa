//! One Newton step: residuals, the direction from the reduced KKT system (refined against
//! the full one), the step to the cones' boundary and the gap it would reach.

use super::*;

/// Buffers of one Newton solve: right-hand side b, residual r, correction c, scratch.
#[derive(Debug, Default)]
pub(super) struct Newton {
    pub(super) b1: Vec<f64>,
    pub(super) b2: Vec<f64>,
    pub(super) b3: Vec<f64>,
    pub(super) r1: Vec<f64>,
    pub(super) r2: Vec<f64>,
    pub(super) r3: Vec<f64>,
    pub(super) cx: Vec<f64>,
    pub(super) cz: Vec<f64>,
    pub(super) cs: Vec<f64>,
    pub(super) v: Vec<f64>,
    pub(super) t1: Vec<f64>,
    pub(super) t2: Vec<f64>,
    pub(super) t3: Vec<f64>,
}

impl Newton {
    pub(super) fn new(n: usize, m: usize, mc: usize) -> Newton {
        let (x, all, cone) = (vec![0.0; n], vec![0.0; m], vec![0.0; mc]);
        Newton {
            b1: x.clone(),
            b2: all.clone(),
            b3: cone.clone(),
            r1: x.clone(),
            r2: all.clone(),
            r3: cone.clone(),
            cx: x,
            cz: all.clone(),
            cs: all,
            v: cone.clone(),
            t1: cone.clone(),
            t2: cone.clone(),
            t3: cone,
        }
    }
}

/// Residual norms, gap and objectives at an iterate.
pub(super) struct Residuals {
    pub(super) primal: f64,
    pub(super) dual: f64,
    pub(super) gap: f64,
    pub(super) pobj: f64,
    pub(super) dobj: f64,
}

impl InteriorPoint {
    /// r_x = Px + q + Aᵀz and r_z = Ax + s − b (into `rx`, `rz`), their norms, the gap sᵀz
    /// and the primal and dual objectives.
    pub(super) fn residuals(&mut self, p: &[f64], q: &[f64], b: &[f64]) -> Residuals {
        let (n, m0) = (self.n, self.cones.zero);
        self.rx.copy_from_slice(q);
        let mut xpx = 0.0;
        for c in 0..n {
            for k in self.p_colptr[c]..self.p_colptr[c + 1] {
                let r = self.p_rowval[k];
                self.rx[r] += p[k] * self.x[c];
                if r != c {
                    self.rx[c] += p[k] * self.x[r];
                    xpx += 2.0 * p[k] * self.x[r] * self.x[c];
                } else {
                    xpx += p[k] * self.x[c] * self.x[c];
                }
            }
        }
        let a = &self.live_a;
        for c in 0..n {
            let range = self.live_colptr[c]..self.live_colptr[c + 1];
            let zc = self.live_rowval[range.clone()].iter().zip(&a[range]);
            self.rx[c] += zc.map(|(&r, ak)| ak * self.z[r]).sum::<f64>();
        }
        // Row by row: each rz entry is one gathered sum instead of scattered updates.
        for (r, out) in self.rz.iter_mut().enumerate() {
            *out = self.live_rows.dot_from(self.s[r] - b[r], r, a, &self.x);
        }
        Residuals {
            primal: inf_norm(&self.rz),
            dual: inf_norm(&self.rx),
            gap: self.s[m0..].iter().zip(&self.z[m0..]).map(|(s, z)| s * z).sum(),
            pobj: 0.5 * xpx + dot(q, &self.x),
            dobj: -0.5 * xpx - dot(b, &self.z),
        }
    }

    /// The gap sᵀz (cone rows) after a step α along (Δs, Δz).
    pub(super) fn gap_after(&self, alpha: f64) -> f64 {
        let m0 = self.cones.zero;
        (m0..self.m)
            .map(|r| (self.s[r] + alpha * self.ds[r]) * (self.z[r] + alpha * self.dz[r]))
            .sum()
    }

    /// Largest step along (Δs, Δz) that keeps both in the cones.
    pub(super) fn step_to_boundary(&self) -> f64 {
        let m0 = self.cones.zero;
        step_length(&self.cones, &self.s[m0..], &self.ds[m0..], &self.z[m0..], &self.dz[m0..])
    }

    /// Newton direction for the current residuals and the complementarity term u:
    ///
    /// ```text
    /// PΔx + AᵀΔz = −r_x,   AΔx + Δs = −r_z,   WΔz + W⁻¹Δs = u (cone rows; Δs = 0 on equality rows)
    /// ```
    ///
    /// solved through the reduced KKT matrix, then, if `refine`, refined against this full
    /// system.
    pub(super) fn direction(&mut self, p: &[f64], refine: bool) {
        let (n, m0, m) = (self.n, self.cones.zero, self.m);
        let mut nw = std::mem::take(&mut self.newton);
        for (r, x) in nw.b1.iter_mut().zip(&self.rx) {
            *r = -x;
        }
        for (r, x) in nw.b2.iter_mut().zip(&self.rz) {
            *r = -x;
        }
        nw.b3.copy_from_slice(&self.u);
        nw.r1.copy_from_slice(&nw.b1);
        nw.r2.copy_from_slice(&nw.b2);
        nw.r3.copy_from_slice(&nw.b3);
        self.reduced_solve(&mut nw);
        self.dx.copy_from_slice(&nw.cx);
        self.dz.copy_from_slice(&nw.cz);
        self.ds.copy_from_slice(&nw.cs);
        let bnorm = inf_norm(&nw.b1).max(inf_norm(&nw.b2)).max(inf_norm(&nw.b3));
        // Refine until the direction's error is well below what the tolerance asks of the
        // iterates (an error left in a direction lands in the next residuals).
        let target = 1e-2 * self.tolerance * (1.0 + bnorm);
        let steps = if refine { self.settings.refinement_steps } else { 0 };
        for _ in 0..steps {
            // r = b − K(Δx, Δz, Δs)
            nw.r1.copy_from_slice(&nw.b1);
            for c in 0..n {
                for k in self.p_colptr[c]..self.p_colptr[c + 1] {
                    let r = self.p_rowval[k];
                    nw.r1[r] -= p[k] * self.dx[c];
                    if r != c {
                        nw.r1[c] -= p[k] * self.dx[r];
                    }
                }
            }
            let a = &self.live_a;
            for c in 0..n {
                let range = self.live_colptr[c]..self.live_colptr[c + 1];
                let zc = self.live_rowval[range.clone()].iter().zip(&a[range]);
                nw.r1[c] -= zc.map(|(&r, ak)| ak * self.dz[r]).sum::<f64>();
            }
            for (r, out) in nw.r2.iter_mut().enumerate() {
                *out = nw.b2[r] - self.ds[r] - self.live_rows.dot(r, a, &self.dx);
            }
            self.scaling.apply_w(&self.dz[m0..], &mut nw.t1);
            self.scaling.apply_winv(&self.ds[m0..], &mut nw.t2);
            for i in 0..m - m0 {
                nw.r3[i] = nw.b3[i] - nw.t1[i] - nw.t2[i];
            }
            let err = inf_norm(&nw.r1).max(inf_norm(&nw.r2)).max(inf_norm(&nw.r3));
            if err <= target {
                break;
            }
            self.reduced_solve(&mut nw);
            self.dx.iter_mut().zip(&nw.cx).for_each(|(d, c)| *d += c);
            self.dz.iter_mut().zip(&nw.cz).for_each(|(d, c)| *d += c);
            self.ds.iter_mut().zip(&nw.cs).for_each(|(d, c)| *d += c);
        }
        self.newton = nw;
    }

    /// One solve of the Newton system with right-hand side (r1, r2, r3) through the reduced
    /// KKT factorization, into (cx, cz, cs).
    pub(super) fn reduced_solve(&mut self, nw: &mut Newton) {
        let (n, m0, m) = (self.n, self.cones.zero, self.m);
        let (a, rows) = (&self.live_a, &self.live_rows);
        // v = W r3 − r2_G; Δz_G = W⁻²(GΔx + v); Δs_G = r2_G − GΔx.
        self.scaling.apply_w(&nw.r3, &mut nw.t1);
        for r in m0..m {
            nw.v[r - m0] = nw.t1[r - m0] - nw.r2[r];
        }
        self.scaling.apply_winv2(&nw.v, &mut nw.t2, &mut nw.t3);
        let by_columns = (&self.live_colptr[..], &self.live_rowval[..], &a[..]);
        self.kkt.load_rhs((&nw.r1, &nw.r2[..m0]), by_columns, (&nw.t2, &nw.v));
        self.kkt.solve();
        nw.cx.copy_from_slice(&self.kkt.sol[..n]);
        nw.cz[..m0].copy_from_slice(&self.kkt.sol[n..n + m0]);
        for r in m0..m {
            let g = rows.dot(r, a, &nw.cx);
            nw.cs[r] = nw.r2[r] - g;
            nw.t1[r - m0] = g + nw.v[r - m0];
        }
        self.scaling.apply_winv2(&nw.t1, &mut nw.t2, &mut nw.t3);
        nw.cz[m0..].copy_from_slice(&nw.t2);
        nw.cs[..m0].fill(0.0);
    }
}
