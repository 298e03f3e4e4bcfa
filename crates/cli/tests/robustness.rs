//! Task and problem files are untrusted input: mutated versions of the shipped examples go
//! through the loaders (parse, check, plan or build, compile) and come back as a problem or
//! as an error located in the file — never a panic. (The same loaders are the cargo-fuzz
//! targets in `fuzz/`; this runs in every test run.)

use armature_cli::task::Source;
use proptest::prelude::*;

const TASK: &str = include_str!("../../../examples/pick-and-place-collision.toml");
const PROBLEM: &str = include_str!("../../../examples/double-integrator.toml");

const PIECES: &[&str] = &[
    "0",
    "-1",
    "2",
    "1e308",
    "-1e308",
    "nan",
    "inf",
    "-inf",
    "0.0",
    "999999999",
    "18446744073709551615",
    "\"",
    "'",
    "[",
    "]",
    "{",
    "}",
    "=",
    ",",
    "\n",
    "#",
    " ",
    "x",
    "\"free\"",
    "\"minimize\"",
    "[[waypoints]]",
    "[[states]]",
    "[collision]",
    "[settings]",
    "nodes = 3",
    "size = 0",
    "dynamics = \"v + \"",
    "expr = \"v <= \"",
    "identity(",
    "**",
    "(",
    ")",
    "ä",
    "ࠠ",
];

/// A mutation: at a fraction of the text, replace `len` bytes by `piece`.
fn mutations() -> impl Strategy<Value = Vec<(f64, usize, usize)>> {
    prop::collection::vec((0.0..1.0f64, 0..8usize, 0..PIECES.len()), 1..6)
}

fn mutate(text: &str, muts: &[(f64, usize, usize)]) -> String {
    let mut t = text.to_string();
    for &(at, len, piece) in muts {
        let mut i = ((t.len() as f64) * at) as usize;
        while !t.is_char_boundary(i) {
            i -= 1;
        }
        let mut j = (i + len).min(t.len());
        while !t.is_char_boundary(j) {
            j += 1;
        }
        t.replace_range(i..j, PIECES[piece]);
    }
    t
}

/// Loads like `armature solve` up to (not including) the solve.
fn load(text: &str) -> Result<(), String> {
    let src = Source { name: "fuzz.toml", text };
    armature_cli::commands::solve::load(src, None).map(|_| ()).map_err(|e| e.message)
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 300, ..ProptestConfig::default() })]

    #[test]
    fn mutated_task_files_never_panic(muts in mutations()) {
        let text = mutate(TASK, &muts);
        if let Err(message) = load(&text) {
            prop_assert!(message.starts_with("fuzz.toml:"), "not located: {message}");
        }
    }

    #[test]
    fn mutated_problem_files_never_panic(muts in mutations()) {
        let text = mutate(PROBLEM, &muts);
        if let Err(message) = load(&text) {
            prop_assert!(message.starts_with("fuzz.toml:"), "not located: {message}");
        }
    }

    #[test]
    fn arbitrary_text_never_panics(text in "\\PC{0,200}") {
        let _ = load(&text);
    }
}
