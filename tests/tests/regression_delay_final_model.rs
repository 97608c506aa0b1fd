//! A late magnetometer's final model left far from its own optimum. The forward search named
//! `time_offset` rightly, but the final model kept the delay where the searches near the
//! optimum of earlier weights had left it: a delay's chi-square has a cliff at each sample
//! interval (a command change at a row passes the delayed read), and under the final model's
//! own weights its optimum lay in a narrow well beyond one. On the independent generator's
//! default stand at 50 Hz with a 0.3 s late magnetometer (seed 1, nothing stated), the
//! augmented simulation left a held-out RMSE of 0.64, 0.35, 1.02 µT at a delay of 0.272 s,
//! where the same recording diagnosed with the stand stated leaves 0.23, 0.20, 0.28 µT; the
//! model file `compensate` uses was three times worse than the data allow. The final model is
//! now refitted under its own weights, the delay over its whole range and then the lead, and
//! where that fits significantly better every term near where it now is
//! (`polish_beside_delay`): 0.284 s and 0.23, 0.20, 0.28 µT.
//!
//! Kept only where the held-out error falls too: on the hexacopter with the commands logged
//! 0.15 s late (seed 1), the weights of the final model (which misfits the first sample after
//! each step, whose moment within its interval the log does not tell) favoured a lead and
//! spin-up that fitted the identification rows better and the held-out ones worse, 0.45,
//! 0.73, 0.61 -> 0.57, 0.95, 0.79 µT, 1.2 times what the stand stated leaves.
//!
//! Asserted against the stand stated (what the recording allows), on the stands and seeds
//! that showed it and on three never looked at: the default stand at 50 Hz with the late
//! magnetometer, seed 3, the hexacopter with it, seed 3, and with the commands late, seed 4.

use magstand_standgen::Stand;
use magstand_tests::independent::{Mode, named_param, run_case_on, suite_case};

/// Most a diagnosis with nothing stated may leave held out on an axis, as a multiple of
/// what the same recording leaves with the generator's stand stated.
const UNSTATED_OVER_STATED: f64 = 1.15;

#[test]
fn a_delays_final_model_fits_as_well_as_the_stated_stand_allows() {
    let at_50_hz = Stand {
        rate_hz: 50.0,
        ..Stand::default()
    };
    let hexacopter = Stand::held_out();
    let late_mag = ("time offset 0.3 s", 0.3);
    let late_commands = ("commands logged late 0.15 s", -0.15);
    for (stand, name, (label, generated_s), seed) in [
        (&at_50_hz, "default stand at 50 Hz", late_mag, 1),
        (&hexacopter, "hexacopter", late_commands, 1),
        (&at_50_hz, "default stand at 50 Hz", late_mag, 3),
        (&hexacopter, "hexacopter", late_mag, 3),
        (&hexacopter, "hexacopter", late_commands, 4),
    ] {
        let case = suite_case(label);
        let unstated = run_case_on(stand, &case, Mode::Unstated, seed);
        let stated = run_case_on(stand, &case, Mode::Stated, seed);
        for o in [&unstated, &stated] {
            assert_eq!(
                o.verdict,
                ["time_offset"],
                "{name}, {label}, seed {seed}: {}",
                o.diagnosis.summary()
            );
        }
        let delay = named_param(&unstated.diagnosis, "time_offset", "mag_delay_s")
            .expect("the delay is reported");
        assert!(
            (delay.value - generated_s).abs() < 0.025,
            "{name}, {label}, seed {seed}: delay {} s, generated {generated_s} s",
            delay.value
        );
        let (got, allowed) = (
            unstated.diagnosis.simulation.holdout_rmse_after_ut,
            stated.diagnosis.simulation.holdout_rmse_after_ut,
        );
        let ratio = [0, 1, 2].map(|a| got[a] / allowed[a]);
        assert!(
            ratio.iter().all(|r| *r <= UNSTATED_OVER_STATED),
            "{name}, {label}, seed {seed}: the unstated final model leaves {got:?} µT held \
             out, the stated one {allowed:?} µT ({ratio:?} times; delay {} s)",
            delay.value
        );
    }
}
