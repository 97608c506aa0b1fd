//! Regression: the automatic structure (LOLIMOT) split an interval as long as each half held at
//! least one row. On a stair, a half could then hold the rows of a single throttle level: a local
//! line with no slope information. The search itself could still fit it on its subset of rows,
//! but the final fit on all rows with the noise weights came out singular, and the whole fit
//! failed ("regressor `intercept` of local model 8 is not independent"). It showed in run 5 of a
//! Monte Carlo study of the shipped fleet-stair scenario. A split is now taken only when each
//! half keeps enough rows at two or more distinct inputs.
use magstand_ident::methods::by_id;
use magstand_study::StudyConfig;
use magstand_tests::scenario;

#[test]
fn automatic_structure_fits_every_run_of_the_fleet_study_that_broke_it() {
    let s = scenario("fleet-stair", &[]);
    let study = StudyConfig::new(6, 3).check(&s).unwrap();
    let seed = magstand_study::run::derive_seed(3, 5);
    let (ident_s, _) = magstand_study::run::run_scenarios(&study, seed).unwrap();
    let ident = magstand_sim::simulate(&ident_s, seed);
    let model = by_id("automatic")
        .unwrap()
        .config
        .check()
        .unwrap()
        .fit_recording(&ident, "fleet-stair run 5");
    let model = model.unwrap_or_else(|e| panic!("automatic fit failed: {e}"));
    // And it is a good model, not merely a model: held-out error near the noise level.
    let held = model.summary.as_ref().unwrap().holdout_rmse_ut;
    assert!(held.iter().all(|h| *h < 1.5), "held-out rmse {held:?}");
}
