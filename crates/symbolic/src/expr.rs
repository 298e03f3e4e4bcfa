//! Expression handles and the operations that build them.

use core::fmt;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

use crate::{Shape, SymbolicError};

/// Elementwise functions of one argument.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum UnaryOp {
    /// `−x`
    Neg,
    /// `√x` (derivative taken as 0 at x = 0, where it is unbounded).
    Sqrt,
    /// `x²`
    Square,
    /// `|x|` (derivative 0 at x = 0).
    Abs,
    /// `sin x`
    Sin,
    /// `cos x`
    Cos,
    /// `tan x`
    Tan,
    /// `eˣ`
    Exp,
    /// `ln x`
    Log,
    /// `tanh x`
    Tanh,
    /// `max(x, 0)` (derivative 0 at x = 0).
    Pos,
    /// `max(x, 0)²`, the squared ReLU of CTCS penalties (smooth).
    SquaredPos,
}

impl UnaryOp {
    /// Value and derivative at `x`.
    #[inline]
    pub(crate) fn eval(self, x: f64) -> (f64, f64) {
        match self {
            UnaryOp::Neg => (-x, -1.0),
            UnaryOp::Sqrt => {
                let s = x.sqrt();
                (s, if s > 0.0 { 0.5 / s } else { 0.0 })
            }
            UnaryOp::Square => (x * x, 2.0 * x),
            UnaryOp::Abs => (
                x.abs(),
                if x > 0.0 {
                    1.0
                } else if x < 0.0 {
                    -1.0
                } else {
                    0.0
                },
            ),
            UnaryOp::Sin => {
                let (s, c) = x.sin_cos();
                (s, c)
            }
            UnaryOp::Cos => {
                let (s, c) = x.sin_cos();
                (c, -s)
            }
            UnaryOp::Tan => {
                let t = x.tan();
                (t, 1.0 + t * t)
            }
            UnaryOp::Exp => {
                let e = x.exp();
                (e, e)
            }
            UnaryOp::Log => (x.ln(), 1.0 / x),
            UnaryOp::Tanh => {
                let t = x.tanh();
                (t, 1.0 - t * t)
            }
            UnaryOp::Pos => {
                if x > 0.0 {
                    (x, 1.0)
                } else {
                    (0.0, 0.0)
                }
            }
            UnaryOp::SquaredPos => {
                if x > 0.0 {
                    (x * x, 2.0 * x)
                } else {
                    (0.0, 0.0)
                }
            }
        }
    }

    pub(crate) fn name(self) -> &'static str {
        match self {
            UnaryOp::Neg => "neg",
            UnaryOp::Sqrt => "sqrt",
            UnaryOp::Square => "square",
            UnaryOp::Abs => "abs",
            UnaryOp::Sin => "sin",
            UnaryOp::Cos => "cos",
            UnaryOp::Tan => "tan",
            UnaryOp::Exp => "exp",
            UnaryOp::Log => "log",
            UnaryOp::Tanh => "tanh",
            UnaryOp::Pos => "pos",
            UnaryOp::SquaredPos => "sqpos",
        }
    }
}

/// Elementwise functions of two arguments (with scalar broadcasting).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum BinaryOp {
    /// `x + y`
    Add,
    /// `x − y`
    Sub,
    /// `x · y`
    Mul,
    /// `x / y`
    Div,
    /// `max(x, y)` (at a tie the derivative follows `x`).
    Max,
    /// `min(x, y)` (at a tie the derivative follows `x`).
    Min,
}

impl BinaryOp {
    /// Value and the two partial derivatives.
    #[inline]
    pub(crate) fn eval(self, x: f64, y: f64) -> (f64, f64, f64) {
        match self {
            BinaryOp::Add => (x + y, 1.0, 1.0),
            BinaryOp::Sub => (x - y, 1.0, -1.0),
            BinaryOp::Mul => (x * y, y, x),
            BinaryOp::Div => {
                let inv = 1.0 / y;
                let v = x * inv;
                (v, inv, -v * inv)
            }
            BinaryOp::Max => {
                if x >= y {
                    (x, 1.0, 0.0)
                } else {
                    (y, 0.0, 1.0)
                }
            }
            BinaryOp::Min => {
                if x <= y {
                    (x, 1.0, 0.0)
                } else {
                    (y, 0.0, 1.0)
                }
            }
        }
    }

    pub(crate) fn symbol(self) -> &'static str {
        match self {
            BinaryOp::Add => "+",
            BinaryOp::Sub => "-",
            BinaryOp::Mul => "*",
            BinaryOp::Div => "/",
            BinaryOp::Max => "max",
            BinaryOp::Min => "min",
        }
    }
}

