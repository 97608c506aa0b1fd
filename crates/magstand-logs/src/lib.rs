//! Real vehicles: what a model becomes on PX4 and ArduPilot, and on firmware of one's own.
//!
//! * [`export`]: the best straight-line approximation of a model over its recorded range, as
//!   PX4's power-compensation parameters or ArduPilot's compassmot parameters, with the heading
//!   error that the autopilot's linear form leaves against the full model; ArduPilot's per-motor
//!   set; the full model as a dependency-free C header or `no_std` Rust module; and a JSON
//!   document for other tools.
//!
//! # Example
//! ```
//! use magstand_core::{Vec3, rbf::paper_tables};
//! use magstand_ident::{Model, InputSpec, InputKind, Structure, LocalLinearNet};
//! use magstand_logs::export::{LineInput, Span, linear_approximation, ardupilot_params};
//!
//! // The paper's Tables I-III as a model of overall throttle (µT = 100 x gauss).
//! let t = paper_tables();
//! let net = LocalLinearNet {
//!     partition: t[0].partition().clone(),
//!     coefficients: std::array::from_fn(|a| {
//!         (0..3).map(|i| vec![100.0 * t[a].slopes()[i], 100.0 * t[a].intercepts()[i]]).collect()
//!     }),
//! };
//! let input = InputSpec { kind: InputKind::Throttle, lo: 0.0, hi: 1.0, motors: 4, off_raw: 0.0 };
//! let model = Model::new("global", input, Vec3::new(20.0, 1.0, 45.0), Structure::LocalLinear(net), None);
//! let line = linear_approximation(&model, LineInput::Throttle, Span::ModelRange)?;
//! let text = ardupilot_params(&line, 1, None)?;
//! assert!(text.contains("COMPASS_MOTCT,1"));
//! // ArduPilot adds COMPASS_MOT x throttle, so its value is minus the fitted slope, in mG.
//! assert!((line.slope[2] * -10.0 - 170.0).abs() < 60.0, "{:?}", line.slope);
//! # Ok::<(), magstand_logs::LogsError>(())
//! ```
#![warn(missing_docs)]

pub mod ardupilot;
pub mod contents;
pub mod dataflash;
pub mod earth;
mod error;
pub mod export;
pub mod field_units;
pub mod import;
pub mod log_writer;
pub mod px4;
pub mod streams;
pub mod ulog;

pub use error::LogsError;
