//! Shared foundations of magstand.
//!
//! * [`Recording`]: one magnetometer sample per row, with the motor commands and optional
//!   battery, temperature, IMU and ground-truth columns. Every subcommand reads and writes it.
//! * [`recording_csv`]: the public CSV contract of a recording, read with errors that name the
//!   file, row and column.
//! * [`rbf`]: normalized Gaussian radial basis functions and the blended local linear form of
//!   Czyba, Janusz and Szafranski (eq. 12-14), used by the simulator's paper-table disturbance
//!   and by the identification crate.
//! * [`interpolation`]: a sampled column read between its samples, held at its ends.
//! * [`atomic_file`]: write-then-rename output so that no half-written file is ever left behind.
//! * [`input_file`]: reading a user's file with its cost bounded by a size limit.
//! * `file_fuzzing` (feature `file-fuzzing`): the hostile values the file-format property
//!   tests of every crate feed their readers.
//!
//! # Example
//! ```
//! use magstand_core::{Recording, recording_csv};
//!
//! let text = "t_s,thr,mag_x_ut,mag_y_ut,mag_z_ut\n0.0,0.0,20.0,1.0,-45.0\n0.1,0.5,22.0,3.0,-50.0\n";
//! let rec = recording_csv::read_str(text, "inline.csv").unwrap();
//! assert_eq!(rec.len(), 2);
//! assert_eq!(rec.overall_throttle(1), 0.5);
//! assert_eq!(rec.mag_ut[1].y, 3.0);
//! ```
#![warn(missing_docs)]

pub mod atomic_file;
pub mod bounded_search;
mod error;
mod fast_csv;
#[cfg(any(test, feature = "file-fuzzing"))]
pub mod file_fuzzing;
pub mod fixed_decimal;
pub mod held_out;
pub mod input_file;
pub mod interpolation;
pub mod magnetometer_frame;
pub mod magnetometer_slot;
pub mod rbf;
mod recording;
pub mod recording_csv;
pub mod seeds;

pub use error::CoreError;
pub use recording::{
    AUTOPILOT_THROTTLE, GAP_INTERVALS, GroundTruth, ImuColumns, OFF_COMMAND, Recording,
    rows_after_gaps, typical_interval_s,
};

/// Whether `v` is a finite number of magnitude at most `limit`: the test every reader and
/// writer of magstand's files applies to a number before it is used or written (a NaN fails).
///
/// ```
/// assert!(magstand_core::within(-3.0, 5.0));
/// assert!(!magstand_core::within(f64::NAN, 5.0) && !magstand_core::within(1e308, 1e5));
/// ```
pub fn within(v: f64, limit: f64) -> bool {
    v.is_finite() && v.abs() <= limit
}

/// A 3-vector of f64, used for every per-axis quantity (field, acceleration, rate).
pub type Vec3 = nalgebra::Vector3<f64>;

/// An attitude: the rotation from the body frame to north-east-down.
pub type Quat = nalgebra::UnitQuaternion<f64>;

/// 3x3 matrix of f64.
pub type Mat3 = nalgebra::Matrix3<f64>;

/// Axis names in the order magstand always uses them (body frame: forward, right, down).
pub const AXES: [&str; 3] = ["x", "y", "z"];