/// Vector norms.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Norm {
    /// Sum of absolute values.
    L1,
    /// Euclidean norm (gradient taken as 0 at the origin).
    L2,
    /// Largest absolute value.
    Inf,
}

/// Lie-group nodes backed by `armature-lie`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum LieOp {
    /// `so3_exp(ω: vector(3)) → matrix(3×3)`
    So3Exp,
    /// `so3_log(R: matrix(3×3)) → vector(3)`
    So3Log,
    /// `se3_exp(ξ = [v; ω]: vector(6)) → matrix(4×4)`
    Se3Exp,
    /// `se3_log(T: matrix(4×4)) → vector(6)`
    Se3Log,
}

impl LieOp {
    pub(crate) fn name(self) -> &'static str {
        match self {
            LieOp::So3Exp => "so3_exp",
            LieOp::So3Log => "so3_log",
            LieOp::Se3Exp => "se3_exp",
            LieOp::Se3Log => "se3_log",
        }
    }
}

/// A user-supplied differentiable function `ℝⁿ → ℝᵐ` used as one node of the graph: for
/// quantities that have a good closed-form or library implementation with exact derivatives
/// (e.g. exact capsule distances), where building them from elementary nodes would be slow or
/// inexact.
///
/// `eval` must write all `m` values and the full `m × n` Jacobian (row-major) without
/// allocating; the tape calls it once per evaluation. Its derivative must be exact: test it
/// against finite differences like any other node.
pub trait ExternalFunction: Send + Sync + core::fmt::Debug {
    /// Name used in displays and constraint names.
    fn name(&self) -> &str;
    /// Number of outputs `m` (1 gives a scalar expression).
    fn n_outputs(&self) -> usize;
    /// Values into `values` (length m) and the Jacobian into `jacobian` (m × n, row-major).
    fn eval(&self, inputs: &[f64], values: &mut [f64], jacobian: &mut [f64]);
    /// Whether [`hessian`](Self::hessian) supplies second derivatives. The default is
    /// `false`: the function's own curvature is then left out of
    /// [`Function::eval_hessian`](crate::Function::eval_hessian), and
    /// [`HessianPattern::missing_second_derivatives`](crate::HessianPattern::missing_second_derivatives)
    /// names it (a caller can add a Gauss–Newton term instead).
    fn has_hessian(&self) -> bool {
        false
    }
    /// Adds the weighted Hessian `Σₒ weights[o] ∇²fₒ(inputs)` (n × n, row-major,
    /// symmetric) into `hessian`, which is zero on entry. Called only when
    /// [`has_hessian`](Self::has_hessian) is true.
    fn hessian(&self, inputs: &[f64], weights: &[f64], hessian: &mut [f64]) {
        let _ = (inputs, weights, hessian);
    }
}

#[derive(Debug)]
pub(crate) enum Op {
    Variable(Arc<str>),
    Parameter(Arc<str>, Arc<[f64]>),
    Constant(Arc<[f64]>),
    /// The row placeholder of a `vmap` body (unique id).
    Placeholder(u64),
    Unary(UnaryOp),
    Binary(BinaryOp),
    MatMul,
    /// Entries of the single argument picked by flat (row-major) index.
    Gather(Arc<[usize]>),
    /// All entries of all arguments in order.
    Concat,
    Sum,
    Norm(Norm),
    Cross,
    QuatToMatrix,
    Lie(LieOp),
    /// `vmap`: the body (a scalar expression of the placeholder) over the rows of `batch`.
    Vmap {
        body: Expr,
        placeholder: u64,
        batch: Arc<[f64]>,
        cols: usize,
    },
    External(Arc<dyn ExternalFunction>),
    Invalid(SymbolicError),
}

#[derive(Debug)]
pub(crate) struct Node {
    pub(crate) op: Op,
    pub(crate) shape: Shape,
    pub(crate) args: Vec<Expr>,
}

/// A shaped symbolic expression: a cheap-to-clone handle to a node of the expression graph.
///
/// Operations never panic: one whose operands do not fit returns an expression that carries
/// the error (naming the operation and both shapes), and every expression built on it carries
/// the first error on. It surfaces as `Err` from [`shape`](Self::shape),
/// [`check`](Self::check) and at compile time.
///
/// # Example
/// ```
/// use armature_symbolic::{Expr, Shape};
///
/// let q = Expr::variable("q", 3);
/// let w = Expr::constant_vector(&[1.0, 2.0, 3.0]);
/// let e = (&q * &w).sum() + 1.0;
/// assert_eq!(e.shape(), Ok(Shape::Scalar));
///
/// let bad = &q + &Expr::variable("p", 2);
/// assert!(bad.shape().unwrap_err().to_string().contains("add: shapes vector(3) and vector(2)"));
/// ```
#[derive(Clone)]
pub struct Expr(pub(crate) Arc<Node>);

