//! The penalized-trust-region (PTR) loop with Clarabel subproblems.
//!
//! # Subproblem
//! Variables `z = [X (N·n) | U (N·m) | S (N) | ν⁺ ((N−1)·n) | ν⁻ ((N−1)·n)]`, around the
//! reference `z̄` with its discretization:
//!
//! ```text
//! minimise   w_t·Δτ·Σ_{k<N−1} s_k  +  λ_vc·Σ(ν⁺ + ν⁻)  +  λ_tr·‖(X, U, S) − (X̄, Ū, S̄)‖²
//! subject to x_{k+1} = A_k x_k + B⁻_k [u_k; s_k] + B⁺_k u_{k+1} + c_k + ν⁺_k − ν⁻_k
//!            (c_k = x_prop_k − A_k x̄_k − B⁻_k [ū_k; s̄_k] − B⁺_k ū_{k+1})
//!            fixed initial / final state components, s_{N−1} = s_{N−2},
//!            box bounds on x, u, s, and ν± ≥ 0.
//! ```
//!
//! The trust-region norm is measured in scaled variables `(z − z̄)/S` with
//! `S = max(1, (max − min)/2)` from each variable's bounds, so a dilation with range [0.1, 10]
//! may move as far, relative to its range, as an acceleration in [−1, 1].
//!
//! The constraint matrix's pattern is built once with a value source per nonzero; each
//! iteration refills the values and updates Clarabel in place (presolve off).
//!
//! The subproblem is solved in deviation form (unknowns `Δz = z − z̄`), so its objective
//! carries no `λ_tr‖z̄‖²` offset that would swamp Clarabel's relative tolerances at large λ_tr.
//! Nodal constraints are either entrywise inequalities (linearised, with a virtual buffer
//! each) or balls `‖g‖ ≤ r` kept as second-order cones around the linearised `g`.
//!
//! # Acceptance
//! By default ([`TrustRegionUpdate::Adaptive`]) the merit
//! `J(z) = w_t·t_f(z) + Σ λ_vc,i·|defect_i(z)| + Σ λ_vb·max(0, violation)` and the
//! subproblem's prediction `L(z*)` give `ρ = (J(z̄) − J(z*)) / (J(z̄) − L(z*))`; a step with
//! `ρ < η₀` is rejected and λ_tr doubles (so the next subproblem differs — no identical
//! re-solves), otherwise λ_tr adapts (×2 below η₁, ×½ above η₂). The published PTR
//! ([`TrustRegionUpdate::Constant`]) accepts every step. A row whose subproblem bought virtual
//! control (or a buffer) gets a doubled price — the ℓ1 penalty is exact only above the
//! multiplier. Converged when an accepted step has `‖Δz‖²_S < ε_tr`, the largest nonlinear
//! defect is below `ε_defect` and the largest nodal violation below `ε_vb`.

use clarabel::algebra::CscMatrix;
use clarabel::solver::{
    DefaultSettings, DefaultSolver, IPSolver, NonnegativeConeT, SecondOrderConeT, SolverStatus,
    SupportedConeT, ZeroConeT,
};
use serde::Serialize;

use crate::{Discretization, DiscretizationSettings, DiscretizationWorkspace, Dynamics};

/// The optimal control problem in dynamics form.
#[derive(Debug, Clone)]
pub struct Ocp {
    /// Compiled dynamics.
    pub dynamics: Dynamics,
    /// Number of nodes N (≥ 2).
    pub nodes: usize,
    /// State bounds (±∞ for none).
    pub x_min: Vec<f64>,
    /// State bounds.
    pub x_max: Vec<f64>,
    /// Control bounds.
    pub u_min: Vec<f64>,
    /// Control bounds.
    pub u_max: Vec<f64>,
    /// Fixed initial components (`None` = free).
    pub x_initial: Vec<Option<f64>>,
    /// Fixed final components (`None` = free).
    pub x_final: Vec<Option<f64>>,
    /// Bounds of the time dilation `s` (total time = s·1 for a uniform grid).
    pub s_min: f64,
    /// Bounds of the time dilation.
    pub s_max: f64,
    /// Bounds of the final time `Δτ·Σ_{k<N−1} s_k` (a linear constraint; `(0, ∞)` for none).
    pub final_time: (f64, f64),
    /// Weight of the final time in the cost (0: fixed-time feasibility).
    pub time_weight: f64,
    /// CTCS increments `(state row, ε, first node, last node)`: `y_{k+1} − y_k ≤ ε` for the
    /// segments of the interval.
    pub increments: Vec<(usize, f64, usize, usize)>,
    /// Nodal constraints, linearised each iteration with virtual buffers.
    pub nodal: Vec<NodalConstraint>,
}

