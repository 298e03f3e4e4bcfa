//! Starting points: warm from the previous solve's duals, cold from a least-squares point;
//! the compaction of A around switched-off rows and the choice of KKT analysis.

use super::*;

impl InteriorPoint {
    /// This solve's nonzero entries of `a` into the `live_*` arrays (allocation-free: their
    /// capacities are A's pattern's).
    pub(super) fn compact(&mut self, a: &[f64]) {
        self.live_a.clear();
        self.live_rowval.clear();
        self.live_colptr.clear();
        self.live_colptr.push(0);
        for c in 0..self.n {
            for k in self.a_colptr[c]..self.a_colptr[c + 1] {
                if a[k] != 0.0 {
                    self.live_a.push(a[k]);
                    self.live_rowval.push(self.a_rowval[k]);
                }
            }
            self.live_colptr.push(self.live_a.len());
        }
        let pattern = (&self.live_colptr[..], &self.live_rowval[..]);
        self.live_rows.rebuild(self.m, pattern, &mut self.live_fill);
    }

    /// Makes `kkt` the analysis for this solve's switched-off rows (switchable rows with at
    /// most one nonzero value, read off the compacted A): the current one, a cached one, or —
    /// once per set of switched-off rows, allocating — a new analysis. A caller that zeroes
    /// the coefficients of rows it knows to be slack (PTR's far peak rows) then factors a
    /// smaller K.
    pub(super) fn select_kkt(&mut self) {
        for (d, &r) in self.off.iter_mut().zip(&self.switchable) {
            *d = self.live_rows.row(r).len() <= 1;
        }
        if self.off == self.kkt_off {
            return;
        }
        let cached =
            |d: &[bool], cache: &[(Vec<bool>, ReducedKkt)]| cache.iter().position(|e| e.0 == d);
        let kkt = match cached(&self.off, &self.kkt_cache) {
            Some(i) => self.kkt_cache.remove(i),
            None => {
                let (switchable, off) = (&self.switchable, &self.off);
                let is_off = |r: usize| switchable.binary_search(&r).is_ok_and(|i| off[i]);
                let p = (&self.p_colptr[..], &self.p_rowval[..]);
                let dense_row = self.settings.dense_row;
                match ReducedKkt::analyse(self.n, p, &self.rows, &self.cones, dense_row, is_off) {
                    Ok(mut kkt) => {
                        if let Some(stages) = &self.stages {
                            kkt.reorder(stages);
                        }
                        (self.off.clone(), kkt)
                    }
                    // A subset of a pattern that was analysed cannot fail; were it to, the
                    // full pattern's analysis (current or kept in the cache) serves any values.
                    Err(_) => {
                        self.off.fill(false);
                        match cached(&self.off, &self.kkt_cache) {
                            Some(i) => self.kkt_cache.remove(i),
                            None => return,
                        }
                    }
                }
            }
        };
        if self.kkt_cache.len() == KKT_CACHE {
            // Never evict the full pattern's analysis (no row off): it serves any values.
            let i = self.kkt_cache.iter().position(|(d, _)| d.iter().any(|&x| x)).unwrap_or(0);
            self.kkt_cache.remove(i);
        }
        let old_off = std::mem::replace(&mut self.kkt_off, kkt.0);
        let old = std::mem::replace(&mut self.kkt, kkt.1);
        self.kkt_cache.push((old_off, old));
    }

    /// Warm start: x = 0 (PTR's deviation form), the previous duals and s = b, each pushed
    /// at least θ inside its cone; nonnegative rows centred at μ₀ (see
    /// [`IpmSettings::warm_start_centring`]).
    pub(super) fn start_warm(&mut self, b: &[f64]) {
        let (m0, theta) = (self.cones.zero, self.settings.warm_start_margin);
        let mu0 = self.settings.warm_start_centring;
        self.x.fill(0.0);
        self.s[..m0].fill(0.0);
        self.s[m0..].copy_from_slice(&b[m0..]);
        push_inside(&mut self.s[m0..], &self.cones, theta);
        let nonneg = m0..m0 + self.cones.nonneg;
        for ((s, z), &b) in self.s[nonneg.clone()].iter_mut().zip(&mut self.z[nonneg]).zip(&b[m0..])
        {
            if mu0 > 0.0 {
                if b >= 0.0 && *z > *s && *z * *s > mu0 {
                    *s = (mu0 / *z).max(b);
                }
                *z = z.max(mu0 / *s);
            } else {
                *z = z.max(theta);
            }
        }
        push_inside_socs(&mut self.z[m0 + self.cones.nonneg..], &self.cones.soc, theta);
    }

    /// Cold start: with W = I, the least-squares point of the KKT system
    /// (x, z₀ from `[P + GᵀG, A₀ᵀ; A₀, −δ] = [−q + Gᵀb_G; b₀]`, z_G = Gx − b_G, s_G = −z_G),
    /// then s and z shifted into the cone interior.
    pub(super) fn start_cold(&mut self, p: &[f64], q: &[f64], a: &[f64], b: &[f64]) -> bool {
        let (n, m0) = (self.n, self.cones.zero);
        self.scaling.identity();
        if !self.kkt.factor(p, a, &self.scaling, &self.cones, self.settings.regularization) {
            return false;
        }
        // The reduced system's right-hand side with r₁ = −q, W = I and v = −b_G.
        let nw = &mut self.newton;
        nw.r1.iter_mut().zip(q).for_each(|(r, qi)| *r = -qi);
        nw.v.iter_mut().zip(&b[m0..]).for_each(|(v, bi)| *v = -bi);
        let by_columns = (&self.live_colptr[..], &self.live_rowval[..], &self.live_a[..]);
        self.kkt.load_rhs((&nw.r1, &b[..m0]), by_columns, (&nw.v, &nw.v));
        self.kkt.solve();
        self.x.copy_from_slice(&self.kkt.sol[..n]);
        self.z[..m0].copy_from_slice(&self.kkt.sol[n..n + m0]);
        self.s.fill(0.0);
        for r in m0..self.m {
            let g = self.live_rows.dot_from(-b[r], r, &self.live_a, &self.x);
            self.z[r] = g;
            self.s[r] = -g;
        }
        shift_into_cone(&mut self.s[m0..], &self.cones);
        shift_into_cone(&mut self.z[m0..], &self.cones);
        true
    }
}
