//! Expression strings from files are untrusted: whatever they contain, parsing returns an
//! expression or an error — never a panic, never a stack overflow.

use armature_symbolic::{
    Expr, Function, MAX_NESTING, MAX_TOKENS, Shape, SymbolTable, parse_constraint, parse_expr,
};
use proptest::prelude::*;

fn symbols() -> SymbolTable {
    let mut s = SymbolTable::new();
    s.insert_leaf(&Expr::variable("x", 3));
    s.insert_leaf(&Expr::variable("y", 1));
    s.insert_leaf(&Expr::variable_shaped("M", Shape::Matrix(3, 3)));
    s.insert_leaf(&Expr::parameter("p", Shape::Vector(3), &[1.0, 2.0, 3.0]));
    s
}

/// Runs `f` on a thread with a small stack, as a test or a worker thread might have.
fn small_stack(f: impl FnOnce() + Send + 'static) {
    std::thread::Builder::new().stack_size(512 * 1024).spawn(f).unwrap().join().unwrap();
}

#[test]
fn deep_nesting_and_long_chains_are_errors_not_stack_overflows() {
    small_stack(|| {
        let s = symbols();
        for depth in [MAX_NESTING + 1, 10_000, 100_000] {
            for text in [
                format!("{}y{}", "(".repeat(depth), ")".repeat(depth)),
                format!("{}y", "-".repeat(depth)),
                format!("{}y{}", "sin(".repeat(depth), ")".repeat(depth)),
                format!("{}y{}", "[".repeat(depth), "]".repeat(depth)),
                format!("y{}", "**y".repeat(depth)),
            ] {
                let err = parse_expr(&text, &s).unwrap_err().to_string();
                assert!(err.contains("nested deeper") || err.contains("longer than"), "{err}");
            }
        }
        let chain = vec!["y"; MAX_TOKENS].join(" + ");
        assert!(parse_expr(&chain, &s).unwrap_err().to_string().contains("longer than"));
        // Just inside the limits, the expression parses and compiles on this small stack.
        let nested = format!("{}y{}", "(".repeat(MAX_NESTING - 2), ")".repeat(MAX_NESTING - 2));
        parse_expr(&nested, &s).unwrap();
        let chain = vec!["y"; MAX_TOKENS / 2].join(" + ");
        let e = parse_expr(&chain, &s).unwrap();
        let f = Function::compile(&[e], &[&[Expr::variable("y", 1)]]).unwrap();
        let mut out = [0.0];
        f.eval(&[2.0], &mut f.workspace(), &mut out, None).unwrap();
        assert_eq!(out[0], 2.0 * (MAX_TOKENS / 2) as f64);
    });
}

const TOKENS: &[&str] = &[
    "x",
    "y",
    "M",
    "p",
    "z",
    "1",
    "0",
    "2.5",
    "1e308",
    "-",
    "+",
    "*",
    "/",
    "@",
    "**",
    "(",
    ")",
    "[",
    "]",
    ",",
    ":",
    ".T",
    "<=",
    ">=",
    "==",
    "norm(",
    "sin(",
    "so3_log(",
    "se3_exp(",
    "dot(",
    "cross(",
    "concat(",
    "stack(",
    "identity(",
    "max(",
    "sum(",
    "quat_to_matrix(",
    "x[0]",
    "M[0:2, 1]",
    "pi",
    " ",
    "inf",
    "nan",
    "=",
    "&",
    "ä",
    "\"",
];

proptest! {
    #![proptest_config(ProptestConfig { cases: 2000, ..ProptestConfig::default() })]

    /// Random token soup: an expression or an error, and errors carry a column inside the
    /// text.
    #[test]
    fn the_parser_never_panics(tokens in prop::collection::vec(prop::sample::select(TOKENS), 0..30)) {
        let text: String = tokens.concat();
        let s = symbols();
        for r in [parse_expr(&text, &s).map(|_| ()), parse_constraint(&text, &s).map(|_| ())] {
            if let Err(armature_symbolic::SymbolicError::Parse { column, .. }) = r {
                prop_assert!(column >= 1 && column <= text.chars().count() + 1);
            }
        }
    }

    /// Arbitrary strings (any characters).
    #[test]
    fn arbitrary_strings_never_panic(text in "\\PC{0,60}") {
        let s = symbols();
        let _ = parse_expr(&text, &s);
        let _ = parse_constraint(&text, &s);
    }
}

/// Inputs that crashed the parser before (found by the properties above), kept as
/// regressions: a multi-byte character after an operator (the two-byte lookahead sliced
/// inside it), a UTF-8 continuation byte 0xA0 read as whitespace, and `identity(n)` with a
/// huge `n` (n·n overflowed).
#[test]
fn inputs_that_once_crashed_are_errors() {
    let s = symbols();
    for text in
        ["𖼌¼6𛃡ශ𐨆*ਲ਼]𑑞&(", "y ࠠ y", "y*ä", "*𖼌", "identity(1e308)", "identity(100000)", "identity(-3)"]
    {
        assert!(parse_expr(text, &s).is_err(), "{text}");
        assert!(parse_constraint(text, &s).is_err(), "{text}");
    }
    assert_eq!(parse_expr("identity(3)", &s).unwrap().shape().unwrap(), Shape::Matrix(3, 3));
}
