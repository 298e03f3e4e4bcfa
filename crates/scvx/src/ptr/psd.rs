//! The nearest matrix of a small symmetric block whose eigenvalues are at least a floor
//! (eigenvalues clipped), by Householder tridiagonalization and the implicit QL algorithm in
//! preallocated scratch — skipped when a Cholesky factorization shows the block is above the
//! floor already.

/// Replaces the symmetric `d×d` row-major `h` by `V·max(Λ, floor)·Vᵀ` (`h = VΛVᵀ`); with
/// `floor = 0` its projection onto the positive-semidefinite cone in the Frobenius norm.
/// `v` (`d×d`) and `lam` (`d`) are scratch. The eigendecomposition is
/// [`symmetric_eigen`]'s. Returns the smallest eigenvalue before clipping (`+∞` for `d = 0`,
/// NaN for a block with a non-finite entry, which is left as it is).
pub(super) fn project_psd(
    h: &mut [f64],
    d: usize,
    floor: f64,
    v: &mut [f64],
    lam: &mut [f64],
) -> f64 {
    let (h, v, lam) = (&mut h[..d * d], &mut v[..d * d], &mut lam[..d]);
    if h.iter().any(|x| !x.is_finite()) {
        return f64::NAN;
    }
    v.copy_from_slice(h);
    // `h` is free until the reconstruction: its first row holds the off-diagonal.
    symmetric_eigen(v, d, lam, &mut h[..d]);
    let smallest = lam.iter().copied().fold(f64::INFINITY, f64::min);
    for a in 0..d {
        for b in a..d {
            let x: f64 = (0..d).map(|i| v[a * d + i] * lam[i].max(floor) * v[b * d + i]).sum();
            h[a * d + b] = x;
            h[b * d + a] = x;
        }
    }
    smallest
}

/// The eigendecomposition `A = V·diag(λ)·Vᵀ` of the symmetric `d×d` row-major `v` (replaced
/// by the eigenvectors, one per column; `lam` gets the eigenvalues, `e` is scratch of length
/// `d`): Householder reduction to tridiagonal form, then the implicit QL algorithm with
/// Wilkinson-like shifts (EISPACK's `tred2` and `tql2`): a fixed reduction and a few QL
/// sweeps per eigenvalue, where the cyclic Jacobi sweeps this replaced repeated all `d²/2`
/// rotations until convergence (on the seed's blocks, a fifth of their time). The entries
/// must be finite.
pub(super) fn symmetric_eigen(v: &mut [f64], d: usize, lam: &mut [f64], e: &mut [f64]) {
    if d == 0 {
        return;
    }
    tridiagonalize(v, d, lam, e);
    tridiagonal_ql(v, d, lam, e);
}

/// `tred2`: `v ← Q` with `QᵀAQ` tridiagonal, its diagonal in `diag` and its subdiagonal in
/// `e[1..]` (`e[0] = 0`).
fn tridiagonalize(v: &mut [f64], n: usize, diag: &mut [f64], e: &mut [f64]) {
    let at = |i: usize, j: usize| i * n + j;
    diag.copy_from_slice(&v[at(n - 1, 0)..at(n - 1, 0) + n]);
    for i in (1..n).rev() {
        let scale: f64 = diag[..i].iter().map(|x| x.abs()).sum();
        let mut h = 0.0;
        if scale == 0.0 {
            e[i] = diag[i - 1];
            for j in 0..i {
                diag[j] = v[at(i - 1, j)];
                v[at(i, j)] = 0.0;
                v[at(j, i)] = 0.0;
            }
        } else {
            for x in &mut diag[..i] {
                *x /= scale;
                h += *x * *x;
            }
            let f = diag[i - 1];
            let g = if f > 0.0 { -h.sqrt() } else { h.sqrt() };
            e[i] = scale * g;
            h -= f * g;
            diag[i - 1] = f - g;
            e[..i].fill(0.0);
            for j in 0..i {
                let f = diag[j];
                v[at(j, i)] = f;
                let mut g = e[j] + v[at(j, j)] * f;
                for k in j + 1..i {
                    g += v[at(k, j)] * diag[k];
                    e[k] += v[at(k, j)] * f;
                }
                e[j] = g;
            }
            let mut f = 0.0;
            for j in 0..i {
                e[j] /= h;
                f += e[j] * diag[j];
            }
            let hh = f / (h + h);
            for j in 0..i {
                e[j] -= hh * diag[j];
            }
            for j in 0..i {
                let (f, g) = (diag[j], e[j]);
                for k in j..i {
                    v[at(k, j)] -= f * e[k] + g * diag[k];
                }
                diag[j] = v[at(i - 1, j)];
                v[at(i, j)] = 0.0;
            }
        }
        diag[i] = h;
    }
    // Accumulate the transformations.
    for i in 0..n - 1 {
        v[at(n - 1, i)] = v[at(i, i)];
        v[at(i, i)] = 1.0;
        let h = diag[i + 1];
        if h != 0.0 {
            for k in 0..=i {
                diag[k] = v[at(k, i + 1)] / h;
            }
            for j in 0..=i {
                let g: f64 = (0..=i).map(|k| v[at(k, i + 1)] * v[at(k, j)]).sum();
                for k in 0..=i {
                    v[at(k, j)] -= g * diag[k];
                }
            }
        }
        for k in 0..=i {
            v[at(k, i + 1)] = 0.0;
        }
    }
    for j in 0..n {
        diag[j] = v[at(n - 1, j)];
        v[at(n - 1, j)] = 0.0;
    }
    v[at(n - 1, n - 1)] = 1.0;
    e[0] = 0.0;
}