impl fmt::Debug for Expr {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "Expr({self})")
    }
}

static PLACEHOLDER_ID: AtomicU64 = AtomicU64::new(1);

fn node(op: Op, shape: Shape, args: Vec<Expr>) -> Expr {
    Expr(Arc::new(Node { op, shape, args }))
}

fn invalid(e: SymbolicError) -> Expr {
    node(Op::Invalid(e), Shape::Scalar, Vec::new())
}

/// The first error among the operands, if any.
fn first_error(args: &[&Expr]) -> Option<Expr> {
    args.iter().find(|a| matches!(a.0.op, Op::Invalid(_))).map(|a| (*a).clone())
}

fn check_data(what: &'static str, name: &str, data: &[f64], shape: Shape) -> Option<SymbolicError> {
    if data.len() != shape.numel() {
        return Some(SymbolicError::BadData {
            what,
            name: name.to_string(),
            reason: format!("{} values for shape {shape}", data.len()),
        });
    }
    if let Some(i) = data.iter().position(|x| !x.is_finite()) {
        return Some(SymbolicError::BadData {
            what,
            name: name.to_string(),
            reason: format!("entry {i} is {}", data[i]),
        });
    }
    None
}

/// Result shape of an elementwise binary operation with scalar broadcasting.
fn broadcast(op: &'static str, a: Shape, b: Shape) -> Result<Shape, SymbolicError> {
    match (a, b) {
        (Shape::Scalar, s) | (s, Shape::Scalar) => Ok(s),
        (x, y) if x == y => Ok(x),
        _ => Err(SymbolicError::ShapeMismatch { op, left: a, right: b }),
    }
}

impl Expr {
    // ----- leaves -------------------------------------------------------------------------

    /// A named vector variable of `n` entries (`n = 1` gives a scalar).
    pub fn variable(name: &str, n: usize) -> Expr {
        Self::variable_shaped(name, if n == 1 { Shape::Scalar } else { Shape::Vector(n) })
    }

    /// A named variable of any shape.
    pub fn variable_shaped(name: &str, shape: Shape) -> Expr {
        if shape.numel() == 0 {
            return invalid(SymbolicError::BadData {
                what: "variable",
                name: name.into(),
                reason: "has no entries".into(),
            });
        }
        node(Op::Variable(name.into()), shape, Vec::new())
    }

    /// A named parameter with its initial value (row-major); its value can change between
    /// evaluations of a compiled function without recompiling
    /// ([`Function::set_parameter`](crate::Function::set_parameter)).
    pub fn parameter(name: &str, shape: Shape, value: &[f64]) -> Expr {
        if let Some(e) = check_data("parameter", name, value, shape) {
            return invalid(e);
        }
        node(Op::Parameter(name.into(), value.into()), shape, Vec::new())
    }

    /// A constant of any shape (row-major data).
    pub fn constant(shape: Shape, data: &[f64]) -> Expr {
        if let Some(e) = check_data("constant", "value", data, shape) {
            return invalid(e);
        }
        node(Op::Constant(data.into()), shape, Vec::new())
    }

    /// A scalar constant.
    pub fn scalar(v: f64) -> Expr {
        Self::constant(Shape::Scalar, &[v])
    }

    /// A constant vector.
    pub fn constant_vector(v: &[f64]) -> Expr {
        Self::constant(Shape::Vector(v.len()), v)
    }

    /// A constant matrix from rows.
    pub fn constant_matrix<const C: usize>(rows: &[[f64; C]]) -> Expr {
        let data: Vec<f64> = rows.iter().flatten().copied().collect();
        Self::constant(Shape::Matrix(rows.len(), C), &data)
    }

    /// A constant from an nalgebra matrix (any fixed or dynamic size).
    pub fn from_matrix<R: nalgebra::Dim, C: nalgebra::Dim, S: nalgebra::RawStorage<f64, R, C>>(
        m: &nalgebra::Matrix<f64, R, C, S>,
    ) -> Expr {
        let (r, c) = m.shape();
        let data: Vec<f64> =
            (0..r).flat_map(|i| (0..c).map(move |j| (i, j))).map(|ij| m[ij]).collect();
        Self::constant(Shape::Matrix(r, c), &data)
    }

    /// The `n`×`n` identity matrix.
    pub fn identity(n: usize) -> Expr {
        let mut d = vec![0.0; n * n];
        for i in 0..n {
            d[i * n + i] = 1.0;
        }
        Self::constant(Shape::Matrix(n, n), &d)
    }

