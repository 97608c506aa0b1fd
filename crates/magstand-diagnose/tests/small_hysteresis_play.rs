//! Regression: the hysteresis play was searched only from 5 % of the stand's largest current,
//! so a 3 A play on a stand drawing about 70 A came out at the edge of the range (3.5 A) with
//! its gains 13 % low, and a `dead_zone` was named beside it for the remainder. The search now
//! starts at 1 %.
mod common;
use common::{bench_supply_stair, diagnose_default};
use magstand_sim::simulate;

#[test]
fn a_three_ampere_play_is_recovered_alone() {
    let (nominal, real) = bench_supply_stair(&["hysteresis.enabled=true", "hysteresis.play_a=3.0"]);
    // A seed that had named the dead zone too.
    let rec = simulate(&real, 4);
    let d = diagnose_default(&rec, "hysteresis.csv", &nominal);
    assert_eq!(d.verdict, ["hysteresis"], "{}", d.summary());
    let param = |name: &str| {
        d.effects[0]
            .params
            .iter()
            .find(|p| p.name == name)
            .unwrap_or_else(|| panic!("no {name}"))
            .value
    };
    let play = param("play_a");
    let gain_z = param("gain_ut_per_a_z");
    assert!(
        (play - 3.0).abs() < 0.3 && (gain_z + 0.06).abs() < 0.006,
        "play {play} A (true 3), z gain {gain_z} µT/A (true -0.06)"
    );
}
