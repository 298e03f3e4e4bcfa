//! The problem-file loader (parse, check, build the `Problem`, compile it) on arbitrary bytes.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else { return };
    let src = armature_cli::task::Source { name: "fuzz.toml", text };
    let Ok(file) = armature_cli::problem_file::parse(src) else { return };
    match armature_cli::problem_file::build(&file, src) {
        Ok((problem, settings)) => {
            // What the loader accepts compiles (or is refused with an error, never a panic).
            let _ = problem.compile(settings);
        }
        Err(e) => assert!(e.to_string().starts_with("fuzz.toml:"), "unlocated: {e}"),
    }
});
