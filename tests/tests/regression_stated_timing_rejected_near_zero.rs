//! Regression: a spin-up time the scenario states too slow was kept, and the misfit named
//! `unexplained`. On the first 80 s (3,999 rows) of the independent generator's default stand
//! at 50 Hz (seed 13, an effect-free control, whose current follows each command at once), a
//! scenario stating only `motors.spinup_tau_s = 0.05` (near the simulator's default) or
//! `0.3` gave `unexplained`, the held-out error 1.4 and 3.6 µT where the refitted spin-up left
//! 0.2 µT; so did the generator's stated stand with 0.3 s in place of its 1 ms. The refit lay
//! near the fastest spin-up searched, 1 ms, where a millisecond more or less changes nothing a
//! 50 Hz recording sees: the chi-square's curvature there gave an sd of 0.70 s (or none at the
//! bound), so the sd test could not reject the statement, and a refit ending at the bound was
//! refused as undetermined. The statement is now also tested by the chi-square itself (the fit
//! at the stated value against the refit's), and a stated spin-up refitted to the fastest one
//! searched is a limit, reported as such, not a refusal.
//!
//! The same with a late magnetometer: a scenario stating `logging.mag_delay_s = 0.2` on that
//! control (no delay) gave `unexplained`, 3.6 µT of held-out error: the delay refitted at 0 was
//! refused as "within one sample interval of zero", where a delay cannot be told from where
//! in its interval a command changed. That holds within an interval of the nominal delay, not
//! of zero: 0.2 s away from the statement, the refit is a finding.
//!
//! And with a lag of the currents (`motors.current_lag_s`, as an augmented scenario writes a
//! slow `current_lag`): 0.5 s stated on that control gave `time_offset, unexplained`, 3.3 µT
//! left, because the catalog's lag could only add to the stated one. A stated lag is now the
//! constant `current_lag` refits, and the refit replaces it.
use magstand_diagnose::{DiagnoseConfig, diagnose};
use magstand_sim::{Scenario, ValidScenario};
use magstand_standgen::Stand;
use magstand_tests::independent::{named_param, recording_on, suite_case};

/// Rows kept of the generated recording: 80 s at 50 Hz.
const ROWS_KEPT: usize = 3999;

fn checked(text: &str) -> ValidScenario {
    Scenario::from_toml_str(text, "stated stand")
        .and_then(|s| s.check("stated stand", None))
        .unwrap_or_else(|e| panic!("{e}\n{text}"))
}

/// A scenario that states the spin-up alone, `spinup_s`.
fn stating_only_the_spinup(spinup_s: f64) -> ValidScenario {
    checked(&format!(
        "name = \"s\"\n[program]\nkind = \"stair\"\nsteps = 4\ndwell_s = 5.0\n\
         [motors]\nspinup_tau_s = {spinup_s}\n"
    ))
}

/// The generator's stand as its stated scenario writes it, with the line stating its 1 ms
/// spin-up replaced by `motors` (lines of its `[motors]` table).
fn stating_the_stand_with(stand: &Stand, motors: &str) -> ValidScenario {
    let spinup = "spinup_tau_s = 0.001\n";
    let stated = stand.stated_scenario(stand.dead_zone);
    assert!(
        stated.contains(spinup),
        "the stated scenario states no 1 ms spin-up:\n{stated}"
    );
    checked(&stated.replace(spinup, motors))
}

/// The generator's stand as its stated scenario writes it, with the spin-up stated as
/// `spinup_s` instead of the 1 ms it states.
fn stating_the_stand_with_spinup(stand: &Stand, spinup_s: f64) -> ValidScenario {
    stating_the_stand_with(stand, &format!("spinup_tau_s = {spinup_s}\n"))
}

/// The first 80 s (3,999 rows) of the generator's default stand at 50 Hz, seed 13, in the
/// suite's case `label`, and that stand.
fn first_80_s_of(label: &str) -> (magstand_core::Recording, Stand) {
    let stand = Stand {
        rate_hz: 50.0,
        ..Stand::default()
    };
    let (whole, _) = recording_on(&stand, &suite_case(label), 13);
    let rec = whole.select_rows(|r| r < ROWS_KEPT);
    assert_eq!(rec.len(), ROWS_KEPT);
    (rec, stand)
}

/// [`first_80_s_of`] the effect-free control.
fn first_80_s_of_the_control() -> (magstand_core::Recording, Stand) {
    first_80_s_of("control")
}

