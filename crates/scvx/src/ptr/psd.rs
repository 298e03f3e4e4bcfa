//! The nearest matrix of a small symmetric block whose eigenvalues are at least a floor
//! (eigenvalues clipped), by cyclic Jacobi rotations in preallocated scratch — skipped when a
//! Cholesky factorization shows the block is above the floor already.

/// Replaces the symmetric `d×d` row-major `h` by `V·max(Λ, floor)·Vᵀ` (`h = VΛVᵀ`); with
/// `floor = 0` its projection onto the positive-semidefinite cone in the Frobenius norm.
/// `v` (`d×d`) and `lam` (`d`) are scratch. Cyclic Jacobi: quadratic convergence, accurate for the small blocks the
/// subproblem's curvature is made of; at most 50 sweeps. Returns the smallest eigenvalue
/// before clipping (`+∞` for `d = 0`).
pub(super) fn project_psd(
    h: &mut [f64],
    d: usize,
    floor: f64,
    v: &mut [f64],
    lam: &mut [f64],
) -> f64 {
    let (h, v, lam) = (&mut h[..d * d], &mut v[..d * d], &mut lam[..d]);
    v.fill(0.0);
    for i in 0..d {
        v[i * d + i] = 1.0;
    }
    let scale: f64 = h.iter().map(|x| x * x).sum::<f64>().sqrt();
    for _ in 0..50 {
        let off: f64 = (0..d)
            .flat_map(|p| (p + 1..d).map(move |q| (p, q)))
            .map(|(p, q)| h[p * d + q].powi(2))
            .sum();
        if off.sqrt() <= 1e-15 * scale {
            break;
        }
        for p in 0..d {
            for q in p + 1..d {
                rotate(h, v, d, p, q);
            }
        }
    }
    let mut smallest = f64::INFINITY;
    for i in 0..d {
        lam[i] = h[i * d + i];
        smallest = smallest.min(lam[i]);
    }
    for a in 0..d {
        for b in a..d {
            let x: f64 = (0..d).map(|i| v[a * d + i] * lam[i].max(floor) * v[b * d + i]).sum();
            h[a * d + b] = x;
            h[b * d + a] = x;
        }
    }
    smallest
}

/// As [`project_psd`] without its return value, but first a Cholesky factorization of
/// `h − floor·I` (into the scratch `v`): where it succeeds every eigenvalue of `h` lies above
/// the floor, the projection is `h` itself, and the eigendecomposition (some hundred times
/// the factorization's work at the subproblem's block sizes) is skipped.
pub(super) fn clip_below(h: &mut [f64], d: usize, floor: f64, v: &mut [f64], lam: &mut [f64]) {
    if !above_floor(&h[..d * d], d, floor, &mut v[..d * d]) {
        project_psd(h, d, floor, v, lam);
    }
}

/// Whether `h − floor·I` is positive definite: its Cholesky factor (lower, into `l`) exists
/// with positive pivots.
fn above_floor(h: &[f64], d: usize, floor: f64, l: &mut [f64]) -> bool {
    for j in 0..d {
        let mut pivot = h[j * d + j] - floor;
        for k in 0..j {
            pivot -= l[j * d + k] * l[j * d + k];
        }
        // A NaN pivot is not positive either.
        if pivot.is_nan() || pivot <= 0.0 {
            return false;
        }
        let root = pivot.sqrt();
        l[j * d + j] = root;
        for i in j + 1..d {
            let mut x = h[i * d + j];
            for k in 0..j {
                x -= l[i * d + k] * l[j * d + k];
            }
            l[i * d + j] = x / root;
        }
    }
    true
}

