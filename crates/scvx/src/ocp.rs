//! The solver-level optimal control problem: dynamics, nodes, bounds, boundary values,
//! nodal and interval constraints, as the PTR loop reads it.

use serde::Serialize;

use crate::{Dynamics, PtrError};

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
    /// The dilations' unit in the trust region; `None`: half their bounds' range (at least 1),
    /// like every other variable. (A problem whose maximum time is far beyond its guess sets
    /// it from the guess, or the region would let the dilations swing across that range.)
    pub s_scale: Option<f64>,
    /// Bounds of the final time `Δτ·Σ_{k<N−1} s_k` (a linear constraint; `(0, ∞)` for none).
    pub final_time: (f64, f64),
    /// Weight of the final time in the cost (0: fixed-time feasibility).
    pub time_weight: f64,
    /// Linear cost on final-state components `(state index, weight)`: a positive weight
    /// minimizes `x_{N−1}[i]`, a negative one maximizes it.
    pub final_cost: Vec<(usize, f64)>,
    /// CTCS increments: `y_{k+1} − y_k ≤ ε` for the segments of each interval.
    pub increments: Vec<Increment>,
    /// Nodal constraints, linearised each iteration with virtual buffers.
    pub nodal: Vec<NodalConstraint>,
    /// State rows whose bounds `x_min ≤ x(t) ≤ x_max` are also enforced between the nodes,
    /// at each segment's peak: the largest (smallest) value of the row on the integration
    /// grid, refined by the parabola through the grid points around it, linearized through
    /// the grid's sensitivities (Danskin: the peak's time held fixed) and bounded with a
    /// virtual buffer. A CTCS integral of the positive part keeps a bound in continuous
    /// time but its linearization is blind where the trajectory touches the bound (the
    /// integrand has no gradient there), so a subproblem pushes through it and the merit
    /// rejects the step; a peak row shows the subproblem the bound with a full gradient.
    pub interval_bounds: Vec<usize>,
    /// Where those rows sit on each segment: at the peak, or at every grid point.
    pub interval_bounds_sampling: Sampling,
    /// Nonlinear state constraints `g(x(t)) ≤ 0` enforced between the nodes the same way:
    /// per segment and output, one buffered row at the output's peak on the integration
    /// grid (see [`IntervalConstraint`]).
    pub interval_constraints: Vec<IntervalConstraint>,
}

/// The nodal increments of a CTCS integral state `y` over nodes `first..=last`:
/// `y_{k+1} − y_k ≤ ε` for `k` in `first..last` (the integral of the violation may grow by
/// at most ε per segment).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Increment {
    /// The integral's state row.
    pub state: usize,
    /// The budget ε per segment.
    pub eps: f64,
    /// First node of the interval.
    pub first: usize,
    /// Last node of the interval.
    pub last: usize,
}

/// A constraint `g(x(t)) ≤ 0` (entrywise) on the states between the nodes of segments
/// `first..last`, enforced at each segment's peak of each output, or at every point of the
/// integration grid ([`Sampling`]).
///
/// # Math
/// On segment k, `g_o` is evaluated at the integration grid's points `t_j`; its largest value,
/// refined by the parabola through the best point and its neighbours, `ĝ_o = Σ_i w_i g_o(x(t_i))`,
/// gives the buffered row `Σ_i w_i ∇g_o(x(t_i))·∂x(t_i)/∂z · Δz − ν_b ≤ −ĝ_o` with the grid's
/// sensitivities `∂x(t_i)/∂z = [Φ | B⁻ | B⁺](t_i)` and the weights held (the envelope theorem
/// for the vertex, Danskin's for the grid maximum).
///
/// Why: a CTCS integral of `max(0, g)` keeps `g ≤ 0` in continuous time, but where the
/// trajectory only touches the constraint between the nodes its linearization is blind or
/// switches on and off (the ReLU's kink), and the merit ratio of a step swings; a peak row
/// gives the subproblem the constraint's full gradient where it is tightest. Use it for
/// clearances (`margin − distance`) and other state constraints the motion rides.
///
/// The named layer builds them from [`BetweenNodes`](crate::BetweenNodes) (see its example).
///
/// # Errors
/// [`Ptr::new`](crate::Ptr::new) returns [`PtrError::IntervalConstraint`] if `g` depends on
/// the controls, the segments are not within the problem's nodes or the activation distance
/// is not positive.
#[derive(Debug, Clone)]
pub struct IntervalConstraint {
    /// Name for diagnostics.
    pub name: String,
    /// `g`, compiled against the groups `[states], [controls]` of the dynamics; it may only
    /// read the states.
    pub function: armature_symbolic::Function,
    /// First segment (= its first node).
    pub first: usize,
    /// One past the last segment (= the last node of the interval); `first < last ≤ N − 1`.
    pub last: usize,
    /// Activation distance (in `g`'s units), or `None` to keep every row. A segment's rows
    /// are switched off while all of its peaks lie more than this below the bound
    /// (`max_o ĝ_o < −activation` at the reference): their coefficients are zeroed, so the
    /// subproblem drops them and the interior point factors a smaller KKT matrix (see
    /// [`crate::ipm::InteriorPoint::with_switchable_rows`]). The segment stays watched — by
    /// the merit, which prices every peak's violation, by the CTCS integral and the nodal
    /// rows — and its rows come back at the first reference where a peak comes within the
    /// distance. Choose it above what one step can move `g`: rows far from their bound are
    /// slack in every subproblem, so dropping them does not change the steps. For
    /// clearances, a few centimetres (the seed's collision variant: 2 cm; its walk keeps
    /// the same steps as with every row in for six iterations, then parts from it).
    pub activation: Option<f64>,
    /// Where the rows sit on each segment: at the peak of each output, or at every point of
    /// the integration grid.
    pub sampling: Sampling,
}