/// [`first_80_s_of`] the case with a 0.5 s lag of the current behind each command.
fn first_80_s_with_a_half_second_lag() -> (magstand_core::Recording, Stand) {
    first_80_s_of("current lag 0.5 s")
}

#[test]
fn a_spin_up_stated_slower_than_the_data_allow_is_named_current_lag() {
    let (rec, stand) = first_80_s_of_the_control();
    let config = DiagnoseConfig::default().check().unwrap();
    for (what, nominal) in [
        ("0.05 s stated alone", stating_only_the_spinup(0.05)),
        ("0.3 s stated alone", stating_only_the_spinup(0.3)),
        (
            "0.3 s in the stated stand",
            stating_the_stand_with_spinup(&stand, 0.3),
        ),
    ] {
        let d = diagnose(&rec, "control", &nominal, &config).unwrap_or_else(|e| panic!("{e}"));
        assert_current_lag_refitted_to_none(&d, what);
    }
}

/// Asserts that `d` (of the control, which has no lag) names `current_lag` alone, its lag
/// refitted under 20 ms, and that the augmented stand leaves the noise (the generator's
/// 0.08 µT at rest and more under load), not a wrong statement's misfit (1.4 to 3.6 µT on x).
fn assert_current_lag_refitted_to_none(d: &magstand_diagnose::Diagnosis, what: &str) {
    assert_eq!(d.verdict, ["current_lag"], "{what}\n{}", d.summary());
    let p = named_param(d, "current_lag", "spinup_tau_s").expect("the refitted lag");
    assert!(
        p.value < 0.02,
        "{what}: refitted {} ± {:?} s, the generator has none\n{}",
        p.value,
        p.sd,
        d.summary()
    );
    let after = d.simulation.holdout_rmse_after_ut;
    assert!(
        after.iter().all(|&r| r < 0.3),
        "{what}: held-out RMSE after {after:?} µT\n{}",
        d.summary()
    );
}

#[test]
fn a_delay_stated_where_the_data_put_none_is_named_time_offset() {
    let (rec, _) = first_80_s_of_the_control();
    let config = DiagnoseConfig::default().check().unwrap();
    let nominal = checked(
        "name = \"s\"\n[program]\nkind = \"stair\"\nsteps = 4\ndwell_s = 5.0\n\
         [logging]\nmag_delay_s = 0.2\n",
    );
    let d = diagnose(&rec, "control", &nominal, &config).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(d.verdict, ["time_offset"], "{}", d.summary());
    let delay = named_param(&d, "time_offset", "mag_delay_s").expect("the refitted delay");
    assert!(
        delay.value.abs() < 0.03,
        "refitted {} ± {:?} s, the generator has none\n{}",
        delay.value,
        delay.sd,
        d.summary()
    );
    let stated = named_param(&d, "time_offset", "stated_mag_delay_s").expect("the statement");
    assert_eq!(stated.value, 0.2, "{}", d.summary());
    let after = d.simulation.holdout_rmse_after_ut;
    assert!(
        after.iter().all(|&r| r < 0.3),
        "held-out RMSE after {after:?} µT\n{}",
        d.summary()
    );
}

/// The generator's stand as its stated scenario writes it, with a lag of the currents stated
/// as `lag_s` beside its 1 ms spin-up.
fn stating_the_stand_with_current_lag(stand: &Stand, lag_s: f64) -> ValidScenario {
    stating_the_stand_with(
        stand,
        &format!("spinup_tau_s = 0.001\ncurrent_lag_s = {lag_s}\n"),
    )
}

#[test]
fn a_current_lag_stated_where_the_data_put_none_is_named_current_lag() {
    let (rec, stand) = first_80_s_of_the_control();
    let config = DiagnoseConfig::default().check().unwrap();
    for (what, nominal) in [
        (
            "0.5 s stated alone",
            checked(
                "name = \"s\"\n[program]\nkind = \"stair\"\nsteps = 4\ndwell_s = 5.0\n\
                 [motors]\ncurrent_lag_s = 0.5\n",
            ),
        ),
        (
            "0.5 s in the stated stand",
            stating_the_stand_with_current_lag(&stand, 0.5),
        ),
    ] {
        let d = diagnose(&rec, "control", &nominal, &config).unwrap_or_else(|e| panic!("{e}"));
        assert_current_lag_refitted_to_none(&d, what);
        let stated = named_param(&d, "current_lag", "stated_current_lag_s").expect("statement");
        assert_eq!(stated.value, 0.5, "{what}\n{}", d.summary());
    }
}

