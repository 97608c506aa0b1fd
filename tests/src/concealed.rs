//! The concealed-effect suite for the mismatch diagnosis: recordings simulated with one catalog
//! effect switched on (at a size comparable to the noise and small beside the main
//! disturbance), two at once, one outside the catalog, and effect-free controls with and
//! without `bat_v` / `temp_c`; each diagnosed against the nominal stand by a run that is not
//! told the effect. `cargo test` runs a fast subset (`tests/tests/diagnosis_concealed.rs`); the full
//! suite with several seeds is `cargo run --release -p magstand-tests --bin concealed-suite`.
use std::collections::BTreeSet;

use magstand_diagnose::{DiagnoseConfig, Diagnosis, UNEXPLAINED, diagnose};
use magstand_sim::{Scenario, ValidScenario, simulate};

const BENCH: &str = "[supply]\nkind = \"bench\"\nvoltage_v = 12.0\n";

/// The nominal stand: up-and-down stairs twice, 50 Hz magnetometer, bench supply.
fn stand_toml(supply: &str, rigid_differential: bool) -> String {
    let differential = if rigid_differential {
        "[differential]\namplitude = 0.04\nfrequency_hz = 0.2\n[stand]\nenabled = false\n"
    } else {
        ""
    };
    format!(
        "name = \"concealed-stand\"\n\
         [program]\nkind = \"stair\"\noff_s = 10.0\nsteps = 10\ndwell_s = 8.0\n\
         direction = \"up_down\"\nrepeats = 2\n\
         {supply}{differential}\
         [motors]\ndead_zone = 0.37\nspinup_tau_s = 0.06\n\
         [magnetometer]\nodr_hz = 50.0\n\
         [logging]\nrecord_power = false\n"
    )
}

/// A parameter to recover: name in the diagnosis, true value, absolute tolerance.
#[derive(Debug, Clone)]
pub struct Check {
    /// Parameter name as the diagnosis reports it.
    pub param: &'static str,
    /// The value the simulation used.
    pub truth: f64,
    /// Stated tolerance (absolute).
    pub tol: f64,
}

/// One concealed case.
#[derive(Debug, Clone)]
pub struct Case {
    /// Short label.
    pub label: &'static str,
    /// The effects switched on (the verdict expected, in any order).
    pub expect: &'static [&'static str],
    supply: &'static str,
    rigid_differential: bool,
    overrides: Vec<&'static str>,
    /// Parameters that must be recovered.
    pub checks: Vec<Check>,
}

fn check(param: &'static str, truth: f64, tol: f64) -> Check {
    Check { param, truth, tol }
}

const BATTERY: &str = "[supply]\nkind = \"battery\"\ncells = 3\ncapacity_ah = 6.0\n\
                       internal_resistance_ohm = 0.02\n";

