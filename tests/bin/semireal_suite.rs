//! Diagnoses the public flight logs as logged and copies of each with one catalog effect
//! added, and prints the Markdown report:
//! `cargo run --release -p magstand-tests --bin semireal-suite`.
//! A second table repeats the judgement with injections of other sizes that the diagnosis
//! was never developed on (`held_out_injections`).
use magstand_tests::semireal::{
    Injection, held_out_injections, injections, logs, markdown, run_log,
};

fn table(injections: &[Injection]) -> String {
    let mut outcomes = Vec::new();
    for log in logs() {
        for o in run_log(&log, injections) {
            eprintln!(
                "{:50} {:30} {:?} {:?} ({:.1} s)",
                o.log, o.injection, o.verdict, o.judged, o.seconds
            );
            outcomes.push(o);
        }
    }
    markdown(&outcomes)
}

fn main() {
    print!("{}", table(&injections()));
    println!("\n### Held out: other sizes, lags and directions\n");
    print!("{}", table(&held_out_injections()));
}