#[test]
fn a_current_lag_stated_as_the_data_have_it_stands_and_a_wrong_one_is_refitted() {
    let (rec, stand) = first_80_s_with_a_half_second_lag();
    let config = DiagnoseConfig::default().check().unwrap();
    let right = stating_the_stand_with_current_lag(&stand, 0.5);
    let d = diagnose(&rec, "lag", &right, &config).unwrap_or_else(|e| panic!("{e}"));
    assert!(d.verdict.is_empty(), "0.5 s stated\n{}", d.summary());
    let wrong = stating_the_stand_with_current_lag(&stand, 0.15);
    let d = diagnose(&rec, "lag", &wrong, &config).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(d.verdict, ["current_lag"], "0.15 s stated\n{}", d.summary());
    assert_lag_refitted_at_half_a_second(&d, "0.15 s stated");
}

/// Asserts that `d` refitted `current_lag` within 3 sd (at least 0.02 s) of the generator's
/// 0.5 s.
fn assert_lag_refitted_at_half_a_second(d: &magstand_diagnose::Diagnosis, what: &str) {
    let refit = named_param(d, "current_lag", "spinup_tau_s").expect("the refitted lag");
    let sd = refit.sd.expect("an sd of the refitted lag");
    assert!(
        (refit.value - 0.5).abs() < 3.0 * sd.max(0.02),
        "{what}: refitted {} ± {sd} s, the generator's 0.5 s\n{}",
        refit.value,
        d.summary()
    );
}

/// A spin-up stated where the recording has none, beside the slow lag it has: the lag was
/// refitted with the stated 0.06 s kept in series behind it, and the misfit of that second
/// lag went to a `time_offset` of about -0.06 s and `unexplained`. The richer form without
/// the stated spin-up is kept where the data ask for it.
#[test]
fn a_slow_lag_beside_a_spin_up_stated_wrong_is_the_only_lag() {
    let (rec, stand) = first_80_s_with_a_half_second_lag();
    let config = DiagnoseConfig::default().check().unwrap();
    let nominal = stating_the_stand_with_spinup(&stand, 0.06);
    let d = diagnose(&rec, "lag", &nominal, &config).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(d.verdict, ["current_lag"], "{}", d.summary());
    let lag = &d.effects[0];
    assert_eq!(
        lag.form.as_deref(),
        Some("without_stated_spinup"),
        "{}",
        d.summary()
    );
    assert_lag_refitted_at_half_a_second(&d, "0.06 s spin-up stated");
}

/// The other side of the test above, on magstand's simulator, whose rotors do spin up: a
/// stated spin-up of 0.06 s that the stand has, beside a 0.5 s lag of its currents, stays
/// behind the refitted lag (the richer form does not lower the held-out error beyond it).
#[test]
fn a_slow_lag_beside_a_spin_up_stated_right_keeps_it() {
    let stand = "name = \"s\"\n[program]\nkind = \"stair\"\noff_s = 10.0\nsteps = 10\n\
                 dwell_s = 8.0\ndirection = \"up_down\"\nrepeats = 2\n\
                 [supply]\nkind = \"bench\"\nvoltage_v = 12.0\n\
                 [motors]\ndead_zone = 0.37\nspinup_tau_s = 0.06\n\
                 [magnetometer]\nodr_hz = 50.0\n[logging]\nrecord_power = false\n";
    let lagged = checked(&stand.replace(
        "spinup_tau_s = 0.06\n",
        "spinup_tau_s = 0.06\ncurrent_lag_s = 0.5\n",
    ));
    let rec = magstand_sim::simulate(&lagged, 1);
    let config = DiagnoseConfig::default().check().unwrap();
    let d = diagnose(&rec, "lag", &checked(stand), &config).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(d.verdict, ["current_lag"], "{}", d.summary());
    assert_eq!(d.effects[0].form, None, "{}", d.summary());
    let refused = d
        .rounds
        .iter()
        .flat_map(|r| &r.candidates)
        .find(|c| c.form.as_deref() == Some("without_stated_spinup"))
        .unwrap_or_else(|| panic!("the richer form was not tried\n{}", d.summary()));
    assert!(
        refused
            .note
            .as_deref()
            .is_some_and(|n| n.starts_with("refused")),
        "{refused:?}"
    );
}