/// A (generally nonconvex) constraint on `g(x_k, u_k)` at listed nodes.
#[derive(Debug, Clone)]
pub struct NodalConstraint {
    /// Name for diagnostics.
    pub name: String,
    /// `g`, compiled against the groups `[states], [controls]` of the dynamics.
    pub function: armature_symbolic::Function,
    /// Nodes where it holds.
    pub nodes: Vec<usize>,
    /// What it says about `g`.
    pub kind: NodalKind,
}

/// The meaning of a [`NodalConstraint`].
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub enum NodalKind {
    /// `g ≤ 0` entrywise, linearised: `g(z̄) + ∇g·(z − z̄) ≤ ν_b` per entry.
    Inequality,
    /// `‖g‖₂ ≤ radius` (e.g. `g = p_ee − waypoint`), linearised inside the norm only:
    /// `‖g(z̄) + ∇g·(z − z̄)‖ ≤ radius + ν_b`, a second-order cone. Keeping the norm exact
    /// (the prox-linear model) captures the ball's curvature, which a linearised norm would
    /// leave to the trust region.
    Ball {
        /// The radius.
        radius: f64,
    },
}

/// PTR settings with documented defaults.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PtrSettings {
    /// Initial trust-region weight λ_tr. Default 1.
    pub lam_tr: f64,
    /// Bounds of λ_tr. Default [1e-4, 1e6].
    pub lam_tr_min: f64,
    /// Bounds of λ_tr.
    pub lam_tr_max: f64,
    /// Cap of the per-row virtual-control and buffer weights. Default 1e6.
    pub lam_vc_max: f64,
    /// Initial virtual-buffer weight λ_vb of nodal constraints, relative to the time weight
    /// (per buffer; doubles when the subproblem buys that buffer, up to `lam_vc_max`).
    /// Default 0.3.
    pub lam_vb: f64,
    /// Convergence: largest nodal violation. Default 1e-6.
    pub eps_vb: f64,
    /// Initial virtual-control weight λ_vc per state row (exact-penalty weight: it must
    /// exceed the dynamics multipliers, and doubles when the subproblem buys virtual control;
    /// a heavier start makes the merit dominated by second-order defects and slows the trust
    /// region — 0.3 suits a time weight of 1 on the seed problem). Default 0.3.
    pub lam_vc: f64,
    /// Convergence: `‖Δz‖²` (scaled) of an accepted step. Default 1e-6.
    pub eps_tr: f64,
    /// Convergence: largest nonlinear defect. Default 1e-6.
    pub eps_defect: f64,
    /// How the trust-region weight evolves. Default `Adaptive { eta: [0, 0.1, 0.5] }`.
    pub trust_region: TrustRegionUpdate,
    /// Iteration cap. Default 100.
    pub max_iterations: usize,
    /// Integrator settings.
    pub discretization: DiscretizationSettings,
}

impl Default for PtrSettings {
    fn default() -> Self {
        PtrSettings {
            lam_tr: 1.0,
            lam_tr_min: 1e-4,
            lam_tr_max: 1e6,
            lam_vc: 0.3,
            lam_vc_max: 1e6,
            lam_vb: 0.3,
            eps_vb: 1e-6,
            eps_tr: 1e-6,
            eps_defect: 1e-6,
            trust_region: TrustRegionUpdate::Adaptive { eta: [0.0, 0.1, 0.5] },
            max_iterations: 100,
            discretization: DiscretizationSettings::default(),
        }
    }
}

/// Trust-region policy.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub enum TrustRegionUpdate {
    /// Penalized trust region as published (Reynolds, Szmuk et al.; OpenSCvx's
    /// `ConstantProximalWeight`): every step is accepted and λ_tr stays fixed; the
    /// virtual-control penalty drives feasibility.
    Constant,
    /// Accept or reject by the actual/predicted merit ratio ρ with thresholds η₀ < η₁ < η₂:
    /// reject below η₀ (λ_tr doubles, so the next subproblem differs), double λ_tr below η₁,
    /// halve it above η₂. Slower than `Constant` on the reference problems so far: second-
    /// order defects weighted by λ_vc keep ρ low, so λ_tr stays high.
    Adaptive {
        /// The thresholds.
        eta: [f64; 3],
    },
}

/// How a solve ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub enum PtrStatus {
    /// Both criteria met.
    Converged,
    /// The iteration cap was reached.
    MaxIterations,
    /// λ_tr hit its cap without an acceptable step.
    Stalled,
    /// Clarabel reported the subproblem infeasible.
    SubproblemInfeasible,
    /// Clarabel failed numerically.
    NumericalFailure,
}

