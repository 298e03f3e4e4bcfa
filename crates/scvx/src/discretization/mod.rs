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

mod control_holds;
mod dense;
mod hessian;
mod integrators;
mod lanes;

pub use control_holds::{ControlHolds, ControlProfile};
pub use hessian::SegmentHessianWorkspace;
use integrators::*;
use lanes::*;

/// Integrator settings.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
#[serde(default, deny_unknown_fields)]
#[non_exhaustive]
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

/// How each segment is integrated (the state and its variational equations together). As
/// data: `"rk4"` or `{ dormand_prince = { rtol = 1e-8, atol = 1e-10 } }`.
#[derive(
    Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema,
)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
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
        /// Relative tolerance (> 0). Default 1e-8.
        #[serde(default = "default_rtol")]
        rtol: f64,
        /// Absolute tolerance (> 0). Default 1e-10.
        #[serde(default = "default_atol")]
        atol: f64,
    },
}

fn default_rtol() -> f64 {
    1e-8
}

fn default_atol() -> f64 {
    1e-10
}

/// Most RK4 steps per segment ([`DiscretizationSettings::substeps`]).
pub const MAX_SUBSTEPS: usize = 1_000;

/// Most integration steps of a whole horizon, `(N − 1)·substeps`: the grid's sensitivities
/// and grid-point rows grow with it.
pub const MAX_GRID_STEPS: usize = 200_000;

/// Steps one Dormand–Prince segment may take before the discretization gives up.
pub const MAX_ADAPTIVE_STEPS: usize = 100_000;

/// Compiled dynamics `f(x, u)` with its sparse Jacobian, ready to discretize.
#[derive(Debug, Clone)]
pub struct Dynamics {
    f: Function,
    n_x: usize,
    n_u: usize,
    foh: Vec<bool>,
    /// Per control entry: time-scaled (the variable is `w = s·u`, see
    /// [`Dynamics::time_scaled`]).
    time_scaled: Vec<bool>,
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
            time_scaled: vec![false; n_u],
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

    /// Marks control entries as time-scaled: the solver's variable for entry `i` is then
    /// `w_i = s·u_i` (the control times the segment's dilation) and the dynamics see
    /// `u_i = w_i / s`, so `dx/dτ = s·f(x, w/s)`. Where `f` is affine in `u_i` (a torque
    /// through an inertia), the term becomes linear in `w_i` and no longer multiplies the
    /// dilation: the linearization of a step that changes both the time and the control is
    /// exact in that term. The bounds of a time-scaled entry are the physical `u`'s, held on
    /// each segment by `u_min·s_k ≤ w ≤ u_max·s_k` at both of its ends.
    ///
    /// # Errors
    /// A mask of the wrong length.
    pub fn time_scaled(mut self, mask: &[bool]) -> Result<Dynamics, DiscretizationError> {
        if mask.len() != self.n_u {
            return Err(DiscretizationError::Size(format!(
                "time-scaled mask has {} entries for {} controls",
                mask.len(),
                self.n_u
            )));
        }
        self.time_scaled = mask.to_vec();
        Ok(self)
    }

    /// Whether control entry `i` is time-scaled ([`time_scaled`](Self::time_scaled)).
    pub fn is_time_scaled(&self, i: usize) -> bool {
        self.time_scaled.get(i).copied().unwrap_or(false)
    }

    /// Whether control entry `i` is first-order hold.
    pub fn is_foh(&self, i: usize) -> bool {
        self.foh.get(i).copied().unwrap_or(false)
    }

    /// The control `u` the dynamics see from the variable `w` of entry `i` on a segment of
    /// dilation `s`: `w / s` if time-scaled, else `w`.
    pub fn physical_control(&self, i: usize, w: f64, s: f64) -> f64 {
        if self.is_time_scaled(i) { w / s } else { w }
    }

    /// The control `u` the dynamics see at fraction `beta` of a segment of dilation `s` whose
    /// nodes hold the variables `uk` and `uk1` (entry `i`): held (first- or zero-order), then
    /// [`physical_control`](Self::physical_control).
    #[inline]
    fn held_control(&self, i: usize, (uk, uk1): (&[f64], &[f64]), beta: f64, s: f64) -> f64 {
        let w = if self.foh[i] { uk[i] + beta * (uk1[i] - uk[i]) } else { uk[i] };
        self.physical_control(i, w, s)
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
}