/// `tql2`: the eigenvalues of the tridiagonal matrix (`diag`, subdiagonal `e[1..]`) into
/// `diag`, its rotations accumulated into `v`'s columns. At most 60 sweeps per eigenvalue.
fn tridiagonal_ql(v: &mut [f64], n: usize, diag: &mut [f64], e: &mut [f64]) {
    let at = |i: usize, j: usize| i * n + j;
    e.copy_within(1..n, 0);
    e[n - 1] = 0.0;
    let (mut f, mut tst1) = (0.0f64, 0.0f64);
    for l in 0..n {
        tst1 = tst1.max(diag[l].abs() + e[l].abs());
        let mut m = l;
        while m < n - 1 && e[m].abs() > f64::EPSILON * tst1 {
            m += 1;
        }
        let mut sweeps = 0;
        while m > l && e[l].abs() > f64::EPSILON * tst1 && sweeps < 60 {
            sweeps += 1;
            // The shift, from the leading 2×2 block.
            let g = diag[l];
            let mut p = (diag[l + 1] - g) / (2.0 * e[l]);
            let r = if p < 0.0 { -p.hypot(1.0) } else { p.hypot(1.0) };
            diag[l] = e[l] / (p + r);
            diag[l + 1] = e[l] * (p + r);
            let dl1 = diag[l + 1];
            let h = g - diag[l];
            for x in &mut diag[l + 2..n] {
                *x -= h;
            }
            f += h;
            // The implicit QL sweep.
            p = diag[m];
            let (mut c, mut c2, mut c3) = (1.0, 1.0, 1.0);
            let el1 = e[l + 1];
            let (mut s, mut s2) = (0.0, 0.0);
            for i in (l..m).rev() {
                c3 = c2;
                c2 = c;
                s2 = s;
                let g = c * e[i];
                let h = c * p;
                let r = p.hypot(e[i]);
                e[i + 1] = s * r;
                s = e[i] / r;
                c = p / r;
                p = c * diag[i] - s * g;
                diag[i + 1] = h + s * (c * g + s * diag[i]);
                for k in 0..n {
                    let h = v[at(k, i + 1)];
                    v[at(k, i + 1)] = s * v[at(k, i)] + c * h;
                    v[at(k, i)] = c * v[at(k, i)] - s * h;
                }
            }
            p = -s * s2 * c3 * el1 * e[l] / dl1;
            e[l] = s * p;
            diag[l] = c * p;
        }
        diag[l] += f;
        e[l] = 0.0;
    }
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

    proptest! {
        /// The eigendecomposition at the block sizes of a segment (two nodes' states and
        /// controls and a dilation: 20–50 columns), with repeated eigenvalues (low rank plus a
        /// multiple of the identity): `VΛVᵀ` gives the block back, `V` is orthogonal, and the
        /// eigenvalues are nalgebra's.
        #[test]
        fn large_blocks_with_repeated_eigenvalues(
            d in 20usize..50,
            rank in 0usize..6,
            shift in -2.0f64..2.0,
            seed in proptest::collection::vec(-1.0f64..1.0, 300),
        ) {
            let mut a = vec![0.0; d * d];
            for r in 0..rank {
                for i in 0..d {
                    for j in 0..d {
                        a[i * d + j] += seed[(r * 50 + i) % 300] * seed[(r * 50 + j) % 300];
                    }
                }
            }
            for i in 0..d {
                a[i * d + i] += shift;
            }
            let (mut v, mut lam, mut e) = (a.clone(), vec![0.0; d], vec![0.0; d]);
            symmetric_eigen(&mut v, d, &mut lam, &mut e);
            let norm = a.iter().map(|x| x * x).sum::<f64>().sqrt().max(1.0);
            for i in 0..d {
                for j in 0..d {
                    let back: f64 = (0..d).map(|k| v[i * d + k] * lam[k] * v[j * d + k]).sum();
                    prop_assert!((back - a[i * d + j]).abs() <= 1e-11 * norm);
                    let dot: f64 = (0..d).map(|k| v[k * d + i] * v[k * d + j]).sum();
                    prop_assert!((dot - f64::from(u8::from(i == j))).abs() <= 1e-12);
                }
            }
            let mut ours = lam.clone();
            ours.sort_by(f64::total_cmp);
            let mut theirs: Vec<f64> =
                SymmetricEigen::new(DMatrix::from_row_slice(d, d, &a)).eigenvalues.iter().copied().collect();
            theirs.sort_by(f64::total_cmp);
            for (x, y) in ours.iter().zip(&theirs) {
                prop_assert!((x - y).abs() <= 1e-11 * norm, "{x} vs {y}");
            }
        }
    }

    #[test]
    fn a_block_with_a_non_finite_entry_is_left_alone() {
        let (mut v, mut lam) = (vec![0.0; 4], vec![0.0; 2]);
        let mut h = [1.0, f64::NAN, f64::NAN, 2.0];
        assert!(project_psd(&mut h, 2, 0.0, &mut v, &mut lam).is_nan());
        assert_eq!(h[0], 1.0);
        assert!(h[1].is_nan() && h[2].is_nan());
        let mut inf = [f64::INFINITY, 0.0, 0.0, -1.0];
        clip_below(&mut inf, 2, 0.0, &mut v, &mut lam);
        assert_eq!(inf[0], f64::INFINITY);
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
