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

use armature_symbolic::{Expr, Function, SparsityPattern, SymbolicError, Workspace};

/// Integrator settings.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct DiscretizationSettings {
    /// RK4 steps per segment; for Dormand–Prince, the first trial step is `Δτ / substeps`.
    /// Default 10.
    pub substeps: usize,
    /// Integrate segments concurrently on the rayon pool, one lane of segments per worker
    /// thread (segments are independent). Default true.
    pub parallel: bool,
    /// The integration scheme. Default fixed-step RK4.
    pub integrator: Integrator,
}

impl Default for DiscretizationSettings {
    fn default() -> Self {
        DiscretizationSettings { substeps: 10, parallel: true, integrator: Integrator::Rk4 }
    }
}

/// How each segment is integrated (the state and its variational equations together).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub enum Integrator {
    /// Classical RK4 with `substeps` equal steps: `A`, `B±` are the exact derivatives of the
    /// numerical propagation map.
    Rk4,
    /// Dormand–Prince 5(4) with embedded error control on the state (`‖e_i / (atol + rtol
    /// |x_i|)‖_rms ≤ 1`), first-same-as-last, step factor in [0.2, 5]. The matrices are the
    /// derivatives of the map for the accepted step sequence (the step-size choice is not
    /// differentiated, the usual practice). Because that sequence changes between a
    /// reference and its candidates, the SCvx model is less faithful than with RK4: on the
    /// seed arm PTR stalls with it. Use it to check a trajectory's accuracy, or with SCvx on
    /// smooth problems.
    DormandPrince {
        /// Relative tolerance (> 0).
        rtol: f64,
        /// Absolute tolerance (> 0).
        atol: f64,
    },
}

/// Steps one Dormand–Prince segment may take before the discretization gives up.
pub const MAX_ADAPTIVE_STEPS: usize = 100_000;

/// Dormand–Prince 5(4) tableau: nodes `c`, rows of `a`, 5th-order weights `b`, and
/// `b − b*` (the embedded 4th-order difference) for the error estimate.
const DP_C: [f64; 7] = [0.0, 1.0 / 5.0, 3.0 / 10.0, 4.0 / 5.0, 8.0 / 9.0, 1.0, 1.0];
const DP_A: [[f64; 6]; 7] = [
    [0.0; 6],
    [1.0 / 5.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [3.0 / 40.0, 9.0 / 40.0, 0.0, 0.0, 0.0, 0.0],
    [44.0 / 45.0, -56.0 / 15.0, 32.0 / 9.0, 0.0, 0.0, 0.0],
    [19372.0 / 6561.0, -25360.0 / 2187.0, 64448.0 / 6561.0, -212.0 / 729.0, 0.0, 0.0],
    [9017.0 / 3168.0, -355.0 / 33.0, 46732.0 / 5247.0, 49.0 / 176.0, -5103.0 / 18656.0, 0.0],
    [35.0 / 384.0, 0.0, 500.0 / 1113.0, 125.0 / 192.0, -2187.0 / 6784.0, 11.0 / 84.0],
];
const DP_E: [f64; 7] = [
    35.0 / 384.0 - 5179.0 / 57600.0,
    0.0,
    500.0 / 1113.0 - 7571.0 / 16695.0,
    125.0 / 192.0 - 393.0 / 640.0,
    -2187.0 / 6784.0 + 92097.0 / 339200.0,
    11.0 / 84.0 - 187.0 / 2100.0,
    -1.0 / 40.0,
];

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
    /// Structural pattern of `[A | B_u | b_s]` (see [`Dynamics::transition_pattern`]).
    transition: SparsityPattern,
    /// Name of each scalar state row (`angle[3]`, `_ctcs_0`).
    state_names: Vec<String>,
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
    /// Points per segment of the integration grid recorded in [`grid`](Self::grid): 0 (no
    /// grid, [`Dynamics::output`]) or `substeps + 1` ([`Dynamics::output_with_grid`]).
    pub grid_points: usize,
    /// The augmented vector `[x, Φ, B⁻, B⁺]` (layout of [`Dynamics::grid_stride`]) at the
    /// grid points `τ_k + j·Δτ/substeps`, j = 0..=substeps, of every segment (segment after
    /// segment, point after point): the trajectory and its sensitivities to the segment's
    /// `x_k`, `[u_k; s_k]` and `u_{k+1}` between the nodes. [`Dynamics::defects`] writes the
    /// states `x` of each block only.
    pub grid: Vec<f64>,
}

