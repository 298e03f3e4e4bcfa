//! Weighted local Hessians `W = Σₒ wₒ ∇²φₒ` of the Lie nodes with respect to their
//! operands (row-major `n × n`, symmetric).
//!
//! - `so3_exp`, `se3_exp`: the closed forms `R = I + a ω^ + b ω^²`,
//!   `p = v + b ω×v + c ω×(ω×v)` differentiated twice by second-order jets (exact in the
//!   whole operand space; the coefficients' series branches near θ = 0 included).
//! - `so3_log`, `se3_log`: the node's Jacobian is the derivative *along* SO(3)
//!   (`armature_lie::SO3::dlog_dmatrix`), so its second derivative is taken along SO(3) as
//!   well: with `Gᵢ(R) = ½ R (jr⁻¹(ω)ᵀ eᵢ)^` and `Aᵢ[e][f] = ∂Gᵢ[e]/∂R_f` (ω moving by
//!   `⟨G, dR⟩`), the node contributes `sym(Σᵢ wᵢ Aᵢ)`. For any `R(x)` that stays a
//!   rotation — the only case a chain rule meets — this gives the exact second derivative
//!   of `log(R(x))`. At θ = π, where `log` is discontinuous, it is the limit from the
//!   side `log` returns. `se3_log` composes it with `ρ = p − ½ ω×p + d(θ²) ω×(ω×p)`.

use armature_lie::SO3;
use nalgebra::{Matrix3, Vector3};

use super::coefficients::{Kind, coefficient};
use super::jet::{Jet, cross, dot};

/// Jets of `R = exp(ω^)` (row-major entries) and of `b`, `c`, from jets of ω.
fn rotation<const N: usize>(w: &[Jet<N>; 3]) -> ([Jet<N>; 9], Jet<N>, Jet<N>) {
    let t = dot(w, w);
    let (a, b, c) = (
        t.compose(coefficient(Kind::A, t.v)),
        t.compose(coefficient(Kind::B, t.v)),
        t.compose(coefficient(Kind::C, t.v)),
    );
    let zero = Jet::constant(0.0);
    let hat = [[zero, w[2] * -1.0, w[1]], [w[2], zero, w[0] * -1.0], [w[1] * -1.0, w[0], zero]];
    let r = core::array::from_fn(|e| {
        let (i, j) = (e / 3, e % 3);
        // ω^² = ωωᵀ − t I.
        let mut sq = w[i] * w[j];
        let mut entry = a * hat[i][j];
        if i == j {
            sq = sq - t;
            entry = entry + Jet::constant(1.0);
        }
        entry + b * sq
    });
    (r, b, c)
}

/// Adds `Σ_e w[e] h_e` of jets into `out` (n × n) at operand indices `idx`.
fn add_weighted<const N: usize>(
    jets: &[Jet<N>],
    w: &[f64],
    idx: &[usize; N],
    n: usize,
    out: &mut [f64],
) {
    for (j, &we) in jets.iter().zip(w) {
        if we == 0.0 {
            continue;
        }
        for a in 0..N {
            for b in 0..N {
                out[idx[a] * n + idx[b]] += we * j.h[a][b];
            }
        }
    }
}

/// `so3_exp(ω)`: 3 operands, 9 outputs.
pub(crate) fn so3_exp(omega: [f64; 3], w: &[f64], out: &mut [f64]) {
    let om: [Jet<3>; 3] = core::array::from_fn(|i| Jet::var(i, omega[i]));
    let (r, _, _) = rotation(&om);
    out[..9].fill(0.0);
    add_weighted(&r, w, &[0, 1, 2], 3, out);
}

/// `se3_exp([v; ω])`: 6 operands, 12 outputs (the top three rows of T).
pub(crate) fn se3_exp(xi: [f64; 6], w: &[f64], out: &mut [f64]) {
    let z: [Jet<6>; 6] = core::array::from_fn(|i| Jet::var(i, xi[i]));
    let (v, om) = ([z[0], z[1], z[2]], [z[3], z[4], z[5]]);
    let (r, b, c) = rotation(&om);
    let wv = cross(&om, &v);
    let wwv = cross(&om, &wv);
    let mut entries = [Jet::constant(0.0); 12];
    for i in 0..3 {
        for j in 0..3 {
            entries[i * 4 + j] = r[i * 3 + j];
        }
        entries[i * 4 + 3] = v[i] + b * wv[i] + c * wwv[i];
    }
    out[..36].fill(0.0);
    add_weighted(&entries, w, &[0, 1, 2, 3, 4, 5], 6, out);
}

