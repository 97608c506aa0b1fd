//! Recordings magstand did not make: the independent stand generator (`tests/standgen`, no
//! magstand crate inside) writes the documented recording format from its own laws, and
//! magstand reads it and identifies its disturbance. The full diagnosis suite on these
//! recordings, with its confusion matrices, is
//! `cargo run --release -p magstand-tests --bin independent-suite` (results/diagnosis-independent.md).
use magstand_ident::{Dataset, Fit, FitConfig, InputKind};
use magstand_standgen::Stand;
use magstand_tests::independent::{
    Case, ROWS, assert_scale_free_axes, named_param, recording, rmse_ut, suite_case,
};

fn control(log_bat_v: bool) -> Case {
    Case {
        label: "control",
        effects: vec![],
        log_bat_v,
        log_temp: false,
    }
}

/// The effect of that name in a diagnosis, if it was named.
fn named<'d>(
    d: &'d magstand_diagnose::Diagnosis,
    name: &str,
) -> Option<&'d magstand_diagnose::diagnosis::EffectReport> {
    d.effects.iter().find(|e| e.name == name)
}

/// The calibrated stand constant `key` of `d` (its scenario key, e.g. `motors.dead_zone`).
fn calibrated<'d>(d: &'d magstand_diagnose::Diagnosis, key: &str) -> &'d magstand_diagnose::Param {
    d.baseline
        .calibration
        .iter()
        .find(|p| p.name == key)
        .unwrap_or_else(|| panic!("no calibrated {key}: {}", d.summary()))
}

/// The suite case labelled `label`, seed 1, on `stand` sampled at `rate_hz`, diagnosed
/// without a scenario.
fn unstated_at(stand: Stand, rate_hz: f64, label: &str) -> magstand_tests::independent::Outcome {
    diagnosed_at(
        stand,
        rate_hz,
        label,
        magstand_tests::independent::Mode::Unstated,
    )
}

/// [`unstated_at`], the stand given as `mode` says.
fn diagnosed_at(
    stand: Stand,
    rate_hz: f64,
    label: &str,
    mode: magstand_tests::independent::Mode,
) -> magstand_tests::independent::Outcome {
    let stand = Stand { rate_hz, ..stand };
    magstand_tests::independent::run_case_on(&stand, &suite_case(label), mode, 1)
}

/// Asserts that `o`'s verdict names exactly `expected` (sorted, in any order), printing
/// `what` and the diagnosis where it does not.
fn assert_named_exactly(o: &magstand_tests::independent::Outcome, expected: &[&str], what: &str) {
    let mut verdict = o.verdict.clone();
    verdict.sort();
    assert_eq!(verdict, expected, "{what}\n{}", o.diagnosis.summary());
}

/// Asserts that `d` names a `current_lag` whose time constant lies within `tolerance_s` of the
/// generator's 0.5 s, printing `what`, the value and its sd where it does not.
fn assert_lag_within(d: &magstand_diagnose::Diagnosis, tolerance_s: f64, what: &str) {
    let p = named_param(d, "current_lag", "spinup_tau_s").expect("the lag");
    assert!(
        (p.value - 0.5).abs() < tolerance_s,
        "{what}: lag {} ± {:?} s, generated 0.5 s",
        p.value,
        p.sd
    );
}

/// Whether a candidate `name` of some round was refused with a note that `says` accepts.
fn refused_with(d: &magstand_diagnose::Diagnosis, name: &str, says: impl Fn(&str) -> bool) -> bool {
    d.rounds
        .iter()
        .flat_map(|r| &r.candidates)
        .any(|c| c.name == name && c.note.as_deref().is_some_and(&says))
}

#[test]
fn the_generator_depends_on_no_magstand_crate() {
    let manifest =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/standgen/Cargo.toml"))
            .unwrap();
    let deps = manifest
        .split("[dependencies]")
        .nth(1)
        .expect("a [dependencies] table")
        .split("\n[")
        .next()
        .unwrap();
    assert!(
        deps.lines()
            .all(|l| l.trim().is_empty() || l.trim().starts_with('#')),
        "the independent generator must stay independent:\n{deps}"
    );
}

#[test]
fn its_recordings_read_as_documented() {
    let (rec, truth) = recording(&control(true), 3);
    assert_eq!(rec.len(), ROWS);
    assert_eq!(rec.motor_count(), 4);
    assert!(rec.bat_v.is_some() && rec.bat_a.is_some() && rec.temp_c.is_none());
    assert_eq!(truth.len(), ROWS);
    // Motors off: no current, so no disturbance, in the generator's own truth.
    let off: Vec<usize> = (0..rec.len())
        .filter(|&r| rec.thr.iter().all(|m| m[r] == 0.0))
        .collect();
    assert!(off.len() > ROWS / 20, "{} motors-off rows", off.len());
    assert!(off.iter().all(|&r| truth[r] == [0.0; 3]));
}

/// Identified on one recording, judged against the generator's truth on another (another
/// seed: other commands, other noise): the default fit follows a disturbance whose law it was
/// not written for to within 2 % of the disturbance's own size on every axis.
#[test]
fn the_default_fit_recovers_a_foreign_disturbance() {
    let (ident, _) = recording(&control(false), 11);
    let (valid, truth) = recording(&control(false), 12);
    let data = Dataset::from_recording(&ident, InputKind::Throttle, "ident").unwrap();
    let model = FitConfig::automatic().check().unwrap().fit(&data).unwrap();
    let err = rmse_ut(&model.dist_column(&valid), &truth);
    let size: [f64; 3] = std::array::from_fn(|a| {
        (truth.iter().map(|t| t[a] * t[a]).sum::<f64>() / truth.len() as f64).sqrt()
    });
    for a in 0..3 {
        assert!(
            err[a] < 0.02 * size[a],
            "axis {a}: RMSE {:.4} µT against a disturbance of RMS {:.3} µT (all axes: {err:?} vs {size:?})",
            err[a],
            size[a]
        );
    }
}

/// Diagnosed as a user without a scenario would: the generator's dead zone (0.12, the
/// default's is 0.37) and its missing spin-up are unknown constants, calibrated under
/// `baseline.calibration`, never named; a 0.5 s current lag is slower than any spin-up and
/// is named.
///
/// Regression: before the calibration rule every recording here, the effect-free controls
/// included, was named `current_lag` and `dead_zone`.
#[test]
fn unstated_constants_are_calibrated_and_a_slow_lag_is_still_named() {
    use magstand_tests::independent::{Mode, run_case};
    let o = run_case(
        &suite_case("control, bat_v and temp_c logged"),
        Mode::Unstated,
        1,
    );
    assert!(
        o.verdict.is_empty(),
        "control named {:?}\n{}",
        o.verdict,
        o.diagnosis.summary()
    );
    let calibrated: Vec<&str> = o
        .diagnosis
        .baseline
        .calibration
        .iter()
        .map(|p| p.name.as_str())
        .collect();
    assert!(
        calibrated.contains(&"motors.dead_zone"),
        "the dead zone is not calibrated: {calibrated:?}"
    );
    let o = run_case(&suite_case("current lag 0.5 s"), Mode::Unstated, 2);
    let tau = named(&o.diagnosis, "current_lag")
        .and_then(|e| e.params.first())
        .map(|p| p.value);
    assert!(
        tau.is_some_and(|t| t > magstand_diagnose::effects::MAX_SPINUP_S),
        "lag {tau:?}: {:?}\n{}",
        o.verdict,
        o.diagnosis.summary()
    );
    // The generator lags the current itself, and a lag beyond any spin-up is modelled so
    // (the field of the currents follows them through it). Regression: modelled as a slow
    // spin-up (the current of a lagged speed, another curve), it calibrated to 0.308 s here.
    assert!(
        tau.is_some_and(|t| (t - 0.5).abs() < 0.05),
        "lag {tau:?} s, generated 0.5 s"
    );
    assert!(
        !o.verdict.iter().any(|n| n == "dead_zone"),
        "{:?}",
        o.verdict
    );
}

/// Regression: beside a 0.5 s current lag the independent stand's recordings (seeds 1 and 2,
/// unstated and stated) were also called `hysteresis` and `unexplained`. Three things were
/// missing from the lag's model: its steps began up to a sample late (each lagged column held
/// its earlier value over the whole interval, not from where the replay put the command's
/// change), the nominal 0.06 s spin-up nobody stated stayed in the replay beside the lag, and
/// a field nonlinear in the current (this generator's squares the lagged total current)
/// follows the lagged current through its curve, which the lagged law columns do not form.
///
/// And its model file: written with every scenario key, it was read back with every key
/// stated, so the unstated spin-up the diagnosis had replaced came back at 0.06 s and the file
/// predicted the disturbance 15 times worse than the diagnosis's own model (0.85 against
/// 0.057 µT on z). The file now records which keys were stated.
#[test]
fn a_slow_lag_is_named_alone_and_its_model_file_predicts_it() {
    use magstand_tests::independent::{Mode, run_case};
    let case = suite_case("current lag 0.5 s");
    let o = run_case(&case, Mode::Unstated, 1);
    assert_eq!(o.verdict, ["current_lag"], "{}", o.diagnosis.summary());
    let tau = named(&o.diagnosis, "current_lag").map(|e| e.params[0].value);
    assert!(
        tau.is_some_and(|t| (t - 0.5).abs() < 0.01),
        "lag {tau:?} s, generated 0.5 s"
    );
    let model = o.diagnosis.model.clone().expect("a model");
    let path = std::env::temp_dir().join(format!("magstand-slow-lag-{}.json", std::process::id()));
    model.save(&path).unwrap();
    let loaded = magstand_diagnose::AugmentedModel::load(&path);
    std::fs::remove_file(&path).ok();
    let loaded = loaded.unwrap();
    let (rec, truth) = recording(&case, 1);
    let error_ut = |m: &magstand_diagnose::AugmentedModel| -> [f64; 3] {
        rmse_ut(&m.dist_column(&rec, "seen.csv").unwrap(), &truth)
    };
    let read_back = error_ut(&loaded);
    assert!(
        read_back.iter().all(|e| *e < 0.1),
        "the model file predicts the disturbance within {read_back:?} µT"
    );
    // Read as a file without the record (every key stated), the nominal spin-up returns.
    let every_key_stated = magstand_diagnose::AugmentedModel {
        stated_keys: None,
        ..loaded
    };
    let old = error_ut(&every_key_stated);
    assert!(
        old[2] > 4.0 * read_back[2],
        "every key stated: {old:?} µT against {read_back:?}"
    );
}