    // ----- inspection ---------------------------------------------------------------------

    /// The shape, or the first error in building this expression.
    pub fn shape(&self) -> Result<Shape, SymbolicError> {
        match &self.0.op {
            Op::Invalid(e) => Err(e.clone()),
            _ => Ok(self.0.shape),
        }
    }

    /// `Ok(self)` if the expression is valid, else its first error.
    pub fn check(&self) -> Result<&Expr, SymbolicError> {
        self.shape().map(|_| self)
    }

    /// The name of a variable or parameter leaf.
    pub fn leaf_name(&self) -> Option<&str> {
        match &self.0.op {
            Op::Variable(n) | Op::Parameter(n, _) => Some(n),
            _ => None,
        }
    }

    /// Whether this is a variable leaf.
    pub fn is_variable(&self) -> bool {
        matches!(self.0.op, Op::Variable(_))
    }

    /// The values of a constant leaf.
    pub fn constant_value(&self) -> Option<&[f64]> {
        match &self.0.op {
            Op::Constant(d) => Some(d),
            _ => None,
        }
    }

    /// Number of distinct nodes reachable from this expression (shared nodes counted once).
    pub fn node_count(&self) -> usize {
        let mut seen = std::collections::HashSet::new();
        let mut stack = vec![self];
        while let Some(e) = stack.pop() {
            if seen.insert(Arc::as_ptr(&e.0) as usize) {
                stack.extend(e.0.args.iter());
            }
        }
        seen.len()
    }

    pub(crate) fn ptr(&self) -> usize {
        Arc::as_ptr(&self.0) as usize
    }

    // ----- elementwise ----------------------------------------------------------------------

    /// Elementwise unary function.
    pub fn unary(&self, op: UnaryOp) -> Expr {
        if let Some(e) = first_error(&[self]) {
            return e;
        }
        node(Op::Unary(op), self.0.shape, vec![self.clone()])
    }

    /// Elementwise binary function with scalar broadcasting.
    pub fn binary(&self, op: BinaryOp, other: &Expr) -> Expr {
        if let Some(e) = first_error(&[self, other]) {
            return e;
        }
        let name = match op {
            BinaryOp::Add => "add",
            BinaryOp::Sub => "sub",
            BinaryOp::Mul => "mul",
            BinaryOp::Div => "div",
            BinaryOp::Max => "max",
            BinaryOp::Min => "min",
        };
        match broadcast(name, self.0.shape, other.0.shape) {
            Ok(s) => node(Op::Binary(op), s, vec![self.clone(), other.clone()]),
            Err(e) => invalid(e),
        }
    }

    /// `√x` elementwise.
    pub fn sqrt(&self) -> Expr {
        self.unary(UnaryOp::Sqrt)
    }
    /// `x²` elementwise.
    pub fn square(&self) -> Expr {
        self.unary(UnaryOp::Square)
    }
    /// `|x|` elementwise.
    pub fn abs(&self) -> Expr {
        self.unary(UnaryOp::Abs)
    }
    /// `sin x` elementwise.
    pub fn sin(&self) -> Expr {
        self.unary(UnaryOp::Sin)
    }
    /// `cos x` elementwise.
    pub fn cos(&self) -> Expr {
        self.unary(UnaryOp::Cos)
    }
    /// `tan x` elementwise.
    pub fn tan(&self) -> Expr {
        self.unary(UnaryOp::Tan)
    }
    /// `eˣ` elementwise.
    pub fn exp(&self) -> Expr {
        self.unary(UnaryOp::Exp)
    }
    /// `ln x` elementwise.
    pub fn log(&self) -> Expr {
        self.unary(UnaryOp::Log)
    }
    /// `tanh x` elementwise.
    pub fn tanh(&self) -> Expr {
        self.unary(UnaryOp::Tanh)
    }
    /// ReLU `max(x, 0)` elementwise.
    pub fn pos(&self) -> Expr {
        self.unary(UnaryOp::Pos)
    }
    /// Squared ReLU `max(x, 0)²` elementwise.
    pub fn squared_pos(&self) -> Expr {
        self.unary(UnaryOp::SquaredPos)
    }
    /// `max(x, y)` elementwise (`y` may be a scalar).
    pub fn max(&self, y: impl Into<Expr>) -> Expr {
        self.binary(BinaryOp::Max, &y.into())
    }
    /// `min(x, y)` elementwise (`y` may be a scalar).
    pub fn min(&self, y: impl Into<Expr>) -> Expr {
        self.binary(BinaryOp::Min, &y.into())
    }

