//! The rotation-angle coefficient functions of the Lie nodes with their first and second
//! derivatives in `t = θ²`, for the second-order local derivatives of `so3/se3` exp and log.
//!
//! `a = sin θ/θ`, `b = (1 − cos θ)/θ²`, `c = (θ − sin θ)/θ³` (exp and its Jacobians) and
//! `d = 1/θ² − cot(θ/2)/(2θ)` (the inverse Jacobians). As functions of `t` they are entire
//! (`d` up to `θ = 2π`), so derivatives in `t` have no singularity at `θ = 0`. Below
//! [`SERIES_T`] their Taylor series in `t` are differentiated term by term; above it the
//! closed forms are differentiated in θ (a second-order dual number) and converted with
//! `f_t = f_θ/(2θ)`, `f_tt = (θ f_θθ − f_θ)/(4θ³)`, whose cancellation is mild there.

/// `t = θ²` below which the series are used (θ < 0.5 rad: ten terms reach round-off).
const SERIES_T: f64 = 0.25;

/// Series terms (`t⁰ … t⁹`).
const TERMS: usize = 10;

/// A coefficient function and its derivatives in `t`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Coefficient {
    pub(crate) f: f64,
    pub(crate) f1: f64,
    pub(crate) f2: f64,
}

/// Which coefficient.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Kind {
    /// `sin θ/θ`
    A,
    /// `(1 − cos θ)/θ²`
    B,
    /// `(θ − sin θ)/θ³`
    C,
    /// `1/θ² − cot(θ/2)/(2θ)`
    D,
}

/// Bernoulli numbers |B_2|, |B_4|, …, |B_20|.
const BERNOULLI: [f64; 10] = [
    1.0 / 6.0,
    1.0 / 30.0,
    1.0 / 42.0,
    1.0 / 30.0,
    5.0 / 66.0,
    691.0 / 2730.0,
    7.0 / 6.0,
    3617.0 / 510.0,
    43867.0 / 798.0,
    174611.0 / 330.0,
];

fn factorial(n: usize) -> f64 {
    (1..=n).map(|k| k as f64).product()
}

/// Series coefficient `k` (of `t^k`).
fn series_coefficient(kind: Kind, k: usize) -> f64 {
    let sign = if k.is_multiple_of(2) { 1.0 } else { -1.0 };
    match kind {
        Kind::A => sign / factorial(2 * k + 1),
        Kind::B => sign / factorial(2 * k + 2),
        Kind::C => sign / factorial(2 * k + 3),
        Kind::D => BERNOULLI[k] / factorial(2 * k + 2),
    }
}

/// Second-order dual number in θ: value, first and second derivative.
#[derive(Debug, Clone, Copy)]
struct Dual2(f64, f64, f64);

impl Dual2 {
    fn mul(self, o: Dual2) -> Dual2 {
        Dual2(
            self.0 * o.0,
            self.1 * o.0 + self.0 * o.1,
            self.2 * o.0 + 2.0 * self.1 * o.1 + self.0 * o.2,
        )
    }
    fn recip(self) -> Dual2 {
        let r = 1.0 / self.0;
        Dual2(r, -self.1 * r * r, (2.0 * self.1 * self.1 * r - self.2) * r * r)
    }
    fn div(self, o: Dual2) -> Dual2 {
        self.mul(o.recip())
    }
    fn sub(self, o: Dual2) -> Dual2 {
        Dual2(self.0 - o.0, self.1 - o.1, self.2 - o.2)
    }
    fn scale(self, s: f64) -> Dual2 {
        Dual2(s * self.0, s * self.1, s * self.2)
    }
    /// `sin` and `cos` of `s·θ` for the identity dual θ.
    fn sin_cos_of(theta: f64, s: f64) -> (Dual2, Dual2) {
        let (sn, cs) = (s * theta).sin_cos();
        (Dual2(sn, s * cs, -s * s * sn), Dual2(cs, -s * sn, -s * s * cs))
    }
}

/// The coefficient `kind` at `t = θ² ≥ 0` with its first two derivatives in `t`.
pub(crate) fn coefficient(kind: Kind, t: f64) -> Coefficient {
    if t < SERIES_T {
        // Horner's rule on the series and on its first and second derivative polynomials.
        let (mut f, mut f1, mut f2) = (0.0, 0.0, 0.0);
        for k in (0..TERMS).rev() {
            let c = series_coefficient(kind, k);
            f = f * t + c;
            if k >= 1 {
                f1 = f1 * t + k as f64 * c;
            }
            if k >= 2 {
                f2 = f2 * t + (k * (k - 1)) as f64 * c;
            }
        }
        return Coefficient { f, f1, f2 };
    }
    let theta = t.sqrt();
    let th = Dual2(theta, 1.0, 0.0);
    let (s, c) = Dual2::sin_cos_of(theta, 1.0);
    let one = Dual2(1.0, 0.0, 0.0);
    let g = match kind {
        Kind::A => s.div(th),
        Kind::B => one.sub(c).div(th.mul(th)),
        Kind::C => th.sub(s).div(th.mul(th).mul(th)),
        Kind::D => {
            let (sh, ch) = Dual2::sin_cos_of(theta, 0.5);
            th.mul(th).recip().sub(ch.div(th.mul(sh).scale(2.0)))
        }
    };
    Coefficient { f: g.0, f1: g.1 / (2.0 * theta), f2: (theta * g.2 - g.1) / (4.0 * t * theta) }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn closed(kind: Kind, t: f64) -> f64 {
        let th = t.sqrt();
        match kind {
            Kind::A => th.sin() / th,
            Kind::B => (1.0 - th.cos()) / t,
            Kind::C => (th - th.sin()) / (t * th),
            Kind::D => 1.0 / t - (0.5 * th).cos() / (2.0 * th * (0.5 * th).sin()),
        }
    }

    /// Values against the closed forms, first derivatives against central differences of
    /// the closed forms, second derivatives against central differences of the first, and continuity across the series switch.
    #[test]
    fn coefficients_and_their_derivatives() {
        for kind in [Kind::A, Kind::B, Kind::C, Kind::D] {
            for &t in &[0.3, 0.7, 1.5, 4.0, 9.0, 9.8696] {
                let k = coefficient(kind, t);
                assert!((k.f - closed(kind, t)).abs() < 1e-13, "{kind:?} {t}");
                let h = 1e-4;
                let d1 = (closed(kind, t + h) - closed(kind, t - h)) / (2.0 * h);
                let d2 = (coefficient(kind, t + h).f1 - coefficient(kind, t - h).f1) / (2.0 * h);
                assert!(
                    (k.f1 - d1).abs() < 1e-8 * d1.abs().max(1e-3),
                    "{kind:?} f1 {t}: {} {d1}",
                    k.f1
                );
                assert!(
                    (k.f2 - d2).abs() < 1e-5 * d2.abs().max(1e-3),
                    "{kind:?} f2 {t}: {} {d2}",
                    k.f2
                );
            }
            let (lo, hi) =
                (coefficient(kind, SERIES_T * (1.0 - 1e-12)), coefficient(kind, SERIES_T));
            for (a, b) in [(lo.f, hi.f), (lo.f1, hi.f1), (lo.f2, hi.f2)] {
                assert!((a - b).abs() < 1e-11 * b.abs().max(1e-3), "{kind:?} switch {a} {b}");
            }
            let z = coefficient(kind, 0.0);
            assert_eq!(z.f, series_coefficient(kind, 0));
            assert_eq!(z.f1, series_coefficient(kind, 1));
            assert_eq!(z.f2, 2.0 * series_coefficient(kind, 2));
        }
    }
}
