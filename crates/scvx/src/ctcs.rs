//! Continuous-time constraint satisfaction (CTCS): integral states of squared-ReLU penalties.
//!
//! A group of constraints `g(x, u) ≤ 0` over the node interval `[a, b]` becomes one state
//! `y` with `ẏ = Σ sqpos(g(x, u))` active on segments `a..b` (gated by the segment index),
//! `y(0) = 0`, and the nodal conditions `y_{k+1} − y_k ≤ ε` on those segments: the integral of
//! the squared violation over each segment is at most ε, so violations between nodes are
//! penalised, not only at the nodes. (Time dilation makes `y` the integral in physical time.)

use armature_symbolic::Expr;

/// The penalty `p(g)` integrated by a CTCS state.
#[derive(Debug, Clone, Copy, PartialEq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Penalty {
    /// `max(0, g)²` (OpenSCvx's default): smooth, but its gradient vanishes with the
    /// violation, so a small ε makes the linearization degenerate.
    #[default]
    SquaredRelu,
    /// `max(0, g)`: the integral bounds the violation linearly (`v·δ/2 ≤ ε` for a violation `v`
    /// lasting `δ`), and its gradient does not vanish as the violation shrinks.
    Relu,
}

/// Constraints `g ≤ 0` (each any shape) enforced continuously over nodes `first..=last`.
#[derive(Debug, Clone)]
pub struct CtcsGroup {
    /// Constraint functions, each meaning `g ≤ 0` entrywise.
    pub constraints: Vec<Expr>,
    /// First node of the interval.
    pub first: usize,
    /// Last node of the interval.
    pub last: usize,
    /// The penalty integrated.
    pub penalty: Penalty,
}

/// The augmented states of `groups`: `(y variable, its right-hand side)` per group, named
/// `_ctcs_0`, `_ctcs_1`, … Append them to the states and dynamics, gate each row to segments
/// `first..last`, fix `y₀ = 0`, bound `y ≥ 0`, and add the increments `y_{k+1} − y_k ≤ ε`.
pub fn ctcs_states(groups: &[CtcsGroup]) -> Vec<(Expr, Expr)> {
    groups
        .iter()
        .enumerate()
        .map(|(i, g)| {
            let y = Expr::variable(&format!("_ctcs_{i}"), 1);
            let mut rhs = Expr::scalar(0.0);
            for c in &g.constraints {
                let p = match g.penalty {
                    Penalty::SquaredRelu => c.squared_pos(),
                    Penalty::Relu => c.pos(),
                };
                rhs = rhs + p.sum();
            }
            (y, rhs)
        })
        .collect()
}
