#![doc = include_str!("../README.md")]
#![warn(missing_docs)]

mod constraint;
mod error;
mod expr;
mod function;
mod hessian;
mod lower;
mod parser;
mod pattern;
mod shape;
mod tape;

pub use constraint::{Constraint, Nodes, Timing};
pub use error::SymbolicError;
pub use expr::{BinaryOp, Expr, ExternalFunction, LieOp, Norm, UnaryOp};
pub use function::{DENSE_MAX_INPUTS, DerivativeMode, Function, InputSlot};
pub use hessian::{HessianPattern, HessianWorkspace};
pub use parser::{
    MAX_IDENTITY, MAX_NESTING, MAX_TOKENS, SymbolTable, parse_constraint, parse_expr,
};
pub use pattern::SparsityPattern;
pub use shape::Shape;
pub use tape::Workspace;
