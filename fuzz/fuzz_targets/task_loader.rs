//! The task- and problem-file loaders (`armature solve` up to the solve) on arbitrary bytes.
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        let src = armature_cli::task::Source { name: "fuzz.toml", text };
        if let Err(e) = armature_cli::commands::solve::load(src, None) {
            assert!(e.message.starts_with("fuzz.toml:"), "unlocated error: {}", e.message);
        }
    }
});