/// Regression: on a stand whose current follows each command at once (this generator's),
/// the calibrated spin-up stopped at the 5 ms end of its search range. At 75 Hz a 5 ms lag
/// leaves 7 % of every step for the first sample after it (up to 4 µT), and three of four
/// effect-free controls were named `unexplained` for it. The range now reaches 1 ms, and the
/// spin-up calibrates below 5 ms.
#[test]
fn a_stand_without_spin_up_is_followed_at_every_step() {
    use magstand_tests::independent::{Mode, run_case};
    let o = run_case(&control(false), Mode::Unstated, 2);
    assert!(
        o.verdict.is_empty(),
        "control named {:?}\n{}",
        o.verdict,
        o.diagnosis.summary()
    );
    let spinup = o
        .diagnosis
        .baseline
        .calibration
        .iter()
        .find(|p| p.name == "motors.spinup_tau_s")
        .map(|p| p.value);
    assert!(
        spinup.is_some_and(|t| t < 0.005),
        "spin-up calibrated to {spinup:?}"
    );
    // The current law's bend that remains is significant at 25,000 rows but carries a few
    // percent of the residual's variance: said in the warnings, with its share, not named.
    assert!(
        o.diagnosis
            .warnings
            .iter()
            .any(|w| w.contains("small structure") && w.contains("share")),
        "warnings {:?}",
        o.diagnosis.warnings
    );
    // What is left there is significant but small, and written as a warning; a field the
    // catalog does not hold (0.6 µT, 7 s period) still carries far more than the tenth of the
    // residual's variance that `unexplained` needs.
    let periodic = Case {
        label: "outside the catalog (periodic field)",
        effects: vec![magstand_standgen::Effect::PeriodicInterference {
            amplitude_ut: [0.6, -0.4, 0.5],
            period_s: 7.0,
        }],
        log_bat_v: false,
        log_temp: false,
    };
    let o = run_case(&periodic, Mode::Unstated, 2);
    assert_eq!(o.verdict, ["unexplained"], "{}", o.diagnosis.summary());
}

/// Three regressions on one recording of a sagging 4S battery (16.8 V full, 0.045 ohm), its
/// voltage logged:
///
/// - this generator's current follows its supply voltage linearly, the nominal motor's about
///   as its square. Once the spin-up could calibrate down to 1 ms, following the logged
///   voltage through the nominal motor made the held-out fit worse, and a battery that sags
///   by 2 V was not named (`thermal_drift` took its slow part). The voltage's steepness is
///   now calibrated with `battery_sag` (a free gain on the current times the voltage's
///   relative change);
/// - the battery reported beside `battery_sag` kept the nominal 12 V supply's three cells,
///   full, whatever the log said, and its resistance and capacity went to the ends of their
///   search ranges (0.003 ohm, 30 Ah). The pack now follows the logged voltage;
/// - `thermal_drift` was named beside `battery_sag` (tau 230 s, 1 % of the held-out rms): one
///   free gain on the current times the voltage's change could not follow how a field that is
///   a nonlinear function of the current (this generator's has a term in the total current
///   squared) moves with the voltage, and the slow remainder looked like heating. The
///   voltage's change now multiplies each column of the calibrated current law.
#[test]
fn a_sagging_battery_is_named_whatever_its_current_law_makes_of_the_voltage() {
    use magstand_tests::independent::{Mode, run_case};
    let o = run_case(&suite_case("battery sag"), Mode::Unstated, 1);
    let sag = named(&o.diagnosis, "battery_sag")
        .unwrap_or_else(|| panic!("{:?}\n{}", o.verdict, o.diagnosis.summary()));
    let param = |name: &str| sag.params.iter().find(|p| p.name == name).map(|p| p.value);
    assert_eq!(param("cells"), Some(4.0), "{:?}", sag.params);
    let r = param("internal_resistance_ohm").unwrap();
    assert!(
        (0.02..0.09).contains(&r),
        "internal resistance {r} ohm, generated 0.045 ohm: {:?}",
        sag.params
    );
    assert_eq!(o.verdict, ["battery_sag"], "{}", o.diagnosis.summary());
}

/// Regression: a spin-up calibrated at the fastest one searched (1 ms, on the generator's
/// stands, whose current follows each command at once) was reported with the chi-square's
/// curvature there as its sd: on the held-out hexacopter's control, seed 2, 0.001 +- 0.334 s,
/// an sd a hundred times the spin-up of the slowest propeller. At the edge of its range the
/// value is a limit, not an estimate: it has no sd, and its basis says which edge.
#[test]
fn a_spin_up_at_the_edge_of_its_range_is_a_limit_without_an_sd() {
    use magstand_tests::independent::{Mode, run_case_on};
    let o = run_case_on(&Stand::held_out(), &control(false), Mode::Unstated, 2);
    let spinup = calibrated(&o.diagnosis, "motors.spinup_tau_s");
    assert!(
        spinup.value <= 0.00102
            && spinup.sd.is_none()
            && spinup.basis.as_deref().is_some_and(|b| b.contains("edge")),
        "{spinup:?}"
    );
    // The text summary shows the calibrated constants and what each rests on.
    let summary = o.diagnosis.summary();
    assert!(
        summary.contains("calibrated, not stated: motors.spinup_tau_s = 0.0010 s")
            && summary.contains("motors.spinup_tau_s rests on the edge"),
        "{summary}"
    );
}

/// Regression: a calibrated dead zone whose chi-square is about as flat over its whole search
/// range as the noise allows was reported with the curvature's sd, wider than the range: on
/// the generator's default stand, control seed 1, 0.060 +- 1.96 for a dead zone searched over
/// 0 to 0.6. Such an sd only says the data do not determine the value there: it is now no
/// sd, with that as its basis (unit test `undetermined_within`'s). Since the thirty-fifth
/// session refines the terms again under their model's own weights, the same control's dead
/// zone is determined (0.128 +- 0.08 under the laws' shapes; the generator's is 0.12): the
/// report holds either way, an sd within the range or none with the reason.
#[test]
fn a_dead_zone_the_data_do_not_determine_within_its_range_has_no_sd() {
    use magstand_tests::independent::{Mode, run_case_on};
    let o = run_case_on(&Stand::default(), &control(false), Mode::Unstated, 1);
    let dz = calibrated(&o.diagnosis, "motors.dead_zone");
    let undetermined = |b: &str| b.contains("0 to 0.6") && b.contains("wider than the range");
    assert!(
        (0.0..=0.6).contains(&dz.value)
            && match dz.sd {
                Some(sd) => sd <= 0.6,
                None => dz.basis.as_deref().is_some_and(undetermined),
            },
        "{dz:?}"
    );
}

/// Regression: the dead zone calibrated on a stand nobody described was reported with the
/// curvature of the chi-square at its optimum as its sd, under one shape of the current law.
/// The law's shape is calibrated too, and not stated; a current that rises slowly from its
/// dead zone looks like a later start, so the optimum moves with the law's shape far beyond
/// that sd. On the generator's hexacopter control (dead zone 0.06), seed 1: 0.146 +- 0.0009,
/// 95 sd from the truth, while laws of three and four powers of speed put the optimum at 0 and
/// 0.18. The sd now holds half the spread of the optimum over the laws of fewer powers, and
/// the value says what it rests on. (Over the suite's 68 recordings with a calibrated dead
/// zone, both stands, seeds 1 and 2, the generator's dead zone lies within 2 sd on 38, 9
/// before: the bias of a law that cannot follow a slow rise remains; see the README.)
#[test]
fn a_calibrated_dead_zone_holds_the_spread_over_the_current_laws_shapes() {
    use magstand_tests::independent::{Mode, run_case_on};
    let stand = Stand::held_out();
    let o = run_case_on(&stand, &suite_case("control"), Mode::Unstated, 1);
    assert_dead_zone_within(&o, &stand, 2.0, "current law");
}

/// Asserts that `o`'s calibrated dead zone lies within `sds` of its sd from `stand`'s, and
/// that its basis mentions `basis`.
fn assert_dead_zone_within(
    o: &magstand_tests::independent::Outcome,
    stand: &Stand,
    sds: f64,
    basis: &str,
) {
    let dz = calibrated(&o.diagnosis, "motors.dead_zone");
    let sd = dz.sd.unwrap_or_else(|| panic!("{dz:?} has no sd"));
    assert!(
        (dz.value - stand.dead_zone).abs() <= sds * sd
            && dz.basis.as_deref().is_some_and(|b| b.contains(basis)),
        "dead zone {} +- {sd}, the generator's {} (within {sds} sd, basis on {basis:?}): {dz:?}",
        dz.value,
        stand.dead_zone
    );
}

/// Regression: the spread of a calibrated dead zone over the current laws' shapes took the laws
/// with the linear power only. On the generator's default stand at 50 Hz (hysteresis, seed 1,
/// no logged command between 0 and 0.161, a current rising as the 1.7th power of the drive
/// above the generator's dead zone of 0.12) every one of them placed the dead zone at 0.200,
/// a logged level, and it was reported as 0.200 +- 0.0007, 121 sd from the truth. A law
/// without the linear power (idle current and the propeller's load) is as plausible a shape,
/// and the one of the baseline's top power places it at 0.08: a calibration's sd now holds
/// the spread over both families. Over the random-step suites' 108 unstated recordings (three
/// stands at 50 Hz, seeds 1 and 2) the generator's dead zone was more than 3 sd off on 40,
/// and is on 10 (`results/diagnosis-independent.md`).
#[test]
fn a_calibrated_dead_zone_holds_the_laws_without_the_linear_power() {
    let stand = Stand::default();
    let o = unstated_at(stand.clone(), 50.0, "hysteresis");
    assert_named_exactly(
        &o,
        &["hysteresis"],
        "default stand at 50 Hz, seed 1, unstated",
    );
    assert_dead_zone_within(&o, &stand, 3.0, "without the linear power");
}

/// Regression: a play's width was reported in amperes with the curvature's sd, where the
/// amperes are the nominal motor's: the field calibrates the current's shape, not its scale,
/// and the current law's amperes come from a least-squares match to the nominal motor's
/// current. On the generator's hexacopter (a play of 3 A on a total of up to 68 A, no current
/// logged) it read 4.53 +- 0.049 A, 31 sd off, and on its octocopter 5.4 to 5.8 A. Where no
/// current is logged and the scenario does not state the motor's constants, the play and its
/// gains now have no sd and say what they rest on, and `play_fraction`, the play over the
/// largest current the recording draws in the same amperes, does not rest on the scale (12
/// diagnoses of three stands' plays: within a fifth of the generator's share).
#[test]
fn a_plays_amperes_rest_on_the_nominal_motor_and_its_share_of_the_current_does_not() {
    use magstand_tests::independent::{Mode, run_case_on};
    let stand = Stand::held_out();
    let o = run_case_on(&stand, &suite_case("hysteresis"), Mode::Unstated, 1);
    assert_named_exactly(&o, &["hysteresis"], "hexacopter, seed 1, unstated");
    let play = named_param(&o.diagnosis, "hysteresis", "play_a").expect("the play");
    assert!(
        play.sd.is_none()
            && play
                .basis
                .as_deref()
                .is_some_and(|b| b.contains("nominal motor's")),
        "{play:?}"
    );
    let share = named_param(&o.diagnosis, "hysteresis", "play_fraction").expect("its share");
    // The generator's play over its largest total current (every motor at full command).
    let largest_a = stand.motors as f64 * (stand.idle_a + stand.full_a);
    let truth = 3.0 / largest_a;
    assert!(
        (share.value / truth - 1.0).abs() < 0.2,
        "play share {} against the generator's {truth} (3 A of {largest_a} A): {share:?}",
        share.value
    );
}

