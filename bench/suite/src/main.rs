//! `cargo run --release -p armature-suite [-- --filter WORD] [--json FILE]`: solves every task
//! of the suite with default settings, verifies each independently and prints the table.

use armature_suite::{generate, run};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let value = |flag: &str| args.iter().position(|a| a == flag).and_then(|i| args.get(i + 1));
    let filter = value("--filter").cloned();
    let tasks: Vec<_> = generate::suite()
        .into_iter()
        .filter(|t| filter.as_ref().is_none_or(|f| t.name.contains(f.as_str())))
        .collect();
    eprintln!("{} tasks", tasks.len());
    let mut outcomes = Vec::new();
    for t in &tasks {
        let o = run::run_one(t);
        eprintln!(
            "{:<26} {:<22} it {:>3}  T {:>7.4}  {:>7.1} ms  worst {:>9.2e} {}",
            o.name, o.status, o.iterations, o.final_time, o.solve_ms, o.worst, o.worst_what
        );
        outcomes.push(o);
    }
    println!("{}", run::table(&outcomes));
    if let Some(path) = value("--json") {
        let json = serde_json::to_string_pretty(&outcomes).expect("outcomes serialize");
        if let Err(e) = std::fs::write(path, json) {
            eprintln!("error: {path}: {e}");
            std::process::exit(4);
        }
    }
}
