//! Discretizing all segments: the parallel lanes (one per worker) and their outputs.

use super::*;

/// One lane's scratch.
#[derive(Debug, Clone)]
pub(super) struct Lane {
    pub(super) f: FEval,
    pub(super) v: Vec<f64>,
    /// Stage derivatives (RK4 uses the first four, Dormand–Prince all seven).
    pub(super) k: [Vec<f64>; 7],
    pub(super) tmp: Vec<f64>,
}

/// One lane's share of a [`Discretization`]: its first segment and its output slices.
pub(super) struct LaneOut<'a> {
    pub(super) first: usize,
    /// Grid values per segment (0 without a grid).
    pub(super) grid_seg: usize,
    pub(super) grid: &'a mut [f64],
    pub(super) a: &'a mut [f64],
    pub(super) b_minus: &'a mut [f64],
    pub(super) b_plus: &'a mut [f64],
    pub(super) x_prop: &'a mut [f64],
    pub(super) defect: &'a mut [f64],
}

impl<'a> LaneOut<'a> {
    /// Splits off the first `segs` segments (`n`, `m` = state and control + 1 sizes).
    pub(super) fn split(self, segs: usize, n: usize, m: usize) -> (LaneOut<'a>, LaneOut<'a>) {
        let (g, g2) = self.grid.split_at_mut(segs * self.grid_seg);
        let (a, a2) = self.a.split_at_mut(segs * n * n);
        let (bm, bm2) = self.b_minus.split_at_mut(segs * n * m);
        let (bp, bp2) = self.b_plus.split_at_mut(segs * n * m);
        let (xp, xp2) = self.x_prop.split_at_mut(segs * n);
        let (d, d2) = self.defect.split_at_mut(segs * n);
        (
            LaneOut {
                first: self.first,
                grid_seg: self.grid_seg,
                grid: g,
                a,
                b_minus: bm,
                b_plus: bp,
                x_prop: xp,
                defect: d,
            },
            LaneOut {
                first: self.first + segs,
                grid_seg: self.grid_seg,
                grid: g2,
                a: a2,
                b_minus: bm2,
                b_plus: bp2,
                x_prop: xp2,
                defect: d2,
            },
        )
    }
}

impl Dynamics {
    pub(super) fn lane(&self) -> Lane {
        let (n, m) = (self.n_x, self.n_u + 1);
        let len = n + n * n + 2 * n * m;
        Lane {
            f: FEval {
                ws: self.f.workspace(),
                input: vec![0.0; n + self.n_u],
                fval: vec![0.0; n],
                jac: vec![0.0; self.f.jacobian_pattern().nnz()],
                needed: vec![true; n],
            },
            v: vec![0.0; len],
            k: std::array::from_fn(|_| vec![0.0; len]),
            tmp: vec![0.0; len],
        }
    }

    /// Discretizes around nodes `x` (N×n row-major), `u` (N×m) and dilations `s` (N, ZOH:
    /// segment k uses `s[k]`) into `out`, allocation-free.
    ///
    /// # Errors
    /// Buffer sizes that do not match; evaluation errors.
    pub fn discretize(
        &self,
        x: &[f64],
        u: &[f64],
        s: &[f64],
        settings: &DiscretizationSettings,
        ws: &mut DiscretizationWorkspace,
        out: &mut Discretization,
    ) -> Result<(), DiscretizationError> {
        self.integrate(x, u, s, settings, ws, out, true)
    }

    /// The propagated states and defects of [`discretize`](Self::discretize) alone, without
    /// the variational equations: `out.x_prop` and `out.defect` are written (the same
    /// numbers `discretize` gives: the state part of its integration does not depend on
    /// the rest), `out.a`, `out.b_minus` and `out.b_plus` are left as they were. This is
    /// what pricing a candidate step needs, at a fraction of the cost (n of the
    /// n + n² + 2n(m + 1) integrated components, and no Jacobian evaluations).
    ///
    /// # Errors
    /// As [`discretize`](Self::discretize).
    pub fn defects(
        &self,
        x: &[f64],
        u: &[f64],
        s: &[f64],
        settings: &DiscretizationSettings,
        ws: &mut DiscretizationWorkspace,
        out: &mut Discretization,
    ) -> Result<(), DiscretizationError> {
        self.integrate(x, u, s, settings, ws, out, false)
    }

