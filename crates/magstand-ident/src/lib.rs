//! Identification and compensation of the magnetometer disturbance caused by motor currents.
//!
//! The method of Czyba, Janusz and Szafranski, and what improves on it:
//!
//! * [`local_linear`]: local linear models blended by normalized Gaussian RBFs (eq. 10-14),
//!   with the paper's local estimation (eq. 15-19) and global estimation;
//! * inverse-variance weighting with a fitted noise model ([`noise_model`]): the paper's
//!   "variance grows with control input", used to make the estimates efficient and written out
//!   for a Kalman filter;
//! * automatic structure ([`structure`], LOLIMOT): number, centres and widths from the data;
//! * inputs beyond the overall throttle ([`InputKind`]): per-motor commands, supply current;
//! * the autopilots' straight lines for comparison ([`baseline`]);
//! * metrics ([`metrics`]): eq. 9, eq. 20, heading error, interference; and the autopilots'
//!   own figures beside a model's ([`compatibility`]);
//! * the rule that chooses among model families by held-out error ([`family_choice`]);
//! * recursive estimation, the paper's future work ([`adaptive`]): the coefficients updated
//!   row by row while compensating, with a forgetting factor.
//!
//! Settings are checked before fitting: a [`FitConfig`] becomes a [`ValidFitConfig`], which
//! implements [`Fit`]. The resulting [`Model`] implements [`Predict`] and compensates.
//!
//! # Example
//! ```
//! use magstand_core::{Recording, Vec3};
//! use magstand_core::rbf::paper_tables;
//! use magstand_ident::{FitConfig, Estimation, Fit, Dataset, InputKind};
//!
//! // A stair whose deviation follows the paper's Tables I-III exactly (eq. 9 shift included).
//! let tables = paper_tables();
//! let mut rec = Recording { thr: vec![vec![]], overall_only: true, ..Default::default() };
//! for k in 0..2100 {
//!     let u = ((k / 100) as f64 / 20.0).min(1.0);
//!     rec.t_s.push(k as f64 * 0.01);
//!     rec.thr[0].push(u);
//!     let d = |a: usize| (tables[a].eval(u) - tables[a].eval(0.0)) * 100.0;
//!     rec.mag_ut.push(Vec3::new(20.0 + d(0), 1.0 + d(1), 45.0 + d(2)));
//! }
//! let data = Dataset::from_recording(&rec, InputKind::Throttle, "stair")?;
//! let model = FitConfig::fixed(vec![0.0, 0.5, 1.0], 4.0, Estimation::Global).check()?.fit(&data)?;
//! let magstand_ident::Structure::LocalLinear(net) = &model.structure else { unreachable!() };
//! // Global estimation returns the tables' slopes (µT per unit throttle = 100 x gauss).
//! assert!((net.coefficients[1][2][0] - 17.656376).abs() < 1e-6);
//! # Ok::<(), magstand_ident::IdentError>(())
//! ```
#![warn(missing_docs)]

pub mod adaptive;
pub mod baseline;
pub mod compatibility;
mod config;
mod dataset;
mod error;
pub mod family_choice;
pub mod flight;
pub mod least_squares;
pub mod local_linear;
pub mod methods;
pub mod metrics;
mod model;
pub mod noise_model;
pub mod row_groups;
pub mod structure;

pub use config::{
    Family, Fit, FitConfig, HeldOut, Predict, ValidFitConfig, evenly_spaced_centers,
    paper_ratio_width,
};
pub use dataset::{
    Dataset, HOLDOUT_EVERY, InputKind, InputSpec, MIN_ROWS, identification_block_s,
    identification_split, motors_off_reference, motors_off_rows,
};
pub use error::{FitSetting, IdentError};
pub use local_linear::{Estimation, LocalLinearNet};
pub use model::{
    FORMAT, FitSummary, IdentifiedRange, Model, Scratch, Structure, VERSION, method_name,
};