    // ----- linear algebra -------------------------------------------------------------------

    /// Matrix product with numpy's rules for vectors: `M@M`, `M@v → v`, `v@M → v`,
    /// `v@v → scalar` (dot).
    pub fn matmul(&self, other: &Expr) -> Expr {
        if let Some(e) = first_error(&[self, other]) {
            return e;
        }
        let (a, b) = (self.0.shape, other.0.shape);
        let out = match (a, b) {
            (Shape::Matrix(_, k), Shape::Matrix(k2, c)) if k == k2 => {
                Some(Shape::of_block(a.rows(), c))
            }
            (Shape::Matrix(r, k), Shape::Vector(k2)) if k == k2 => Some(Shape::of_block(r, 1)),
            (Shape::Vector(k), Shape::Matrix(k2, c)) if k == k2 => {
                Some(if c == 1 { Shape::Scalar } else { Shape::Vector(c) })
            }
            (Shape::Vector(k), Shape::Vector(k2)) if k == k2 => Some(Shape::Scalar),
            _ => None,
        };
        match out {
            Some(s) => node(Op::MatMul, s, vec![self.clone(), other.clone()]),
            None => invalid(SymbolicError::ShapeMismatch { op: "matmul", left: a, right: b }),
        }
    }

    /// Transpose of a matrix; vectors and scalars are returned unchanged (numpy semantics).
    pub fn transpose(&self) -> Expr {
        if let Some(e) = first_error(&[self]) {
            return e;
        }
        match self.0.shape {
            Shape::Matrix(r, c) => {
                let idx: Vec<usize> = (0..c).flat_map(|j| (0..r).map(move |i| i * c + j)).collect();
                self.gather(idx, Shape::Matrix(c, r))
            }
            _ => self.clone(),
        }
    }

    /// Dot product of two vectors of equal length.
    pub fn dot(&self, other: &Expr) -> Expr {
        if let Some(e) = first_error(&[self, other]) {
            return e;
        }
        match (self.0.shape, other.0.shape) {
            (Shape::Vector(a), Shape::Vector(b)) if a == b => (self * other).sum(),
            (l, r) => invalid(SymbolicError::ShapeMismatch { op: "dot", left: l, right: r }),
        }
    }

    /// Cross product of two 3-vectors.
    pub fn cross(&self, other: &Expr) -> Expr {
        if let Some(e) = first_error(&[self, other]) {
            return e;
        }
        match (self.0.shape, other.0.shape) {
            (Shape::Vector(3), Shape::Vector(3)) => {
                node(Op::Cross, Shape::Vector(3), vec![self.clone(), other.clone()])
            }
            (l, r) => invalid(SymbolicError::ShapeMismatch { op: "cross", left: l, right: r }),
        }
    }

    /// Sum of all entries.
    pub fn sum(&self) -> Expr {
        if let Some(e) = first_error(&[self]) {
            return e;
        }
        node(Op::Sum, Shape::Scalar, vec![self.clone()])
    }

    /// A vector (or scalar) norm.
    pub fn norm(&self, kind: Norm) -> Expr {
        if let Some(e) = first_error(&[self]) {
            return e;
        }
        match self.0.shape {
            Shape::Scalar | Shape::Vector(_) => {
                node(Op::Norm(kind), Shape::Scalar, vec![self.clone()])
            }
            s => invalid(SymbolicError::BadShape { op: "norm", shape: s, expected: "a vector" }),
        }
    }

    /// Euclidean norm.
    pub fn norm2(&self) -> Expr {
        self.norm(Norm::L2)
    }

    /// Rotation matrix of a quaternion `[w, x, y, z]` (normalised inside, like OpenSCvx's QDCM).
    pub fn quat_to_matrix(&self) -> Expr {
        if let Some(e) = first_error(&[self]) {
            return e;
        }
        match self.0.shape {
            Shape::Vector(4) => node(Op::QuatToMatrix, Shape::Matrix(3, 3), vec![self.clone()]),
            s => invalid(SymbolicError::BadShape {
                op: "quat_to_matrix",
                shape: s,
                expected: "vector(4)",
            }),
        }
    }

    // ----- indexing and assembly ------------------------------------------------------------

    pub(crate) fn gather(&self, idx: Vec<usize>, shape: Shape) -> Expr {
        node(Op::Gather(idx.into()), shape, vec![self.clone()])
    }

