//! Runs the full concealed-effect suite and prints its Markdown report:
//! `cargo run --release -p magstand-tests --bin concealed-suite -- [SEEDS]` (default 5).
use magstand_tests::concealed::{cases, markdown, run_case};

fn main() {
    let seeds: u64 = std::env::args()
        .nth(1)
        .map(|s| s.parse().expect("SEEDS: a whole number"))
        .unwrap_or(5);
    let mut outcomes = Vec::new();
    for case in cases() {
        for seed in 1..=seeds {
            let o = run_case(&case, seed);
            eprintln!(
                "{:50} seed {seed}: {:?} ({:.1} s)",
                case.label, o.verdict, o.diagnose_s
            );
            outcomes.push(o);
        }
    }
    print!("{}", markdown(&outcomes));
}
