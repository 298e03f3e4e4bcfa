//! Errors of the symbolic crate.

use crate::Shape;

/// Everything that can go wrong when building, compiling or evaluating expressions.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SymbolicError {
    /// Two operands whose shapes do not fit the operation.
    #[error("{op}: shapes {left} and {right} do not fit")]
    ShapeMismatch {
        /// The operation (e.g. `add`, `matmul`).
        op: &'static str,
        /// Shape of the left operand.
        left: Shape,
        /// Shape of the right operand.
        right: Shape,
    },
    /// An operand whose shape the operation does not accept.
    #[error("{op}: operand of shape {shape} is not {expected}")]
    BadShape {
        /// The operation.
        op: &'static str,
        /// The operand's shape.
        shape: Shape,
        /// What the operation needs.
        expected: &'static str,
    },
    /// An index or range outside the operand.
    #[error("{op}: index {index} is out of bounds for shape {shape}")]
    OutOfBounds {
        /// The operation.
        op: &'static str,
        /// The offending index or range, as written.
        index: String,
        /// The operand's shape.
        shape: Shape,
    },
    /// A constant or parameter whose data does not match its declared shape, or is not finite.
    #[error("{what} '{name}': {reason}")]
    BadData {
        /// `constant` or `parameter`.
        what: &'static str,
        /// Its name (or a description for constants).
        name: String,
        /// What is wrong.
        reason: String,
    },
    /// An operation that needs at least one operand got none.
    #[error("{op}: needs at least one operand")]
    Empty {
        /// The operation.
        op: &'static str,
    },
    /// An expression uses a variable that is in none of the input groups.
    #[error("variable '{name}' is not in any input group of this function")]
    UnknownVariable {
        /// The variable's name.
        name: String,
    },
    /// The same name is used for two different leaves (variables or parameters).
    #[error("name '{name}' is used twice: {detail}")]
    DuplicateName {
        /// The name.
        name: String,
        /// How the two uses differ.
        detail: String,
    },
    /// An input group entry that is not a variable.
    #[error("input group {group}: entry {index} is not a variable")]
    NotAVariable {
        /// Index of the group.
        group: usize,
        /// Index of the entry in the group.
        index: usize,
    },
    /// `set_parameter` with a name the function does not use.
    #[error("parameter '{name}' is not used by this function")]
    UnknownParameter {
        /// The name.
        name: String,
    },
    /// A caller-provided buffer of the wrong length.
    #[error("{what}: expected length {expected}, got {got}")]
    BufferLength {
        /// Which buffer.
        what: &'static str,
        /// Length the function needs.
        expected: usize,
        /// Length given.
        got: usize,
    },
    /// A workspace created by another function (it holds that function's constants).
    #[error("workspace belongs to another function: create one with Function::workspace()")]
    ForeignWorkspace,
    /// A constraint that cannot be used as stated.
    #[error("constraint '{name}': {reason}")]
    BadConstraint {
        /// The constraint's name.
        name: String,
        /// What is wrong.
        reason: String,
    },
    /// An expression string that does not parse or does not type-check.
    #[error("{message} at column {column}\n  {source_text}\n  {caret}")]
    Parse {
        /// What is wrong.
        message: String,
        /// 1-based column of the offending character.
        column: usize,
        /// The expression text.
        source_text: String,
        /// A caret line pointing at the column.
        caret: String,
    },
}

impl SymbolicError {
    /// Builds a [`SymbolicError::Parse`] with its caret line; `offset` is a byte offset.
    pub(crate) fn parse(message: impl Into<String>, text: &str, offset: usize) -> Self {
        let column = text[..offset.min(text.len())].chars().count() + 1;
        SymbolicError::Parse {
            message: message.into(),
            column,
            source_text: text.to_string(),
            caret: format!("{}^", " ".repeat(column - 1)),
        }
    }
}