/// A densely sampled trajectory from [`Dynamics::propagate_dense`].
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct DenseTrajectory {
    /// Sample times (s), starting at 0.
    pub time: Vec<f64>,
    /// States, one row of n per sample.
    pub x: Vec<f64>,
    /// First-order-hold controls, one row of m per sample.
    pub u: Vec<f64>,
    /// The segment each sample ends (0 for the first sample).
    pub segment: Vec<usize>,
}

/// Preallocated integrator scratch (no allocation per discretization): one lane per rayon
/// worker thread (at creation), each integrating a contiguous run of segments.
#[derive(Debug, Clone)]
pub struct DiscretizationWorkspace {
    lanes: Vec<Lane>,
}

/// One lane's scratch.
#[derive(Debug, Clone)]
struct Lane {
    f: FEval,
    v: Vec<f64>,
    /// Stage derivatives (RK4 uses the first four, Dormand–Prince all seven).
    k: [Vec<f64>; 7],
    tmp: Vec<f64>,
}

/// Scratch of one evaluation of the dynamics `f(x, u)`.
#[derive(Debug, Clone)]
struct FEval {
    ws: Workspace,
    input: Vec<f64>,
    fval: Vec<f64>,
    jac: Vec<f64>,
    /// The rows whose derivatives the segment needs (its gated rows are not).
    needed: Vec<bool>,
}

/// One lane's share of a [`Discretization`]: its first segment and its output slices.
struct LaneOut<'a> {
    first: usize,
    /// Grid values per segment (0 without a grid).
    grid_seg: usize,
    grid: &'a mut [f64],
    a: &'a mut [f64],
    b_minus: &'a mut [f64],
    b_plus: &'a mut [f64],
    x_prop: &'a mut [f64],
    defect: &'a mut [f64],
}

