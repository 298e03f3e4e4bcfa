//! A second-order forward jet in `N` variables (value, gradient, Hessian), for the local
//! second derivatives of the Lie nodes.

use core::ops::{Add, Mul, Sub};

use super::coefficients::Coefficient;

/// `v + gᵀδ + ½ δᵀ h δ`: a scalar with its gradient and (symmetric) Hessian in `N` variables.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Jet<const N: usize> {
    pub(crate) v: f64,
    pub(crate) g: [f64; N],
    pub(crate) h: [[f64; N]; N],
}

impl<const N: usize> Jet<N> {
    /// A constant.
    pub(crate) fn constant(v: f64) -> Self {
        Self { v, g: [0.0; N], h: [[0.0; N]; N] }
    }

    /// Variable `i` at value `v`.
    pub(crate) fn var(i: usize, v: f64) -> Self {
        let mut j = Self::constant(v);
        j.g[i] = 1.0;
        j
    }

    /// `k(self)` for a coefficient function given with its first two derivatives at
    /// `self.v`: `h = k′ h + k″ g gᵀ`.
    pub(crate) fn compose(&self, k: Coefficient) -> Self {
        let mut out = Self::constant(k.f);
        for i in 0..N {
            out.g[i] = k.f1 * self.g[i];
            for j in 0..N {
                out.h[i][j] = k.f1 * self.h[i][j] + k.f2 * self.g[i] * self.g[j];
            }
        }
        out
    }
}

impl<const N: usize> Add for Jet<N> {
    type Output = Self;
    fn add(mut self, o: Self) -> Self {
        self.v += o.v;
        for i in 0..N {
            self.g[i] += o.g[i];
            for j in 0..N {
                self.h[i][j] += o.h[i][j];
            }
        }
        self
    }
}

impl<const N: usize> Sub for Jet<N> {
    type Output = Self;
    fn sub(self, o: Self) -> Self {
        self + o * -1.0
    }
}

impl<const N: usize> Mul<f64> for Jet<N> {
    type Output = Self;
    fn mul(mut self, s: f64) -> Self {
        self.v *= s;
        for i in 0..N {
            self.g[i] *= s;
            for j in 0..N {
                self.h[i][j] *= s;
            }
        }
        self
    }
}

impl<const N: usize> Mul for Jet<N> {
    type Output = Self;
    fn mul(self, o: Self) -> Self {
        let mut out = Self::constant(self.v * o.v);
        for i in 0..N {
            out.g[i] = self.g[i] * o.v + self.v * o.g[i];
            for j in 0..N {
                out.h[i][j] = self.h[i][j] * o.v
                    + self.v * o.h[i][j]
                    + self.g[i] * o.g[j]
                    + o.g[i] * self.g[j];
            }
        }
        out
    }
}

/// `a × b` of jet 3-vectors.
pub(crate) fn cross<const N: usize>(a: &[Jet<N>; 3], b: &[Jet<N>; 3]) -> [Jet<N>; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

/// `a · b` of jet 3-vectors.
pub(crate) fn dot<const N: usize>(a: &[Jet<N>; 3], b: &[Jet<N>; 3]) -> Jet<N> {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `f(x, y) = x² y + 3 y`: gradient and Hessian by hand.
    #[test]
    fn products_and_sums() {
        let (x, y) = (Jet::<2>::var(0, 2.0), Jet::<2>::var(1, -1.0));
        let f = x * x * y + y * 3.0;
        assert_eq!(f.v, -4.0 - 3.0);
        assert_eq!(f.g, [-4.0, 4.0 + 3.0]);
        assert_eq!(f.h, [[-2.0, 4.0], [4.0, 0.0]]);
        let k = Coefficient { f: 5.0, f1: 2.0, f2: 3.0 };
        let c = (x - y).compose(k);
        assert_eq!(c.g, [2.0, -2.0]);
        assert_eq!(c.h, [[3.0, -3.0], [-3.0, 3.0]]);
    }
}