    /// Entry `i` of a vector (or `0` of a scalar), as a scalar.
    pub fn at(&self, i: usize) -> Expr {
        if let Some(e) = first_error(&[self]) {
            return e;
        }
        match self.0.shape {
            Shape::Scalar | Shape::Vector(_) if i < self.0.shape.numel() => {
                self.gather(vec![i], Shape::Scalar)
            }
            s => invalid(SymbolicError::OutOfBounds {
                op: "index",
                index: format!("[{i}]"),
                shape: s,
            }),
        }
    }

    /// Entries `start..end` of a vector.
    pub fn slice(&self, start: usize, end: usize) -> Expr {
        if let Some(e) = first_error(&[self]) {
            return e;
        }
        match self.0.shape {
            Shape::Vector(n) if start < end && end <= n => {
                self.gather((start..end).collect(), Shape::of_block(end - start, 1))
            }
            s => invalid(SymbolicError::OutOfBounds {
                op: "slice",
                index: format!("[{start}:{end}]"),
                shape: s,
            }),
        }
    }

    /// Entry `(r, c)` of a matrix, as a scalar.
    pub fn get(&self, r: usize, c: usize) -> Expr {
        self.block(r, r + 1, c, c + 1)
    }

    /// The block `rows r0..r1`, `cols c0..c1` of a matrix: a scalar for 1×1, a vector for a
    /// single column or row, else a matrix (numpy's `T[0:3, 3]` is a vector).
    pub fn block(&self, r0: usize, r1: usize, c0: usize, c1: usize) -> Expr {
        if let Some(e) = first_error(&[self]) {
            return e;
        }
        let s = self.0.shape;
        let (rows, cols) = (s.rows(), s.cols());
        if !matches!(s, Shape::Matrix(..)) || r0 >= r1 || c0 >= c1 || r1 > rows || c1 > cols {
            return invalid(SymbolicError::OutOfBounds {
                op: "block",
                index: format!("[{r0}:{r1}, {c0}:{c1}]"),
                shape: s,
            });
        }
        let idx: Vec<usize> = (r0..r1).flat_map(|i| (c0..c1).map(move |j| i * cols + j)).collect();
        let shape = match (r1 - r0, c1 - c0) {
            (1, 1) => Shape::Scalar,
            (1, n) | (n, 1) => Shape::Vector(n),
            (r, c) => Shape::Matrix(r, c),
        };
        self.gather(idx, shape)
    }

    /// Concatenation of scalars and vectors into one vector.
    pub fn concat(parts: &[Expr]) -> Expr {
        if parts.is_empty() {
            return invalid(SymbolicError::Empty { op: "concat" });
        }
        let refs: Vec<&Expr> = parts.iter().collect();
        if let Some(e) = first_error(&refs) {
            return e;
        }
        if let Some(p) = parts.iter().find(|p| matches!(p.0.shape, Shape::Matrix(..))) {
            return invalid(SymbolicError::BadShape {
                op: "concat",
                shape: p.0.shape,
                expected: "a scalar or vector",
            });
        }
        let n = parts.iter().map(|p| p.0.shape.numel()).sum();
        node(Op::Concat, Shape::of_block(n, 1), parts.to_vec())
    }

    /// Stacks equal-length vectors (or scalars) as the rows of a matrix.
    pub fn stack(rows: &[Expr]) -> Expr {
        if rows.is_empty() {
            return invalid(SymbolicError::Empty { op: "stack" });
        }
        let refs: Vec<&Expr> = rows.iter().collect();
        if let Some(e) = first_error(&refs) {
            return e;
        }
        let first = rows[0].0.shape;
        for r in rows {
            if r.0.shape != first || matches!(first, Shape::Matrix(..)) {
                return invalid(SymbolicError::ShapeMismatch {
                    op: "stack",
                    left: first,
                    right: r.0.shape,
                });
            }
        }
        node(Op::Concat, Shape::Matrix(rows.len(), first.numel()), rows.to_vec())
    }

    /// Reinterprets the entries with another shape of the same size (row-major).
    pub fn reshape(&self, shape: Shape) -> Expr {
        if let Some(e) = first_error(&[self]) {
            return e;
        }
        if shape.numel() != self.0.shape.numel() {
            return invalid(SymbolicError::ShapeMismatch {
                op: "reshape",
                left: self.0.shape,
                right: shape,
            });
        }
        self.gather((0..shape.numel()).collect(), shape)
    }

    // ----- Lie groups -------------------------------------------------------------------------

    fn lie(&self, op: LieOp, input: Shape, output: Shape, expected: &'static str) -> Expr {
        if let Some(e) = first_error(&[self]) {
            return e;
        }
        if self.0.shape != input {
            return invalid(SymbolicError::BadShape {
                op: op.name(),
                shape: self.0.shape,
                expected,
            });
        }
        node(Op::Lie(op), output, vec![self.clone()])
    }

