//! `logging.command_delay_s` logs each row's commands as they were that long before the row's
//! time stamp, and changes nothing else: the physics, the noise and every other column are
//! the same bits as without it.
use magstand_sim::{Scenario, ValidScenario, simulate};

fn scenario(overrides: &[&str]) -> ValidScenario {
    let text = magstand_sim::builtin::get("czyba2015-stair").expect("shipped scenario");
    let overrides: Vec<String> = overrides.iter().map(|s| s.to_string()).collect();
    Scenario::from_toml_with_overrides(text, "stair", &overrides)
        .and_then(|s| s.check("stair", None))
        .unwrap_or_else(|e| panic!("{overrides:?}: {e}"))
}

#[test]
fn commands_logged_late_are_the_commands_of_that_long_before() {
    let rate = ["magnetometer.odr_hz=50.0"];
    let on_time = simulate(&scenario(&rate), 3);
    let late = simulate(&scenario(&[rate[0], "logging.command_delay_s=0.1"]), 3);
    assert_eq!(
        format!("{:?}", on_time.mag_ut),
        format!("{:?}", late.mag_ut)
    );
    assert_eq!(format!("{:?}", on_time.t_s), format!("{:?}", late.t_s));
    assert_eq!(format!("{:?}", on_time.bat_a), format!("{:?}", late.bat_a));
    // 0.1 s is five rows at 50 Hz: each row logs the commands five rows before it (the first
    // five, the program's start).
    let changes = on_time.thr[0].windows(2).filter(|w| w[0] != w[1]).count();
    assert!(changes > 3, "the stair changes its command {changes} times");
    for (m, (a, b)) in on_time.thr.iter().zip(&late.thr).enumerate() {
        for r in 5..a.len() {
            assert_eq!(b[r], a[r - 5], "motor {m}, row {r}");
        }
        assert!(
            b[..5].iter().all(|&c| c == a[0]),
            "motor {m}: {:?}",
            &b[..5]
        );
    }
}

#[test]
fn a_command_delay_outside_its_range_is_refused_by_name() {
    let text = magstand_sim::builtin::get("czyba2015-stair").expect("shipped scenario");
    for bad in ["-0.1", "11.0", "nan"] {
        let e = Scenario::from_toml_with_overrides(
            text,
            "stair",
            &[format!("logging.command_delay_s={bad}")],
        )
        .and_then(|s| s.check("stair", None))
        .expect_err(bad)
        .to_string();
        assert!(e.contains("logging.command_delay_s"), "{bad}: {e}");
    }
}
