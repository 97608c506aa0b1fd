//! Regression: on the shipped bench-supply stand sampled at 100 Hz, with no effect switched
//! on, the diagnosis named a `time_offset` of one sample (p about 4e-5) although the residual
//! passed the white-noise test and the held-out RMSE moved by 0.0001 µT: at 28 000 rows the
//! candidate tests pick up the frame's small rocking on its mount after each step, which the
//! replay leaves out. Names are now given only when the baseline residual fails the
//! white-noise test; the candidates are still tried once and recorded.
mod common;
use common::{bench_supply_stair, diagnose_default};
use magstand_sim::simulate;

#[test]
fn a_clean_recording_at_100_hz_gets_an_empty_verdict() {
    let (nominal, real) = bench_supply_stair(&[]);
    // The seed that gave the false name.
    let rec = simulate(&real, 11);
    let d = diagnose_default(&rec, "clean.csv", &nominal);
    assert!(d.verdict.is_empty(), "{}", d.summary());
    let first = &d.rounds[0];
    let white = first.whiteness_p.unwrap();
    assert!(
        white.iter().all(|&p| p >= d.settings.significance / 3.0),
        "the residual was white: {white:?}"
    );
    assert!(
        first.candidates.iter().any(|c| c.p_value.is_some()) && first.accepted.is_none(),
        "{:?}",
        first
    );
}