/// Every case of the suite.
pub fn cases() -> Vec<Case> {
    let case = |label, expect, overrides: Vec<&'static str>, checks| Case {
        label,
        expect,
        supply: BENCH,
        rigid_differential: false,
        overrides,
        checks,
    };
    vec![
        case("control", &[], vec![], vec![]),
        case(
            "control, bat_v and temp_c logged",
            &[],
            vec!["logging.record_power=true", "logging.record_temp=true"],
            vec![],
        ),
        // The nominal scenario is a description, never exact: a stand whose motors, wiring,
        // noise, heading and sampling rate all differ from it, with no catalog effect, must
        // still come out clean (the calibration absorbs what is linear in the nominal
        // regressors; what is not must not be forced onto a name).
        case(
            "control, constants unlike the nominal (100 Hz)",
            &[],
            vec![
                "magnetometer.odr_hz=100.0",
                "motors.kv_rpm_per_v=1000.0",
                "motors.winding_resistance_ohm=0.2",
                "motors.idle_current_a=0.8",
                "disturbance.scale=1.4",
                "noise.sensor_sd_ut=0.25",
                "stand.heading_deg=120.0",
            ],
            vec![],
        ),
        Case {
            supply: BATTERY,
            ..case(
                "battery_sag",
                &["battery_sag"],
                vec![],
                vec![check("capacity_ah", 6.0, 3.0)],
            )
        },
        Case {
            supply: BATTERY,
            ..case(
                "battery_sag, bat_v logged",
                &["battery_sag"],
                vec!["logging.record_power=true"],
                vec![
                    check("capacity_ah", 6.0, 1.5),
                    check("internal_resistance_ohm", 0.02, 0.01),
                ],
            )
        },
        case(
            "thermal_drift",
            &["thermal_drift"],
            vec!["thermal.enabled=true"],
            vec![
                check("tau_s", 120.0, 40.0),
                check("offset_ut_per_w_z", 0.0024, 0.0006),
            ],
        ),
        case(
            "thermal_drift, temp_c logged",
            &["thermal_drift"],
            vec!["thermal.enabled=true", "logging.record_temp=true"],
            vec![
                check("offset_ut_per_c_x", 0.08, 0.025),
                check("offset_ut_per_c_z", 0.12, 0.025),
                check("tau_s", 120.0, 20.0),
            ],
        ),
        case(
            "current_lag",
            &["current_lag"],
            vec!["motors.spinup_tau_s=0.25"],
            vec![check("spinup_tau_s", 0.25, 0.04)],
        ),
        case(
            "time_offset",
            &["time_offset"],
            vec!["logging.mag_delay_s=0.08"],
            vec![check("mag_delay_s", 0.08, 0.015)],
        ),
        case(
            "hysteresis",
            &["hysteresis"],
            vec!["hysteresis.enabled=true"],
            vec![
                check("play_a", 6.0, 1.5),
                check("gain_ut_per_a_z", -0.06, 0.015),
            ],
        ),
        Case {
            rigid_differential: true,
            ..case(
                "motor_asymmetry",
                &["motor_asymmetry"],
                vec![
                    "wiring.extra_motor_ut_per_a=[[0.15,-0.1,0.05],[-0.05,0.0,0.0],[0.0,0.0,0.0],[-0.1,0.1,-0.05]]",
                ],
                vec![
                    check("motor1_gain_ut_per_a_x", 0.15, 0.05),
                    check("motor4_gain_ut_per_a_y", 0.10, 0.05),
                ],
            )
        },
        case(
            "dead_zone",
            &["dead_zone"],
            vec!["motors.dead_zone=0.45"],
            vec![check("dead_zone", 0.45, 0.05)],
        ),
        case(
            "thermal_drift + current_lag",
            &["thermal_drift", "current_lag"],
            vec!["thermal.enabled=true", "motors.spinup_tau_s=0.25"],
            vec![check("spinup_tau_s", 0.25, 0.05)],
        ),
        case(
            "outside the catalog (external alternating field)",
            &[UNEXPLAINED],
            vec!["interference.amplitude_ut=[0.4,-0.3,0.5]"],
            vec![],
        ),
    ]
}

impl Case {
    /// The nominal scenario the diagnosis is given.
    pub fn nominal(&self) -> ValidScenario {
        let text = stand_toml(BENCH, self.rigid_differential);
        Scenario::from_toml_str(&text, "concealed nominal")
            .and_then(|s| s.check("concealed nominal", None))
            .expect("the nominal stand checks")
    }

    /// The scenario the recording is simulated from (the effect switched on).
    pub fn real(&self) -> ValidScenario {
        let text = stand_toml(self.supply, self.rigid_differential);
        let o: Vec<String> = self.overrides.iter().map(|s| s.to_string()).collect();
        Scenario::from_toml_with_overrides(&text, self.label, &o)
            .and_then(|s| s.check(self.label, None))
            .unwrap_or_else(|e| panic!("{}: {e}", self.label))
    }
}

/// What one diagnosed recording gave.
#[derive(Debug, Clone)]
pub struct Outcome {
    /// Case label.
    pub label: &'static str,
    /// Seed of the recording.
    pub seed: u64,
    /// The verdict.
    pub verdict: Vec<String>,
    /// Verdict equals the expected set.
    pub named_right: bool,
    /// Parameter checks that failed, with the value found.
    pub param_failures: Vec<String>,
    /// Held-out RMSE summed over axes fell with the accepted terms (or nothing was accepted).
    pub improved: bool,
    /// Seconds spent diagnosing.
    pub diagnose_s: f64,
    /// The diagnosis.
    pub diagnosis: Diagnosis,
}