    /// `exp` of SO(3): rotation vector `vector(3)` → rotation matrix `matrix(3×3)`.
    pub fn so3_exp(&self) -> Expr {
        self.lie(LieOp::So3Exp, Shape::Vector(3), Shape::Matrix(3, 3), "vector(3)")
    }

    /// `log` of SO(3): rotation matrix → rotation vector with `|ω| ≤ π`. Its derivative is
    /// the one along SO(3) (exact whenever the argument is a rotation, as in FK chains).
    pub fn so3_log(&self) -> Expr {
        self.lie(LieOp::So3Log, Shape::Matrix(3, 3), Shape::Vector(3), "matrix(3×3)")
    }

    /// `exp` of SE(3): twist `[v; ω]` → homogeneous `matrix(4×4)`. The product-of-exponentials
    /// case `se3_exp(constant_screw * angle)` compiles to a handful of scalar operations.
    pub fn se3_exp(&self) -> Expr {
        self.lie(LieOp::Se3Exp, Shape::Vector(6), Shape::Matrix(4, 4), "vector(6)")
    }

    /// `log` of SE(3): homogeneous matrix → twist `[v; ω]`.
    pub fn se3_log(&self) -> Expr {
        self.lie(LieOp::Se3Log, Shape::Matrix(4, 4), Shape::Vector(6), "matrix(4×4)")
    }

    // ----- vmap -------------------------------------------------------------------------------

    /// Maps a scalar-valued `body` over the rows of a constant `batch` (row-major,
    /// `rows × cols`), giving `vector(rows)`. The body receives the row as a placeholder of
    /// shape `vector(cols)` (scalar for one column) and may use any outer expression; it is
    /// compiled once, as one batched node, not copied per row.
    ///
    /// ```
    /// use armature_symbolic::Expr;
    /// let p = Expr::variable("p", 3);
    /// // Distance from p to three points.
    /// let pts = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 2.0, 0.0];
    /// let d = Expr::vmap(&pts, 3, |row| (&p - row).norm2());
    /// assert_eq!(d.shape().unwrap(), armature_symbolic::Shape::Vector(3));
    /// ```
    pub fn vmap(batch: &[f64], cols: usize, body: impl FnOnce(&Expr) -> Expr) -> Expr {
        if cols == 0 || batch.is_empty() || !batch.len().is_multiple_of(cols) {
            return invalid(SymbolicError::BadData {
                what: "constant",
                name: "vmap batch".into(),
                reason: format!("{} values do not form rows of {cols}", batch.len()),
            });
        }
        if let Some(i) = batch.iter().position(|x| !x.is_finite()) {
            return invalid(SymbolicError::BadData {
                what: "constant",
                name: "vmap batch".into(),
                reason: format!("entry {i} is {}", batch[i]),
            });
        }
        let id = PLACEHOLDER_ID.fetch_add(1, Ordering::Relaxed);
        let shape = if cols == 1 { Shape::Scalar } else { Shape::Vector(cols) };
        let ph = node(Op::Placeholder(id), shape, Vec::new());
        let body = body(&ph);
        if let Some(e) = first_error(&[&body]) {
            return e;
        }
        if body.0.shape != Shape::Scalar {
            return invalid(SymbolicError::BadShape {
                op: "vmap",
                shape: body.0.shape,
                expected: "a scalar body",
            });
        }
        let rows = batch.len() / cols;
        node(
            Op::Vmap { body, placeholder: id, batch: batch.into(), cols },
            Shape::of_block(rows, 1),
            Vec::new(),
        )
    }
}

impl Expr {
    /// An [`ExternalFunction`] applied to the entries of `inputs` (concatenated in order):
    /// a scalar for one output, else `vector(m)`.
    pub fn external(f: Arc<dyn ExternalFunction>, inputs: &[Expr]) -> Expr {
        if inputs.is_empty() {
            return invalid(SymbolicError::Empty { op: "external" });
        }
        let refs: Vec<&Expr> = inputs.iter().collect();
        if let Some(e) = first_error(&refs) {
            return e;
        }
        let m = f.n_outputs();
        if m == 0 {
            return invalid(SymbolicError::Empty { op: "external (no outputs)" });
        }
        node(Op::External(f), Shape::of_block(m, 1), inputs.to_vec())
    }
}

impl From<f64> for Expr {
    fn from(v: f64) -> Expr {
        Expr::scalar(v)
    }
}

impl From<&Expr> for Expr {
    fn from(e: &Expr) -> Expr {
        e.clone()
    }
}

