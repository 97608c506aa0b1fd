//! Mismatch diagnosis: when a simulated test stand and a recording differ, locate the
//! mismatch, name the physics the simulation left out, model it, and show the fit improve.
//!
//! 1. **Baseline.** The recording's own motor commands are replayed through the nominal
//!    physics ([`magstand_sim::replay`]: dead zone, spin-up lag, supply, current law) and the
//!    free parameters are calibrated to the recording: the motors-off field and the wiring
//!    gains on the motor currents, with a cubic in rotor speed so that a current law other than
//!    the nominal one is followed. Fits use only identification rows; every third time block is
//!    held out and used only to judge.
//! 2. **Locate.** Held-out residuals, standardized by a noise variance that grows with the load
//!    (eq. 8), are tested against white noise (Ljung-Box) and located by windowed chi-square
//!    tests ([`Location`]): axes, throttle range, time span, up against down, steps against
//!    steady state, one motor or all.
//! 3. **Name.** Each catalog [`Effect`] is fitted (its nonlinear parameters by search, its
//!    regressors by weighted least squares) and judged by a one-sided paired test of its
//!    held-out improvement over blocks. The best significant one is accepted, the accepted
//!    terms' nonlinear parameters are refitted together, and the search repeats, so several
//!    effects are found. Candidates are accepted only when the baseline residual fails the
//!    white-noise test of step 2 (a clean recording stays clean however many candidates are
//!    tried); what remains structured is reported as "unexplained" with its location rather
//!    than forced onto a wrong name. A term that re-fits a stand constant the scenario leaves
//!    out (a dead zone, a spin-up time) is the stand's calibration, not a finding: it stays in
//!    the model and is reported under `baseline.calibration`. Only a stated constant the data
//!    reject, or a lag slower than any spin-up, is named.
//! 4. **Model it.** The accepted effects switch the matching simulator modules on with the
//!    fitted values ([`Diagnosis::augmented_scenario`]), and the replayed simulation of that
//!    scenario is compared with the recording again. The calibrated augmented physics is also
//!    a model that compensates recordings ([`AugmentedModel`], `magstand compensate`).
//!
//! # Example
//! ```
//! use magstand_diagnose::{DiagnoseConfig, diagnose};
//! use magstand_sim::{Scenario, simulate};
//!
//! // The recording's stand spins up in 0.3 s; the scenario states 0.06 s. (A constant the
//! // scenario leaves out would be calibrated and reported under `baseline.calibration`.)
//! let stand = r#"
//!     name = "steps"
//!     [motors]
//!     spinup_tau_s = 0.06
//!     [program]
//!     kind = "random_steps"
//!     off_s = 2.0
//!     count = 40
//!     dwell_min_s = 1.0
//!     dwell_max_s = 2.0
//!     [supply]
//!     kind = "bench"
//!     voltage_v = 12.0
//!     [magnetometer]
//!     odr_hz = 50.0
//! "#;
//! let nominal = Scenario::from_toml_str(stand, "nominal")?.check("nominal", None)?;
//! let real = Scenario::from_toml_with_overrides(stand, "real", &["motors.spinup_tau_s=0.3".into()])?
//!     .check("real", None)?;
//! let rec = simulate(&real, 1);
//! let d = diagnose(&rec, "real.csv", &nominal, &DiagnoseConfig::default().check()?)?;
//! assert_eq!(d.verdict, ["current_lag"]);
//! let tau = &d.effects[0].params[0];
//! assert!((tau.value - 0.3).abs() < 0.05, "{tau:?}");
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
#![warn(missing_docs)]

pub mod augmented_model;
mod config;
pub mod diagnosis;
pub mod effects;
mod error;
mod fit;
mod locate;
pub mod model_choice;
pub mod observer;
mod optimize;
mod pipeline;
mod stats;
mod versioned_json;

pub use augmented_model::AugmentedModel;
pub use config::{DiagnoseConfig, MAX_BLOCK_S, ValidConfig};
pub use diagnosis::{Diagnosis, UNEXPLAINED};
pub use effects::{Context, Effect, EffectFit, Param, catalog};
pub use error::DiagnoseError;
pub use locate::Location;
pub use observer::{DiagnoseObserver, Stage};
pub use optimize::Search;
pub use pipeline::{diagnose, diagnose_observed};

/// The nominal test stand assumed when no scenario is given: the simulator's defaults (dead
/// zone 0.37, 920 KV motors, default wiring) on a 12 V bench supply.
pub const DEFAULT_NOMINAL: &str = r#"
name = "default nominal stand"
description = "Simulator defaults on a 12 V bench supply; the program is replaced by the recording's commands"
[program]
kind = "stair"
steps = 10
dwell_s = 10.0
[supply]
kind = "bench"
voltage_v = 12.0
"#;

/// The nominal stand of a diagnosis given no scenario: [`DEFAULT_NOMINAL`] with nothing
/// stated (`Scenario::states` is false for every key), since its constants are starting
/// points, not claims about the user's stand.
pub fn unstated_nominal() -> Result<magstand_sim::ValidScenario, DiagnoseError> {
    Ok(
        magstand_sim::Scenario::from_toml_str(DEFAULT_NOMINAL, "default nominal stand")?
            .with_nothing_stated()
            .check("default nominal stand", None)?,
    )
}