/// One Jacobi rotation zeroing `h[p][q]`, accumulated into the eigenvectors' columns `v`.
fn rotate(h: &mut [f64], v: &mut [f64], d: usize, p: usize, q: usize) {
    let hpq = h[p * d + q];
    if hpq == 0.0 {
        return;
    }
    let theta = (h[q * d + q] - h[p * d + p]) / (2.0 * hpq);
    let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
    let t = if theta == 0.0 { 1.0 } else { t };
    let c = 1.0 / (t * t + 1.0).sqrt();
    let s = t * c;
    for k in 0..d {
        let (hkp, hkq) = (h[k * d + p], h[k * d + q]);
        h[k * d + p] = c * hkp - s * hkq;
        h[k * d + q] = s * hkp + c * hkq;
    }
    for k in 0..d {
        let (hpk, hqk) = (h[p * d + k], h[q * d + k]);
        h[p * d + k] = c * hpk - s * hqk;
        h[q * d + k] = s * hpk + c * hqk;
    }
    for k in 0..d {
        let (vkp, vkq) = (v[k * d + p], v[k * d + q]);
        v[k * d + p] = c * vkp - s * vkq;
        v[k * d + q] = s * vkp + c * vkq;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{DMatrix, SymmetricEigen};
    use proptest::prelude::*;

    proptest! {
        /// Against nalgebra's eigendecomposition: the same clipped reconstruction and the same
        /// smallest eigenvalue, for random symmetric blocks of the sizes the subproblem has.
        #[test]
        fn projection_matches_the_clipped_eigendecomposition(
            d in 1usize..16,
            seed in proptest::collection::vec(-3.0f64..3.0, 256),
            rank_one in proptest::bool::ANY,
        ) {
            let mut h = vec![0.0; d * d];
            for a in 0..d {
                for b in a..d {
                    let x = if rank_one { seed[a] * seed[b] } else { seed[a * 16 + b] };
                    h[a * d + b] = x;
                    h[b * d + a] = x;
                }
            }
            let m = DMatrix::from_row_slice(d, d, &h);
            let eig = SymmetricEigen::new(m);
            let clipped = eig.eigenvalues.map(|l| l.max(0.0));
            let want = &eig.eigenvectors * DMatrix::from_diagonal(&clipped) * eig.eigenvectors.transpose();
            let (mut v, mut lam) = (vec![0.0; d * d], vec![0.0; d]);
            let smallest = project_psd(&mut h, d, 0.0, &mut v, &mut lam);
            let norm = want.norm().max(1.0);
            for a in 0..d {
                for b in 0..d {
                    prop_assert!((h[a * d + b] - want[(a, b)]).abs() <= 1e-10 * norm);
                }
            }
            prop_assert!((smallest - eig.eigenvalues.min()).abs() <= 1e-10 * norm);
        }

        /// `clip_below` is `project_psd`'s reconstruction, whether the Cholesky shortcut
        /// applies (every eigenvalue above the floor: the block unchanged) or not.
        #[test]
        fn clipping_below_a_floor_is_the_projection(
            d in 1usize..16,
            seed in proptest::collection::vec(-3.0f64..3.0, 256),
            shift in -2.0f64..8.0,
            floor in 0.0f64..1.0,
        ) {
            let mut h = vec![0.0; d * d];
            for a in 0..d {
                for b in a..d {
                    let x = seed[a * 16 + b] / d as f64 + if a == b { shift } else { 0.0 };
                    h[a * d + b] = x;
                    h[b * d + a] = x;
                }
            }
            let (mut v, mut lam) = (vec![0.0; d * d], vec![0.0; d]);
            let mut want = h.clone();
            project_psd(&mut want, d, floor, &mut v, &mut lam);
            let mut got = h.clone();
            clip_below(&mut got, d, floor, &mut v, &mut lam);
            let norm = want.iter().map(|x| x * x).sum::<f64>().sqrt().max(1.0);
            for (g, w) in got.iter().zip(&want) {
                prop_assert!((g - w).abs() <= 1e-10 * norm, "{g} vs {w}");
            }
            let eig = SymmetricEigen::new(DMatrix::from_row_slice(d, d, &h));
            if eig.eigenvalues.min() > floor + 1e-9 {
                prop_assert!(got == h, "definite above the floor: unchanged");
            }
        }
    }

    #[test]
    fn edge_cases_empty_zero_and_already_definite_blocks() {
        let (mut v, mut lam) = (vec![0.0; 9], vec![0.0; 3]);
        assert_eq!(project_psd(&mut [], 0, 0.0, &mut v, &mut lam), f64::INFINITY);
        let mut zero = vec![0.0; 9];
        assert_eq!(project_psd(&mut zero, 3, 0.0, &mut v, &mut lam), 0.0);
        assert!(zero.iter().all(|&x| x == 0.0));
        let spd = [4.0, 1.0, 0.0, 1.0, 3.0, 0.5, 0.0, 0.5, 2.0];
        let mut h = spd;
        assert!(project_psd(&mut h, 3, 0.0, &mut v, &mut lam) > 0.0);
        for (a, b) in h.iter().zip(&spd) {
            assert!((a - b).abs() < 1e-13);
        }
        // Negative definite: projected to zero.
        let mut neg = [-1.0, 0.2, 0.2, -2.0];
        assert!(project_psd(&mut neg, 2, 0.0, &mut v, &mut lam) < 0.0);
        assert!(neg.iter().all(|x| x.abs() < 1e-15));
        // With a floor: every eigenvalue at least the floor, those above it kept.
        let mut mixed = [3.0, 0.0, 0.0, -1.0];
        project_psd(&mut mixed, 2, 0.5, &mut v, &mut lam);
        assert!((mixed[0] - 3.0).abs() < 1e-15 && (mixed[3] - 0.5).abs() < 1e-15);
        assert!(mixed[1].abs() < 1e-15 && mixed[2].abs() < 1e-15);
    }
}