/// One iteration's record.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Iteration {
    /// 1-based iteration number.
    pub iteration: usize,
    /// Whether the step was accepted.
    pub accepted: bool,
    /// ‖Δz‖² of the step (scaled variables).
    pub j_tr: f64,
    /// Σ|ν| of the subproblem.
    pub j_vc: f64,
    /// Largest nonlinear defect of the candidate.
    pub max_defect: f64,
    /// Largest nodal-constraint violation of the candidate.
    pub max_violation: f64,
    /// Final time of the candidate.
    pub final_time: f64,
    /// Actual / predicted merit reduction.
    pub rho: f64,
    /// λ_tr used.
    pub lam_tr: f64,
}

/// The outcome: the last accepted trajectory and the history.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PtrResult {
    /// How it ended.
    pub status: PtrStatus,
    /// States (N×n, row-major).
    pub x: Vec<f64>,
    /// Controls (N×m).
    pub u: Vec<f64>,
    /// Dilations (N).
    pub s: Vec<f64>,
    /// `Δτ·Σ s_k`.
    pub final_time: f64,
    /// Per-iteration records.
    pub history: Vec<Iteration>,
}

#[derive(Debug, Clone, Copy)]
enum Source {
    Const(f64),
    A(usize),
    Bm(usize),
    Bp(usize),
    /// A nodal-constraint Jacobian nonzero (index into the per-iteration buffer).
    G(usize),
    /// Its negative (cone rows: `s = b − A z`).
    NegG(usize),
}

/// Scratch for evaluating the nodal constraints (allocated once per solve).
#[derive(Debug)]
struct NodalEval {
    ws: Vec<armature_symbolic::Workspace>,
    input: Vec<f64>,
    values: Vec<f64>,
    jac: Vec<f64>,
    violation: Vec<f64>,
}

/// Where one nodal constraint row sits: its evaluation block and its subproblem row.
#[derive(Debug, Clone, Copy)]
struct NodalRow {
    output: usize,
    row: usize,
    /// Index of its (constraint, node) evaluation block in `g_offsets`.
    eval: usize,
    /// A cone row (`b = g(z̄) − ∇g·z̄`) rather than an inequality (`b = ∇g·z̄ − g(z̄)`).
    cone: bool,
}

/// The PTR solver for one [`Ocp`], with its subproblem pattern built once.
#[derive(Debug)]
pub struct Ptr {
    ocp: Ocp,
    settings: PtrSettings,
    n_vars: usize,
    a_colptr: Vec<usize>,
    a_rowval: Vec<usize>,
    sources: Vec<Source>,
    b: Vec<f64>,
    /// Row index of the first dynamics row (ZeroCone rows come first).
    n_zero: usize,
    n_nonneg: usize,
    dws: DiscretizationWorkspace,
    /// Start of the virtual-buffer variables.
    vb0: usize,
    nodal_rows: Vec<NodalRow>,
    /// Per (constraint, node) evaluation: offset of its values and Jacobian nonzeros.
    g_offsets: Vec<(usize, usize)>,
    g_len: (usize, usize),
    /// Per virtual buffer: its evaluation block and output (`None` for a ball's norm).
    buffers: Vec<(usize, usize, Option<usize>)>,
    /// Sizes of the second-order cones (after the nonnegative rows).
    socs: Vec<usize>,
}

impl Ptr {
    fn layout(&self) -> (usize, usize, usize, usize) {
        let (n, m, nn) = (self.ocp.dynamics.n_x(), self.ocp.dynamics.n_u(), self.ocp.nodes);
        (nn * n, nn * n + nn * m, nn * n + nn * m + nn, (nn - 1) * n)
    }

