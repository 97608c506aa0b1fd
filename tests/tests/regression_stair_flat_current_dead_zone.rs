//! Regression: on the independent generator's hexacopter driven by an eight-level stair at
//! 50 Hz (current `0.4 A + 11 A e^2.3`, dead zone 0.06), the stated true dead zone was rejected
//! and named `dead_zone` beside a current lag, a late command log, a battery or a delay (8 of
//! 36 stated diagnoses), fitted at 0.165 ± 0.023. The first level, 0.125, draws 0.02 A beyond
//! idle: a law of powers of speed from the first must be flat there and rise through the seven
//! levels above, and misfits them; a dead zone above that level turns it into motors armed
//! within their dead zone, whose column takes up the level on its own, and the fit is better.
//! The dead zone's uncertainty held the spread of its optimum over laws of three and four
//! powers, all with the linear one (0.12 to 0.165). The test of a stated value now also tries
//! the law of four powers without the linear one (as many columns as the baseline's cubic): a
//! propeller's load grows with the square of its speed, and such a law is flat at low speed
//! like the stand's. A wrong dead zone on the same stair
//! is still named.

use magstand_standgen::Stand;
use magstand_tests::independent::{Mode, named_param, on_a_stair, run_case_on, suite_case};

/// The generator's hexacopter at 50 Hz on an eight-level stair, the suite case `label`,
/// stated, seed 1.
fn stated_hexacopter_stair(label: &str) -> magstand_tests::independent::Outcome {
    run_case_on(
        &on_a_stair(Stand::held_out()),
        &suite_case(label),
        Mode::Stated,
        1,
    )
}

#[test]
fn a_stated_dead_zone_below_a_flat_first_level_holds_beside_a_lag() {
    let o = stated_hexacopter_stair("current lag 0.5 s");
    assert_eq!(o.verdict, ["current_lag"], "{}", o.diagnosis.summary());
}

#[test]
fn a_wrong_stated_dead_zone_on_the_same_stair_is_still_named() {
    let o = stated_hexacopter_stair("dead zone 0.25 (stated 0.12)");
    let dz = named_param(&o.diagnosis, "dead_zone", "dead_zone").map(|p| p.value);
    // Levels 0.125 apart, and the level above 0.25 draws 0.2 A beyond idle: the data place
    // the dead zone between 0.25 and that level.
    assert!(
        dz.is_some_and(|v| (0.24..0.38).contains(&v)),
        "stated 0.06, generated 0.25: verdict {:?}, fitted {dz:?}\n{}",
        o.verdict,
        o.diagnosis.summary()
    );
}