macro_rules! binop {
    ($trait:ident, $method:ident, $op:expr) => {
        impl core::ops::$trait<&Expr> for &Expr {
            type Output = Expr;
            fn $method(self, rhs: &Expr) -> Expr {
                self.binary($op, rhs)
            }
        }
        impl core::ops::$trait<Expr> for Expr {
            type Output = Expr;
            fn $method(self, rhs: Expr) -> Expr {
                self.binary($op, &rhs)
            }
        }
        impl core::ops::$trait<&Expr> for Expr {
            type Output = Expr;
            fn $method(self, rhs: &Expr) -> Expr {
                self.binary($op, rhs)
            }
        }
        impl core::ops::$trait<Expr> for &Expr {
            type Output = Expr;
            fn $method(self, rhs: Expr) -> Expr {
                self.binary($op, &rhs)
            }
        }
        impl core::ops::$trait<f64> for Expr {
            type Output = Expr;
            fn $method(self, rhs: f64) -> Expr {
                self.binary($op, &Expr::scalar(rhs))
            }
        }
        impl core::ops::$trait<f64> for &Expr {
            type Output = Expr;
            fn $method(self, rhs: f64) -> Expr {
                self.binary($op, &Expr::scalar(rhs))
            }
        }
        impl core::ops::$trait<Expr> for f64 {
            type Output = Expr;
            fn $method(self, rhs: Expr) -> Expr {
                Expr::scalar(self).binary($op, &rhs)
            }
        }
        impl core::ops::$trait<&Expr> for f64 {
            type Output = Expr;
            fn $method(self, rhs: &Expr) -> Expr {
                Expr::scalar(self).binary($op, rhs)
            }
        }
    };
}

binop!(Add, add, BinaryOp::Add);
binop!(Sub, sub, BinaryOp::Sub);
binop!(Mul, mul, BinaryOp::Mul);
binop!(Div, div, BinaryOp::Div);

impl core::ops::Neg for Expr {
    type Output = Expr;
    fn neg(self) -> Expr {
        self.unary(UnaryOp::Neg)
    }
}

impl core::ops::Neg for &Expr {
    type Output = Expr;
    fn neg(self) -> Expr {
        self.unary(UnaryOp::Neg)
    }
}

// ----- display ----------------------------------------------------------------------------

impl fmt::Display for Expr {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let n = &self.0;
        let a = &n.args;
        match &n.op {
            Op::Variable(name) | Op::Parameter(name, _) => write!(f, "{name}"),
            Op::Constant(d) => {
                if d.len() == 1 {
                    write!(f, "{}", d[0])
                } else {
                    write!(f, "const{}", n.shape)
                }
            }
            Op::Placeholder(_) => write!(f, "row"),
            Op::Unary(UnaryOp::Neg) => write!(f, "-({})", a[0]),
            Op::Unary(u) => write!(f, "{}({})", u.name(), a[0]),
            Op::Binary(b @ (BinaryOp::Max | BinaryOp::Min)) => {
                write!(f, "{}({}, {})", b.symbol(), a[0], a[1])
            }
            Op::Binary(b) => write!(f, "({} {} {})", a[0], b.symbol(), a[1]),
            Op::MatMul => write!(f, "({} @ {})", a[0], a[1]),
            Op::Gather(idx) => {
                if idx.len() == 1 {
                    write!(f, "{}[{}]", a[0], idx[0])
                } else {
                    write!(f, "{}[..{}]", a[0], idx.len())
                }
            }
            Op::Concat => {
                write!(f, "concat(")?;
                for (i, x) in a.iter().enumerate() {
                    if i > 0 {
                        write!(f, ", ")?;
                    }
                    write!(f, "{x}")?;
                }
                write!(f, ")")
            }
            Op::Sum => write!(f, "sum({})", a[0]),
            Op::Norm(Norm::L1) => write!(f, "norm({}, 1)", a[0]),
            Op::Norm(Norm::L2) => write!(f, "norm({})", a[0]),
            Op::Norm(Norm::Inf) => write!(f, "norm({}, inf)", a[0]),
            Op::Cross => write!(f, "cross({}, {})", a[0], a[1]),
            Op::QuatToMatrix => write!(f, "quat_to_matrix({})", a[0]),
            Op::Lie(l) => write!(f, "{}({})", l.name(), a[0]),
            Op::Vmap { body, .. } => write!(f, "vmap({body})"),
            Op::External(x) => {
                write!(f, "{}(", x.name())?;
                for (i, y) in a.iter().enumerate() {
                    if i > 0 {
                        write!(f, ", ")?;
                    }
                    write!(f, "{y}")?;
                }
                write!(f, ")")
            }
            Op::Invalid(e) => write!(f, "<error: {e}>"),
        }
    }
}
