//! The default fit chooses among model families (local linear on throttle, on current, per
//! motor; the stand's physics) by held-out error. Judged against ground truth on recordings
//! magstand did not make (the independent stand generator: its own current law, dead zone,
//! supply, noise, and a field with a term in the square of the total current), identified on
//! one recording and judged on another of the same stand.
use magstand_core::{Quat, Recording};
use magstand_diagnose::model_choice::{PHYSICS, choose_model, fit_physics, identification_split};
use magstand_diagnose::unstated_nominal;
use magstand_ident::family_choice::FamilyId;
use magstand_ident::{Dataset, FitConfig, InputKind};
use magstand_tests::independent::{Case, recording, rmse_ut};

fn control(log_bat_v: bool) -> Case {
    Case {
        label: "control",
        effects: vec![],
        log_bat_v,
        log_temp: false,
    }
}

/// The truth RMSE (norm over the axes) of every family fitted on its own, by family id.
fn truth_rmse_by_family(
    ident: &Recording,
    valid: &Recording,
    truth: &[[f64; 3]],
) -> Vec<(String, f64)> {
    let norm = |e: [f64; 3]| (e.iter().map(|x| x * x).sum::<f64>()).sqrt();
    let mut out = Vec::new();
    for (id, input) in [
        ("automatic", InputKind::Throttle),
        ("automatic-current", InputKind::Current),
        ("automatic-motors", InputKind::Motors),
    ] {
        let Ok(data) = Dataset::from_recording(ident, input, "ident") else {
            continue;
        };
        let (m, _) = FitConfig::automatic()
            .with_input(input)
            .check()
            .unwrap()
            .fit_holding_out(&data)
            .unwrap();
        out.push((id.to_string(), norm(rmse_ut(&m.dist_column(valid), truth))));
    }
    let split = identification_split(ident).check().unwrap();
    let p = fit_physics(ident, "ident", &unstated_nominal().unwrap(), &split).unwrap();
    let dist = p.model.dist_column(valid, "valid").unwrap();
    out.push((PHYSICS.to_string(), norm(rmse_ut(&dist, truth))));
    out
}

/// Fails unless the `chosen` family's truth RMSE is within 1.25 times the best family's.
fn assert_within_truths_best(by_family: &[(String, f64)], chosen: &str) {
    let best = by_family.iter().map(|f| f.1).fold(f64::INFINITY, f64::min);
    let mine = by_family.iter().find(|f| f.0 == chosen).unwrap().1;
    assert!(
        mine <= 1.25 * best,
        "chosen {chosen} {mine} µT, families {by_family:?}"
    );
}

/// With `bat_a` logged every family applies; the one chosen by held-out error is, against
/// the generator's truth on another recording, within 0.015 µT RMS on every axis (the
/// issue's goal), and no worse than 1.25 times the most accurate family.
#[test]
fn with_current_logged_the_choice_meets_the_goal_on_an_independent_stand() {
    let (ident, _) = recording(&control(true), 31);
    let (valid, truth) = recording(&control(true), 32);
    let (chosen, choice) = choose_model(&ident, "ident", &unstated_nominal().unwrap(), None)
        .unwrap_or_else(|e| panic!("{e}"));
    let scored: Vec<&str> = choice
        .families
        .iter()
        .filter(|f| f.holdout_rmse_ut.is_some())
        .map(|f| f.family.id())
        .collect();
    // bat_a is logged and the commands differ (attitude-like differentials).
    assert_eq!(
        scored,
        [
            "automatic",
            "automatic-current",
            "automatic-motors",
            PHYSICS
        ],
        "{choice:#?}"
    );
    let e = rmse_ut(&chosen.dist_column(&valid, "valid").unwrap(), &truth);
    assert!(
        e.iter().all(|x| *x <= 0.015),
        "{} chosen: RMSE {e:?} µT against the truth\n{choice:#?}",
        chosen.family()
    );
    let by_family = truth_rmse_by_family(&ident, &valid, &truth);
    // Printed for results/family-choice.md (`--nocapture`).
    eprintln!(
        "with bat_a: {} chosen, RMSE {e:?} µT against the truth; by family {by_family:?}",
        chosen.family()
    );
    assert_within_truths_best(&by_family, chosen.family());
}