/// `sym(Σᵢ γᵢ Aᵢ)` of `so3_log` at the rotation `r` with `ω = log r` and gradient matrices
/// `g[i][e] = ∂ωᵢ/∂R_e`, added into `out` (n × n) at the entries' operand indices `idx`.
fn so3_log_into(
    r: &Matrix3<f64>,
    omega: &Vector3<f64>,
    g: &[[f64; 9]; 3],
    gamma: &Vector3<f64>,
    idx: &[usize; 9],
    n: usize,
    out: &mut [f64],
) {
    let t = omega.norm_squared();
    let dk = coefficient(Kind::D, t);
    let wwg = omega.cross(&omega.cross(gamma));
    // ū = Σ γᵢ uᵢ with uᵢ = eᵢ + ½ eᵢ×ω + d ω×(ω×eᵢ) (row i of jr⁻¹).
    let ubar = gamma + 0.5 * gamma.cross(omega) + dk.f * wwg;
    let hat_ubar = SO3::hat(&ubar);
    let mut a = [[0.0; 9]; 9];
    for f in 0..9 {
        let dw = Vector3::new(g[0][f], g[1][f], g[2][f]);
        // U_f = Σ γᵢ ∂uᵢ along dω.
        let u = 0.5 * gamma.cross(&dw)
            + 2.0 * dk.f1 * omega.dot(&dw) * wwg
            + dk.f * (dw.cross(&omega.cross(gamma)) + omega.cross(&dw.cross(gamma)));
        let m = 0.5 * r * SO3::hat(&u);
        let (rf, cf) = (f / 3, f % 3);
        for e in 0..9 {
            let (re, ce) = (e / 3, e % 3);
            let from_e = if re == rf { 0.5 * hat_ubar[(cf, ce)] } else { 0.0 };
            a[e][f] = from_e + m[(re, ce)];
        }
    }
    for e in 0..9 {
        for f in 0..9 {
            out[idx[e] * n + idx[f]] += 0.5 * (a[e][f] + a[f][e]);
        }
    }
}

/// `so3_log(R)`: 9 operands, 3 outputs; `local` is the node's Jacobian (3 × 9).
pub(crate) fn so3_log(m: &[f64], local: &[f64], w: &[f64], out: &mut [f64]) {
    let rot = SO3::from_matrix_unchecked(&Matrix3::from_row_slice(&m[..9]));
    let g: [[f64; 9]; 3] = core::array::from_fn(|i| core::array::from_fn(|e| local[i * 9 + e]));
    out[..81].fill(0.0);
    let idx = core::array::from_fn(|e| e);
    so3_log_into(&rot.matrix(), &rot.log(), &g, &Vector3::new(w[0], w[1], w[2]), &idx, 9, out);
}

/// `se3_log(T)`: 12 operands (top three rows), 6 outputs `[ρ; ω]`; `local` is the node's
/// Jacobian (6 × 12).
pub(crate) fn se3_log(m: &[f64], local: &[f64], w: &[f64], out: &mut [f64]) {
    let rm = Matrix3::from_fn(|i, j| m[i * 4 + j]);
    let rot = SO3::from_matrix_unchecked(&rm);
    let omega = rot.log();
    let ridx: [usize; 9] = core::array::from_fn(|e| (e / 3) * 4 + e % 3);
    // ∂ω/∂R from the ω rows of the node's Jacobian.
    let g: [[f64; 9]; 3] =
        core::array::from_fn(|k| core::array::from_fn(|e| local[(3 + k) * 12 + ridx[e]]));
    // ρ = F(ω, p) as jets over z = (ω, p).
    let z: [Jet<6>; 6] =
        core::array::from_fn(|i| Jet::var(i, if i < 3 { omega[i] } else { m[(i - 3) * 4 + 3] }));
    let (om, p) = ([z[0], z[1], z[2]], [z[3], z[4], z[5]]);
    let t = dot(&om, &om);
    let d = t.compose(coefficient(Kind::D, t.v));
    let wp = cross(&om, &p);
    let wwp = cross(&om, &wp);
    let rho: [Jet<6>; 3] = core::array::from_fn(|k| p[k] - wp[k] * 0.5 + d * wwp[k]);
    // γ = w_ω + Σ_k w_ρk ∂ρ_k/∂ω.
    let gamma =
        Vector3::from_fn(|mi, _| w[3 + mi] + (0..3).map(|k| w[k] * rho[k].g[mi]).sum::<f64>());
    out[..144].fill(0.0);
    so3_log_into(&rot.matrix(), &omega, &g, &gamma, &ridx, 12, out);
    // Jᵀ K J with K = Σ_k w_ρk ∇²ρ_k over z and J = ∂z/∂(entries).
    let mut k = [[0.0; 6]; 6];
    for (rk, &wk) in rho.iter().zip(w) {
        for a in 0..6 {
            for b in 0..6 {
                k[a][b] += wk * rk.h[a][b];
            }
        }
    }
    let jz = |a: usize, e: usize| -> f64 {
        if a < 3 {
            g[a].iter().zip(&ridx).find(|(_, ri)| **ri == e).map_or(0.0, |(v, _)| *v)
        } else if e == (a - 3) * 4 + 3 {
            1.0
        } else {
            0.0
        }
    };
    let mut jzm = [[0.0; 12]; 6];
    for a in 0..6 {
        for e in 0..12 {
            jzm[a][e] = jz(a, e);
        }
    }
    for e in 0..12 {
        for f in 0..12 {
            let mut s = 0.0;
            for a in 0..6 {
                if jzm[a][e] == 0.0 {
                    continue;
                }
                for b in 0..6 {
                    s += jzm[a][e] * k[a][b] * jzm[b][f];
                }
            }
            out[e * 12 + f] += s;
        }
    }
}
