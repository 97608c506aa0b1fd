//! Runs the diagnosis and fit suite on recordings from the independent stand generator and
//! prints its Markdown report:
//! `cargo run --release -p magstand-tests --bin independent-suite -- [SEEDS [LABEL]]`
//! (default 2 seeds, every case, both modes; LABEL keeps the cases whose label contains it,
//! and LABEL `fit` runs only the fit comparison, LABEL `battery-variants` the battery without
//! `bat_v` on [`battery_variants`]; FIRST_SEED in the environment starts elsewhere;
//! MODE=stated or MODE=unstated runs that mode alone, without the fit comparison;
//! STAND=held-out runs the generator's second stand, `Stand::held_out`, STAND=octocopter its
//! third, `Stand::octocopter`, and RATE_HZ samples at another rate). With
//! WRITE_RECORDINGS=DIR it only writes each case's recordings there as CSV
//! (`NN-label-seedS.csv`, the case's index in the suite), for timing the `magstand` command
//! on them, each beside the generator's noise-free disturbance at its rows (`.truth`, columns
//! `dist_x_ut,dist_y_ut,dist_z_ut`, as `compensate --out` writes its prediction): a model's
//! error against the truth shows where in time it misses, which the noise hides. With LABEL
//! `battery-variants` it writes the battery without `bat_v` on each variant
//! (`vNN-variant-seedS.csv`).
use magstand_core::Recording;
use magstand_tests::SuiteArgs;
use magstand_tests::independent::{
    Case, Mode, battery_variants, cases, fit_accuracy, markdown, recording, recording_on, run_case,
    run_case_on,
};

fn main() {
    let SuiteArgs { seeds, only } = SuiteArgs::from_env(2);
    if let Some(dir) = std::env::var_os("WRITE_RECORDINGS") {
        let dir = std::path::PathBuf::from(dir);
        if let Err(e) = std::fs::create_dir_all(&dir) {
            eprintln!("error: {}: {e}", dir.display());
            std::process::exit(1);
        }
        let slug = |label: &str| -> String {
            label
                .chars()
                .map(|c| if c.is_ascii_alphanumeric() { c } else { '-' })
                .collect()
        };
        // Each file's name and recording: the suite's cases on its stand, or with LABEL
        // `battery-variants` the battery without `bat_v` on each variant.
        let write = |name: String, (rec, truth): (Recording, Vec<[f64; 3]>)| {
            let path = dir.join(name);
            if let Err(e) = write_with_truth(&rec, &truth, &path) {
                eprintln!("error: {e}");
                std::process::exit(1);
            }
            println!("{}", path.display());
        };
        if only == "battery-variants" {
            let case = battery_without_bat_v();
            for (k, (label, stand)) in battery_variants().into_iter().enumerate() {
                for seed in seeds.clone() {
                    let name = format!("v{k:02}-{}-seed{seed}.csv", slug(label));
                    write(name, recording_on(&stand, &case, seed));
                }
            }
        } else {
            for (k, case) in cases().into_iter().enumerate() {
                if !case.label.contains(&only) {
                    continue;
                }
                for seed in seeds.clone() {
                    let name = format!("{k:02}-{}-seed{seed}.csv", slug(case.label));
                    write(name, recording(&case, seed));
                }
            }
        }
        return;
    }
    if only == "fit" {
        print_fit_accuracy();
        return;
    }
    if only == "battery-variants" {
        print_battery_variants(seeds);
        return;
    }
    let mut outcomes = Vec::new();
    for case in cases().into_iter().filter(|c| c.label.contains(&only)) {
        for mode in modes() {
            for seed in seeds.clone() {
                let o = run_case(&case, mode, seed);
                eprintln!(
                    "{:40} {mode:?} seed {seed}: {:?} ({:.1} s)",
                    case.label, o.verdict, o.diagnose_s
                );
                outcomes.push(o);
            }
        }
    }
    print!("{}", markdown(&outcomes));
    if only.is_empty() && std::env::var_os("MODE").is_none() {
        print_fit_accuracy();
    }
}

/// The modes `MODE` names (`stated` or `unstated`), else both. Exits with an error for any
/// other value.
fn modes() -> Vec<Mode> {
    match std::env::var("MODE").as_deref() {
        Err(_) => vec![Mode::Unstated, Mode::Stated],
        Ok("stated") => vec![Mode::Stated],
        Ok("unstated") => vec![Mode::Unstated],
        Ok(other) => {
            eprintln!("error: MODE={other:?}: expected `stated` or `unstated`");
            std::process::exit(2);
        }
    }
}

/// The suite's case that [`battery_variants`] runs on each variant: the battery without
/// `bat_v`. Exits with an error where the suite has none.
fn battery_without_bat_v() -> Case {
    let Some(case) = cases()
        .into_iter()
        .find(|c| c.label == "battery sag, bat_v not logged")
    else {
        eprintln!("error: the suite has no case of a battery without bat_v");
        std::process::exit(1);
    };
    case
}

/// Writes `rec` to `path` as CSV, and beside it the generator's noise-free disturbance
/// `truth` at its rows (`.truth`).
fn write_with_truth(
    rec: &Recording,
    truth: &[[f64; 3]],
    path: &std::path::Path,
) -> Result<(), String> {
    let truth_csv = std::iter::once("dist_x_ut,dist_y_ut,dist_z_ut".to_string())
        .chain(truth.iter().map(|v| format!("{},{},{}", v[0], v[1], v[2])))
        .collect::<Vec<_>>()
        .join("\n")
        + "\n";
    let truth_path = path.with_extension("truth");
    // The recording's error names its file already.
    magstand_core::recording_csv::write(rec, path).map_err(|e| e.to_string())?;
    std::fs::write(&truth_path, truth_csv).map_err(|e| format!("{}: {e}", truth_path.display()))
}

/// The battery without `bat_v` on each of [`battery_variants`], both modes, as a table.
fn print_battery_variants(seeds: std::ops::Range<u64>) {
    let case = battery_without_bat_v();
    println!("| variant | mode | seed | verdict | exact |\n|---|---|---|---|---|");
    let mut exact = 0;
    let mut runs = 0;
    for (label, stand) in battery_variants() {
        for mode in modes() {
            for seed in seeds.clone() {
                let o = run_case_on(&stand, &case, mode, seed);
                eprintln!("{label:44} {mode:?} seed {seed}: {:?}", o.verdict);
                let right = o.correct();
                exact += usize::from(right);
                runs += 1;
                println!(
                    "| {label} | {mode:?} | {seed} | {} | {} |",
                    o.verdict.join(", "),
                    if right { "yes" } else { "no" }
                );
            }
        }
    }
    println!("\n{exact} of {runs} diagnoses exactly right.");
}

fn print_fit_accuracy() {
    println!(
        "\n### Fit on independent data (identified on seed 101, judged on seed 102 against the generator's truth)\n"
    );
    println!("| method | RMSE x, y, z (µT) |\n|---|---|");
    for (name, r) in fit_accuracy(101, 102) {
        match r {
            Ok(r) => println!("| {name} | {:.3}, {:.3}, {:.3} |", r[0], r[1], r[2]),
            Err(why) => println!("| {name} | not determined: {why} |"),
        }
    }
}