/// Regression: with `bat_v` and `bat_a` logged, the pack reported beside `battery_sag` was the
/// one that gives the logged voltage through the simulator's motors' current, with the
/// chi-square's curvature as its sd: on the held-out hexacopter (6S, 4 Ah, 0.03 ohm) the
/// resistance was 0.0036 +- 0.0000007 ohm and the capacity 20.8 +- 0.00003 Ah, and the
/// default stand's capacity 2.14 +- 0.00003 Ah against its 1.3. The resistance and the
/// open-circuit voltage's fall per ampere-hour drawn now come from the logged voltage and
/// current, whatever the motors draw and whatever the pack's chemistry, with an sd that holds
/// the spread of the run's halves (the default stand's pack empties two thirds of the way
/// through, where its voltage stops falling). The capacity is the LiPo curve's scale: it has
/// no sd, and says what it rests on.
#[test]
fn a_logged_packs_resistance_and_fall_are_its_own_whatever_the_motors_draw() {
    use magstand_standgen::Supply;
    use magstand_tests::independent::{Mode, run_case_on};
    for stand in [Stand::default(), Stand::held_out()] {
        let Supply::Battery { resistance_ohm, .. } = stand.battery else {
            panic!("the generator's stands have a battery: {:?}", stand.battery)
        };
        let fall_v_per_ah = stand.battery.cell_fall_v_per_ah().unwrap();
        let o = run_case_on(&stand, &suite_case("battery sag"), Mode::Unstated, 1);
        let d = &o.diagnosis;
        let param = |name| {
            named_param(d, "battery_sag", name)
                .unwrap_or_else(|| panic!("no {name}: {:?}\n{}", o.verdict, d.summary()))
        };
        for (p, truth) in [
            (param("internal_resistance_ohm"), resistance_ohm),
            (param("open_circuit_fall_per_cell_v_per_ah"), fall_v_per_ah),
        ] {
            let sd = p.sd.unwrap_or_else(|| panic!("{p:?} has no sd"));
            assert!(
                (p.value - truth).abs() <= 3.0 * sd && sd < 0.5 * truth,
                "{} {} +- {sd}, the generator's {truth}",
                p.name,
                p.value
            );
        }
        let capacity = param("capacity_ah");
        assert!(
            capacity.sd.is_none()
                && capacity
                    .basis
                    .as_deref()
                    .is_some_and(|b| b.contains("LiPo")),
            "{capacity:?}"
        );
    }
}

/// Regression: the same generator's battery (4S, 1.3 Ah, 0.045 ohm, an open-circuit voltage
/// straight in the charge, emptied two thirds of the way through the run), `bat_v` not logged
/// (the suite's case). The catalog's battery replays the nominal motor (current about as the
/// voltage squared) on a LiPo pack (a plateau and a knee), with only resistance and capacity
/// free: the voltage's course over the run was not this pack's, and what it left was named
/// `unexplained` beside `battery_sag` (seeds 1, 2 and 4, unstated and stated). Its richer
/// forms free the discharge's shape and the current's sensitivity to the voltage, to first
/// and to second order; each is kept where its gain beyond the form before it is
/// significant. The catalog's form on magstand's own LiPo stand, where the richer form is
/// refused, is the concealed suite's (`diagnosis_concealed.rs`).
#[test]
fn a_battery_without_bat_v_whose_discharge_is_not_a_lipos_is_named_alone() {
    use magstand_tests::independent::Mode;
    for (mode, seed) in [(Mode::Unstated, 2), (Mode::Stated, 1)] {
        battery_is_named_alone_in_the_form(&Stand::default(), mode, seed, "free_discharge");
    }
}

/// Regression: the generator's held-out hexacopter (6S, 4 Ah, 0.03 ohm, the open-circuit
/// voltage straight in the charge), `bat_v` not logged, draws under 3 Ah in its run: the pack
/// neither empties nor crosses a bend of its curve. Its capacity then only scales the
/// voltage's fall, and its resistance's sag follows the commands at once, which the
/// calibrated current law holds: neither is identifiable, and every form that searched them
/// ran to the edge of its range (resistance 0.003 ohm, capacity 30 Ah). Stated, every seed
/// was `unexplained`; unstated, one of four was right. The form `drawn_charge` (the field's
/// change at a command in proportion to the charge drawn, no constant of the pack) names it
/// on all eight.
#[test]
fn a_battery_without_bat_v_that_the_run_neither_empties_nor_bends_is_named_without_its_constants() {
    use magstand_tests::independent::Mode;
    for (mode, seed) in [(Mode::Unstated, 2), (Mode::Stated, 1)] {
        battery_is_named_alone_in_the_form(&Stand::held_out(), mode, seed, "drawn_charge");
    }
}

/// Regression: the same hexacopter on a larger pack (8 Ah, 0.05 ohm, one of
/// `independent::battery_variants`), stated, seed 5. The catalog's LiPo replay fitted worse
/// than the baseline on held-out rows (mean gain -5.7), so no richer form was tried beside
/// it, and the recording was called `unexplained`. A form with no nonlinear parameters of its
/// own is tried wherever the catalog's form was fitted: it cannot trade freedom against that
/// form's parameters, and must still beat it.
#[test]
fn a_battery_whose_catalog_form_fits_worse_than_none_is_still_named() {
    use magstand_tests::independent::Mode;
    let stand = battery_variant("hexacopter, 8 Ah, 0.05 ohm");
    battery_is_named_alone_in_the_form(&stand, Mode::Stated, 5, "drawn_charge");
}

/// Regression: the default quad on a 5 Ah, 0.02 ohm pack (`independent::battery_variants`),
/// stated, seed 5. The catalog's form fitted well but with its resistance at the lower end
/// of its range, and was refused; every richer form, fitted as well as it and no better, was
/// refused as not lowering the held-out error beyond it, and the recording was called
/// `unexplained`. Where the form before it is undetermined at the edge of a parameter's
/// range, a richer form without that parameter is judged on its own.
#[test]
fn a_form_without_the_parameter_its_catalog_form_leaves_at_an_edge_is_judged_on_its_own() {
    use magstand_tests::independent::Mode;
    let stand = battery_variant("quad, 5 Ah, 0.02 ohm");
    battery_is_named_alone_in_the_form(&stand, Mode::Stated, 5, "drawn_charge");
}

/// Regression: the default stand's battery without `bat_v`, unstated, seed 4, was
/// `battery_sag, unexplained`. The richer form `free_discharge` fitted worse than the
/// catalog's form it extends (chi-square 15,900 against 10,700): its fit, singular in a
/// straight-discharge column, left out the baseline's motors armed within the dead zone with
/// it. Kept, the form is named alone, and its constants are near the generator's (0.011 ohm
/// per cell, 1.3 Ah; 0.032 ohm and 2.84 Ah before, from the catalog's form).
#[test]
fn a_richer_battery_form_keeps_the_baselines_armed_motors() {
    use magstand_tests::independent::Mode;
    battery_is_named_alone_in_the_form(&Stand::default(), Mode::Unstated, 4, "free_discharge");
}

/// Regression: the default quad whose current follows the drive to the power 1.3 on a 3 Ah
/// pack (`independent::battery_variants`), without `bat_v`, unstated, seed 6, was
/// `battery_sag, unexplained`. The battery's columns (each current-law column times the
/// pack's discharge) held the count of motors armed within their dead zone, whose draw does
/// not follow the pack's voltage through the motor, and whose free gains fitted the few rows
/// between the stand's dead zone and the calibrated one. They now hold the driven motors' law
/// only (see `a_battery_through_bat_v_moves_the_driven_motors_current_only`); the variants'
/// held-out seeds 5 to 8 went from 67 to 70 of 72 with it.
#[test]
fn a_battery_without_bat_v_moves_the_driven_motors_current_only() {
    use magstand_tests::independent::Mode;
    let stand = battery_variant("quad, current exponent 1.3, 3 Ah");
    battery_is_named_alone_in_the_form(&stand, Mode::Unstated, 6, "free_discharge");
}

/// Regression: the default quad on a 10 Ah pack (`independent::battery_variants`), without
/// `bat_v`, unstated, seed 5, was `unexplained`. The catalog's battery gained most and was
/// accepted, its capacity inside its range, but refined beside the other terms the capacity
/// ran to its largest (30 Ah: the run hardly moves this pack's voltage) and it was refused.
/// `drawn_charge`, which needs no capacity, had been judged in the same round against the
/// catalog's form (and fitted no better), and once that form was refused nothing was left to
/// try it beside. A catalog form refused at an edge now has the form that edge stands for
/// tried in its place, on its own gain.
#[test]
fn a_catalog_battery_refused_at_its_largest_capacity_has_drawn_charge_tried_in_its_place() {
    use magstand_tests::independent::Mode;
    let stand = battery_variant("quad, 10 Ah");
    battery_is_named_alone_in_the_form(&stand, Mode::Unstated, 5, "drawn_charge");
}

/// The stand of `independent::battery_variants` labelled `label`.
fn battery_variant(label: &str) -> Stand {
    magstand_tests::independent::battery_variants()
        .into_iter()
        .find(|(l, _)| *l == label)
        .map(|(_, stand)| stand)
        .unwrap_or_else(|| panic!("no battery variant {label:?}"))
}

/// Regression: the default stand's battery without `bat_v`, stated, seed 3. The form
/// `free_discharge` gained most, but its resistance refined to the lower end of its range
/// (0.003 ohm: a sag under load that follows the commands is in the calibrated current law),
/// so it was refused; the catalog's form in its place left `unexplained`, and a `dead_zone`
/// took some of it. A resistance at its lowest stands for the same form without a sag under
/// load, which is tried in its place and keeps the capacity. Unstated, the same seed was
/// `battery_sag, unexplained` (a form without a sag at 13.8 Ah) while a form could be fitted
/// twice in a round, beside different forms before it (the second order of the form without
/// a sag is reached two ways); fitted once, the first way it is reached, it is named alone.
#[test]
fn a_free_discharge_whose_resistance_runs_to_its_lowest_is_kept_without_a_sag() {
    use magstand_tests::independent::Mode;
    for mode in [Mode::Stated, Mode::Unstated] {
        battery_is_named_alone_in_the_form(&Stand::default(), mode, 3, "free_discharge_no_sag");
    }
}

