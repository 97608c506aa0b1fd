//! Regression: the automatic choice judged every family on the identification split's
//! held-out rows *and* the physics split's, even when the physics was not tried. The physics
//! split closes gaps, so after a gap (two flights in one log) its blocks fell out of step
//! with the identification split's and the two agreed on few rows: log171 was judged on 120
//! of its 448 held-out rows. Without the physics family the judging rows are now exactly the
//! identification fit's held-out rows.
use magstand_core::Quat;
use magstand_diagnose::model_choice::{DisturbanceModel, choose_model};
use magstand_diagnose::unstated_nominal;
use magstand_tests::independent::{Case, recording};

#[test]
fn a_gap_does_not_shrink_the_rows_the_families_are_judged_on() {
    let case = Case {
        label: "two flights",
        effects: vec![],
        log_bat_v: true,
        log_temp: false,
    };
    let (mut rec, _) = recording(&case, 61);
    // Two flights ten minutes apart, their rows marked as flight.
    let half = rec.len() / 2;
    for t in rec.t_s.iter_mut().skip(half) {
        *t += 600.0;
    }
    rec.attitude = Some(vec![Quat::identity(); rec.len()]);
    rec.extra
        .push(("segment".into(), vec!["flight".to_string(); rec.len()]));
    let (chosen, choice) = choose_model(&rec, "two flights", &unstated_nominal().unwrap(), None)
        .unwrap_or_else(|e| panic!("{e}"));
    let DisturbanceModel::LocalLinear(model) = chosen else {
        panic!("a flight got the physics: {choice:?}")
    };
    let held = model.summary.as_ref().unwrap().holdout_rows;
    assert_eq!(
        choice.holdout_rows, held,
        "judged on {} rows, the fit held out {held}",
        choice.holdout_rows
    );
}
