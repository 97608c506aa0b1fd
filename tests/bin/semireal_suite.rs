//! Diagnoses the public flight logs as logged and copies of each with one catalog effect
//! added, and prints the Markdown report:
//! `cargo run --release -p magstand-tests --bin semireal-suite`.
//! A second table repeats the judgement with injections of other sizes that the diagnosis
//! was never developed on (`held_out_injections`).
//!
//! With `WRITE_RECORDINGS=DIR` it writes the recordings it diagnoses instead, as recording
//! CSV: each log as imported (`LOG.csv`) and each copy (`LOG-dev-K.csv`, `LOG-held-out-K.csv`,
//! K the injection's place in its list), for `magstand diagnose` to look into.
use magstand_tests::semireal::{
    Injection, held_out_injections, import, injections, logs, markdown, run_log,
};

/// Writes every imported log and its copies into `dir` (see the module's docs).
fn write_recordings(dir: &std::path::Path) -> Result<(), String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let write = |rec: &magstand_core::Recording, name: String| {
        // The recording's error names its file already.
        magstand_core::recording_csv::write(rec, dir.join(name)).map_err(|e| e.to_string())
    };
    for log in logs() {
        let stem = log.file.split('.').next().unwrap_or(log.file);
        // A log the suite cannot import is reported in its table; here it is only skipped.
        let rec = match import(&log) {
            Ok(rec) => rec,
            Err(e) => {
                eprintln!("semireal-suite: {}: not written: {e}", log.file);
                continue;
            }
        };
        write(&rec, format!("{stem}.csv"))?;
        for (set, list) in [("dev", injections()), ("held-out", held_out_injections())] {
            for (k, inj) in list.iter().enumerate().filter(|(_, i)| i.applies(&rec)) {
                write(&inj.apply(&rec), format!("{stem}-{set}-{k}.csv"))?;
            }
        }
    }
    Ok(())
}

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
    if let Some(dir) = std::env::var_os("WRITE_RECORDINGS") {
        if let Err(e) = write_recordings(std::path::Path::new(&dir)) {
            eprintln!("semireal-suite: {e}");
            std::process::exit(1);
        }
        return;
    }
    print!("{}", table(&injections()));
    println!("\n### Held out: other sizes, lags and directions\n");
    print!("{}", table(&held_out_injections()));
}