/// Simulates `case` with `seed` and diagnoses it against the nominal stand.
pub fn run_case(case: &Case, seed: u64) -> Outcome {
    let rec = simulate(&case.real(), seed);
    let start = std::time::Instant::now();
    let d = diagnose(
        &rec,
        case.label,
        &case.nominal(),
        &DiagnoseConfig::default().check().expect("default settings"),
    )
    .unwrap_or_else(|e| panic!("{} seed {seed}: {e}", case.label));
    let diagnose_s = start.elapsed().as_secs_f64();
    let got: BTreeSet<&str> = d.verdict.iter().map(String::as_str).collect();
    let want: BTreeSet<&str> = case.expect.iter().copied().collect();
    let param_failures = case
        .checks
        .iter()
        .filter_map(|c| {
            let found = d
                .effects
                .iter()
                .flat_map(|e| &e.params)
                .find(|p| p.name == c.param);
            match found {
                Some(p) if (p.value - c.truth).abs() <= c.tol => None,
                Some(p) => Some(format!(
                    "{} = {:.4} (truth {} ± {})",
                    c.param, p.value, c.truth, c.tol
                )),
                None => Some(format!("{} not reported", c.param)),
            }
        })
        .collect();
    let sum = |v: [f64; 3]| v.iter().sum::<f64>();
    let accepted: Vec<_> = d.effects.iter().filter(|e| e.name != UNEXPLAINED).collect();
    let improved = accepted
        .iter()
        .all(|e| sum(e.holdout_rmse_after_ut) < sum(e.holdout_rmse_before_ut))
        && (accepted.is_empty()
            || sum(d.simulation.holdout_rmse_after_ut) < sum(d.simulation.holdout_rmse_before_ut));
    Outcome {
        label: case.label,
        seed,
        named_right: got == want,
        verdict: d.verdict.clone(),
        param_failures,
        improved,
        diagnose_s,
        diagnosis: d,
    }
}

/// The suite's results as Markdown: per-case table, confusion matrix, false-alarm rate.
pub fn markdown(outcomes: &[Outcome]) -> String {
    let mut names: Vec<&str> = magstand_diagnose::effects::names();
    names.push(UNEXPLAINED);
    let mut s = String::new();
    s.push_str("| case | runs | right verdict | parameters within tolerance | fit improved | diagnose time (mean, s) |\n|---|---|---|---|---|---|\n");
    let mut labels: Vec<&str> = Vec::new();
    for o in outcomes {
        if !labels.contains(&o.label) {
            labels.push(o.label);
        }
    }
    for l in &labels {
        let runs: Vec<&Outcome> = outcomes.iter().filter(|o| o.label == *l).collect();
        let n = runs.len();
        let count = |f: &dyn Fn(&Outcome) -> bool| runs.iter().filter(|o| f(o)).count();
        s.push_str(&format!(
            "| {l} | {n} | {} | {} | {} | {:.1} |\n",
            count(&|o| o.named_right),
            count(&|o| o.param_failures.is_empty()),
            count(&|o| o.improved),
            runs.iter().map(|o| o.diagnose_s).sum::<f64>() / n as f64
        ));
    }
    s.push_str("\nConfusion matrix: how often each name appeared in the verdict, per case (a run can name more than one; \"none\" is an empty verdict).\n\n");
    s.push_str(&format!(
        "| case | {} | none |\n|---|{}---|\n",
        names.join(" | "),
        "---|".repeat(names.len())
    ));
    for l in &labels {
        let runs: Vec<&Outcome> = outcomes.iter().filter(|o| o.label == *l).collect();
        let cells: Vec<String> = names
            .iter()
            .map(|n| {
                runs.iter()
                    .filter(|o| o.verdict.iter().any(|v| v == n))
                    .count()
                    .to_string()
            })
            .collect();
        let none = runs.iter().filter(|o| o.verdict.is_empty()).count();
        s.push_str(&format!("| {l} | {} | {none} |\n", cells.join(" | ")));
    }
    let controls: Vec<&Outcome> = outcomes
        .iter()
        .filter(|o| o.label.starts_with("control"))
        .collect();
    let alarms = controls.iter().filter(|o| !o.verdict.is_empty()).count();
    let all = cases();
    let wrong_names: usize = outcomes
        .iter()
        .map(|o| {
            let want: Vec<&str> = all
                .iter()
                .find(|c| c.label == o.label)
                .map(|c| c.expect.to_vec())
                .unwrap_or_default();
            o.verdict
                .iter()
                .filter(|v| !want.contains(&v.as_str()))
                .count()
        })
        .sum();
    s.push_str(&format!(
        "\nFalse-alarm rate on effect-free controls: {alarms} of {} runs named something.\n\
         Names given that were not switched on, over all runs: {wrong_names}.\n",
        controls.len()
    ));
    let failures: Vec<String> = outcomes
        .iter()
        .filter(|o| !o.param_failures.is_empty() || !o.named_right)
        .map(|o| {
            format!(
                "- {} seed {}: verdict {:?}{}",
                o.label,
                o.seed,
                o.verdict,
                if o.param_failures.is_empty() {
                    String::new()
                } else {
                    format!("; {}", o.param_failures.join("; "))
                }
            )
        })
        .collect();
    if !failures.is_empty() {
        s.push_str("\nRuns that missed:\n\n");
        s.push_str(&failures.join("\n"));
        s.push('\n');
    }
    s
}
