//! Multiple-shooting discretization with time dilation, first-order-hold controls and the
//! variational equations (A, B⁻, B⁺).
//!
//! # Math
//! Normalised time τ ∈ [0, 1] with N nodes, Δτ = 1/(N − 1). The dynamics `ẋ = f(x, u)` are
//! dilated by a zero-order-hold control `s` (physical time per unit τ): `dx/dτ = s·f(x, u)`.
//! On segment k the controls are a true first-order hold,
//! `u(τ) = u_k + β(τ)(u_{k+1} − u_k)` with `β = τ/Δτ ∈ [0, 1]` on FOH entries (OpenSCvx uses
//! β = τ·N, which overshoots; see its notes §11.1), and `u_k` on ZOH entries. From
//! `x(0) = x_k`, with `A = s ∂f/∂x`, the variational equations
//!
//! ```text
//! dΦ/dτ  = A Φ,                                  Φ(0)  = I
//! dB⁻/dτ = A B⁻ + [s ∂f/∂u · diag(α) | f],        B⁻(0) = 0     (α = 1 − β; the last column is s)
//! dB⁺/dτ = A B⁺ + s ∂f/∂u · diag(β),              B⁺(0) = 0
//! ```
//!
//! are integrated with the state by fixed-step RK4 (`substeps` per segment), giving
//! `x_prop_k = x(Δτ)` and `A_k = Φ(Δτ)`, `B⁻_k`, `B⁺_k`. Because the same explicit scheme
//! integrates both, these matrices are the exact derivatives of the numerical map
//! `(x_k, u_k, s_k, u_{k+1}) ↦ x_prop_k` — what the linearised subproblem needs.
//!
//! `∂f/∂x` is applied through the symbolic Jacobian's CSC pattern (computed once), so the
//! seed's `angle' = velocity` block costs one multiply-add per row, not n.

use armature_symbolic::{Expr, Function, SymbolicError, Workspace};

/// Integrator settings.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct DiscretizationSettings {
    /// RK4 steps per segment. Default 10.
    pub substeps: usize,
}

impl Default for DiscretizationSettings {
    fn default() -> Self {
        DiscretizationSettings { substeps: 10 }
    }
}

/// Compiled dynamics `f(x, u)` with its sparse Jacobian, ready to discretize.
#[derive(Debug, Clone)]
pub struct Dynamics {
    f: Function,
    n_x: usize,
    n_u: usize,
    foh: Vec<bool>,
    /// CSC columns of the Jacobian: for input column j, (row, nonzero position) pairs.
    col_ptr: Vec<usize>,
    rows: Vec<usize>,
    /// `(state row, first segment, end segment)`: the row's dynamics are active only on
    /// segments `first..end` (CTCS intervals); elsewhere the row is held constant.
    gates: Vec<(usize, usize, usize)>,
}

/// The discretized problem around one trajectory: per segment k = 0..N−2, row-major
/// `A_k` (n×n), `B⁻_k`, `B⁺_k` (n×(m+1), the last column being the dilation `s`), the
/// propagated state and the defect `x_{k+1} − x_prop_k`.
#[derive(Debug, Clone, PartialEq)]
pub struct Discretization {
    /// Number of segments.
    pub segments: usize,
    /// `A_k` row-major, segment after segment.
    pub a: Vec<f64>,
    /// `B⁻_k` row-major (n × (m + 1)), segment after segment.
    pub b_minus: Vec<f64>,
    /// `B⁺_k` row-major (n × (m + 1)), segment after segment (zero in the `s` column).
    pub b_plus: Vec<f64>,
    /// `x_prop_k`, segment after segment.
    pub x_prop: Vec<f64>,
    /// `x_{k+1} − x_prop_k`, segment after segment.
    pub defect: Vec<f64>,
}

/// Preallocated integrator scratch (no allocation per discretization).
#[derive(Debug, Clone)]
pub struct DiscretizationWorkspace {
    fws: Workspace,
    input: Vec<f64>,
    fval: Vec<f64>,
    jac: Vec<f64>,
    v: Vec<f64>,
    k: [Vec<f64>; 4],
    tmp: Vec<f64>,
}

/// Errors of the discretization.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DiscretizationError {
    /// The dynamics expressions do not compile.
    #[error("dynamics: {0}")]
    Symbolic(#[from] SymbolicError),
    /// Sizes that do not fit.
    #[error("{0}")]
    Size(String),
}

