//! Diagnoses the public flight logs as logged and copies of each with one catalog effect
//! added, and prints the Markdown report:
//! `cargo run --release -p magstand-tests --bin semireal-suite`.
use magstand_tests::semireal::{injections, logs, markdown, run_log};

fn main() {
    let mut outcomes = Vec::new();
    for log in logs() {
        for o in run_log(&log, &injections()) {
            eprintln!(
                "{:50} {:30} {:?} {:?} ({:.1} s)",
                o.log, o.injection, o.verdict, o.judged, o.seconds
            );
            outcomes.push(o);
        }
    }
    print!("{}", markdown(&outcomes));
}
