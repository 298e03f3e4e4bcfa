//! The expression parser on arbitrary strings, with a few names of each shape in scope.
#![no_main]

use armature_symbolic::{Expr, Shape, SymbolTable, parse_constraint, parse_expr};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        let mut s = SymbolTable::new();
        s.insert_leaf(&Expr::variable("x", 3));
        s.insert_leaf(&Expr::variable("y", 1));
        s.insert_leaf(&Expr::variable_shaped("M", Shape::Matrix(3, 3)));
        let _ = parse_expr(text, &s);
        let _ = parse_constraint(text, &s);
    }
});
