//! Regression: the independent generator's default stand driven by the paper's protocol (an
//! eight-level stair up and down, 6 s a level, at 50 Hz) with a play of 3 A on its total
//! current got `thermal_drift` beside `hysteresis`, on both seeds, without a scenario: on one
//! the drift was even named first. The diagnosis's play acted on the nominal motor's current,
//! whose shape over the command is not the generator's (a 1.7th power beyond its dead zone).
//! A play moves its output only where the current changes by more than its width, which on a
//! stair of such another shape happens at other levels; a heating lag of 19 s fitted the loop
//! as well as that play (held-out gains 1.100 against 1.090), and the play found was 1.3 A.
//! The play now acts on the stand's current as the calibrated baseline's law has it
//! (`Context::current_law`), and the model file carries that law (`current_law`).

use magstand_standgen::Stand;
use magstand_tests::independent::{
    Mode, assert_the_model_file_follows_its_law, named_param, on_a_stair, run_case_on, suite_case,
};

#[test]
fn a_play_on_a_stair_is_named_alone_and_its_loop_has_the_generated_size() {
    let case = suite_case("hysteresis");
    let stand = on_a_stair(Stand::default());
    let o = run_case_on(&stand, &case, Mode::Unstated, 1);
    assert_eq!(o.verdict, ["hysteresis"], "{}", o.diagnosis.summary());
    // The play's width is in the calibrated current's amperes, whose scale without a logged
    // current is the nominal motor's; the loop's field, play times gain, is the stand's.
    let param = |name: &str| {
        named_param(&o.diagnosis, "hysteresis", name)
            .unwrap_or_else(|| panic!("no {name}: {}", o.diagnosis.summary()))
            .value
    };
    let play_a = param("play_a");
    let generated_ut = [3.0 * 0.05, 3.0 * 0.04, 3.0 * -0.06];
    for (axis, generated) in ["x", "y", "z"].iter().zip(generated_ut) {
        let loop_ut = play_a * param(&format!("gain_ut_per_a_{axis}"));
        assert!(
            (loop_ut - generated).abs() < 0.15 * generated.abs(),
            "{axis}: play {play_a} A x gain = {loop_ut} µT, generated {generated} µT"
        );
    }
    // The model file follows the same current: on an unseen seed it predicts the
    // disturbance, and worse on the replayed current in its place.
    assert_the_model_file_follows_its_law(&o, &stand, &case, 2);
}