    /// Integrates `segments` segments into `out`, split evenly over `lanes`: the first lane
    /// runs on the calling thread, the others are spawned on the rayon pool (one small
    /// allocation per spawned lane; a `rayon::join` from outside the pool would queue both
    /// halves behind a possibly sleeping worker).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn discretize_lanes(
        &self,
        x: &[f64],
        u: &[f64],
        s: &[f64],
        plan: (usize, Integrator, bool),
        lanes: &mut [Lane],
        segments: usize,
        out: LaneOut<'_>,
    ) -> Result<(), DiscretizationError> {
        let count = lanes.len();
        let (first, rest) = lanes.split_first_mut().expect("at least one lane");
        if rest.is_empty() {
            return self.discretize_segments(x, u, s, plan, first, segments, out);
        }
        let (n, m) = (self.n_x, self.n_u + 1);
        let share = |i: usize| segments * (i + 1) / count - segments * i / count;
        let (mine, mut others) = out.split(share(0), n, m);
        let failed = std::sync::Mutex::new(None);
        rayon::in_place_scope(|scope| {
            for (i, lane) in rest.iter_mut().enumerate() {
                let (part, tail) = others.split(share(i + 1), n, m);
                others = tail;
                let failed = &failed;
                scope.spawn(move |_| {
                    let r = self.discretize_segments(x, u, s, plan, lane, share(i + 1), part);
                    if let Err(e) = r {
                        *failed.lock().unwrap_or_else(|p| p.into_inner()) = Some(e);
                    }
                });
            }
            if let Err(e) = self.discretize_segments(x, u, s, plan, first, share(0), mine) {
                *failed.lock().unwrap_or_else(|p| p.into_inner()) = Some(e);
            }
        });
        match failed.into_inner().unwrap_or_else(|p| p.into_inner()) {
            Some(e) => Err(e),
            None => Ok(()),
        }
    }

    /// Integrates segments `out.first..out.first + count` with one lane's scratch.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn discretize_segments(
        &self,
        x: &[f64],
        u: &[f64],
        s: &[f64],
        (substeps, integrator, full): (usize, Integrator, bool),
        ws: &mut Lane,
        count: usize,
        out: LaneOut<'_>,
    ) -> Result<(), DiscretizationError> {
        let (n, mu) = (self.n_x, self.n_u);
        let m = mu + 1;
        let nodes = s.len();
        let dtau = 1.0 / (nodes - 1) as f64;
        let h = dtau / substeps as f64;
        let len = if full { ws.v.len() } else { n };
        for local in 0..count {
            let seg = out.first + local;
            let (uk, uk1) = (&u[seg * mu..(seg + 1) * mu], &u[(seg + 1) * mu..(seg + 2) * mu]);
            let sk = s[seg];
            ws.v.fill(0.0);
            ws.v[..n].copy_from_slice(&x[seg * n..(seg + 1) * n]);
            for i in 0..n {
                ws.v[n + i * n + i] = 1.0;
            }
            let stride = self.grid_stride();
            let grid = &mut out.grid[local * out.grid_seg..(local + 1) * out.grid_seg];
            if !grid.is_empty() {
                grid[..len].copy_from_slice(&ws.v[..len]);
            }
            if let Integrator::DormandPrince { rtol, atol } = integrator {
                self.dormand_prince((rtol, atol), h, dtau, (uk, uk1, sk, seg), ws, full, grid)?;
            } else {
                let Lane { f, v, k, tmp } = &mut *ws;
                let [k0, k1, k2, k3, ..] = k;
                let seg_data = (uk, uk1, sk, seg);
                for step in 0..substeps {
                    let b0 = step as f64 / substeps as f64;
                    let bh = (step as f64 + 0.5) / substeps as f64;
                    let b1 = (step as f64 + 1.0) / substeps as f64;
                    // tmp = v + c·k over the first `len` entries.
                    let stage = |tmp: &mut [f64], v: &[f64], c: f64, k: &[f64]| {
                        for ((t, x), d) in tmp[..len].iter_mut().zip(&v[..len]).zip(&k[..len]) {
                            *t = x + c * d;
                        }
                    };
                    self.rhs(v, b0, seg_data, f, k0, full)?;
                    stage(tmp, v, 0.5 * h, k0);
                    self.rhs(tmp, bh, seg_data, f, k1, full)?;
                    stage(tmp, v, 0.5 * h, k1);
                    self.rhs(tmp, bh, seg_data, f, k2, full)?;
                    stage(tmp, v, h, k2);
                    self.rhs(tmp, b1, seg_data, f, k3, full)?;
                    let ks = k0[..len].iter().zip(&k1[..len]).zip(&k2[..len]).zip(&k3[..len]);
                    for (x, (((a, b), c), d)) in v[..len].iter_mut().zip(ks) {
                        *x += h / 6.0 * (a + 2.0 * b + 2.0 * c + d);
                    }
                    if !grid.is_empty() {
                        let at = (step + 1) * stride;
                        grid[at..at + len].copy_from_slice(&v[..len]);
                    }
                }
            }
            let v = &ws.v;
            let (phi0, bm0, bp0) = (n, n + n * n, n + n * n + n * m);
            out.x_prop[local * n..(local + 1) * n].copy_from_slice(&v[..n]);
            if full {
                out.a[local * n * n..(local + 1) * n * n].copy_from_slice(&v[phi0..phi0 + n * n]);
                out.b_minus[local * n * m..(local + 1) * n * m]
                    .copy_from_slice(&v[bm0..bm0 + n * m]);
                out.b_plus[local * n * m..(local + 1) * n * m]
                    .copy_from_slice(&v[bp0..bp0 + n * m]);
            }
            for i in 0..n {
                out.defect[local * n + i] = x[(seg + 1) * n + i] - v[i];
            }
        }
        Ok(())
    }
}