/// Asserts that the suite's battery without `bat_v` on `stand` is named alone, in a form whose
/// name starts with `form`, and that the model file, written and read back, predicts the
/// disturbance within 0.1 µT RMS on each axis.
fn battery_is_named_alone_in_the_form(
    stand: &Stand,
    mode: magstand_tests::independent::Mode,
    seed: u64,
    form: &str,
) {
    use magstand_tests::independent::{recording_on, run_case_on};
    let case = suite_case("battery sag, bat_v not logged");
    let o = run_case_on(stand, &case, mode, seed);
    assert_eq!(
        o.verdict,
        ["battery_sag"],
        "{mode:?} seed {seed}: {}",
        o.diagnosis.summary()
    );
    // The model file names the form kept, and predicts the disturbance with it when read
    // back (a file read with the catalog's form would lack its columns, and be refused).
    let model = o.diagnosis.model.clone().expect("a model");
    let kept = model
        .effects
        .iter()
        .find(|t| t.name == "battery_sag")
        .and_then(|t| t.variant.clone());
    assert!(
        kept.as_deref().is_some_and(|f| f.starts_with(form)),
        "{mode:?} seed {seed}: expected the form {form}, got {:?}",
        model.effects
    );
    // The diagnosis names the same form beside the effect.
    let reported: Vec<Option<&str>> = o
        .diagnosis
        .effects
        .iter()
        .map(|e| e.form.as_deref())
        .collect();
    assert_eq!(
        reported,
        [kept.as_deref()],
        "{mode:?} seed {seed}: {}",
        o.diagnosis.summary()
    );
    // The pack's cells are reported only where they are known (here: stated). Unstated,
    // the data see the voltage's relative fall only: a resistance is per cell, and the
    // nominal supply's cell count, a default, is not reported as the stand's.
    let params: Vec<&str> = o.diagnosis.effects[0]
        .params
        .iter()
        .map(|p| p.name.as_str())
        .collect();
    let cells = o.diagnosis.effects[0]
        .params
        .iter()
        .find(|p| p.name == "cells")
        .map(|p| p.value);
    match (mode, &stand.battery) {
        (magstand_tests::independent::Mode::Unstated, _) => assert!(
            cells.is_none() && !params.contains(&"internal_resistance_ohm"),
            "{mode:?} seed {seed}: {params:?}"
        ),
        (_, magstand_standgen::Supply::Battery { cells: truth, .. }) => assert!(
            params.is_empty() || cells == Some(*truth as f64),
            "{mode:?} seed {seed}: {params:?}, cells {cells:?} (the stand's {truth})"
        ),
        _ => unreachable!("the stand's battery is a battery"),
    }
    // A directory of its own: tests of the same form and mode run at once.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("model.json");
    model.save(&path).unwrap();
    let loaded = magstand_diagnose::AugmentedModel::load(&path);
    let (rec, truth) = recording_on(stand, &case, seed);
    let error_ut = rmse_ut(
        &loaded.unwrap().dist_column(&rec, "seen.csv").unwrap(),
        &truth,
    );
    assert!(
        error_ut.iter().all(|e| *e < 0.1),
        "{mode:?} seed {seed}: the model file ({kept:?}) predicts the disturbance within {error_ut:?} µT"
    );
}

/// Issue 18's accuracy goal on data magstand did not make: the physics model fitted to one
/// recording of the generator's stand, with no current logged (the generator draws its
/// current as a power 1.7 of the command, and its field has a term in the square of the
/// total current, neither of which is the nominal motor's law), predicts the disturbance of
/// another recording (other seed: other commands, other noise) within 0.015 µT RMS on every
/// axis, judged against the generator's truth. The seeds are not the report's (101, 102).
///
/// Regression: with the current law's shape held to a cubic in speed, the same fit left
/// 0.031, 0.017 and 0.043 µT: it could not follow the generator's law.
#[test]
fn the_physics_fit_follows_a_foreign_current_law_within_15_nt() {
    use magstand_diagnose::model_choice::{fit_physics, identification_split};
    use magstand_tests::independent::{Mode, nominal};
    let (ident, _) = recording(&control(false), 13);
    let (valid, truth) = recording(&control(false), 14);
    let split = identification_split(&ident).check().unwrap();
    let fit = fit_physics(&ident, "ident", &nominal(Mode::Unstated), &split).unwrap();
    let err = rmse_ut(&fit.model.dist_column(&valid, "valid").unwrap(), &truth);
    assert!(
        err.iter().all(|e| *e <= 0.015),
        "physics fit RMSE against the truth {err:?} µT (goal 0.015 per axis)"
    );
}

/// Two regressions on one recording of a 0.3 s late magnetometer, stated stand:
///
/// - the delay was reported as 0.287 ± 0.0001 s. The generator logs each command after it
///   acted; the lead the baseline calibrates on the delayed data takes the other reading (a
///   command acts from its own row on), and the two differ by one sample interval (13 ms at
///   75 Hz), which the data cannot tell apart. The reported uncertainty now holds that
///   interval: the truth lies within 3 sd;
/// - `dead_zone` was named beside it (and beside hysteresis, a battery, a current lag) with a
///   fitted dead zone of 0.166 against the stated 0.12 and an sd of 6e-6. No logged command
///   lies between the two: they differ only in how a command maps to speed above both, which
///   the calibrated current law takes up as well, so the data cannot reject the stated dead
///   zone for the dead zone itself. The candidate now says so and is not tested. Since the
///   motors armed within their dead zone draw current of their own in the model (a column of
///   the baseline), the candidate finds commands between the two (0.195), but its change of
///   the prediction is significant on no axis, and it is refused for that. Since the replay
///   reads the late magnetometer's rows at their delayed times, the fitted dead zone (0.185 ±
///   0.022) lies within 3 sd of the statement, and is refused for that.
#[test]
fn a_late_magnetometer_is_reported_with_its_timing_ambiguity_and_nothing_else() {
    use magstand_tests::independent::{Mode, run_case};
    let o = run_case(&suite_case("time offset 0.3 s"), Mode::Stated, 1);
    assert_eq!(o.verdict, ["time_offset"], "{}", o.diagnosis.summary());
    let p = named(&o.diagnosis, "time_offset")
        .and_then(|e| e.params.first())
        .expect("the delay");
    let sd = p.sd.expect("an uncertainty");
    assert!(
        (p.value - 0.3).abs() < 3.0 * sd && sd < 0.02,
        "delay {} ± {sd} s, generated 0.3 s",
        p.value
    );
    let noted = refused_with(&o.diagnosis, "dead_zone", |n| {
        n.contains("no logged command lies between")
            || n.contains("on any axis")
            || n.contains("do not reject the statement")
    });
    assert!(noted, "{:?}", o.diagnosis.rounds);
}

/// Regression: commands logged late (stamped 0.15 s after they acted, so that the field
/// changes before the logged command that causes it) were named `unexplained`, or a
/// `hysteresis` beside a lag, and the effects beside them were missed: `time_offset` searched
/// only a late magnetometer. It now searches half a second either way, and a negative delay is
/// the commands' (`logging.command_delay_s` in the augmented scenario). Checked on the
/// generator's two first stands, each on a seed of its own.
#[test]
fn commands_logged_late_are_a_negative_time_offset() {
    use magstand_tests::independent::{Mode, run_case_on};
    for (stand, seed) in [(Stand::default(), 1), (Stand::held_out(), 2)] {
        let o = run_case_on(
            &stand,
            &suite_case("commands logged late 0.15 s"),
            Mode::Unstated,
            seed,
        );
        assert_named_exactly(&o, &["time_offset"], &format!("seed {seed}"));
        let p = named_param(&o.diagnosis, "time_offset", "mag_delay_s").expect("the delay");
        let sd = p.sd.expect("an uncertainty");
        assert!(
            (p.value + 0.15).abs() < 3.0 * sd && sd < 0.03,
            "seed {seed}: delay {} ± {sd} s, generated -0.15 s",
            p.value
        );
        let augmented =
            magstand_sim::Scenario::from_toml_str(&o.diagnosis.augmented_scenario, "augmented")
                .expect("the augmented scenario reads");
        assert_eq!(
            (
                augmented.logging.mag_delay_s,
                augmented.logging.command_delay_s
            ),
            (0.0, -p.value),
            "seed {seed}: the augmented scenario's delays"
        );
    }
}

/// Regression: a dead zone of 0.25 stated as 0.12 was never named (0 of 4 seeds). The
/// generator's motors draw their idle current whenever they are commanded above zero, within
/// the dead zone too; magstand's only while the ESC drives them, so its fit put the dead zone
/// just below the lowest logged command (0.166), where the two laws agree, with no command
/// between it and 0.12 to reject the statement by. The motors armed within their dead zone
/// are now a column of the baseline (`armed_in_dead_zone`), and the dead zone comes out
/// between the logged commands either side of 0.25.
#[test]
fn a_dead_zone_stated_too_low_is_named_with_the_armed_motors_current() {
    use magstand_tests::independent::{Mode, run_case};
    let o = run_case(&suite_case("dead zone 0.25 (stated 0.12)"), Mode::Stated, 1);
    assert_eq!(o.verdict, ["dead_zone"], "{}", o.diagnosis.summary());
    let p = named_param(&o.diagnosis, "dead_zone", "dead_zone").expect("the fitted dead zone");
    // Seed 1 logs commands at 0.2351 and 0.2569 and none between: the data place the dead
    // zone within about that interval.
    assert!(
        (0.23..=0.27).contains(&p.value),
        "dead zone {} (generated 0.25, stated 0.12)\n{}",
        p.value,
        o.diagnosis.summary()
    );
    // The law's shape is calibrated from the commands here too, though the stand is stated:
    // the fitted dead zone's sd holds its spread over the laws' shapes, as a calibrated one's
    // does (it had the chi-square's curvature alone).
    let sd = p.sd.unwrap_or_else(|| panic!("{p:?} has no sd"));
    assert!(
        (p.value - 0.25).abs() <= 2.0 * sd
            && p.basis
                .as_deref()
                .is_some_and(|b| b.contains("current law")),
        "dead zone {} +- {sd} (generated 0.25): {p:?}",
        p.value
    );
}

