//! A restrained multirotor test stand, simulated with known ground truth.
//!
//! It reproduces the experiment of Czyba, Janusz and Szafranski: a quadrotor held down, its
//! motors commanded directly, the magnetometer logged while the overall throttle rises
//! stair-wise. Each physical part is a module with its own parameters in the scenario file:
//!
//! | module | physics |
//! |---|---|
//! | [`program`] | throttle programs: stair, ramp, per-motor steps, random steps, replay, differential commands |
//! | [`motor`] | ESC dead zone, first-order spin-up, propeller load, voltage dependence |
//! | [`battery`] | bench supply, or LiPo battery with discharge curve and internal resistance |
//! | [`wiring`] | current paths and their field at the sensor by Biot-Savart |
//! | [`noise`] | sensor noise mu and load-dependent noise eta (eq. 8) |
//! | [`thermal`] | board heating and magnetometer offset drift |
//! | [`hysteresis`] | play-operator hysteresis of nearby steel |
//! | [`interference`] | an alternating field from equipment beside the stand |
//! | [`replay`] | the electrical part alone on a recording's own commands, for the diagnosis |
//! | [`magnetometer`] | Earth field, hard and soft iron, range, quantization, data rate |
//! | [`stand`] | the frame as a rapier3d rigid body on a compliant mount |
//! | [`motion`] | a gimbal turning the whole stand: a flight's attitude changes without flying |
//!
//! The measurement follows eq. 8, `m_meas = m + mu + dmag(thr) + eta(thr)`, and the recording
//! carries the truth: `true_field` (m), `true_dist` (dmag) and `true_sd` (sd of mu + eta).
//!
//! # Example
//! ```
//! use magstand_sim::{Scenario, simulate};
//!
//! let text = r#"
//!     name = "short stair"
//!     [program]
//!     kind = "stair"
//!     off_s = 0.5
//!     steps = 4
//!     dwell_s = 0.5
//! "#;
//! let scenario = Scenario::from_toml_str(text, "inline")?.check("inline", None)?;
//! let rec = simulate(&scenario, 7);
//! let truth = rec.truth.as_ref().unwrap();
//! // Motors off: no disturbance. Full throttle: tens of amperes, a clear disturbance.
//! assert_eq!(truth.dist_ut[0].norm(), 0.0);
//! let last_on = rec.len() - 60;
//! assert!(truth.dist_ut[last_on].norm() > 5.0);
//! # Ok::<(), magstand_sim::SimError>(())
//! ```
#![warn(missing_docs)]

pub mod battery;
mod error;
pub mod hysteresis;
pub mod interference;
pub mod lag;
pub mod magnetometer;
pub mod motion;
pub mod motor;
pub mod noise;
pub mod program;
pub mod replay;
pub mod scenario;
mod simulate;
pub mod stand;
pub mod stand_module;
pub mod thermal;
pub mod variation;
pub mod wiring;

pub use error::SimError;

/// Largest field a scenario may state (a hard-iron offset, an interference amplitude), µT:
/// ten thousand µT is two hundred Earth fields, beyond any magnetometer's range.
pub const MAX_FIELD_UT: f64 = 1e4;
/// Largest field per ampere or per degree a scenario may state (wiring, hysteresis and
/// thermal gains), µT/A or µT/°C.
pub const MAX_GAIN_UT_PER_A: f64 = 1e3;
/// Largest distance in a stand's geometry (sensor position, wire ends, loops), m.
pub const MAX_DISTANCE_M: f64 = 10.0;
pub use scenario::{Scenario, ValidScenario};
pub use simulate::{Observer, Silent, simulate, simulate_batch, simulate_observed};

/// Scenarios shipped in `scenarios/`, embedded so that the binary runs without the source tree.
pub mod builtin {
    /// (file name without `.toml`, TOML text) of every shipped scenario.
    pub const ALL: &[(&str, &str)] = &[
        (
            "czyba2015-stair",
            include_str!("../../../scenarios/czyba2015-stair.toml"),
        ),
        (
            "czyba2015-tables",
            include_str!("../../../scenarios/czyba2015-tables.toml"),
        ),
        (
            "bench-supply-stair",
            include_str!("../../../scenarios/bench-supply-stair.toml"),
        ),
        (
            "per-motor-steps",
            include_str!("../../../scenarios/per-motor-steps.toml"),
        ),
        (
            "random-steps",
            include_str!("../../../scenarios/random-steps.toml"),
        ),
        (
            "battery-sag",
            include_str!("../../../scenarios/battery-sag.toml"),
        ),
        ("thermal", include_str!("../../../scenarios/thermal.toml")),
        ("lag", include_str!("../../../scenarios/lag.toml")),
        (
            "hysteresis",
            include_str!("../../../scenarios/hysteresis.toml"),
        ),
        (
            "asymmetric-wiring",
            include_str!("../../../scenarios/asymmetric-wiring.toml"),
        ),
        (
            "fleet-stair",
            include_str!("../../../scenarios/fleet-stair.toml"),
        ),
        (
            "flight-turns",
            include_str!("../../../scenarios/flight-turns.toml"),
        ),
    ];

    /// The TOML text of a shipped scenario by name.
    pub fn get(name: &str) -> Option<&'static str> {
        ALL.iter().find(|(n, _)| *n == name).map(|(_, t)| *t)
    }
}
