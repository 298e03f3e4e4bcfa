//! Constraints built from comparisons, with the continuous-time and nodal modifiers of the
//! OpenSCvx modeling layer.

use core::fmt::{self, Write};

use crate::{Expr, SymbolicError};

/// Where along the trajectory a constraint holds.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Timing {
    /// At discretization nodes.
    Nodal(Nodes),
    /// Continuously in time (CTCS): the integral of the squared violation over the segments
    /// between nodes `a` and `b` (`None`: the whole trajectory) is driven to zero.
    Continuous(Option<(usize, usize)>),
}

/// A set of nodes.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Nodes {
    /// Every node.
    All,
    /// The listed nodes.
    List(Vec<usize>),
    /// Nodes `a..=b`.
    Range(usize, usize),
}

impl Nodes {
    /// The nodes of this set for a trajectory of `n` nodes (out-of-range entries dropped).
    pub fn resolve(&self, n: usize) -> Vec<usize> {
        match self {
            Nodes::All => (0..n).collect(),
            Nodes::List(v) => v.iter().copied().filter(|&k| k < n).collect(),
            Nodes::Range(a, b) => (*a..=(*b).min(n.saturating_sub(1))).collect(),
        }
    }
}

/// A constraint `g(x, u) ≤ 0` (or `= 0`), with its timing, a name for diagnostics and a
/// convexity flag.
///
/// Comparisons canonicalise to `g = lhs − rhs ≤ 0` (`le`), `g = rhs − lhs ≤ 0` (`ge`) and
/// `g = lhs − rhs = 0` (`eq`). By default a constraint is nodal at every node; the
/// modifiers follow the seed tutorial:
///
/// | seed (OpenSCvx) | armature |
/// |---|---|
/// | `ox.ctcs(g <= 0)` | `g.le(0.0).ctcs()` |
/// | `(g <= 0).over((a, b))` | `g.le(0.0).ctcs().over(a, b)` |
/// | `(g <= 0).at([k])` | `g.le(0.0).at(&[k])` |
/// | — (nodal on a range) | `g.le(0.0).over(a, b)` |
///
/// ```
/// use armature_symbolic::{Expr, Timing};
/// let p = Expr::variable("p", 3);
/// let wp = Expr::constant_vector(&[0.35, -0.25, 0.05]);
/// let c = (&p - &wp).norm2().le(0.01).at(&[4]).named("grasp");
/// assert_eq!(c.name(), "grasp");
/// let z = p.at(2).ge(0.0).ctcs();
/// assert_eq!(z.name(), "p[2] >= 0");
/// assert_eq!(z.timing(), &Timing::Continuous(None));
/// ```
#[derive(Debug, Clone)]
pub struct Constraint {
    g: Expr,
    equality: bool,
    timing: Timing,
    name: String,
    convex: bool,
}

/// Longest derived name; longer renderings are cut with "…".
const NAME_LIMIT: usize = 72;

struct Bounded {
    s: String,
    limit: usize,
}

impl Write for Bounded {
    fn write_str(&mut self, t: &str) -> fmt::Result {
        for ch in t.chars() {
            if self.s.chars().count() >= self.limit {
                return Err(fmt::Error);
            }
            self.s.push(ch);
        }
        Ok(())
    }
}

/// The expression rendered to at most `limit` characters.
pub(crate) fn describe(e: &Expr, limit: usize) -> String {
    let mut b = Bounded { s: String::new(), limit };
    if write!(b, "{e}").is_err() {
        b.s.push('…');
    }
    b.s
}

impl Constraint {
    fn new(lhs: &Expr, rhs: &Expr, op: &str, g: Expr, equality: bool) -> Constraint {
        let name =
            format!("{} {op} {}", describe(lhs, NAME_LIMIT / 2), describe(rhs, NAME_LIMIT / 2));
        Constraint { g, equality, timing: Timing::Nodal(Nodes::All), name, convex: false }
    }

    /// The constraint function `g` (`g ≤ 0`, or `g = 0` for an equality).
    pub fn function(&self) -> &Expr {
        &self.g
    }

    /// Whether this is an equality `g = 0`.
    pub fn is_equality(&self) -> bool {
        self.equality
    }