/// Regression: beside the generator's battery (its current linear in the supply voltage,
/// its open-circuit voltage a straight line in the charge drawn, both unlike the nominal
/// battery's), a stated dead zone of 0.12 (right) was rejected for 0.187 on seed 2, and
/// `dead_zone` named beside `battery_sag`. The battery term leaves misfit at the lowest
/// commands, and a dead zone above the lowest logged level hands those rows the armed
/// motors' own coefficient, which fits them freely. A dead zone above the stated one is now
/// named only where it changes the prediction at commands above it, where every coefficient
/// is shared (unit test `a_higher_dead_zone_testifies_only_where_a_command_lies_above_it`).
/// Since the battery's calibration is of second order in the voltage, the gain left to a
/// dead zone is smaller and was refused earlier, by the halves rule; since the replayed
/// motors follow the logged voltage between its rows (thirty-fifth session), the dead zone
/// fitted beside the battery lies within 3 sd of the statement, which the data then do not
/// reject. Either way no candidate dead zone stands.
#[test]
fn a_battery_law_unlike_the_nominal_one_does_not_raise_the_stated_dead_zone() {
    use magstand_tests::independent::{Mode, run_case};
    let o = run_case(&suite_case("battery sag"), Mode::Stated, 2);
    assert_eq!(o.verdict, ["battery_sag"], "{}", o.diagnosis.summary());
    let dead_zone_candidates = || {
        o.diagnosis
            .rounds
            .iter()
            .flat_map(|r| &r.candidates)
            .filter(|c| c.name == "dead_zone")
    };
    assert!(
        dead_zone_candidates().next().is_some()
            && dead_zone_candidates().all(|c| c.note.as_deref().is_some_and(|n| {
                n.starts_with("refused") || n.contains("the data do not reject the statement")
            })),
        "{:?}",
        o.diagnosis.rounds
    );
}

/// Regression: on the generator's hexacopter (`Stand::held_out`), whose attitude-like commands
/// pair motors 1 and 5, and 2 and 6, on every row, a motor whose wires carry 1.6 times the
/// others' field was never named: per-motor gains cannot be fitted for motors no row tells
/// apart, the candidate's regressors were degenerate, and the structure it left was called
/// `unexplained` (both seeds). Per-motor terms are now fitted per group of motors commanded
/// alike, each motor of a group taking the group's gain.
#[test]
fn a_motor_asymmetry_is_named_where_motors_are_commanded_in_pairs() {
    use magstand_tests::independent::{Mode, run_case_on};
    let o = run_case_on(
        &Stand::held_out(),
        &suite_case("motor asymmetry"),
        Mode::Unstated,
        1,
    );
    assert_eq!(o.verdict, ["motor_asymmetry"], "{}", o.diagnosis.summary());
    let gain = |m: usize| {
        ["x", "y", "z"].map(|a| {
            named_param(
                &o.diagnosis,
                "motor_asymmetry",
                &format!("motor{m}_gain_ut_per_a_{a}"),
            )
            .map_or(f64::NAN, |p| p.value)
        })
    };
    // Paired motors share their gain; the third motor's (the generator's scaled one) is the
    // largest and points along the stand's wiring field (-0.35, 0.60, 0.50 µT/A).
    assert_eq!(gain(1), gain(5), "{}", o.diagnosis.summary());
    assert_eq!(gain(2), gain(6), "{}", o.diagnosis.summary());
    let norm = |g: [f64; 3]| g.iter().map(|v| v * v).sum::<f64>().sqrt();
    for m in [1, 2, 4, 5, 6] {
        assert!(
            norm(gain(3)) > 2.0 * norm(gain(m)),
            "motor 3 {:?} against motor {m} {:?}",
            gain(3),
            gain(m)
        );
    }
    let g3 = gain(3);
    let wiring = [-0.35, 0.60, 0.50];
    let cos = g3.iter().zip(wiring).map(|(a, b)| a * b).sum::<f64>() / (norm(g3) * norm(wiring));
    assert!(
        cos > 0.95,
        "motor 3's gain {g3:?} against the wiring {wiring:?}: cosine {cos}"
    );
    // Regression (forty-sixth session): the gains are per ampere of the nominal motor's scale,
    // where no current is logged, and came out 0.63 of the generator's with an sd of 1.5 %.
    // They now have no sd, and the field each adds at its motor's largest current (which does
    // not rest on that scale) holds the generator's: motor 3 carries 1.6 times the wiring's
    // field against the six motors' mean of 1.1 times it, at up to 11.4 A.
    let stand = Stand::held_out();
    let largest_a = stand.idle_a + stand.full_a;
    assert_scale_free_axes(
        &o.diagnosis,
        "motor_asymmetry",
        ("motor3_gain_ut_per_a", "motor3_field_at_largest_ut"),
        stand.gains_ut_per_a[2].map(|g| 0.5 * g * largest_a),
        |p, truth| p.sd.is_some_and(|sd| (p.value - truth).abs() < 3.0 * sd),
    );
}

/// Regression: on the held-out hexacopter with its constants stated, the motor made 1.6 times
/// stronger got `dead_zone` (0.19 for the stated 0.06) beside `motor_asymmetry`, on all four
/// seeds. The per-motor gains followed the nominal motor's current, whose shape at low
/// commands is not this stand's (its current rises as the power 2.3 of the drive); a dead zone
/// moved up took the misfit. A per-motor term, once named, now follows each motor's current as
/// the baseline's calibrated law has it, which the model file records and evaluates. (Named on
/// that current too, the term came back beside a late magnetometer at 200 Hz: see
/// `a_term_whose_coefficients_are_not_told_from_zero_is_not_named`. It is named on the nominal
/// current.)
#[test]
fn an_asymmetric_motor_follows_the_calibrated_current_law() {
    use magstand_tests::independent::{Mode, run_case_on};
    let stand = Stand::held_out();
    let case = suite_case("motor asymmetry");
    let o = run_case_on(&stand, &case, Mode::Stated, 1);
    assert_eq!(o.verdict, ["motor_asymmetry"], "{}", o.diagnosis.summary());
    let model = o.diagnosis.model.clone().expect("a model");
    let law = model
        .motor_current_law
        .clone()
        .expect("the calibrated current law");
    assert!(
        law.columns.iter().any(|c| c.starts_with("speed^")),
        "{law:?}"
    );
    let (rec, truth) = magstand_tests::independent::recording_on(&stand, &case, 1);
    let error_ut = |m: &magstand_diagnose::AugmentedModel| -> [f64; 3] {
        rmse_ut(&m.dist_column(&rec, "seen.csv").unwrap(), &truth)
    };
    let followed = error_ut(&model);
    // The same coefficients on the nominal motor's current predict worse: the file's law is
    // what the gains were fitted with.
    let nominal = error_ut(&magstand_diagnose::AugmentedModel {
        motor_current_law: None,
        ..model.clone()
    });
    assert!(
        followed.iter().all(|e| *e < 0.03) && followed.iter().zip(&nominal).all(|(f, n)| f < n),
        "calibrated current: {followed:?} µT, nominal current: {nominal:?} µT"
    );
    // A law naming a column the model does not have is refused by name.
    let crafted = magstand_diagnose::AugmentedModel {
        motor_current_law: Some(magstand_diagnose::augmented_model::MotorCurrentLaw {
            columns: vec!["speed^9".into()],
            a_per_unit: vec![1.0],
        }),
        ..model.clone()
    };
    let err = crafted
        .dist_column(&rec, "seen.csv")
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("motor_current_law") && err.contains("speed^9"),
        "{err}"
    );
    // So is a hysteresis's current law with a value that is not finite.
    let crafted = magstand_diagnose::AugmentedModel {
        current_law: Some(magstand_diagnose::augmented_model::MotorCurrentLaw {
            columns: vec!["speed^1".into()],
            a_per_unit: vec![f64::NAN],
        }),
        ..model
    };
    let err = crafted
        .dist_column(&rec, "seen.csv")
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("the model's current_law") && err.contains("NaN"),
        "{err}"
    );
}

/// Regression: the generator's hexacopter sampled at 200 Hz (25,000 rows, 125 s) with its
/// magnetometer 0.3 s late got `motor_asymmetry` beside `time_offset`. Its held-out gain test
/// passed (p = 4e-5), while every one of its nine gains lay within two of its uncertainties of
/// zero: at 200 Hz the misfit the held-out blocks share runs for seconds (the residuals'
/// long-run sd is 5.4 times the independent rows'). A name must now also lower the fit's
/// chi-square by more than its parameters would from noise, with that correlation allowed
/// for (a likelihood-ratio test). Since the seventeenth session the replay reads a late
/// magnetometer's rows at their delayed times by its own steps, and the held-out gain test no
/// longer passes either (p = 0.46): where it does, the likelihood-ratio test must refuse it.
#[test]
fn a_term_whose_coefficients_are_not_told_from_zero_is_not_named() {
    let o = unstated_at(Stand::held_out(), 200.0, "time offset 0.3 s");
    assert!(
        o.verdict.iter().any(|n| n == "time_offset")
            && !o.verdict.iter().any(|n| n == "motor_asymmetry"),
        "{}",
        o.diagnosis.summary()
    );
    // Every round in which its held-out gain passed refused it as not told from zero.
    for round in &o.diagnosis.rounds {
        for c in round
            .candidates
            .iter()
            .filter(|c| c.name == "motor_asymmetry")
        {
            if c.p_value.is_some_and(|p| p < round.threshold) && c.improvement > Some(0.0) {
                assert!(
                    c.note
                        .as_deref()
                        .is_some_and(|n| n.contains("not told from zero")),
                    "{c:?}"
                );
            }
        }
    }
}

/// Regression: uncertainties were taken as if every row were independent. On recordings whose
/// physics magstand models only approximately, what the model misses runs for seconds to
/// minutes, and the reported sds were 10 to 250 times smaller than the error against the
/// generator's truth: the board's 90 s heating (fitted from the logged temperature through the
/// replayed power) at 84.9 ± 0.07 s, the 0.5 s current lag at 0.493 ± 0.0006 s. An sd is now
/// widened by the long-run variance of its residuals (batch means over the identification
/// rows), and the truth lies within a few of them. The lag's model has the generator's form
/// since its steps act where the commands change and the square of the lagged current is a
/// column of its own (`a_slow_lag_is_named_alone_and_its_model_file_predicts_it`), but its sd
/// still does not hold its error (the ignored test below).
#[test]
fn reported_uncertainties_hold_the_generators_truth() {
    use magstand_tests::independent::{Mode, run_case};
    let within = |case: &str, effect: &str, param: &str, truth: f64, sds: f64| {
        let o = run_case(&suite_case(case), Mode::Unstated, 1);
        let p = named_param(&o.diagnosis, effect, param)
            .unwrap_or_else(|| panic!("{case}: no {effect}.{param} in {:?}", o.verdict));
        let sd = p.sd.unwrap_or_else(|| panic!("{case}: {param} has no sd"));
        assert!(
            (p.value - truth).abs() < sds * sd,
            "{case}: {param} = {} ± {sd}, generated {truth}: {:.1} sd off (allowed {sds})",
            p.value,
            (p.value - truth) / sd
        );
    };
    within("thermal drift", "thermal_drift", "tau_s", 90.0, 3.0);
    // The lag itself is within 1 % of the truth; its sd is the known gap below.
    let o = run_case(&suite_case("current lag 0.5 s"), Mode::Unstated, 1);
    let lag = named_param(&o.diagnosis, "current_lag", "spinup_tau_s").map(|p| p.value);
    assert!(
        lag.is_some_and(|v| (v - 0.5).abs() < 0.005),
        "lag {lag:?} s, generated 0.5 s"
    );
}

