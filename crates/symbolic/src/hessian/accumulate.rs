//! Where the second-order terms of a reverse sweep go: `H += c g_s g_sᵀ` and
//! `H += c (g_a g_bᵀ + g_b g_aᵀ)` for slot gradients `g`, into a dense square (few inputs),
//! the lower triangle of a sparse pattern, a dense local matrix (a `vmap` body), or
//! straight into a Hessian-vector product.

use crate::SparsityPattern;
use crate::tape::{Tape, Workspace};

/// A sink for the rank-one and symmetric rank-two terms of the Hessian.
pub(crate) trait Accumulate {
    /// `H += c g_s g_sᵀ`.
    fn rank1(&mut self, tape: &Tape, ws: &Workspace, s: u32, c: f64);
    /// `H += c (g_a g_bᵀ + g_b g_aᵀ)`.
    fn rank2(&mut self, tape: &Tape, ws: &Workspace, a: u32, b: u32, c: f64);
}

/// The sparse gradient of slot `s`: its dependency columns and their derivatives.
#[inline(always)]
fn sparse<'a>(tape: &'a Tape, ws: &'a Workspace, s: u32) -> (&'a [u32], &'a [f64]) {
    let (o, n) = tape.range(s);
    (tape.deps(s), &ws.dval[o..o + n])
}

/// Dense rows: slot gradients are `ws.dval[s·N..(s+1)·N]`; `h` is the full `N × N` square.
#[derive(Debug)]
pub(crate) struct DenseSquare<'a, const N: usize> {
    pub(crate) h: &'a mut [f64],
}

impl<const N: usize> DenseSquare<'_, N> {
    #[inline(always)]
    fn row(ws: &Workspace, s: u32) -> &[f64; N] {
        let o = s as usize * N;
        ws.dval[o..o + N].try_into().expect("row of N")
    }
}

impl<const N: usize> Accumulate for DenseSquare<'_, N> {
    #[inline]
    fn rank1(&mut self, tape: &Tape, ws: &Workspace, s: u32, c: f64) {
        if tape.range(s).1 == 0 {
            return;
        }
        let g = Self::row(ws, s);
        for i in 0..N {
            let ci = c * g[i];
            if ci != 0.0 {
                let h: &mut [f64; N] = (&mut self.h[i * N..i * N + N]).try_into().expect("row");
                for j in 0..N {
                    h[j] += ci * g[j];
                }
            }
        }
    }

    #[inline]
    fn rank2(&mut self, tape: &Tape, ws: &Workspace, a: u32, b: u32, c: f64) {
        if tape.range(a).1 == 0 || tape.range(b).1 == 0 {
            return;
        }
        let (ga, gb) = (Self::row(ws, a), Self::row(ws, b));
        for i in 0..N {
            let (ca, cb) = (c * ga[i], c * gb[i]);
            if ca != 0.0 || cb != 0.0 {
                let h: &mut [f64; N] = (&mut self.h[i * N..i * N + N]).try_into().expect("row");
                for j in 0..N {
                    h[j] += ca * gb[j] + cb * ga[j];
                }
            }
        }
    }
}

/// Sparse gradients into the nonzeros of a lower-triangular pattern.
#[derive(Debug)]
pub(crate) struct SparseLower<'a> {
    pub(crate) pattern: &'a SparsityPattern,
    pub(crate) h: &'a mut [f64],
}

impl SparseLower<'_> {
    #[inline]
    fn add(&mut self, i: u32, j: u32, v: f64) {
        let (r, c) = if i >= j { (i, j) } else { (j, i) };
        if let Some(p) = self.pattern.position(r as usize, c as usize) {
            self.h[p] += v;
        }
    }
}

impl Accumulate for SparseLower<'_> {
    fn rank1(&mut self, tape: &Tape, ws: &Workspace, s: u32, c: f64) {
        let (cols, g) = sparse(tape, ws, s);
        for (ii, (&i, &gi)) in cols.iter().zip(g).enumerate() {
            for (&j, &gj) in cols[..=ii].iter().zip(g) {
                self.add(i, j, c * gi * gj);
            }
        }
    }

    fn rank2(&mut self, tape: &Tape, ws: &Workspace, a: u32, b: u32, c: f64) {
        let ((ca, ga), (cb, gb)) = (sparse(tape, ws, a), sparse(tape, ws, b));
        for (&i, &gi) in ca.iter().zip(ga) {
            for (&j, &gj) in cb.iter().zip(gb) {
                let v = c * gi * gj;
                self.add(i, j, if i == j { 2.0 * v } else { v });
            }
        }
    }
}

/// Sparse gradients into a full dense `n × n` matrix (the local Hessian of a `vmap` body
/// with respect to its captured operands).
#[derive(Debug)]
pub(crate) struct LocalSquare<'a> {
    pub(crate) n: usize,
    pub(crate) h: &'a mut [f64],
}

impl Accumulate for LocalSquare<'_> {
    fn rank1(&mut self, tape: &Tape, ws: &Workspace, s: u32, c: f64) {
        let (cols, g) = sparse(tape, ws, s);
        for (&i, &gi) in cols.iter().zip(g) {
            for (&j, &gj) in cols.iter().zip(g) {
                self.h[i as usize * self.n + j as usize] += c * gi * gj;
            }
        }
    }

    fn rank2(&mut self, tape: &Tape, ws: &Workspace, a: u32, b: u32, c: f64) {
        let ((ca, ga), (cb, gb)) = (sparse(tape, ws, a), sparse(tape, ws, b));
        for (&i, &gi) in ca.iter().zip(ga) {
            for (&j, &gj) in cb.iter().zip(gb) {
                let v = c * gi * gj;
                self.h[i as usize * self.n + j as usize] += v;
                self.h[j as usize * self.n + i as usize] += v;
            }
        }
    }
}

/// `out += H v` term by term, with sparse gradients: `c g_s (g_s·v)` and
/// `c (g_a (g_b·v) + g_b (g_a·v))`.
#[derive(Debug)]
pub(crate) struct HessianVector<'a> {
    pub(crate) v: &'a [f64],
    pub(crate) out: &'a mut [f64],
}

impl HessianVector<'_> {
    /// `g_s · v`.
    fn dot(&self, tape: &Tape, ws: &Workspace, s: u32) -> f64 {
        let (cols, g) = sparse(tape, ws, s);
        cols.iter().zip(g).map(|(&c, g)| g * self.v[c as usize]).sum()
    }

    /// `out += k g_s`.
    fn axpy(&mut self, tape: &Tape, ws: &Workspace, s: u32, k: f64) {
        if k == 0.0 {
            return;
        }
        let (cols, g) = sparse(tape, ws, s);
        for (&c, g) in cols.iter().zip(g) {
            self.out[c as usize] += k * g;
        }
    }
}

impl Accumulate for HessianVector<'_> {
    fn rank1(&mut self, tape: &Tape, ws: &Workspace, s: u32, c: f64) {
        let d = self.dot(tape, ws, s);
        self.axpy(tape, ws, s, c * d);
    }

    fn rank2(&mut self, tape: &Tape, ws: &Workspace, a: u32, b: u32, c: f64) {
        let (da, db) = (self.dot(tape, ws, a), self.dot(tape, ws, b));
        self.axpy(tape, ws, a, c * db);
        self.axpy(tape, ws, b, c * da);
    }
}