impl Dynamics {
    /// Compiles `dx/dt = f(x, u)`: `rhs` lists one expression per state variable (concatenated
    /// in order, matching `states`), `controls` the control variables; `foh[i]` says whether
    /// control entry `i` is first-order hold (else zero-order hold).
    ///
    /// # Errors
    /// Shape and name errors of the expressions; a `foh` mask of the wrong length; right-hand
    /// sides whose total size differs from the state size.
    pub fn new(
        states: &[Expr],
        controls: &[Expr],
        rhs: &[Expr],
        foh: &[bool],
    ) -> Result<Dynamics, DiscretizationError> {
        let f = Function::compile(rhs, &[states, controls])?;
        let (n_x, n_u) = (f.group_range(0).len(), f.group_range(1).len());
        if f.n_outputs() != n_x {
            return Err(DiscretizationError::Size(format!(
                "{} dynamics entries for {n_x} states",
                f.n_outputs()
            )));
        }
        if foh.len() != n_u {
            return Err(DiscretizationError::Size(format!(
                "FOH mask has {} entries for {n_u} controls",
                foh.len()
            )));
        }
        let p = f.jacobian_pattern();
        Ok(Dynamics {
            n_x,
            n_u,
            foh: foh.to_vec(),
            col_ptr: p.col_ptr().to_vec(),
            rows: p.row_idx().to_vec(),
            f,
            gates: Vec::new(),
        })
    }

    /// Restricts state row `row`'s dynamics to segments `first..end` (a CTCS interval; the
    /// segment index gates the integrand as in OpenSCvx). Outside, the row stays constant.
    ///
    /// # Errors
    /// A row or interval out of range.
    pub fn gate(
        mut self,
        row: usize,
        first: usize,
        end: usize,
    ) -> Result<Dynamics, DiscretizationError> {
        if row >= self.n_x || first >= end {
            return Err(DiscretizationError::Size(format!(
                "gate: row {row} of {} with segments {first}..{end}",
                self.n_x
            )));
        }
        self.gates.push((row, first, end));
        Ok(self)
    }

    /// State size n.
    pub fn n_x(&self) -> usize {
        self.n_x
    }

    /// Control size m (without the dilation).
    pub fn n_u(&self) -> usize {
        self.n_u
    }

    /// The compiled right-hand side.
    pub fn function(&self) -> &Function {
        &self.f
    }

    /// Scratch for [`discretize`](Self::discretize).
    pub fn workspace(&self) -> DiscretizationWorkspace {
        let (n, m) = (self.n_x, self.n_u + 1);
        let len = n + n * n + 2 * n * m;
        DiscretizationWorkspace {
            fws: self.f.workspace(),
            input: vec![0.0; n + self.n_u],
            fval: vec![0.0; n],
            jac: vec![0.0; self.f.jacobian_pattern().nnz()],
            v: vec![0.0; len],
            k: std::array::from_fn(|_| vec![0.0; len]),
            tmp: vec![0.0; len],
        }
    }

    /// An empty result for `nodes` nodes.
    pub fn output(&self, nodes: usize) -> Discretization {
        let (n, m, k) = (self.n_x, self.n_u + 1, nodes.saturating_sub(1));
        Discretization {
            segments: k,
            a: vec![0.0; k * n * n],
            b_minus: vec![0.0; k * n * m],
            b_plus: vec![0.0; k * n * m],
            x_prop: vec![0.0; k * n],
            defect: vec![0.0; k * n],
        }
    }