/// Where an interval constraint's rows sit between the nodes.
///
/// A peak row moves with the trajectory: where `g` rides its bound over a stretch of the
/// segment (an orientation held within a narrow range, say), the peak hops between grid
/// points from one iteration to the next and its gradient with it, and the steps zig-zag.
/// A row at each grid point is smooth (each has its own fixed time), at the price of one row
/// per point and output.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Sampling {
    /// One row per segment and output, at the output's largest value on the segment's grid
    /// (refined by a parabola).
    #[default]
    Peak,
    /// One row per output at every point of the integration grid of each segment (its
    /// nodes included), each bounding `g_o` over its half-step cell: the parabola through
    /// the point and its neighbours at its largest there, plus a bound on its cubic error
    /// from the grid's third differences, `ĝ_o = Σ_i w_i g_o(x(t_i))` over up to five points,
    /// and the row `Σ_i w_i ∇g_o(x(t_i))·∂x(t_i)/∂z · Δz − ν_b ≤ −ĝ_o`. The rows of one
    /// output (or bound side) on one segment share their buffer `ν_b`: the subproblem and
    /// the merit price the segment's largest violation of it.
    GridPoints,
}

impl IntervalConstraint {
    /// Whether `g` reads an input past the first `states` (the states come first, the
    /// controls after them): an interval constraint may read the states only, because the
    /// grid records the states and their sensitivities.
    pub fn reads_controls(&self, states: usize) -> bool {
        self.function.jacobian_pattern().entries().any(|(_, col)| col >= states)
    }
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
    /// With [`NodalKind::Inequality`]: a name per entry of `g`, under which
    /// [`PtrResult::violations`](crate::PtrResult::violations) reports the entry (entries that share a name, together).
    /// One vector constraint evaluates what its entries share once per node — the seed
    /// arm's collision pairs share the forward kinematics — where one constraint per entry
    /// would repeat it for each. Empty: the constraint is reported as one under `name` (as
    /// it must be with [`NodalKind::Ball`]).
    pub output_names: Vec<String>,
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

impl NodalKind {
    /// How far `g` lies beyond what the constraint allows (≤ 0: it holds): the largest entry
    /// of an inequality, `‖g‖ − radius` for a ball.
    ///
    /// # Example
    /// ```
    /// use armature_scvx::NodalKind;
    ///
    /// assert_eq!(NodalKind::Inequality.excess(&[-1.0, 0.25]), 0.25);
    /// assert_eq!(NodalKind::Ball { radius: 1.0 }.excess(&[3.0, 4.0]), 4.0);
    /// ```
    pub fn excess(&self, g: &[f64]) -> f64 {
        match *self {
            NodalKind::Inequality => g.iter().copied().fold(f64::NEG_INFINITY, f64::max),
            NodalKind::Ball { radius } => g.iter().map(|v| v * v).sum::<f64>().sqrt() - radius,
        }
    }
}

impl Ocp {
    /// Checks that the parts fit together: sizes of the bounds and boundary values, bounds in
    /// order, nodes within the grid, functions compiled against `[states], [controls]`, the
    /// rows each part names. [`Ptr::new`](crate::Ptr::new) calls it, so a problem is checked
    /// once, before its subproblem pattern is built.
    ///
    /// # Errors
    /// [`PtrError::Ocp`], [`PtrError::IntervalBoundRow`], [`PtrError::NodalConstraint`] or
    /// [`PtrError::IntervalConstraint`] naming the first part that does not fit.
    pub fn validate(&self) -> Result<(), PtrError> {
        let (n, m, nn) = (self.dynamics.n_x(), self.dynamics.n_u(), self.nodes);
        let bad =
            |field: &str, reason: String| Err(PtrError::Ocp { field: field.to_string(), reason });
        if !(2..=crate::MAX_NODES).contains(&nn) {
            return bad("nodes", format!("{nn} must be 2 to {}", crate::MAX_NODES));
        }
        let sizes: [(&str, usize, usize); 6] = [
            ("x_min", self.x_min.len(), n),
            ("x_max", self.x_max.len(), n),
            ("u_min", self.u_min.len(), m),
            ("u_max", self.u_max.len(), m),
            ("x_initial", self.x_initial.len(), n),
            ("x_final", self.x_final.len(), n),
        ];
        for (field, got, expected) in sizes {
            if got != expected {
                return bad(field, format!("has {got} entries for {expected} rows"));
            }
        }
        let pairs = self.x_min.iter().zip(&self.x_max).chain(self.u_min.iter().zip(&self.u_max));
        if let Some(i) = pairs.clone().position(|(lo, hi)| lo.is_nan() || hi.is_nan() || lo > hi) {
            let (field, row) = if i < n { ("x_min", i) } else { ("u_min", i - n) };
            return bad(field, format!("row {row} lies above its maximum (or is NaN)"));
        }
        if !(self.s_min > 0.0 && self.s_min <= self.s_max && self.s_max.is_finite()) {
            return bad("s_min", "and s_max must satisfy 0 < s_min ≤ s_max < ∞".into());
        }
        let (t0, t1) = self.final_time;
        if t0.is_nan() || t1.is_nan() || t0 > t1 {
            return bad("final_time", format!("({t0}, {t1}) is not an interval"));
        }
        if !self.time_weight.is_finite() {
            return bad("time_weight", "must be finite".into());
        }
        if let Some(&(i, w)) = self.final_cost.iter().find(|(i, w)| *i >= n || !w.is_finite()) {
            return bad("final_cost", format!("({i}, {w}) names no state row or is not finite"));
        }
        for (i, inc) in self.increments.iter().enumerate() {
            if inc.state >= n
                || !(inc.first < inc.last && inc.last < nn)
                || inc.eps.is_nan()
                || inc.eps < 0.0
            {
                let reason = "needs a state row, first < last ≤ N − 1 and ε ≥ 0".into();
                return bad(&format!("increments[{i}]"), reason);
            }
        }
        if let Some(&row) = self.interval_bounds.iter().find(|&&r| r >= n) {
            return Err(PtrError::IntervalBoundRow { row, states: n });
        }
        self.validate_constraints()
    }

