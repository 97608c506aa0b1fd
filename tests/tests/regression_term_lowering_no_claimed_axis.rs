//! Regression: a term that raised the held-out error on every axis it claimed was named. On the
//! independent generator's default stand sampled at 50 Hz with a 0.3 s late magnetometer and
//! nothing stated (seed 13, a configuration first run as a held-out check), the verdict was
//! `time_offset, motor_asymmetry`. Each motor's field at its largest current lay within one sd
//! of zero, and the augmented model's held-out RMSE rose on both axes it claimed (x 0.293 ->
//! 0.296, z 0.398 -> 0.402 µT); yet its held-out gain, weighted by each row's inverse noise
//! variance, was significant (p 4e-11), won at the few quiet rows at steps that a delay one
//! sample early leaves off. The replication rule refused only a *significant* worsening on a
//! claimed axis; a term must now also lower the held-out error on at least one of them.

use magstand_standgen::Stand;
use magstand_tests::independent::{Mode, run_case_on, suite_case};

#[test]
fn a_term_raising_the_held_out_error_where_it_acts_is_refused() {
    let stand = Stand {
        rate_hz: 50.0,
        ..Stand::default()
    };
    let o = run_case_on(&stand, &suite_case("time offset 0.3 s"), Mode::Unstated, 13);
    assert_eq!(o.verdict, ["time_offset"], "{}", o.diagnosis.summary());
    let refused = o
        .diagnosis
        .rounds
        .iter()
        .flat_map(|r| &r.candidates)
        .filter(|c| c.name == "motor_asymmetry")
        .filter_map(|c| c.note.as_deref())
        .any(|n| n.contains("falls on none of the axes"));
    assert!(refused, "{}", o.diagnosis.summary());
}
