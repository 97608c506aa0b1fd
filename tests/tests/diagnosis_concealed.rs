//! Fast subset of the concealed-effect suite (one seed per case, a few cases): the diagnosis
//! is never told which effect was switched on. The full suite, every case with five seeds, is
//! `cargo run --release -p magstand-tests --bin concealed-suite` (results/diagnosis.md).
use magstand_tests::concealed::{Outcome, cases, run_case};

fn case(label: &str, seed: u64) -> Outcome {
    let c = cases()
        .into_iter()
        .find(|c| c.label == label)
        .unwrap_or_else(|| panic!("no case {label}"));
    run_case(&c, seed)
}

fn assert_found(o: &Outcome) {
    assert!(
        o.named_right && o.param_failures.is_empty() && o.improved,
        "{} seed {}: verdict {:?}, parameter misses {:?}, improved {}\n{}",
        o.label,
        o.seed,
        o.verdict,
        o.param_failures,
        o.improved,
        o.diagnosis.summary()
    );
}

#[test]
fn an_effect_free_recording_with_power_and_temperature_columns_comes_out_clean() {
    assert_found(&case("control, bat_v and temp_c logged", 11));
}

#[test]
fn a_stand_unlike_the_nominal_in_its_constants_comes_out_clean() {
    assert_found(&case("control, constants unlike the nominal (100 Hz)", 16));
}

#[test]
fn a_slow_spin_up_is_named_current_lag_with_its_time_constant() {
    assert_found(&case("current_lag", 12));
}

#[test]
fn board_heating_without_a_temperature_column_is_named_thermal_drift() {
    assert_found(&case("thermal_drift", 13));
}

#[test]
fn two_effects_at_once_are_both_found() {
    assert_found(&case("thermal_drift + current_lag", 14));
}

#[test]
fn a_field_outside_the_catalog_is_called_unexplained_not_forced_onto_a_name() {
    assert_found(&case(
        "outside the catalog (external alternating field)",
        15,
    ));
}

/// Regression: with the replication rule's third condition read as "the held-out error drops
/// on every axis the term changes", the dead zone of this recording (0.45 against the stated
/// 0.37, p = 4e-24 over all axes) was refused because its y axis went from 0.5112 to
/// 0.5128 µT, a rise well within the held-out error's own noise, and the verdict was
/// `unexplained`. A claimed axis now refuses a term only where it gets significantly worse.
#[test]
fn a_rejected_stated_dead_zone_is_named_though_one_axis_barely_moves() {
    assert_found(&case("dead_zone", 3));
}

/// A LiPo pack without `bat_v` on magstand's own stand, whose motor is the nominal one: the
/// battery's richer form (a free discharge shape and voltage sensitivity, for stands whose
/// physics is not the nominal's) does not lower the held-out error beyond the catalog's form
/// here, and is refused; the capacity is the catalog form's, within the suite's tolerance.
/// Kept with that form, the extra freedom traded against the resistance and capacity (they
/// went to the edge of their range, or the capacity to 1.4 or 10 Ah against the pack's 6).
#[test]
fn a_lipo_battery_without_bat_v_keeps_the_catalog_form_and_its_capacity() {
    let o = case("battery_sag", 3);
    assert_found(&o);
    let refused = o.diagnosis.rounds.iter().any(|r| {
        r.candidates.iter().any(|c| {
            c.name == "battery_sag"
                && c.note.as_deref().is_some_and(|n| {
                    n.contains("`free_discharge` does not lower the held-out error")
                })
        })
    });
    assert!(refused, "{:#?}", o.diagnosis.rounds);
}