/// Without `bat_a` the current family is not tried and says why; the choice still agrees
/// with the truth's ranking of the families it tried, and meets issue 18's goal of 0.015 µT
/// per axis against the truth (the physics family, whose current law follows this
/// generator's: 0.008, 0.003, 0.007 µT; the best family left 0.049, 0.031, 0.073 µT while
/// the current law was held to a cubic in speed).
#[test]
fn without_current_the_choice_follows_the_truth_ranking() {
    let (mut ident, _) = recording(&control(false), 33);
    ident.bat_a = None;
    let (mut valid, truth) = recording(&control(false), 34);
    valid.bat_a = None;
    let (chosen, choice) =
        choose_model(&ident, "ident", &unstated_nominal().unwrap(), None).unwrap();
    let current = choice
        .families
        .iter()
        .find(|f| f.family == FamilyId::Current)
        .unwrap();
    assert!(
        current.holdout_rmse_ut.is_none()
            && current.note.as_deref().is_some_and(|n| n.contains("bat_a")),
        "{current:?}"
    );
    let by_family = truth_rmse_by_family(&ident, &valid, &truth);
    assert!(
        by_family.iter().all(|f| f.0 != "automatic-current"),
        "{by_family:?}"
    );
    let e = rmse_ut(&chosen.dist_column(&valid, "valid").unwrap(), &truth);
    eprintln!(
        "without bat_a: {} chosen, RMSE {e:?} µT against the truth; by family {by_family:?}",
        chosen.family()
    );
    assert_within_truths_best(&by_family, chosen.family());
    assert!(
        e.iter().all(|v| *v <= 0.015),
        "{} chosen: RMSE {e:?} µT against the truth (goal 0.015 per axis)",
        chosen.family()
    );
}

/// A recording that is not from a restrained stand (a flight: its rows marked `flight`, its
/// attitude logged) never gets the stand's physics: that family is not tried, and says why.
#[test]
fn a_flight_never_gets_the_physics_family() {
    let (mut rec, _) = recording(&control(true), 35);
    rec.attitude = Some(vec![Quat::identity(); rec.len()]);
    rec.extra
        .push(("segment".into(), vec!["flight".to_string(); rec.len()]));
    let (chosen, choice) =
        choose_model(&rec, "flight", &unstated_nominal().unwrap(), None).unwrap();
    assert_ne!(chosen.family(), PHYSICS);
    let physics = choice
        .families
        .iter()
        .find(|f| f.family == FamilyId::Physics)
        .unwrap();
    assert!(
        physics.holdout_rmse_ut.is_none()
            && physics
                .note
                .as_deref()
                .is_some_and(|n| n.contains("flight")),
        "{physics:?}"
    );
}

/// The paper-like study (battery, `bat_a` logged): the default fit's choice is, in median over
/// the runs, within 2x of the current-input model's error against the simulator's truth,
/// where the local linear model on throttle leaves far more (battery sag is outside its
/// structure). The physics method runs in the study too, and beats the throttle model.
#[test]
fn in_the_paper_like_study_the_choice_is_within_twice_the_current_model() {
    use magstand_study::{Silent, StudyConfig, Summary, run_study};
    let scenario = magstand_sim::Scenario::load_spec("builtin:czyba2015-stair", &[]).unwrap();
    let mut config = StudyConfig::new(3, 3);
    config.methods = ["automatic", "automatic-current", "physics", "chosen"]
        .map(String::from)
        .to_vec();
    let study = config.check(&scenario).unwrap();
    let result = run_study(&study, Some(2), &Silent).unwrap();
    let summary = Summary::new(result.info.clone(), &result.outcomes);
    let p50 = |id: &str| {
        let m = summary.method(id).unwrap();
        assert_eq!(m.failures, 0, "{id} failed: {:?}", result.outcomes);
        m.figure(magstand_study::FigureId::RmseUt).unwrap().p50
    };
    let (throttle, current, physics, chosen) = (
        p50("automatic"),
        p50("automatic-current"),
        p50("physics"),
        p50("chosen"),
    );
    assert!(
        chosen <= 2.0 * current,
        "chosen {chosen} µT against current {current} µT"
    );
    assert!(
        physics < throttle,
        "physics {physics} µT against throttle {throttle} µT"
    );
}
