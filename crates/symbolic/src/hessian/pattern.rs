//! The structure of `∇²(wᵀf)`, computed once from the tape: the union, over instructions
//! with a structurally nonzero second derivative, of their operands' dependency columns
//! paired (lower triangle).

use crate::SparsityPattern;
use crate::expr::BinaryOp;
use crate::tape::{Instr, Reduce, Tape};

use super::sweep::unary_is_curved;

/// The lower-triangular structure of the weighted Hessian `H(x, w) = Σᵢ wᵢ ∇²fᵢ(x)` of a
/// compiled [`Function`](crate::Function), fixed at compile time.
///
/// `lower()` is an `n × n` pattern (n inputs) with `row ≥ col`; Hessian values are written
/// in its storage order. Every entry that can be nonzero for some input and weights is in
/// it. External functions that give no second derivatives
/// ([`ExternalFunction::has_hessian`](crate::ExternalFunction::has_hessian) false) are
/// listed by [`missing_second_derivatives`](Self::missing_second_derivatives): their own
/// curvature is left out (the chain rule through them is still exact to first order), so a
/// caller can add a Gauss–Newton term for them.
///
/// # Example
/// ```
/// use armature_symbolic::{Expr, Function};
/// let x = Expr::variable("x", 3);
/// // x₀·x₁ + sin x₂: curvature couples x₀ with x₁ and x₂ with itself.
/// let f = Function::compile(&[x.at(0) * x.at(1) + x.at(2).sin()], &[&[x]]).unwrap();
/// let p = f.hessian_pattern();
/// assert_eq!(p.lower().entries().collect::<Vec<_>>(), vec![(1, 0), (2, 2)]);
/// assert!(p.is_exact());
/// ```
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct HessianPattern {
    lower: SparsityPattern,
    missing: Vec<String>,
}

impl HessianPattern {
    /// The structural nonzeros with `row ≥ col`.
    pub fn lower(&self) -> &SparsityPattern {
        &self.lower
    }

    /// Number of stored (lower-triangle) nonzeros.
    pub fn nnz(&self) -> usize {
        self.lower.nnz()
    }

    /// Whether every node supplies its second derivatives (no external function without).
    pub fn is_exact(&self) -> bool {
        self.missing.is_empty()
    }

    /// Names of the external functions whose curvature is not included.
    pub fn missing_second_derivatives(&self) -> &[String] {
        &self.missing
    }

    /// The full symmetric dense matrix (row-major) from lower-triangle values.
    pub fn to_dense(&self, values: &[f64]) -> Vec<f64> {
        let n = self.lower.ncols();
        let mut d = vec![0.0; n * n];
        for ((r, c), &v) in self.lower.entries().zip(values) {
            d[r * n + c] = v;
            d[c * n + r] = v;
        }
        d
    }

    pub(crate) fn of(tape: &Tape) -> Self {
        let mut entries = Vec::new();
        let mut missing = Vec::new();
        collect(tape, &mut entries, &mut missing);
        Self {
            lower: SparsityPattern::from_entries(tape.n_inputs, tape.n_inputs, &entries),
            missing,
        }
    }
}

fn collect(tape: &Tape, entries: &mut Vec<(usize, usize)>, missing: &mut Vec<String>) {
    let mut pair = |a: u32, b: u32| {
        for &i in tape.deps(a) {
            for &j in tape.deps(b) {
                let (i, j) = (i as usize, j as usize);
                entries.push(if i >= j { (i, j) } else { (j, i) });
            }
        }
    };
    for ins in &tape.instrs {
        match *ins {
            Instr::Unary { op, x, .. } if unary_is_curved(op) => pair(x, x),
            Instr::SinCos { x, .. } => pair(x, x),
            Instr::Mul { x, y, .. } => pair(x, y),
            Instr::Binary { op: BinaryOp::Div, x, y, .. } => {
                pair(x, y);
                pair(y, y);
            }
            Instr::Reduce { op: Reduce::Norm2, a0, n, .. }
            | Instr::Lie { a0, n, .. }
            | Instr::Vmap { a0, n, .. } => {
                let args = &tape.args[a0 as usize..(a0 + n) as usize];
                for (j, &a) in args.iter().enumerate() {
                    for &b in &args[..=j] {
                        pair(a, b);
                    }
                }
            }
            Instr::External { func, a0, n, .. } => {
                let ext = &tape.externals[func as usize];
                if ext.has_hessian() {
                    let args = &tape.args[a0 as usize..(a0 + n) as usize];
                    for (j, &a) in args.iter().enumerate() {
                        for &b in &args[..=j] {
                            pair(a, b);
                        }
                    }
                } else if !missing.iter().any(|m| m == ext.name()) {
                    missing.push(ext.name().to_string());
                }
            }
            _ => {}
        }
    }
    for v in &tape.vmaps {
        let mut ignored = Vec::new();
        collect(&v.tape, &mut ignored, missing);
    }
}