/// The known gap of issue 22: on an unstated stand a slow lag's reported sd is smaller than
/// its error against the generator. The generator steps its lag by Euler at 1 kHz, so its
/// time constant in effect is `-dt / ln(1 - dt / 0.5)` = 0.4995 s, not 0.5 s. Against that,
/// in the twentieth session: default stand seeds 1-4 at 0.50088, 0.49983, 0.49920, 0.49938 ±
/// 0.0004 s (seed 1 3.5 sds off); hexacopter 0.49836, 0.49997, 0.49822, 0.49936 ± 0.0003 to
/// 0.0005 s (seeds 1 and 3 3.2 and 2.8 sds off). Stated, the sd (0.004 to 0.005 s) holds it.
/// Neither the curvature with the command lead free (the two trade off, but that widens it
/// only 1.5 times) nor a sandwich estimate over the time blocks (0.0004 to 0.0006 s) sees
/// it: the error is a bias of the model, not scatter within the recording. Run with
/// `--ignored` to see it (both stands, seeds 1 and 2).
#[test]
#[ignore = "known gap (issue 22): a slow lag's sd does not hold its error"]
fn a_slow_lags_reported_uncertainty_holds_the_generators_truth() {
    use magstand_tests::independent::{Mode, run_case_on};
    // The generator's Euler step of the lag, 1 ms: its time constant in effect.
    let truth = -1e-3 / (1.0 - 1e-3 / 0.5f64).ln();
    for stand in [Stand::default(), Stand::held_out()] {
        for seed in [1, 2] {
            let o = run_case_on(
                &stand,
                &suite_case("current lag 0.5 s"),
                Mode::Unstated,
                seed,
            );
            let p = named_param(&o.diagnosis, "current_lag", "spinup_tau_s").expect("the lag");
            let sd = p.sd.expect("an sd");
            assert!(
                (p.value - truth).abs() < 3.0 * sd,
                "seed {seed}: lag {} ± {sd} s, generated {truth} s in effect: {:.1} sd off",
                p.value,
                (p.value - truth) / sd
            );
        }
    }
}

/// Calibration rounds open an unstated diagnosis: only the stand constants nobody stated are
/// tried, with the effects whose misfit can pass for them (a late magnetometer), until no
/// calibration is accepted, then the whole catalog. A lag found there that is slower than any
/// spin-up is not a calibration and waits for the catalog's rounds: on this recording a late
/// magnetometer (0.3 s) looks like such a lag until `time_offset` is tried beside it, and
/// accepting it as the lag first named `current_lag` and `unexplained` instead of the offset
/// and the heating. Where that finding gains most, the catalog's round comes before any
/// calibration: fitting the dead zone first beside a 0.5 s lag's misfit left `unexplained`
/// beside the lag on held-out seeds 3 and 4.
#[test]
fn calibration_rounds_come_first_and_leave_findings_to_the_catalog() {
    use magstand_tests::independent::{Mode, run_case};
    let o = run_case(
        &suite_case("thermal drift + time offset"),
        Mode::Unstated,
        1,
    );
    assert_named_exactly(&o, &["thermal_drift", "time_offset"], "");
    let names = |r: &magstand_diagnose::diagnosis::Round| -> Vec<String> {
        r.candidates.iter().map(|c| c.name.clone()).collect()
    };
    let calibration_round = |n: &[String]| {
        n.iter()
            .all(|n| n == "dead_zone" || n == "current_lag" || n == "time_offset")
    };
    let rounds = &o.diagnosis.rounds;
    let first = names(&rounds[0]);
    assert!(calibration_round(&first), "the first round tried {first:?}");
    let full = rounds
        .iter()
        .position(|r| names(r).iter().any(|n| n == "thermal_drift"))
        .expect("a round of the whole catalog");
    assert!(
        rounds[..full].iter().all(|r| calibration_round(&names(r))),
        "rounds before the catalog's: {:?}",
        rounds[..full].iter().map(names).collect::<Vec<_>>()
    );
    let left = rounds[..full].iter().flat_map(|r| &r.candidates).any(|c| {
        (c.name == "current_lag" || c.name == "time_offset")
            && c.note
                .as_deref()
                .is_some_and(|n| n.contains("left to the catalog"))
    });
    assert!(left, "the finding was not left to the catalog: {rounds:?}");
}

/// Regression: with the stand stated, the 0.5 s lag was named with `unexplained` beside it
/// (seed 2): the refinement calibrated the command lead to 0 and the lag to 0.488 s, a valley
/// of the two (each shifts when the field follows a step) that a search of one parameter at
/// a time crosses in ever smaller steps and leaves early. A pattern step after the
/// coordinate passes repeats their move while the chi-square falls.
#[test]
fn a_stated_stands_slow_lag_is_followed_along_its_valley_with_the_command_lead() {
    use magstand_tests::independent::{Mode, run_case};
    let o = run_case(&suite_case("current lag 0.5 s"), Mode::Stated, 2);
    assert_eq!(o.verdict, ["current_lag"], "{}", o.diagnosis.summary());
    // Within 1 % (its sd is the known gap of `a_slow_lags_reported_uncertainty_holds_...`).
    assert_lag_within(&o.diagnosis, 0.005, "stated, seed 2");
}

/// Regression: at 10 Hz, behind a 0.5 s lag, the rows after each command change share that
/// change's timing error (the log only says the command changed within a 0.1 s interval),
/// most of the residual after each step; the test for remaining structure counted it and the
/// hexacopter's lag got `unexplained` beside it. Each change's moment is now profiled out of
/// the residual before that test.
#[test]
fn a_slow_lag_at_10_hz_is_named_alone() {
    let o = unstated_at(Stand::held_out(), 10.0, "current lag 0.5 s");
    assert_eq!(o.verdict, ["current_lag"], "{}", o.diagnosis.summary());
}

/// Regression: at 25 Hz a magnetometer 0.3 s late was read between the replay's rows on a
/// straight line, which gave the row the delay puts within a change's interval half the step
/// (8 µT rms there), and the diagnosis named `unexplained` beside `time_offset`. The replay
/// now reads the delayed times by its own steps.
#[test]
fn a_late_magnetometer_at_25_hz_is_named_alone() {
    let o = unstated_at(Stand::default(), 25.0, "time offset 0.3 s");
    assert_eq!(o.verdict, ["time_offset"], "{}", o.diagnosis.summary());
}

/// Regression: with the stand stated (a 1 ms spin-up), a 0.5 s current lag at 10 Hz was
/// calibrated at 0.45 s with the commands acting a fifth of an interval before each row, and
/// `hysteresis` was named for the misfit that left. Two faults: the field's lag took a change
/// that the spin-up had half passed by a row for two steps (a false dip of the chi-square, now
/// solved exactly as two lags in series), and the lag and the moment of the changes trade off
/// in a narrow valley that the coordinate search left early (now followed by Newton steps).
#[test]
fn a_slow_lag_at_10_hz_on_a_stated_stand_is_named_alone_at_its_time_constant() {
    let o = diagnosed_at(
        Stand::default(),
        10.0,
        "current lag 0.5 s",
        magstand_tests::independent::Mode::Stated,
    );
    assert_eq!(o.verdict, ["current_lag"], "{}", o.diagnosis.summary());
    let tau = named_param(&o.diagnosis, "current_lag", "spinup_tau_s").expect("its time constant");
    assert!(
        (tau.value - 0.5).abs() < 0.01,
        "lag {} s against the generator's 0.5 s\n{}",
        tau.value,
        o.diagnosis.summary()
    );
}

/// Regression: on a stated stand a sagging battery with `bat_v` logged got `dead_zone` (the
/// default stand, seed 4; the hexacopter at 25 Hz) or `thermal_drift` (the default stand at
/// 100 Hz) beside `battery_sag`. The generator's current is linear in the voltage, the nominal
/// motor's about quadratic, and the voltage falls 15 % over the run: the calibration to first
/// order in the voltage's change left a misfit of a few percent of the field, largest where
/// the voltage was highest, that those effects took up. The calibration is now to second order.
#[test]
fn a_sagging_battery_on_a_stated_stand_is_named_alone() {
    use magstand_tests::independent::{Mode, run_case};
    let o = run_case(&suite_case("battery sag"), Mode::Stated, 4);
    assert_eq!(o.verdict, ["battery_sag"], "{}", o.diagnosis.summary());
    let o = diagnosed_at(Stand::held_out(), 25.0, "battery sag", Mode::Stated);
    assert_eq!(o.verdict, ["battery_sag"], "{}", o.diagnosis.summary());
}

/// Regression: a refinement's first pass stopped searching older terms with one basin over
/// their whole range, the delay among them; but a delay's chi-square has a kink at each sample
/// interval, and on the hexacopter at 200 Hz the late magnetometer stayed at a local minimum
/// (0.285 s against 0.296 s) once the spin-up was calibrated beside it, and `unexplained` was
/// added. The delay is searched over its whole range again.
#[test]
fn a_late_magnetometer_at_200_hz_leaves_no_structure_after_the_calibrations() {
    let o = unstated_at(Stand::held_out(), 200.0, "time offset 0.3 s");
    assert_eq!(o.verdict, ["time_offset"], "{}", o.diagnosis.summary());
}

/// Regression: on the hexacopter at 200 Hz with `bat_v` logged, once `battery_sag` was named
/// the refinement calibrated the dead zone below every command, and the model's reweighting
/// from its own residuals left the battery's second-order voltage columns undetermined: the
/// diagnosis stopped with "the baseline fit is singular". The model now keeps the weights it
/// was searched with where the reweighted fit is not determined.
#[test]
fn a_reweighting_that_leaves_a_term_undetermined_keeps_the_searched_weights() {
    let o = unstated_at(Stand::held_out(), 200.0, "battery sag");
    assert_eq!(o.verdict, ["battery_sag"], "{}", o.diagnosis.summary());
}