    /// Builds the solver (the subproblem pattern is computed here, once).
    pub fn new(ocp: Ocp, settings: PtrSettings) -> Ptr {
        let (n, m, nn) = (ocp.dynamics.n_x(), ocp.dynamics.n_u(), ocp.nodes);
        let mc = m + 1;
        let x0 = 0;
        let u0 = nn * n;
        let s0 = u0 + nn * m;
        let vp0 = s0 + nn;
        let vm0 = vp0 + (nn - 1) * n;
        let vb0 = vm0 + (nn - 1) * n;
        let n_buffers: usize = ocp
            .nodal
            .iter()
            .map(|c| {
                c.nodes.len()
                    * match c.kind {
                        NodalKind::Inequality => c.function.n_outputs(),
                        NodalKind::Ball { .. } => 1,
                    }
            })
            .sum();
        let n_vars = vb0 + n_buffers;
        // Evaluation buffers of the nodal constraints, per (constraint, node).
        let mut g_offsets = Vec::new();
        let (mut gv, mut gj) = (0, 0);
        for c in &ocp.nodal {
            for _ in &c.nodes {
                g_offsets.push((gv, gj));
                gv += c.function.n_outputs();
                gj += c.function.jacobian_pattern().nnz();
            }
        }
        let mut trip: Vec<(usize, usize, Source)> = Vec::new();
        let mut b = Vec::new();
        let mut row = 0;
        // Dynamics rows: A x_k − x_{k+1} + B⁻[u_k; s_k] + B⁺ u_{k+1} + ν⁺ − ν⁻ = −c_k.
        for k in 0..nn - 1 {
            for r in 0..n {
                for j in 0..n {
                    trip.push((row, x0 + k * n + j, Source::A(k * n * n + r * n + j)));
                }
                trip.push((row, x0 + (k + 1) * n + r, Source::Const(-1.0)));
                for i in 0..m {
                    trip.push((row, u0 + k * m + i, Source::Bm(k * n * mc + r * mc + i)));
                    trip.push((row, u0 + (k + 1) * m + i, Source::Bp(k * n * mc + r * mc + i)));
                }
                trip.push((row, s0 + k, Source::Bm(k * n * mc + r * mc + m)));
                trip.push((row, vp0 + k * n + r, Source::Const(1.0)));
                trip.push((row, vm0 + k * n + r, Source::Const(-1.0)));
                b.push(0.0);
                row += 1;
            }
        }
        for (i, v) in ocp.x_initial.iter().enumerate() {
            if let Some(v) = v {
                trip.push((row, x0 + i, Source::Const(1.0)));
                b.push(*v);
                row += 1;
            }
        }
        for (i, v) in ocp.x_final.iter().enumerate() {
            if let Some(v) = v {
                trip.push((row, x0 + (nn - 1) * n + i, Source::Const(1.0)));
                b.push(*v);
                row += 1;
            }
        }
        trip.push((row, s0 + nn - 1, Source::Const(1.0)));
        trip.push((row, s0 + nn - 2, Source::Const(-1.0)));
        b.push(0.0);
        row += 1;
        let n_zero = row;
        // Inequalities `a·z ≤ b` as rows of the nonnegative cone.
        let ineq = |col: usize,
                    sign: f64,
                    bound: f64,
                    trip: &mut Vec<(usize, usize, Source)>,
                    b: &mut Vec<f64>,
                    row: &mut usize| {
            if bound.is_finite() {
                trip.push((*row, col, Source::Const(sign)));
                b.push(sign * bound);
                *row += 1;
            }
        };
        for k in 0..nn {
            for i in 0..n {
                ineq(x0 + k * n + i, 1.0, ocp.x_max[i], &mut trip, &mut b, &mut row);
                ineq(x0 + k * n + i, -1.0, ocp.x_min[i], &mut trip, &mut b, &mut row);
            }
            for i in 0..m {
                ineq(u0 + k * m + i, 1.0, ocp.u_max[i], &mut trip, &mut b, &mut row);
                ineq(u0 + k * m + i, -1.0, ocp.u_min[i], &mut trip, &mut b, &mut row);
            }
            ineq(s0 + k, 1.0, ocp.s_max, &mut trip, &mut b, &mut row);
            ineq(s0 + k, -1.0, ocp.s_min, &mut trip, &mut b, &mut row);
        }
        let dtau = 1.0 / (nn - 1) as f64;
        for (sign, bound) in [(1.0, ocp.final_time.1), (-1.0, ocp.final_time.0)] {
            if bound.is_finite() && (sign > 0.0 || bound > 0.0) {
                for k in 0..nn - 1 {
                    trip.push((row, s0 + k, Source::Const(sign * dtau)));
                }
                b.push(sign * bound);
                row += 1;
            }
        }
        for &(r, eps, first, last) in &ocp.increments {
            for k in first..last.min(nn - 1) {
                trip.push((row, x0 + (k + 1) * n + r, Source::Const(1.0)));
                trip.push((row, x0 + k * n + r, Source::Const(-1.0)));
                b.push(eps);
                row += 1;
            }
        }
        // Nodal rows ∇g·z − ν_b ≤ ∇g·z̄ − g(z̄) (values refilled per iteration).
        // Entries of output `out` of a (constraint, node) Jacobian as subproblem columns.
        let jac_row = |c: &NodalConstraint, k: usize, goff: usize, out: usize| {
            let p = c.function.jacobian_pattern();
            let mut v = Vec::new();
            for col in 0..p.ncols() {
                for nzi in p.col_ptr()[col]..p.col_ptr()[col + 1] {
                    if p.row_idx()[nzi] == out {
                        let var = if col < n { x0 + k * n + col } else { u0 + k * m + (col - n) };
                        v.push((var, goff + nzi));
                    }
                }
            }
            v
        };
        let mut nodal_rows = Vec::new();
        let mut buffers = Vec::new();
        let mut eval = 0;
        let mut ball_evals = Vec::new();
        for (ci, c) in ocp.nodal.iter().enumerate() {
            for &k in &c.nodes {
                let (_, goff) = g_offsets[eval];
                match c.kind {
                    NodalKind::Inequality => {
                        for out in 0..c.function.n_outputs() {
                            for (var, i) in jac_row(c, k, goff, out) {
                                trip.push((row, var, Source::G(i)));
                            }
                            trip.push((row, vb0 + buffers.len(), Source::Const(-1.0)));
                            nodal_rows.push(NodalRow { output: out, row, eval, cone: false });
                            buffers.push((eval, ci, Some(out)));
                            b.push(0.0);
                            row += 1;
                        }
                    }
                    NodalKind::Ball { .. } => {
                        ball_evals.push((ci, k, eval, vb0 + buffers.len()));
                        buffers.push((eval, ci, None));
                    }
                }
                eval += 1;
            }
        }
        for c in vp0..n_vars {
            ineq(c, -1.0, 0.0, &mut trip, &mut b, &mut row);
        }
        let n_nonneg = row - n_zero;
        // Balls: [radius + ν_b; g(z̄) + ∇g·(z − z̄)] in the second-order cone.
        let mut socs = Vec::new();
        for &(ci, k, ev, buffer) in &ball_evals {
            let c = &ocp.nodal[ci];
            let NodalKind::Ball { radius } = c.kind else { continue };
            trip.push((row, buffer, Source::Const(-1.0)));
            b.push(radius);
            row += 1;
            let (_, goff) = g_offsets[ev];
            for out in 0..c.function.n_outputs() {
                for (var, i) in jac_row(c, k, goff, out) {
                    trip.push((row, var, Source::NegG(i)));
                }
                nodal_rows.push(NodalRow { output: out, row, eval: ev, cone: true });
                b.push(0.0);
                row += 1;
            }
            socs.push(1 + c.function.n_outputs());
        }
        trip.sort_by_key(|t| (t.1, t.0));
        let mut a_colptr = vec![0; n_vars + 1];
        for t in &trip {
            a_colptr[t.1 + 1] += 1;
        }
        for c in 0..n_vars {
            a_colptr[c + 1] += a_colptr[c];
        }
        let a_rowval = trip.iter().map(|t| t.0).collect();
        let sources = trip.iter().map(|t| t.2).collect();
        let dws = ocp.dynamics.workspace();
        Ptr {
            ocp,
            settings,
            n_vars,
            a_colptr,
            a_rowval,
            sources,
            b,
            n_zero,
            n_nonneg,
            dws,
            vb0,
            nodal_rows,
            g_offsets,
            g_len: (gv, gj),
            buffers,
            socs,
        }
    }

