//! A batch of stands in one world gives each run the same recording, byte for byte, as
//! that run simulated alone: the stands never interact, and each run keeps its own random
//! streams. Mixed here: different scenarios, seeds, durations, physics rates, a disabled stand,
//! stand modules (thermal, hysteresis), a gimbal and a magnetometer delay.
use magstand_sim::{Scenario, ValidScenario, simulate, simulate_batch};

fn scenario(name: &str, overrides: &[&str]) -> ValidScenario {
    let text = magstand_sim::builtin::get(name).expect("shipped scenario");
    let overrides: Vec<String> = overrides.iter().map(|s| s.to_string()).collect();
    Scenario::from_toml_with_overrides(text, name, &overrides)
        .and_then(|s| s.check(name, None))
        .unwrap_or_else(|e| panic!("{name} {overrides:?}: {e}"))
}

/// Every number of a recording, written exactly (`{:?}` of an `f64` round-trips its bits).
fn fingerprint(rec: &magstand_core::Recording) -> String {
    format!("{rec:?}")
}

#[test]
fn a_batched_run_gives_the_same_recording_as_that_run_alone() {
    let short = ["program.off_s=0.5", "program.dwell_s=0.3"];
    let runs = [
        (scenario("czyba2015-stair", &short), 11),
        (scenario("czyba2015-stair", &short), 12),
        (
            scenario(
                "czyba2015-stair",
                &[
                    "program.off_s=0.4",
                    "program.dwell_s=0.2",
                    "program.steps=5",
                ],
            ),
            11,
        ),
        (scenario("thermal", &short), 3),
        (scenario("hysteresis", &short), 4),
        (
            scenario(
                "czyba2015-stair",
                &[
                    "program.off_s=0.5",
                    "program.dwell_s=0.3",
                    "stand.enabled=false",
                ],
            ),
            5,
        ),
        (
            scenario(
                "czyba2015-stair",
                &[
                    "program.off_s=0.5",
                    "program.dwell_s=0.3",
                    "physics_hz=800.0",
                ],
            ),
            6,
        ),
        (
            scenario(
                "flight-turns",
                &["program.off_s=0.5", "program.dwell_max_s=1.5"],
            ),
            7,
        ),
        (
            scenario(
                "czyba2015-stair",
                &[
                    "program.off_s=0.5",
                    "program.dwell_s=0.3",
                    "logging.mag_delay_s=0.02",
                ],
            ),
            8,
        ),
    ];
    let refs: Vec<(&ValidScenario, u64)> = runs.iter().map(|(s, seed)| (s, *seed)).collect();
    let batched = simulate_batch(&refs);
    assert_eq!(batched.len(), runs.len());
    for (i, ((s, seed), rec)) in runs.iter().zip(&batched).enumerate() {
        let alone = simulate(s, *seed);
        assert!(alone.len() > 50, "run {i}: {} rows", alone.len());
        assert!(
            fingerprint(&alone) == fingerprint(rec),
            "run {i} (seed {seed}): the batched recording differs from the run alone \
             ({} rows alone, {} batched)",
            alone.len(),
            rec.len()
        );
    }
    // The order of the batch does not matter either.
    let reversed: Vec<(&ValidScenario, u64)> = refs.iter().rev().copied().collect();
    for (rec, again) in batched.iter().rev().zip(simulate_batch(&reversed)) {
        assert!(
            fingerprint(rec) == fingerprint(&again),
            "reversed batch differs"
        );
    }
}

#[test]
fn an_empty_batch_gives_no_recordings() {
    assert!(simulate_batch(&[]).is_empty());
}