/// Regression: at 25 Hz the default stand's 1.3 Ah battery is empty a third of the way
/// through the run, and `battery_sag` was first refused (its gain did not hold in the second
/// half), so `thermal_drift` was named; once `battery_sag` was named a round later, the
/// refinement moved the heating's time constant to its 10 s limit, and both names stood.
/// The edge rule now holds for refined parameters: that older finding is withdrawn, with a
/// warning. Since the thirty-second session the battery, logged through `bat_v`, is judged
/// beside the dead zone refitted with it and named in the first catalog round, before the
/// heating: where the heating is named in a round, it must be withdrawn
/// (`a_stated_constant_refined_to_the_edge_of_its_range_is_withdrawn` keeps the withdrawal
/// itself under test).
#[test]
fn a_finding_refined_to_the_edge_of_its_range_is_withdrawn() {
    let o = unstated_at(Stand::default(), 25.0, "battery sag");
    assert_eq!(o.verdict, ["battery_sag"], "{}", o.diagnosis.summary());
    let heating_named = o
        .diagnosis
        .rounds
        .iter()
        .any(|r| r.accepted.as_deref() == Some("thermal_drift"));
    assert!(
        !heating_named
            || o.diagnosis
                .warnings
                .iter()
                .any(|w| w.starts_with("thermal_drift") && w.contains("withdrawn")),
        "{:?}",
        o.diagnosis.warnings
    );
    // The battery's report measures its gain on the model as it stands, without the withdrawn
    // heating (it was measured beside it, at the parameters of its round).
    let r = &o.diagnosis.effects[0];
    for a in 0..3 {
        let (before, after) = (r.holdout_rmse_before_ut[a], r.holdout_rmse_after_ut[a]);
        assert!(
            after.is_finite() && after < before,
            "axis {a}: held-out RMSE {before} -> {after} µT"
        );
    }
}

/// Regression: a 0.5 s current lag beside a magnetometer logged 0.3 s late (the default stand,
/// unstated, seeds 1 to 3) was named `current_lag, time_offset, hysteresis, unexplained`.
/// Both make the field follow a command change late: the lag, named first, was calibrated at
/// 0.7 s to hold the delay too, the delay accepted beside it at 0.12 s, and the refinement,
/// a grid step of each at a time, crawled along the valley of more lag with less delay to
/// 0.52 and 0.24 s; the misfit left was named twice more. The delay is now searched over its
/// whole range with the lag refitted at each delay, in the refinement and, where the delay's
/// gain with the lag held is significant, in its candidate's fit: stated, with the lag held
/// the delay gained less than a hysteresis, which took the round before it and stayed. The
/// same case at other rates, seeds and sizes was looked at while the change was made; this
/// one is its regression.
#[test]
fn a_slow_lag_beside_a_late_magnetometer_is_named_with_both_times() {
    use magstand_tests::independent::{Mode, run_case};
    for mode in [Mode::Unstated, Mode::Stated] {
        let o = run_case(&suite_case("current lag + time offset"), mode, 1);
        let d = &o.diagnosis;
        assert_named_exactly(&o, &["current_lag", "time_offset"], &format!("{mode:?}"));
        let tau = named_param(d, "current_lag", "spinup_tau_s").expect("the lag");
        assert!(
            (tau.value - 0.5).abs() < 0.02,
            "{mode:?}: lag {} ± {:?} s, generated 0.5 s\n{}",
            tau.value,
            tau.sd,
            d.summary()
        );
        let delay = named_param(d, "time_offset", "mag_delay_s").expect("the delay");
        let sd = delay.sd.expect("an uncertainty");
        assert!(
            (delay.value - 0.3).abs() < 3.0 * sd && sd < 0.02,
            "{mode:?}: delay {} ± {sd} s, generated 0.3 s\n{}",
            delay.value,
            d.summary()
        );
    }
}

/// Regression: a change of this session (the twenty-fifth) searched a newest late
/// magnetometer's delay only near where it was in the refinement's profile beside a slow lag,
/// since its candidate's fit had profiled the whole range. The coordinate passes between
/// the two had moved the lead and the lag, and the same case sampled at 100 Hz, stated, was
/// named `current_lag, time_offset, hysteresis` (default stand and hexacopter, seed 1). The
/// refinement's profile searches the whole range again.
#[test]
fn a_slow_lag_beside_a_late_magnetometer_at_100_hz_is_named_with_both_times() {
    use magstand_tests::independent::{Mode, run_case_on};
    let stand = Stand {
        rate_hz: 100.0,
        ..Stand::default()
    };
    let o = run_case_on(
        &stand,
        &suite_case("current lag + time offset"),
        Mode::Stated,
        1,
    );
    assert_named_exactly(&o, &["current_lag", "time_offset"], "");
}

/// Regression: a battery beside a 0.5 s current lag on the generator's default stand, `bat_v`
/// logged, was named with an extra `unexplained` (unstated, seed 2) or `dead_zone` (stated,
/// seeds 1 and 2). The generator's current is the current law times the voltage's ratio,
/// lagged; the battery's columns were the voltage's change times the law's columns already
/// lagged, which moved the voltage's part of every step a lag early. They are now formed
/// from the law before the lag and lagged with it (`Effect::changes_the_currents`).
#[test]
fn a_battery_beside_a_slow_lag_is_named_with_the_lag() {
    use magstand_tests::independent::{Mode, run_case};
    for (mode, seed) in [(Mode::Unstated, 2), (Mode::Stated, 1)] {
        let o = run_case(&suite_case("battery sag + current lag"), mode, seed);
        assert_named_exactly(
            &o,
            &["battery_sag", "current_lag"],
            &format!("{mode:?}, seed {seed}"),
        );
        let tau = named_param(&o.diagnosis, "current_lag", "spinup_tau_s").expect("the lag");
        assert!(
            (tau.value - 0.5).abs() < 0.05,
            "{mode:?}, seed {seed}: lag {} s, generated 0.5 s",
            tau.value
        );
    }
}

/// Regression: the same without `bat_v` (unstated, seed 2) was named `current_lag,
/// battery_sag, hysteresis, unexplained`. The replay stepped each command in full and let the
/// pack sag with that current at once, where the current that flows lags behind the command:
/// the voltage fell a lag's length early at every step. The replay's supply now sees the
/// current through the same lags (`replay::SupplyLags`).
#[test]
fn a_battery_without_bat_v_beside_a_slow_lag_sags_with_the_lagged_current() {
    use magstand_tests::independent::{Mode, run_case};
    let o = run_case(
        &suite_case("battery sag + current lag, bat_v not logged"),
        Mode::Unstated,
        2,
    );
    assert_named_exactly(&o, &["battery_sag", "current_lag"], "");
}

/// Regression: a lag slower than any spin-up was written to the augmented scenario as a spin-up
/// that slow, the nearest physics the simulator then had, while the diagnosis models it as the
/// motors' current lagging the current of their speed. Replayed, the augmented scenario agreed
/// with the recording three times worse than the model file (the 0.5 s lag, default stand
/// seed 1: held-out 1.70/0.80/2.77 µT against 0.47/0.28/0.72 µT). The scenario now carries the
/// lag as `motors.current_lag_s` beside the calibrated spin-up, which the simulator and the
/// replay run, and its simulation agrees with the recording at least as well as the lag's own
/// fit did (both stands). Stated back (`--scenario` the augmented scenario), the lag is the
/// stand's: a diagnosis design ignored a stated `current_lag_s` in the field (its baseline
/// 3.9/1.9/6.3 µT held out) and named `current_lag` again; now nothing is named. The stated
/// lag's baseline then lacked the finding's second order of a field nonlinear in the current
/// (`lagged_current_squared_a2`), and seed 2 stated back was `unexplained` (held out
/// 0.27/0.24/0.30 µT); with it, nothing (0.23/0.22/0.23 µT).
#[test]
fn a_slow_lags_augmented_scenario_runs_the_lag_the_diagnosis_found() {
    use magstand_tests::independent::{Mode, recording_on, run_case_on};
    for (stand, seed) in [
        (Stand::default(), 1),
        (Stand::held_out(), 1),
        (Stand::default(), 2),
    ] {
        let case = suite_case("current lag 0.5 s");
        let o = run_case_on(&stand, &case, Mode::Unstated, seed);
        let d = &o.diagnosis;
        let augmented = magstand_sim::Scenario::from_toml_str(&d.augmented_scenario, "augmented")
            .expect("the augmented scenario parses");
        let motors = &augmented.motors;
        assert!(
            (motors.current_lag_s - 0.5).abs() < 0.01 && motors.spinup_tau_s <= 0.3,
            "current lag {} s beside a spin-up of {} s; generated 0.5 s",
            motors.current_lag_s,
            motors.spinup_tau_s
        );
        let lag = d
            .effects
            .iter()
            .find(|e| e.name == "current_lag")
            .expect("the lag is named");
        let (simulated, fitted) = (
            d.simulation.holdout_rmse_after_ut,
            lag.holdout_rmse_after_ut,
        );
        assert!(
            (0..3).all(|a| simulated[a] <= 1.1 * fitted[a]),
            "the augmented scenario's replay leaves {simulated:?} µT, the lag's fit {fitted:?} µT"
        );
        let stated = augmented
            .check("augmented", None)
            .expect("the augmented scenario is valid");
        let (rec, _) = recording_on(&stand, &case, seed);
        let config = magstand_diagnose::DiagnoseConfig::default()
            .check()
            .unwrap();
        let again = magstand_diagnose::diagnose(&rec, case.label, &stated, &config).unwrap();
        assert!(
            again.verdict.is_empty(),
            "seed {seed}: stated back, the augmented scenario leaves {:?} (baseline held out {:?} µT)",
            again.verdict,
            again.baseline.holdout_rmse_ut
        );
    }
}

/// Regression: on the generator's third stand (an octocopter at 120 Hz, added after the
/// diagnosis was developed on the other two), a battery logged through `bat_v` beside a 0.5 s
/// current lag was missed on seed 1 and its misfit named `unexplained`. The dead zone,
/// calibrated at 0.147 before the battery was in the model (0.10 in the generator), had taken
/// part of the battery's misfit, and with it held the battery's held-out gain was negative. A
/// candidate that changes the currents and searches nothing of its own is now also fitted
/// beside the calibrated dead zone refitted with it. The dead zone then lies at 0 under every
/// law's shape, a limit: no sd, the range as its basis (it had the law's shape's, of no width).
#[test]
fn a_battery_logged_through_bat_v_is_judged_beside_the_dead_zone_calibrated_with_it() {
    let stand = Stand::octocopter();
    let o = unstated_at(stand.clone(), stand.rate_hz, "battery sag + current lag");
    assert_named_exactly(
        &o,
        &["battery_sag", "current_lag"],
        "octocopter, battery and a 0.5 s lag, bat_v logged, seed 1, unstated",
    );
    let dz = calibrated(&o.diagnosis, "motors.dead_zone");
    match dz.sd {
        Some(sd) => assert!(
            (dz.value - stand.dead_zone).abs() < 3.0 * sd,
            "dead zone {} +- {sd}, generated {}",
            dz.value,
            stand.dead_zone
        ),
        None => assert!(
            dz.basis
                .as_deref()
                .is_some_and(|b| b.contains("edge of its search range")),
            "a dead zone without an sd is a limit at an edge: {dz:?}"
        ),
    }
}

