//! Regression: `diagnose` without a scenario refused a stand recording whose commands all lay
//! at or below 0.37 ("the motors never run under the nominal physics (dead zone 0.37)"), and
//! `fit` left its physics family out for the same reason. 0.37 is the simulator's default
//! dead zone, a starting point nobody stated; a run at low throttle (up to 0.3 here) is an
//! ordinary recording. An unstated dead zone that no command exceeds now starts at 0 and is
//! calibrated from there; a stated one still refuses the recording, naming the key and the
//! scenario, and a recording whose commands are all 0 is refused as such.
mod common;
use common::magstand;

/// A stand recording at 50 Hz whose four motors step through 0, 0.05, ..., 0.3 and whose field
/// grows with the square of the command, with uniform noise of sd 0.17 µT (a fixed LCG).
/// `scale` multiplies the commands.
fn low_throttle_csv(dir: &std::path::Path, scale: f64) -> std::path::PathBuf {
    let mut state: u64 = 12345;
    let mut noise = || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 0.6
    };
    let mut text = String::from("t_s,thr_1,thr_2,thr_3,thr_4,mag_x_ut,mag_y_ut,mag_z_ut\n");
    for i in 0..3000 {
        let q = ((i / 150) % 7) as f64 * 0.05;
        let c = q * scale;
        text += &format!(
            "{:.2},{c},{c},{c},{c},{:.4},{:.4},{:.4}\n",
            i as f64 * 0.02,
            20.0 + 40.0 * q * q + noise(),
            2.0 - 20.0 * q * q + noise(),
            40.0 + 60.0 * q * q + noise()
        );
    }
    let csv = dir.join(format!("low-{scale}.csv"));
    std::fs::write(&csv, text).unwrap();
    csv
}

#[test]
fn an_unstated_dead_zone_above_every_command_is_calibrated_not_a_refusal() {
    let dir = tempfile::tempdir().unwrap();
    let csv = low_throttle_csv(dir.path(), 1.0);
    let (r, d) = common::diagnose(&csv, &dir.path().join("d.json"), &[]);
    assert!(r.ok, "{}", r.stderr);
    let d = d.expect("a diagnosis file");
    // The field's own spread is about 1.2 µT rms on x; the baseline leaves the noise.
    for (axis, rmse) in d["baseline"]["holdout_rmse_ut"]
        .as_array()
        .unwrap()
        .iter()
        .enumerate()
    {
        let rmse = rmse.as_f64().unwrap();
        assert!(
            rmse < 0.25,
            "axis {axis}: held-out RMSE {rmse} µT, noise 0.17 µT\n{}",
            r.stdout
        );
    }
    assert_eq!(d["verdict"], serde_json::json!([]), "{}", r.stdout);
}

#[test]
fn a_stated_dead_zone_above_every_command_is_refused_by_its_key() {
    let dir = tempfile::tempdir().unwrap();
    let csv = low_throttle_csv(dir.path(), 1.0);
    let scenario = dir.path().join("stand.toml");
    std::fs::write(
        &scenario,
        "name = \"s\"\n[program]\nkind = \"stair\"\nsteps = 4\ndwell_s = 5.0\n\
         [motors]\ndead_zone = 0.5\n",
    )
    .unwrap();
    let json = dir.path().join("d.json");
    let (r, d) = common::diagnose(&csv, &json, &["--scenario", scenario.to_str().unwrap()]);
    assert!(!r.ok, "{}", r.stdout);
    for said in ["low-1.csv", "0.3000", "stand.toml", "`motors.dead_zone`"] {
        assert!(r.stderr.contains(said), "{said} not in: {}", r.stderr);
    }
    assert!(
        d.is_none(),
        "no diagnosis is written for a refused recording"
    );
}

#[test]
fn commands_that_are_all_zero_are_refused_as_such() {
    let dir = tempfile::tempdir().unwrap();
    let csv = low_throttle_csv(dir.path(), 0.0);
    let r = magstand(&["diagnose", "--recording", csv.to_str().unwrap()]);
    assert!(!r.ok, "{}", r.stdout);
    assert!(
        r.stderr.contains("low-0.csv") && r.stderr.contains("every motor command is 0"),
        "{}",
        r.stderr
    );
}

#[test]
fn the_physics_family_is_tried_on_a_low_throttle_recording() {
    let dir = tempfile::tempdir().unwrap();
    let csv = low_throttle_csv(dir.path(), 1.0);
    let model = dir.path().join("m.json");
    let r = common::fit(csv.to_str().unwrap(), model.to_str().unwrap());
    assert!(r.ok, "{}", r.stderr);
    let physics = r
        .stdout
        .lines()
        .find(|l| l.trim_start().starts_with("physics"))
        .unwrap_or_else(|| panic!("no physics row:\n{}", r.stdout));
    assert!(
        !physics.contains("never run"),
        "the physics family was left out: {physics}"
    );
}