    /// The problem.
    pub fn ocp(&self) -> &Ocp {
        &self.ocp
    }

    /// Evaluates every nodal constraint at `(x, u)` into the buffers (values, Jacobians and
    /// per-buffer violations); returns `(Σ w·violation, largest violation)`.
    fn eval_nodal(&self, x: &[f64], u: &[f64], ev: &mut NodalEval, weights: &[f64]) -> (f64, f64) {
        let (n, m) = (self.ocp.dynamics.n_x(), self.ocp.dynamics.n_u());
        let mut e = 0;
        for (ci, c) in self.ocp.nodal.iter().enumerate() {
            let (nout, nnz) = (c.function.n_outputs(), c.function.jacobian_pattern().nnz());
            for &k in &c.nodes {
                ev.input[..n].copy_from_slice(&x[k * n..(k + 1) * n]);
                ev.input[n..n + m].copy_from_slice(&u[k * m..(k + 1) * m]);
                let (vo, jo) = self.g_offsets[e];
                let (vals, jac) = (&mut ev.values[vo..vo + nout], &mut ev.jac[jo..jo + nnz]);
                // Compiled against the dynamics' groups: evaluation cannot fail on sizes.
                if c.function.eval(&ev.input[..n + m], &mut ev.ws[ci], vals, Some(jac)).is_err() {
                    vals.fill(f64::INFINITY);
                }
                e += 1;
            }
        }
        let (mut sum, mut max) = (0.0, 0.0f64);
        for (i, &(eval, ci, out)) in self.buffers.iter().enumerate() {
            let c = &self.ocp.nodal[ci];
            let vo = self.g_offsets[eval].0;
            let v = match (out, c.kind) {
                (Some(o), _) => ev.values[vo + o],
                (None, NodalKind::Ball { radius }) => {
                    let g = &ev.values[vo..vo + c.function.n_outputs()];
                    g.iter().map(|v| v * v).sum::<f64>().sqrt() - radius
                }
                (None, NodalKind::Inequality) => 0.0,
            };
            ev.violation[i] = v.max(0.0);
            sum += weights[i] * v.max(0.0);
            max = max.max(v);
        }
        (sum, max)
    }