/// A stated constant that a later term's refinement moves to the edge of its range, on a
/// recording magstand did not make: the third stand's battery and 0.5 s lag (`bat_v` logged,
/// seed 2) with a scenario that states the motor count and a dead zone of 0.147 (the
/// generator's is 0.10) and nothing else. Until the thirty-fifth session the stated dead zone
/// was rejected and named first, and once the battery was named, refitted beside it, ran to 0,
/// the edge of its range: it was withdrawn with a warning. Since the replayed motors follow
/// the logged voltage between its rows and the terms are refined again under their model's
/// weights, the statement is not rejected at all (nor on seeds 1 to 4 with 0.13, 0.147 or
/// 0.17 stated, the battery with or without `bat_v`): the verdict is the generator's two
/// effects either way, and a dead zone named on the way must have been withdrawn. (The
/// withdrawal has no trigger left in the suites; the restatement after one is unit-tested,
/// `every_finding_after_a_withdrawal_is_restated_in_order`.)
#[test]
fn a_stated_constant_a_later_term_refutes_is_not_in_the_verdict() {
    use magstand_tests::independent::recording_on;
    let stand = Stand::octocopter();
    let case = suite_case("battery sag + current lag");
    let (rec, _) = recording_on(&stand, &case, 2);
    let stated = magstand_sim::Scenario::from_toml_str(
        "name = \"dead zone stated\"\n[program]\nkind = \"random_steps\"\ncount = 10\n\
         dwell_min_s = 1.0\ndwell_max_s = 2.0\n[motors]\ncount = 8\ndead_zone = 0.147\n",
        "stated",
    )
    .and_then(|s| s.check("stated", None))
    .expect("the scenario is valid");
    let config = magstand_diagnose::DiagnoseConfig::default()
        .check()
        .unwrap();
    let d = magstand_diagnose::diagnose(&rec, case.label, &stated, &config).unwrap();
    let mut verdict = d.verdict.clone();
    verdict.sort();
    assert_eq!(verdict, ["battery_sag", "current_lag"], "{}", d.summary());
    let named_on_the_way = d
        .rounds
        .iter()
        .any(|r| r.accepted.as_deref() == Some("dead_zone"));
    let withdrawn = d
        .warnings
        .iter()
        .any(|w| w.starts_with("dead_zone") && w.contains("withdrawn"));
    assert!(
        !named_on_the_way || withdrawn,
        "a dead zone named on the way is gone without a withdrawal: {:?}\n{}",
        d.warnings,
        d.summary()
    );
}

/// The suite's battery with `bat_v` logged on the default stand sampled at 30 Hz, seed 2,
/// diagnosed as `mode` says, asserted to be named `battery_sag` alone.
fn battery_at_30_hz_named_alone(
    mode: magstand_tests::independent::Mode,
) -> magstand_tests::independent::Outcome {
    let stand = Stand {
        rate_hz: 30.0,
        ..Stand::default()
    };
    let o = magstand_tests::independent::run_case_on(&stand, &suite_case("battery sag"), mode, 2);
    assert_named_exactly(
        &o,
        &["battery_sag"],
        &format!("default stand at 30 Hz, battery with bat_v logged, seed 2, {mode:?}"),
    );
    o
}

/// Regression: the same recording with the stand stated was `battery_sag, unexplained`, its
/// model within 0.02 µT rms of the generator's truth. What was named was 0.02 to 0.03 µT left
/// at low throttle after steps down, where the generator's noise is smallest: the structure's
/// share was measured on the residual standardized by the noise law, where it carried a tenth
/// of the variance, while it added about 1 % to the residual's rms in µT, which the rule is
/// about. The share is now measured in µT too, and structure is named only where it is large
/// both ways (the misfits at full throttle of `a_battery_without_bat_v_beside_a_slow_lag_...`
/// and `a_free_discharge_whose_resistance_...`, small against the noise there, carry a tenth
/// of the variance in µT: measured in µT alone, they were named). It stays in the warnings.
#[test]
fn structure_that_adds_little_to_the_residuals_rms_in_ut_is_not_named() {
    let o = battery_at_30_hz_named_alone(magstand_tests::independent::Mode::Stated);
    assert!(
        o.diagnosis
            .warnings
            .iter()
            .any(|w| w.contains("small structure")),
        "warnings {:?}",
        o.diagnosis.warnings
    );
}

/// Regression: on the generator's default stand sampled at 30 Hz (a rate no suite had run), a
/// battery logged through `bat_v` (seed 2, unstated) was named `thermal_drift, unexplained`.
/// The battery's columns (the supply's change times each current-law column) held the count of
/// motors armed within their dead zone, calibrated at 0.17 there (0.12 in the generator). Their
/// free gains made the held-out residual at the lowest throttles 16 times worse while every
/// other throttle's fell about fivefold, so the battery's weighted held-out gain was negative
/// and a heating model took the drift. A motor within its dead zone is not driven, and its
/// draw does not follow the pack's voltage through the motor: the battery's columns now hold
/// the driven motors' law only.
#[test]
fn a_battery_through_bat_v_moves_the_driven_motors_current_only() {
    let o = battery_at_30_hz_named_alone(magstand_tests::independent::Mode::Unstated);
    let columns = &o
        .diagnosis
        .model
        .as_ref()
        .expect("a named battery gives a model")
        .columns;
    assert!(
        columns.iter().any(|c| c.starts_with("voltage_change_x_"))
            && !columns
                .iter()
                .any(|c| c.starts_with("voltage_change") && c.ends_with("armed_in_dead_zone")),
        "the battery's columns are the driven motors' law times the change: {columns:?}"
    );
}

/// The suite's battery and 0.5 s current lag with `bat_v` logged, seed 4 of the default
/// stand, diagnosed as `mode` says: the verdict, and the lag's time constant within 2 % of the
/// generator's.
fn battery_and_lag_named_with_the_lag_where_it_is(mode: magstand_tests::independent::Mode) {
    use magstand_tests::independent::run_case_on;
    let o = run_case_on(
        &Stand::default(),
        &suite_case("battery sag + current lag"),
        mode,
        4,
    );
    assert_named_exactly(
        &o,
        &["battery_sag", "current_lag"],
        &format!("default stand, battery and lag with bat_v logged, seed 4, {mode:?}"),
    );
    assert_lag_within(&o.diagnosis, 0.01, &format!("{mode:?}"));
}

/// Regression: the replay held a logged voltage over each interval at the row before it, so
/// behind a lag of the field (replayed without spin-up) each row's speed was the steady speed
/// at the previous row's voltage. A battery's sag moves the voltage at every step: the
/// generator's 0.5 s lag was calibrated at 0.484 s, the field's response off by up to 0.2 µT
/// for a second after each step, and the misfit named `unexplained` (seed 4, unstated). The
/// voltage now runs in a straight line between the rows and the motors follow it.
#[test]
fn a_battery_and_a_lag_are_named_alone_where_the_motors_follow_the_logged_voltage() {
    battery_and_lag_named_with_the_lag_where_it_is(magstand_tests::independent::Mode::Unstated);
}

/// Regression: with the stand stated, the same recording's lag was refined after the battery's
/// acceptance under the weights of the model before it, whose residual held the battery's sag
/// as noise at full load; those rows fix the lag's time constant. Under the weights of its own
/// model 0.495 s fitted better than the 0.481 s it kept, by 4,000 in chi-square, and the misfit
/// was named `unexplained`. After an acceptance the terms are now refined again under the
/// weights of the model they make.
#[test]
fn a_battery_and_a_lag_are_named_alone_where_the_lag_is_refined_under_its_models_weights() {
    battery_and_lag_named_with_the_lag_where_it_is(magstand_tests::independent::Mode::Stated);
}

/// Commands logged at a third of the magnetometer's rate and held between its rows (each
/// change shows zero to two rows late) were named, beside a slow lag, `hysteresis` and
/// `unexplained` without a word on the timing: the diagnosis now says what it sees in its
/// warnings. The recording without the hold gets no such warning.
#[test]
fn commands_held_over_rows_are_said_in_the_warnings() {
    let (rec, _) = recording(&suite_case("current lag 0.5 s"), 1);
    let rec = rec.select_rows(|r| r < 9000);
    let mut held = rec.clone();
    for column in held.thr.iter_mut() {
        let logged = column.clone();
        for (r, c) in column.iter_mut().enumerate() {
            *c = logged[r - r % 3];
        }
    }
    let config = magstand_diagnose::DiagnoseConfig::default()
        .check()
        .unwrap();
    let nominal = magstand_diagnose::unstated_nominal().unwrap();
    for (what, rec, expected) in [("as generated", &rec, false), ("held", &held, true)] {
        let d = magstand_diagnose::diagnose(rec, "held.csv", &nominal, &config).unwrap();
        let said = d
            .warnings
            .iter()
            .any(|w| w.contains("held.csv") && w.contains("multiple of 3 rows"));
        assert_eq!(said, expected, "{what}: warnings {:?}", d.warnings);
    }
}

/// The doubts `fit`, `diagnose`, `compensate` and `report` warn of (units, unread columns, a
/// supply that drops out, a temperature that jumps, a stand's magnetometer that spikes) are
/// about glitches, not about a stand's physics: every case of the suite, on all three of the
/// generator's stands at a seed no other test uses, reads without one. A rule that took a
/// battery's sag, a board's heating, a late magnetometer or a slow lag for a glitch would
/// warn a user of their own good data.
#[test]
fn recordings_of_a_stand_magstand_did_not_make_raise_no_doubt() {
    use magstand_tests::independent::{cases, recording_on};
    for stand in [Stand::default(), Stand::held_out(), Stand::octocopter()] {
        for case in cases() {
            let (rec, _) = recording_on(&stand, &case, 77);
            let doubts = rec.doubts();
            assert!(
                doubts.is_empty(),
                "{} on the stand of {} motors: {doubts:?}",
                case.label,
                stand.motors
            );
        }
    }
}
