//! Regression: the independent generator's stand driven by the paper's protocol (an
//! eight-level stair up and down, 6 s a level, at 50 Hz) instead of random steps had its
//! stated dead zone of 0.12, its true one, rejected and named `dead_zone` on every recording
//! (29 of 36 stated diagnoses wrong). Few distinct commands give the baseline a current law
//! of three powers of speed (so that the law cannot pass through every level and take up a
//! real dead zone's misfit); that cubic misfit the generator's current (a power 1.7 of the
//! command beyond its dead zone), and a dead zone fitted beside it moved to 0.155 to make up
//! for the law's shape, with an sd from the chi-square's curvature alone (0.0001). The dead
//! zone's uncertainty now holds the spread of its optimum over the laws up to one power of
//! speed more than the baseline's, where beside four powers it stays near the stated value;
//! a dead zone of 0.25 stated as 0.12 on the same stair is still named.
//!
//! On the generator's hexacopter (current `0.4 A + 11 A e^2.3`) on the same kind of stair,
//! the cubic then left a misfit in every stated recording's final residuals, named
//! `unexplained`: the law's shape, a constant nobody stated, now takes one more power where
//! that power takes up what would be named so.

use magstand_standgen::Stand;
use magstand_tests::independent::{Mode, named_param, on_a_stair, run_case_on, suite_case};

fn stated_on(stand: &Stand, label: &str) -> magstand_tests::independent::Outcome {
    run_case_on(stand, &suite_case(label), Mode::Stated, 1)
}

/// The suite case `label` on the default generator stand's stair, stated.
fn stated(label: &str) -> magstand_tests::independent::Outcome {
    stated_on(&on_a_stair(Stand::default()), label)
}

#[test]
fn a_stated_true_dead_zone_on_a_stair_is_not_named() {
    let o = stated("control");
    assert!(
        o.verdict.is_empty(),
        "stated control on a stair: {:?}\n{}",
        o.verdict,
        o.diagnosis.summary()
    );
    // The dead zone candidate was fitted and kept in the record as not rejecting the
    // statement, with an uncertainty that holds the law's shape.
    let note = o
        .diagnosis
        .rounds
        .iter()
        .flat_map(|r| &r.candidates)
        .find(|c| c.name == "dead_zone")
        .and_then(|c| c.note.clone())
        .unwrap_or_default();
    assert!(
        note.contains("do not reject the statement"),
        "dead_zone candidate's note: {note:?}"
    );
}

#[test]
fn a_stated_wrong_dead_zone_on_a_stair_is_still_named() {
    let o = stated("dead zone 0.25 (stated 0.12)");
    assert!(
        o.verdict.iter().any(|n| n == "dead_zone"),
        "stated 0.12, generated 0.25, on a stair: {:?}\n{}",
        o.verdict,
        o.diagnosis.summary()
    );
    let dz = named_param(&o.diagnosis, "dead_zone", "dead_zone").map(|p| p.value);
    assert!(
        dz.is_some_and(|v| (v - 0.25).abs() < 0.05),
        "fitted dead zone {dz:?}, generated 0.25"
    );
}

#[test]
fn a_steeper_current_law_on_a_stair_is_calibrated_not_unexplained() {
    let o = stated_on(&on_a_stair(Stand::held_out()), "control");
    assert!(
        o.verdict.is_empty(),
        "stated hexacopter control on a stair: {:?}\n{}",
        o.verdict,
        o.diagnosis.summary()
    );
    assert!(
        o.diagnosis
            .warnings
            .iter()
            .any(|w| w.contains("the current law takes 4 powers of speed")),
        "no word of the richer law: {:?}",
        o.diagnosis.warnings
    );
}
