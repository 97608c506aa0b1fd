//! Regression: a supply voltage at or below zero went through without a word. `simulate` ran a
//! 12 V bench behind 10 ohm, which cannot drive four idling motors and the avionics (1.9 A),
//! and wrote a terminal voltage of -7 V on every row, the motors drawing their idle current at
//! it; and `fit` and `diagnose` read a recording whose `bat_v` was -5 V and answered with exit
//! 0. A supply that cannot drive the stand's idle load is now refused by name, as an impossible
//! setting, and a recording's `bat_v` cannot be negative, its row and column named otherwise.
mod common;

use common::magstand;

#[test]
fn a_supply_that_cannot_drive_the_idle_load_is_refused_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    // The 12 V bench stair behind a source resistance of `ohm`.
    let simulate = |ohm: &str| {
        let set = format!("supply.source_resistance_ohm={ohm}");
        magstand(&[
            "simulate",
            "--scenario",
            "builtin:bench-supply-stair",
            "--out",
            out.to_str().unwrap(),
            "--set",
            &set,
        ])
    };
    let r = simulate("10");
    assert!(!r.ok, "simulated: {}", r.stdout);
    assert!(
        r.stderr.contains("supply.source_resistance_ohm")
            && r.stderr.contains("idle load of 1.90 A")
            && r.stderr.contains("-7.00 V"),
        "{}",
        r.stderr
    );
    assert!(!out.exists(), "a refused run wrote {}", out.display());

    // Just within what the supply can drive, the run's voltage stays above zero throughout.
    let r = simulate("6.3");
    assert!(r.ok, "{}", r.stderr);
    let rec = magstand_core::recording_csv::read(out.join("recording.csv")).unwrap();
    let lowest = rec
        .bat_v
        .as_deref()
        .unwrap()
        .iter()
        .copied()
        .fold(f64::INFINITY, f64::min);
    assert!(lowest > 0.0, "the supply fell to {lowest} V");
}

#[test]
fn a_recording_with_a_negative_supply_voltage_is_refused_with_its_row() {
    let dir = tempfile::tempdir().unwrap();
    for (bad, row) in [("-5", 3), ("-0.2", 2)] {
        let mut text = String::from("t_s,thr_1,thr_2,mag_x_ut,mag_y_ut,mag_z_ut,bat_v,bat_a\n");
        for r in 0..40 {
            let v = if r + 1 == row { bad } else { "12.1" };
            let thr = (r % 10) as f64 / 10.0;
            text.push_str(&format!(
                "{:.2},{thr},{thr},{},-3.0,40.0,{v},{}\n",
                r as f64 * 0.1,
                20.0 + thr,
                10.0 * thr
            ));
        }
        let path = dir.path().join("rec.csv");
        std::fs::write(&path, text).unwrap();
        for command in [vec!["fit", "--model-out"], vec!["diagnose", "--json"]] {
            let out = dir.path().join("out.json");
            let mut args = vec![command[0], "--recording", path.to_str().unwrap()];
            args.extend(&command[1..]);
            args.push(out.to_str().unwrap());
            let r = magstand(&args);
            assert!(!r.ok, "{command:?} with bat_v {bad}: {}", r.stdout);
            let expected = format!(
                "row {row}, column `bat_v`: \"{bad}\" is not a supply voltage of 0 V or more"
            );
            assert!(
                r.stderr.contains(&expected),
                "{command:?} with bat_v {bad}: {}",
                r.stderr
            );
            assert!(!out.exists(), "{command:?} wrote {}", out.display());
        }
    }
}
