//! Regression: the independent generator's default stand on one slow stair cycle (ten levels
//! of 25 s up and down, the paper's protocol at its closest) with its board heating logged as
//! `temp_c`, diagnosed against a scenario that states the generator's true dead zone (0.12),
//! got `hysteresis` beside `thermal_drift` on both seeds, with or without a late
//! magnetometer beside them (4 of 4). The stated dead zone is true, but the current law's
//! powers of speed misfit the levels near it (the data would put it at 0.13 ± 0.02, within
//! the statement's tolerance, and stating 0.13 left the heating alone). On one cycle a play
//! of 21.5 A with a gain of a few nT/A took up part of that misfit (held-out gain 0.019,
//! where refitting the dead zone gains 0.041) and pulled the heating's offsets from the
//! generator's 0.06 / -0.04 / 0.08 µT/°C to 0.099 / -0.062 / 0.127. A term whose gain is
//! below that of a stated constant refitted within the statement's tolerance must now also
//! stand beside the constant so refitted (significant, and replicating there); the play does
//! not. Refusing such a term outright was tried first: it also refused a real 0.3 s late
//! magnetometer on the same probe (seed 2, gain 0.004 against the dead zone's 0.013), which
//! stands beside the refitted dead zone and is kept.

use magstand_standgen::Stand;
use magstand_tests::independent::{Mode, named_param, on_the_stair, run_case_on, suite_case};

#[test]
fn one_slow_cycle_with_a_true_stated_dead_zone_names_the_heating_alone() {
    let stand = on_the_stair(Stand::default(), "stair,10,25,10");
    let o = run_case_on(&stand, &suite_case("thermal drift"), Mode::Stated, 1);
    assert_eq!(o.verdict, ["thermal_drift"], "{}", o.diagnosis.summary());
    for (axis, generated) in ["x", "y", "z"].iter().zip([0.06, -0.04, 0.08]) {
        let p = named_param(
            &o.diagnosis,
            "thermal_drift",
            &format!("offset_ut_per_c_{axis}"),
        )
        .unwrap_or_else(|| panic!("no offset on {axis}: {}", o.diagnosis.summary()));
        let sd = p.sd.expect("an sd");
        assert!(
            (p.value - generated).abs() < 3.0 * sd,
            "{axis}: offset {} ± {sd} µT/°C, generated {generated}",
            p.value
        );
    }
}

#[test]
fn a_late_magnetometer_beside_a_better_refit_of_the_stated_dead_zone_is_still_named() {
    let stand = on_the_stair(Stand::default(), "stair,10,25,10");
    let o = run_case_on(&stand, &suite_case("time offset 0.3 s"), Mode::Stated, 2);
    assert_eq!(o.verdict, ["time_offset"], "{}", o.diagnosis.summary());
}