impl<'a> LaneOut<'a> {
    /// Splits off the first `segs` segments (`n`, `m` = state and control + 1 sizes).
    fn split(self, segs: usize, n: usize, m: usize) -> (LaneOut<'a>, LaneOut<'a>) {
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

/// Reachability closure of `∂f/∂x` (see [`Dynamics::transition_pattern`]).
fn transition_pattern(jac: &SparsityPattern, n: usize, mu: usize) -> SparsityPattern {
    // reach[r·n + j]: state r is reachable from state j (Φ[r, j] may be nonzero).
    let mut reach = vec![false; n * n];
    for i in 0..n {
        reach[i * n + i] = true;
    }
    let deps: Vec<(usize, usize)> = jac.entries().filter(|&(_, c)| c < n).collect();
    // Φ' = AΦ: Φ[r, c] gains entries from Φ[j, c] for every dependency (r, j); iterate to the
    // fixed point (at most n rounds).
    loop {
        let mut changed = false;
        for &(r, j) in &deps {
            for c in 0..n {
                if reach[j * n + c] && !reach[r * n + c] {
                    reach[r * n + c] = true;
                    changed = true;
                }
            }
        }
        if !changed {
            break;
        }
    }
    let mut entries = Vec::new();
    for r in 0..n {
        for j in 0..n {
            if reach[r * n + j] {
                entries.push((r, j));
            }
        }
        for i in 0..mu {
            let direct = |row: usize| jac.contains(row, n + i);
            if (0..n).any(|j| reach[r * n + j] && direct(j)) {
                entries.push((r, n + i));
            }
        }
        entries.push((r, n + mu));
    }
    SparsityPattern::from_entries(n, n + mu + 1, &entries)
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
        let transition = transition_pattern(p, n_x, n_u);
        let mut state_names = Vec::with_capacity(n_x);
        for (g, e) in states.iter().enumerate() {
            let name = e.leaf_name().map_or_else(|| format!("state {g}"), str::to_owned);
            let len = e.shape()?.numel();
            if len == 1 {
                state_names.push(name);
            } else {
                state_names.extend((0..len).map(|i| format!("{name}[{i}]")));
            }
        }
        Ok(Dynamics {
            state_names,
            n_x,
            n_u,
            foh: foh.to_vec(),
            col_ptr: p.col_ptr().to_vec(),
            rows: p.row_idx().to_vec(),
            f,
            gates: Vec::new(),
            transition,
        })
    }

    /// Structural sparsity of the discretized matrices, `n × (n + m + 1)` over the columns
    /// `[x | u | s]`: entry `(r, j)` of `A_k = Φ` (j < n), of `B⁻_k`/`B⁺_k` (n ≤ j < n + m) and
    /// of the dilation column (j = n + m) can be nonzero only where this pattern has it.
    ///
    /// `Φ(τ)` is a sum of products of `A = s·∂f/∂x`, so `Φ[r, j] ≠ 0` only if state `r` is
    /// reachable from state `j` in the dependency graph of `∂f/∂x` (itself included); `B[r, i]`
    /// only if `r` is reachable from a state whose derivative depends on control `i`; the
    /// dilation column (`f` integrated through `Φ`) only if `r` is reachable from a row with
    /// any dependence at all (every row is kept: a constant `f_r ≠ 0` has no dependence).
    /// Entries outside the pattern stay exactly zero in [`discretize`](Self::discretize)'s
    /// arithmetic, so the subproblem drops them. For the seed arm (angle' = velocity,
    /// velocity' = τ/I, 4 CTCS rows) this keeps 194 of the 612 entries per segment.
    pub fn transition_pattern(&self) -> &SparsityPattern {
        &self.transition
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

    /// Name of scalar state row `row`: the state variable's name, indexed for vectors
    /// (`angle[3]`); `None` out of range.
    pub fn state_name(&self, row: usize) -> Option<&str> {
        self.state_names.get(row).map(String::as_str)
    }

    /// Sets a parameter of the dynamics; the next discretization uses it, nothing recompiles.
    ///
    /// # Errors
    /// The symbolic crate's: unknown parameter, wrong length, non-finite value.
    pub fn set_parameter(&mut self, name: &str, value: &[f64]) -> Result<(), SymbolicError> {
        self.f.set_parameter(name, value)
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

    /// Scratch for [`discretize`](Self::discretize): one lane per thread of the current
    /// rayon pool.
    pub fn workspace(&self) -> DiscretizationWorkspace {
        DiscretizationWorkspace {
            lanes: (0..rayon::current_num_threads().max(1)).map(|_| self.lane()).collect(),
        }
    }

    fn lane(&self) -> Lane {
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

    /// One segment by Dormand–Prince into `v` (which holds the initial value on entry).
    #[allow(clippy::too_many_arguments)]
    fn dormand_prince(
        &self,
        (rtol, atol): (f64, f64),
        first_step: f64,
        dtau: f64,
        (uk, uk1, sk, seg): (&[f64], &[f64], f64, usize),
        ws: &mut Lane,
        full: bool,
        grid: &mut [f64],
    ) -> Result<(), DiscretizationError> {
        let n = self.n_x;
        let len = if full { ws.v.len() } else { n };
        let stride = self.grid_stride();
        let points = grid.len() / stride;
        // The next grid point to land on (steps are clipped to reach it exactly).
        let mut next = 1;
        let Lane { f, v, k, tmp } = ws;
        let mut t = 0.0;
        let mut h = first_step.min(dtau);
        // k[0] = f(t, v) (first same as last: refreshed from k[6] after each accepted step).
        self.rhs(v, 0.0, (uk, uk1, sk, seg), f, &mut k[0], full)?;
        let mut steps = 0;
        while t < dtau * (1.0 - 1e-14) {
            steps += 1;
            if steps > MAX_ADAPTIVE_STEPS {
                return Err(DiscretizationError::Size(format!(
                    "Dormand–Prince: segment {seg} needs more than {MAX_ADAPTIVE_STEPS} steps (tolerances too tight, or stiff dynamics)"
                )));
            }
            h = h.min(dtau - t);
            let mut land = false;
            if next < points {
                let tg = dtau * next as f64 / (points - 1) as f64;
                if t + h >= tg - 1e-14 * dtau {
                    h = tg - t;
                    land = true;
                }
            }
            for stage in 1..7 {
                for i in 0..len {
                    let mut acc = v[i];
                    for (j, a) in DP_A[stage][..stage].iter().enumerate() {
                        if *a != 0.0 {
                            acc += h * a * k[j][i];
                        }
                    }
                    tmp[i] = acc;
                }
                let beta = (t + DP_C[stage] * h) / dtau;
                self.rhs(tmp, beta.min(1.0), (uk, uk1, sk, seg), f, &mut k[stage], full)?;
            }
            // tmp holds the 5th-order solution (stage 7's argument); error on the state part.
            let mut err = 0.0;
            for i in 0..n {
                let e: f64 = h * (0..7).map(|j| DP_E[j] * k[j][i]).sum::<f64>();
                let scale = atol + rtol * v[i].abs().max(tmp[i].abs());
                err += (e / scale) * (e / scale);
            }
            if tmp[..n].iter().any(|x| !x.is_finite()) {
                return Err(DiscretizationError::Size(format!(
                    "Dormand–Prince: non-finite state on segment {seg}"
                )));
            }
            // An overflowing ratio (tolerances far below the state's scale) just rejects.
            let err = (err / n.max(1) as f64).sqrt().min(f64::MAX);
            if h < 1e-12 * dtau {
                return Err(DiscretizationError::Size(format!(
                    "Dormand–Prince: the step on segment {seg} fell below 1e-12·Δτ: the tolerances cannot be met"
                )));
            }
            let factor = if err == 0.0 { 5.0 } else { (0.9 * err.powf(-0.2)).clamp(0.2, 5.0) };
            if err <= 1.0 {
                t += h;
                v[..len].copy_from_slice(&tmp[..len]);
                let (first, last) = k.split_at_mut(6);
                first[0][..len].copy_from_slice(&last[0][..len]);
                if land {
                    grid[next * stride..next * stride + len].copy_from_slice(&v[..len]);
                    next += 1;
                }
            }
            h *= factor;
        }
        Ok(())
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
            grid_points: 0,
            grid: Vec::new(),
        }
    }

    /// Length of one grid block `[x, Φ, B⁻, B⁺]`: `n + n² + 2n(m + 1)`; its parts start at
    /// 0, n, n + n² and n + n² + n(m + 1), each row-major as in [`Discretization`].
    pub fn grid_stride(&self) -> usize {
        let (n, m) = (self.n_x, self.n_u + 1);
        n + n * n + 2 * n * m
    }

    /// An empty result for `nodes` nodes that also records the trajectory and its
    /// sensitivities at the `substeps + 1` points of each segment's integration grid (see
    /// [`Discretization::grid`]); discretize it with the same `substeps`.
    pub fn output_with_grid(&self, nodes: usize, substeps: usize) -> Discretization {
        let mut out = self.output(nodes);
        out.grid_points = substeps + 1;
        out.grid = vec![0.0; out.segments * out.grid_points * self.grid_stride()];
        out
    }

    /// Time derivative of the augmented vector `V = [x, Φ, B⁻, B⁺]` at normalised segment
    /// time `beta` (β of the FOH) on segment `seg` (controls `uk`, `uk1`, dilation `s`),
    /// into `dv`; with `full` false, of the state `x` alone (`dv[..n]`).
    fn rhs(
        &self,
        v: &[f64],
        beta: f64,
        (uk, uk1, s, seg): (&[f64], &[f64], f64, usize),
        fe: &mut FEval,
        dv: &mut [f64],
        full: bool,
    ) -> Result<(), DiscretizationError> {
        let (n, mu) = (self.n_x, self.n_u);
        let m = mu + 1;
        let FEval { ws: fws, input, fval, jac, needed } = fe;
        input[..n].copy_from_slice(&v[..n]);
        for i in 0..mu {
            input[n + i] = if self.foh[i] { uk[i] + beta * (uk1[i] - uk[i]) } else { uk[i] };
        }
        if !full {
            // The state alone: no Jacobian, no variational equations.
            self.f.eval(input, fws, fval, None)?;
            for &(row, first, end) in &self.gates {
                if seg < first || seg >= end {
                    fval[row] = 0.0;
                }
            }
            for r in 0..n {
                dv[r] = s * fval[r];
            }
            return Ok(());
        }
        // Gated rows (inactive CTCS integrands on this segment) are not differentiated, nor
        // penalties whose constraints all hold here (their derivatives are zero): see
        // `Function::eval_pruned`.
        needed.fill(true);
        for &(row, first, end) in &self.gates {
            if seg < first || seg >= end {
                needed[row] = false;
            }
        }
        self.f.eval_pruned(input, fws, fval, jac, Some(needed))?;
        for (v, &need) in fval.iter_mut().zip(needed.iter()) {
            if !need {
                *v = 0.0;
            }
        }
        dv.fill(0.0);
        for r in 0..n {
            dv[r] = s * fval[r];
        }
        let (phi0, bm0, bp0) = (n, n + n * n, n + n * n + n * m);
        // A·[Φ | B⁻ | B⁺] through the CSC columns of ∂f/∂x, scaled by s (entries that are zero
        // here, such as an inactive penalty's, are skipped).
        let axpy = |dst: &mut [f64], a: f64, src: &[f64]| {
            for (d, x) in dst.iter_mut().zip(src) {
                *d += a * x;
            }
        };
        for j in 0..n {
            for p in self.col_ptr[j]..self.col_ptr[j + 1] {
                if jac[p] == 0.0 {
                    continue;
                }
                let (r, a) = (self.rows[p], s * jac[p]);
                axpy(&mut dv[phi0 + r * n..][..n], a, &v[phi0 + j * n..][..n]);
                axpy(&mut dv[bm0 + r * m..][..m], a, &v[bm0 + j * m..][..m]);
                axpy(&mut dv[bp0 + r * m..][..m], a, &v[bp0 + j * m..][..m]);
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
        self.propagate_dense(x0, u, s, dt).map(|d| (d.time, d.x))
    }

    /// [`propagate`](Self::propagate) with the first-order-hold controls at every sample
    /// (what the dynamics saw there) and each sample's segment.
    ///
    /// # Errors
    /// As [`propagate`](Self::propagate).
    pub fn propagate_dense(
        &self,
        x0: &[f64],
        u: &[f64],
        s: &[f64],
        dt: f64,
    ) -> Result<DenseTrajectory, DiscretizationError> {
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
        let mut ws = self.lane();
        let (mut times, mut states) = (vec![0.0], x0.to_vec());
        let mut controls = u[..mu].to_vec();
        let mut segment = vec![0];
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
                    let FEval { ws: fws, input, fval, .. } = &mut ws.f;
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
                segment.push(seg);
                for i in 0..mu {
                    controls.push(if self.foh[i] { uk[i] + b1 * (uk1[i] - uk[i]) } else { uk[i] });
                }
            }
        }
        Ok(DenseTrajectory { time: times, x: states, u: controls, segment })
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

    #[allow(clippy::too_many_arguments)]
    fn integrate(
        &self,
        x: &[f64],
        u: &[f64],
        s: &[f64],
        settings: &DiscretizationSettings,
        ws: &mut DiscretizationWorkspace,
        out: &mut Discretization,
        full: bool,
    ) -> Result<(), DiscretizationError> {
        let (n, mu) = (self.n_x, self.n_u);
        let nodes = s.len();
        if nodes < 2
            || x.len() != nodes * n
            || u.len() != nodes * mu
            || out.segments != nodes - 1
            || settings.substeps == 0
            || (out.grid_points != 0 && out.grid_points != settings.substeps + 1)
        {
            return Err(DiscretizationError::Size(format!(
                "{nodes} nodes need x of {} (got {}), u of {} (got {}), an output for {} segments (has {}), substeps ≥ 1 and a grid of substeps + 1 points (substeps {}, grid points {})",
                nodes * n,
                x.len(),
                nodes * mu,
                u.len(),
                nodes.saturating_sub(1),
                out.segments,
                settings.substeps,
                out.grid_points
            )));
        }
        let segments = nodes - 1;
        let lanes = if settings.parallel { ws.lanes.len().min(segments) } else { 1 };
        let all = LaneOut {
            first: 0,
            grid_seg: out.grid_points * self.grid_stride(),
            grid: &mut out.grid,
            a: &mut out.a,
            b_minus: &mut out.b_minus,
            b_plus: &mut out.b_plus,
            x_prop: &mut out.x_prop,
            defect: &mut out.defect,
        };
        let plan = (settings.substeps, settings.integrator, full);
        self.discretize_lanes(x, u, s, plan, &mut ws.lanes[..lanes], segments, all)
    }

    /// Integrates `segments` segments into `out`, split evenly over `lanes`: the first lane
    /// runs on the calling thread, the others are spawned on the rayon pool (one small
    /// allocation per spawned lane; a `rayon::join` from outside the pool would queue both
    /// halves behind a possibly sleeping worker).
    #[allow(clippy::too_many_arguments)]
    fn discretize_lanes(
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
    fn discretize_segments(
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