    /// Merit `(J, t_f, max defect, max nodal violation)` of a trajectory.
    fn merit(
        &self,
        x: &[f64],
        u: &[f64],
        s: &[f64],
        d: &Discretization,
        ev: &mut NodalEval,
        (lam_vc, lam_vb): (&[f64], &[f64]),
    ) -> (f64, f64, f64, f64) {
        let nn = self.ocp.nodes;
        let dtau = 1.0 / (nn - 1) as f64;
        let tf = dtau * s[..nn - 1].iter().sum::<f64>();
        let n = self.ocp.dynamics.n_x();
        let l1: f64 = d.defect.iter().enumerate().map(|(i, x)| lam_vc[i % n] * x.abs()).sum();
        let max = d.defect.iter().fold(0.0f64, |a, x| a.max(x.abs()));
        let (viol, max_viol) = self.eval_nodal(x, u, ev, lam_vb);
        (self.ocp.time_weight * tf + l1 + viol, tf, max, max_viol)
    }

    /// Runs PTR from the guess `(x, u, s)` (N×n, N×m, N).
    ///
    /// # Errors
    /// Guesses of the wrong size, or a dynamics evaluation error.
    pub fn solve(
        &mut self,
        x: &[f64],
        u: &[f64],
        s: &[f64],
    ) -> Result<PtrResult, crate::DiscretizationError> {
        let (n, m, nn) = (self.ocp.dynamics.n_x(), self.ocp.dynamics.n_u(), self.ocp.nodes);
        let (u0, s0, vp0, _) = self.layout();
        let nv = self.n_vars;
        let set = self.settings.clone();
        let (mut xb, mut ub, mut sb) = (x.to_vec(), u.to_vec(), s.to_vec());
        let mut dbar = self.ocp.dynamics.output(nn);
        self.ocp.dynamics.discretize(
            &xb,
            &ub,
            &sb,
            &set.discretization,
            &mut self.dws,
            &mut dbar,
        )?;
        let mut dcand = self.ocp.dynamics.output(nn);
        let mut ev = NodalEval {
            ws: self.ocp.nodal.iter().map(|c| c.function.workspace()).collect(),
            input: vec![0.0; n + m],
            values: vec![0.0; self.g_len.0],
            jac: vec![0.0; self.g_len.1],
            violation: vec![0.0; self.buffers.len()],
        };
        let mut lam_vc = vec![set.lam_vc; n];
        let mut lam_vb = vec![set.lam_vb; self.buffers.len()];
        let (mut jbar, mut tf, _, _) =
            self.merit(&xb, &ub, &sb, &dbar, &mut ev, (&lam_vc, &lam_vb));
        let mut lam_tr = set.lam_tr;
        let mut history = Vec::new();
        let dtau = 1.0 / (nn - 1) as f64;
        let n_primal = vp0;
        // P: 2λ_tr on the (x, u, s) diagonal; q and b refilled per iteration.
        let p_colptr: Vec<usize> = (0..=self.n_vars).map(|c| c.min(n_primal)).collect();
        let p_rowval: Vec<usize> = (0..n_primal).collect();
        let mut q = vec![0.0; self.n_vars];
        let mut zbar = vec![0.0; n_primal];
        let mut zc = vec![0.0; n_primal];
        let mut pvals = vec![0.0; n_primal];
        // Trust-region scale per variable: S = max(1, range/2) from its bounds (OpenSCvx's
        // affine scaling), so the region is measured in comparable units.
        let scale_of = |lo: f64, hi: f64| {
            if lo.is_finite() && hi.is_finite() { (0.5 * (hi - lo)).max(1.0) } else { 1.0 }
        };
        let inv_s2: Vec<f64> = (0..n_primal)
            .map(|i| {
                let sc = if i < u0 {
                    scale_of(self.ocp.x_min[i % n], self.ocp.x_max[i % n])
                } else if i < s0 {
                    scale_of(
                        self.ocp.u_min[(i - u0) % m.max(1)],
                        self.ocp.u_max[(i - u0) % m.max(1)],
                    )
                } else {
                    scale_of(self.ocp.s_min, self.ocp.s_max)
                };
                1.0 / (sc * sc)
            })
            .collect();
        let mut nz = vec![0.0; self.a_rowval.len()];
        let mut b = self.b.clone();
        let mut cones: Vec<SupportedConeT<f64>> =
            vec![ZeroConeT(self.n_zero), NonnegativeConeT(self.n_nonneg)];
        cones.extend(self.socs.iter().map(|&d| SecondOrderConeT(d)));
        let settings = DefaultSettings::<f64> {
            verbose: false,
            presolve_enable: false,
            ..DefaultSettings::default()
        };
        let mut solver: Option<DefaultSolver<f64>> = None;
        let mut status = PtrStatus::MaxIterations;
        for it in 1..=set.max_iterations {
            // Values of this linearization.
            self.eval_nodal(&xb, &ub, &mut ev, &lam_vb);
            for (v, src) in nz.iter_mut().zip(&self.sources) {
                *v = match *src {
                    Source::Const(c) => c,
                    Source::A(i) => dbar.a[i],
                    Source::Bm(i) => dbar.b_minus[i],
                    Source::Bp(i) => dbar.b_plus[i],
                    Source::G(i) => ev.jac[i],
                    Source::NegG(i) => -ev.jac[i],
                };
            }
            // Deviation form: the unknowns are Δz = z − z̄ (ν and buffers keep their values), so
            // the constant rows `A z ≤ b` become `A Δz ≤ b − A z̄`. The objective then carries
            // no λ_tr‖z̄‖² offset, which at large λ_tr would swamp Clarabel's relative gap
            // tolerance.
            zbar[..u0].copy_from_slice(&xb);
            zbar[u0..s0].copy_from_slice(&ub);
            zbar[s0..vp0].copy_from_slice(&sb);
            b.copy_from_slice(&self.b);
            for c in 0..n_primal {
                for p in self.a_colptr[c]..self.a_colptr[c + 1] {
                    b[self.a_rowval[p]] -= nz[p] * zbar[c];
                }
            }
            // Rows linearised at z̄ have their right-hand sides directly in deviation form:
            // dynamics `… = x̄_{k+1} − x_prop_k` (the defect), inequalities `∇g·Δz − ν ≤ −g(z̄)`,
            // cones `[r + ν; g(z̄) + ∇g·Δz]`.
            b[..(nn - 1) * n].copy_from_slice(&dbar.defect);
            for nr in &self.nodal_rows {
                let g = ev.values[self.g_offsets[nr.eval].0 + nr.output];
                b[nr.row] = if nr.cone { g } else { -g };
            }
            q.fill(0.0);
            for k in 0..nn - 1 {
                q[s0 + k] += self.ocp.time_weight * dtau;
            }
            for (i, qi) in q.iter_mut().enumerate().skip(vp0) {
                *qi = if i < self.vb0 { lam_vc[(i - vp0) % n] } else { lam_vb[i - self.vb0] };
            }
            for (p, w) in pvals.iter_mut().zip(&inv_s2) {
                *p = 2.0 * lam_tr * w;
            }
            // In-place update when the solver exists (same pattern); rebuild if that fails.
            if let Some(sv) = solver.as_mut() {
                let updated = sv.update_P(&pvals).is_ok()
                    && sv.update_q(&q).is_ok()
                    && sv.update_A(&nz).is_ok()
                    && sv.update_b(&b).is_ok();
                if !updated {
                    solver = None;
                }
            }
            if solver.is_none() {
                let pm = CscMatrix::new(
                    self.n_vars,
                    self.n_vars,
                    p_colptr.clone(),
                    p_rowval.clone(),
                    pvals.clone(),
                );
                let am = CscMatrix::new(
                    b.len(),
                    self.n_vars,
                    self.a_colptr.clone(),
                    self.a_rowval.clone(),
                    nz.clone(),
                );
                solver = DefaultSolver::new(&pm, &q, &am, &b, &cones, settings.clone()).ok();
            }
            let Some(sv) = solver.as_mut() else {
                status = PtrStatus::NumericalFailure;
                break;
            };
            sv.solve();
            match sv.solution.status {
                SolverStatus::Solved | SolverStatus::AlmostSolved => {}
                SolverStatus::PrimalInfeasible | SolverStatus::AlmostPrimalInfeasible => {
                    status = PtrStatus::SubproblemInfeasible;
                    break;
                }
                _ => {
                    status = PtrStatus::NumericalFailure;
                    break;
                }
            }
            let z = &sv.solution.x;
            for i in 0..n_primal {
                zc[i] = zbar[i] + z[i];
            }
            let (xc, uc, sc) = (&zc[..u0], &zc[u0..s0], &zc[s0..vp0]);
            let j_vc: f64 = z[vp0..self.vb0].iter().map(|v| v.abs()).sum();
            let vc_cost: f64 =
                z[vp0..self.vb0].iter().enumerate().map(|(i, v)| lam_vc[i % n] * v.abs()).sum();
            let vb_cost: f64 =
                z[self.vb0..nv].iter().zip(&lam_vb).map(|(v, w)| w * v.max(0.0)).sum();
            let j_tr: f64 = (0..n_primal).map(|i| z[i] * z[i] * inv_s2[i]).sum();
            self.ocp.dynamics.discretize(
                xc,
                uc,
                sc,
                &set.discretization,
                &mut self.dws,
                &mut dcand,
            )?;
            let (jc, tfc, max_defect, max_violation) =
                self.merit(xc, uc, sc, &dcand, &mut ev, (&lam_vc, &lam_vb));
            let predicted = jbar
                - (self.ocp.time_weight * dtau * sc[..nn - 1].iter().sum::<f64>()
                    + vc_cost
                    + vb_cost);
            let rho = if predicted.abs() > 1e-14 { (jbar - jc) / predicted } else { 1.0 };
            let accept = match set.trust_region {
                TrustRegionUpdate::Constant => true,
                TrustRegionUpdate::Adaptive { eta } => rho >= eta[0] || predicted.abs() <= 1e-14,
            };
            history.push(Iteration {
                iteration: it,
                accepted: accept,
                j_tr,
                j_vc,
                max_defect,
                max_violation,
                final_time: tfc,
                rho,
                lam_tr,
            });
            // Exact-penalty prices: the ℓ1 penalty is exact only above the constraint's
            // multiplier, so a row whose subproblem bought virtual control (or a buffer) at
            // this price is priced too low — double it. Nonlinear defects after a step are a
            // curvature effect that shrinks with the step and does not raise prices (raising
            // them there makes second-order defects dominate the merit and stalls the trust
            // region: the Maratos effect).
            let mut repriced = false;
            let nseg = (nn - 1) * n;
            for r in 0..n {
                let used = (0..nn - 1)
                    .map(|k| z[vp0 + k * n + r] + z[vp0 + nseg + k * n + r])
                    .fold(0.0, f64::max);
                if used > set.eps_defect && lam_vc[r] < set.lam_vc_max {
                    lam_vc[r] = (lam_vc[r] * 2.0).min(set.lam_vc_max);
                    repriced = true;
                }
            }
            for (w, v) in lam_vb.iter_mut().zip(&z[self.vb0..nv]) {
                if *v > set.eps_vb && *w < set.lam_vc_max {
                    *w = (*w * 2.0).min(set.lam_vc_max);
                    repriced = true;
                }
            }
            if accept {
                xb.copy_from_slice(xc);
                ub.copy_from_slice(uc);
                sb.copy_from_slice(sc);
                std::mem::swap(&mut dbar, &mut dcand);
                (jbar, tf) = (jc, tfc);
                // Stationarity, not just a short step: the subproblem's optimality gives
                // ‖∇L‖ ≈ 2λ_tr‖Δz‖, so a step kept short by a heavy trust region does not count.
                let stationary = j_tr < set.eps_tr;
                if stationary && max_defect < set.eps_defect && max_violation < set.eps_vb {
                    status = PtrStatus::Converged;
                    break;
                }
                if let TrustRegionUpdate::Adaptive { eta } = set.trust_region {
                    if rho < eta[1] {
                        lam_tr = (lam_tr * 2.0).min(set.lam_tr_max);
                    } else if rho > eta[2] {
                        lam_tr = (lam_tr * 0.5).max(set.lam_tr_min);
                    }
                }
            } else {
                if lam_tr >= set.lam_tr_max {
                    status = PtrStatus::Stalled;
                    break;
                }
                lam_tr = (lam_tr * 2.0).min(set.lam_tr_max);
            }
            // The reference merit under the (possibly new) prices, so ρ stays consistent.
            if repriced {
                jbar = self.merit(&xb, &ub, &sb, &dbar, &mut ev, (&lam_vc, &lam_vb)).0;
            }
        }
        Ok(PtrResult { status, x: xb, u: ub, s: sb, final_time: tf, history })
    }
}