    /// Time derivative of the augmented vector `V = [x, Φ, B⁻, B⁺]` at normalised segment
    /// time `beta` (β of the FOH), into `dv`.
    #[allow(clippy::too_many_arguments)]
    fn rhs(
        &self,
        v: &[f64],
        beta: f64,
        uk: &[f64],
        uk1: &[f64],
        s: f64,
        seg: usize,
        fws: &mut Workspace,
        input: &mut [f64],
        fval: &mut [f64],
        jac: &mut [f64],
        dv: &mut [f64],
    ) -> Result<(), DiscretizationError> {
        let (n, mu) = (self.n_x, self.n_u);
        let m = mu + 1;
        input[..n].copy_from_slice(&v[..n]);
        for i in 0..mu {
            input[n + i] = if self.foh[i] { uk[i] + beta * (uk1[i] - uk[i]) } else { uk[i] };
        }
        self.f.eval(input, fws, fval, Some(jac))?;
        // Gated rows (inactive CTCS integrands on this segment): zero value and derivatives.
        for &(row, first, end) in &self.gates {
            if seg < first || seg >= end {
                fval[row] = 0.0;
                for (v, &r) in jac.iter_mut().zip(&self.rows) {
                    if r == row {
                        *v = 0.0;
                    }
                }
            }
        }
        dv.fill(0.0);
        for r in 0..n {
            dv[r] = s * fval[r];
        }
        let (phi0, bm0, bp0) = (n, n + n * n, n + n * n + n * m);
        // A·[Φ | B⁻ | B⁺] through the CSC columns of ∂f/∂x, scaled by s.
        for j in 0..n {
            for p in self.col_ptr[j]..self.col_ptr[j + 1] {
                let (r, a) = (self.rows[p], s * jac[p]);
                for c in 0..n {
                    dv[phi0 + r * n + c] += a * v[phi0 + j * n + c];
                }
                for c in 0..m {
                    dv[bm0 + r * m + c] += a * v[bm0 + j * m + c];
                    dv[bp0 + r * m + c] += a * v[bp0 + j * m + c];
                }
            }
        }
        // Control columns: s ∂f/∂u · diag(α) into B⁻, · diag(β) into B⁺.
        for i in 0..mu {
            let (alpha, b) = if self.foh[i] { (1.0 - beta, beta) } else { (1.0, 0.0) };
            for p in self.col_ptr[n + i]..self.col_ptr[n + i + 1] {
                let (r, d) = (self.rows[p], s * jac[p]);
                dv[bm0 + r * m + i] += d * alpha;
                dv[bp0 + r * m + i] += d * b;
            }
        }
        // The dilation column: ∂(s f)/∂s = f, zero-order hold.
        for r in 0..n {
            dv[bm0 + r * m + mu] += fval[r];
        }
        Ok(())
    }

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
        let mut ws = self.workspace();
        let (mut times, mut states) = (vec![0.0], x0.to_vec());
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
                    let DiscretizationWorkspace { fws, input, fval, .. } = &mut ws;
                    input[..n].copy_from_slice(x);
                    for i in 0..mu {
                        input[n + i] =
                            if self.foh[i] { uk[i] + beta * (uk1[i] - uk[i]) } else { uk[i] };
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
            }
        }
        Ok((times, states))
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
        let (n, mu) = (self.n_x, self.n_u);
        let m = mu + 1;
        let nodes = s.len();
        if nodes < 2
            || x.len() != nodes * n
            || u.len() != nodes * mu
            || out.segments != nodes - 1
            || settings.substeps == 0
        {
            return Err(DiscretizationError::Size(format!(
                "{nodes} nodes need x of {} (got {}), u of {} (got {}), an output for {} segments (has {}) and substeps ≥ 1",
                nodes * n,
                x.len(),
                nodes * mu,
                u.len(),
                nodes.saturating_sub(1),
                out.segments
            )));
        }
        let dtau = 1.0 / (nodes - 1) as f64;
        let h = dtau / settings.substeps as f64;
        let len = ws.v.len();
        let DiscretizationWorkspace { fws, input, fval, jac, v, k, tmp } = ws;
        let [k0, k1, k2, k3] = k;
        for seg in 0..nodes - 1 {
            let (uk, uk1) = (&u[seg * mu..(seg + 1) * mu], &u[(seg + 1) * mu..(seg + 2) * mu]);
            let sk = s[seg];
            v.fill(0.0);
            v[..n].copy_from_slice(&x[seg * n..(seg + 1) * n]);
            for i in 0..n {
                v[n + i * n + i] = 1.0;
            }
            for step in 0..settings.substeps {
                let b0 = step as f64 / settings.substeps as f64;
                let bh = (step as f64 + 0.5) / settings.substeps as f64;
                let b1 = (step as f64 + 1.0) / settings.substeps as f64;
                self.rhs(v, b0, uk, uk1, sk, seg, fws, input, fval, jac, k0)?;
                for i in 0..len {
                    tmp[i] = v[i] + 0.5 * h * k0[i];
                }
                self.rhs(tmp, bh, uk, uk1, sk, seg, fws, input, fval, jac, k1)?;
                for i in 0..len {
                    tmp[i] = v[i] + 0.5 * h * k1[i];
                }
                self.rhs(tmp, bh, uk, uk1, sk, seg, fws, input, fval, jac, k2)?;
                for i in 0..len {
                    tmp[i] = v[i] + h * k2[i];
                }
                self.rhs(tmp, b1, uk, uk1, sk, seg, fws, input, fval, jac, k3)?;
                for i in 0..len {
                    v[i] += h / 6.0 * (k0[i] + 2.0 * k1[i] + 2.0 * k2[i] + k3[i]);
                }
            }
            let (phi0, bm0, bp0) = (n, n + n * n, n + n * n + n * m);
            out.x_prop[seg * n..(seg + 1) * n].copy_from_slice(&v[..n]);
            out.a[seg * n * n..(seg + 1) * n * n].copy_from_slice(&v[phi0..phi0 + n * n]);
            out.b_minus[seg * n * m..(seg + 1) * n * m].copy_from_slice(&v[bm0..bm0 + n * m]);
            out.b_plus[seg * n * m..(seg + 1) * n * m].copy_from_slice(&v[bp0..bp0 + n * m]);
            for i in 0..n {
                out.defect[seg * n + i] = x[(seg + 1) * n + i] - v[i];
            }
        }
        Ok(())
    }
}
