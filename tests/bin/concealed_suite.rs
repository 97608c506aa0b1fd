//! Runs the full concealed-effect suite and prints its Markdown report:
//! `cargo run --release -p magstand-tests --bin concealed-suite -- [SEEDS [LABEL]]` (default 5
//! seeds, every case; LABEL keeps the cases whose label contains it; FIRST_SEED and VERBOSE in
//! the environment start elsewhere and print every candidate).
use magstand_tests::SuiteArgs;
use magstand_tests::concealed::{cases, markdown, run_case};

fn main() {
    let SuiteArgs { seeds, only } = SuiteArgs::from_env(5);
    let mut outcomes = Vec::new();
    for case in cases().into_iter().filter(|c| c.label.contains(&only)) {
        for seed in seeds.clone() {
            let o = run_case(&case, seed);
            eprintln!(
                "{:50} seed {seed}: {:?} ({:.1} s)",
                case.label, o.verdict, o.diagnose_s
            );
            if std::env::var("VERBOSE").is_ok() {
                for r in &o.diagnosis.rounds {
                    eprintln!("    residual whiteness p {:?}", r.whiteness_p);
                    for c in &r.candidates {
                        eprintln!(
                            "    {:16} gain {:?} p {:?}",
                            c.name, c.improvement, c.p_value
                        );
                    }
                    eprintln!("    -> {:?} (threshold {:.1e})", r.accepted, r.threshold);
                }
            }
            outcomes.push(o);
        }
    }
    print!("{}", markdown(&outcomes));
}