    /// Where it holds.
    pub fn timing(&self) -> &Timing {
        &self.timing
    }

    /// Whether the user declared it convex (it then enters subproblems exactly).
    pub fn is_convex(&self) -> bool {
        self.convex
    }

    /// Its name: the one given with [`named`](Self::named), else derived from the comparison.
    pub fn name(&self) -> &str {
        &self.name
    }

    /// Sets the name.
    pub fn named(mut self, name: impl Into<String>) -> Self {
        self.name = name.into();
        self
    }

    /// Declares the constraint convex (affine equalities, convex `g ≤ 0`).
    pub fn convex(mut self) -> Self {
        self.convex = true;
        self
    }

    /// Makes it continuous-time over the whole trajectory (CTCS).
    pub fn ctcs(mut self) -> Self {
        self.timing = Timing::Continuous(None);
        self
    }

    /// Restricts it to nodes `a..=b`: continuous over the segments from node `a` to node `b`
    /// if it is continuous, nodal at those nodes otherwise.
    pub fn over(mut self, a: usize, b: usize) -> Self {
        self.timing = match self.timing {
            Timing::Continuous(_) => Timing::Continuous(Some((a, b))),
            Timing::Nodal(_) => Timing::Nodal(Nodes::Range(a, b)),
        };
        self
    }

    /// Makes it nodal at the listed nodes.
    pub fn at(mut self, nodes: &[usize]) -> Self {
        self.timing = Timing::Nodal(Nodes::List(nodes.to_vec()));
        self
    }

    /// Checks the constraint against a trajectory of `n_nodes` nodes.
    ///
    /// # Errors
    /// [`SymbolicError::BadConstraint`] for an invalid expression, a continuous-time equality,
    /// an empty or out-of-range node set or interval.
    pub fn validate(&self, n_nodes: usize) -> Result<(), SymbolicError> {
        let bad = |reason: String| SymbolicError::BadConstraint { name: self.name.clone(), reason };
        self.g.check().map_err(|e| bad(e.to_string()))?;
        match &self.timing {
            Timing::Continuous(_) if self.equality => {
                return Err(
                    bad("a continuous-time (ctcs) constraint must be an inequality".into()),
                );
            }
            Timing::Continuous(Some((a, b))) | Timing::Nodal(Nodes::Range(a, b))
                if a >= b || *b >= n_nodes =>
            {
                return Err(bad(format!(
                    "node range {a}..={b} is empty or beyond the last node {}",
                    n_nodes - 1
                )));
            }
            Timing::Nodal(Nodes::List(v)) => {
                if v.is_empty() {
                    return Err(bad("empty node list".into()));
                }
                if let Some(k) = v.iter().find(|&&k| k >= n_nodes) {
                    return Err(bad(format!("node {k} is beyond the last node {}", n_nodes - 1)));
                }
            }
            _ => {}
        }
        Ok(())
    }
}

impl fmt::Display for Constraint {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.name)?;
        match &self.timing {
            Timing::Continuous(None) => write!(f, " (ctcs)"),
            Timing::Continuous(Some((a, b))) => write!(f, " (ctcs over nodes {a}..={b})"),
            Timing::Nodal(Nodes::All) => write!(f, " (all nodes)"),
            Timing::Nodal(Nodes::List(v)) => write!(f, " (nodes {v:?})"),
            Timing::Nodal(Nodes::Range(a, b)) => write!(f, " (nodes {a}..={b})"),
        }
    }
}

impl Expr {
    /// `self ≤ rhs`, as `self − rhs ≤ 0`.
    pub fn le(&self, rhs: impl Into<Expr>) -> Constraint {
        let rhs = rhs.into();
        Constraint::new(self, &rhs, "<=", self - &rhs, false)
    }

    /// `self ≥ rhs`, as `rhs − self ≤ 0`.
    pub fn ge(&self, rhs: impl Into<Expr>) -> Constraint {
        let rhs = rhs.into();
        Constraint::new(self, &rhs, ">=", &rhs - self, false)
    }

    /// `self = rhs`, as `self − rhs = 0`.
    pub fn eq(&self, rhs: impl Into<Expr>) -> Constraint {
        let rhs = rhs.into();
        Constraint::new(self, &rhs, "==", self - &rhs, true)
    }
}