    /// The nodal and interval constraints.
    fn validate_constraints(&self) -> Result<(), PtrError> {
        let (n, m, nn) = (self.dynamics.n_x(), self.dynamics.n_u(), self.nodes);
        for c in &self.nodal {
            let bad = |reason| Err(PtrError::NodalConstraint { name: c.name.clone(), reason });
            if c.function.n_inputs() != n + m {
                return bad("it must be compiled against the groups [states], [controls]");
            }
            if c.nodes.iter().any(|&k| k >= nn) {
                return bad("a node lies beyond the last node");
            }
            let names = c.output_names.len();
            if names > 0 && matches!(c.kind, NodalKind::Ball { .. }) {
                return bad("a ball constraint is one constraint: its entries take no names");
            }
            if names > 0 && names != c.function.n_outputs() {
                return bad("output_names must name every entry of g, or none");
            }
            if let NodalKind::Ball { radius } = c.kind
                && !(radius.is_finite() && radius >= 0.0)
            {
                return bad("its radius must be finite and ≥ 0");
            }
        }
        for c in &self.interval_constraints {
            let bad = |reason| Err(PtrError::IntervalConstraint { name: c.name.clone(), reason });
            if !(c.first < c.last && c.last < nn) {
                return bad("its segments first..last must satisfy first < last ≤ N − 1");
            }
            if c.function.n_inputs() != n + m {
                return bad("it must be compiled against the groups [states], [controls]");
            }
            if c.reads_controls(n) {
                return bad(
                    "it reads the controls; an interval constraint may read the states only",
                );
            }
            if c.activation.is_some_and(|a| a.is_nan() || a <= 0.0) {
                return bad("its activation distance must be positive (or None)");
            }
        }
        Ok(())
    }
}
