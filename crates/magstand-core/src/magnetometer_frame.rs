//! The frame an autopilot's magnetometer compensation lives in, carried from `import` through
//! `fit` to `export`, so that coefficients fitted in the body frame are written in the frame
//! the firmware adds them in.
//!
//! A recording's field is in the body frame. PX4 adds its power compensation to the reading as
//! the driver published it, before its calibration: `R · S · (raw + power · C − offset)`, with
//! `R` the calibration's rotation (`CAL_MAGn_ROT`, or `SENS_BOARD_ROT` for an internal sensor)
//! and `S` its scale matrix (`CAL_MAGn_{X,Y,Z}SCALE`, `ODIAG`). A body-frame slope `s` is
//! therefore `C = −(R · S)⁻¹ s` in PX4's parameters, not `−s`: on a board mounted turned by
//! 180 degrees the x and y coefficients have the other sign. `import` writes `R · S` (the
//! transform it applied to the readings) in the recording's `mag_to_body` column, the same in
//! every row; `fit` keeps it in the model file. ArduPilot adds its compensation after rotating
//! the reading to the body frame; firmware without per-motor compensation adds it before the
//! compass's soft-iron matrix, which its import writes there instead (later firmware needs
//! none).
//!
//! # Example
//! ```
//! use magstand_core::magnetometer_frame::SensorToBody;
//! use magstand_core::Vec3;
//!
//! // A sensor turned by 180 degrees about z, its x axis read 10 % large.
//! let frame: SensorToBody = "-1.1 0 0 0 -1 0 0 0 1".parse().unwrap();
//! let body = Vec3::new(2.2, 1.0, 3.0);
//! let sensor = frame.to_sensor(body).unwrap();
//! assert!((sensor - Vec3::new(-2.0, -1.0, 3.0)).norm() < 1e-12);
//! assert_eq!(frame.to_string().parse::<SensorToBody>(), Ok(frame));
//! assert!("1 0 0 0 1 0 0 0 0".parse::<SensorToBody>().is_err()); // singular
//! ```
use std::fmt;
use std::path::Path;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

use crate::{CoreError, Recording, Vec3};

/// The recording column that holds the transform.
pub const COLUMN: &str = "mag_to_body";

/// The range a transform's singular values must lie in: a calibration's rotation times its
/// scale matrix stretches no axis far from 1, and one that all but flattens an axis would
/// turn a compensation into noise.
const SINGULAR_VALUES: std::ops::RangeInclusive<f64> = 1e-3..=1e3;

/// The matrix that took a magnetometer's readings, as its driver published them, to a
/// recording's body frame (row by row: `body = M · sensor`). It is invertible and finite.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "[[f64; 3]; 3]", into = "[[f64; 3]; 3]")]
pub struct SensorToBody {
    rows: [[f64; 3]; 3],
}

impl SensorToBody {
    /// The transform with these rows, or why it cannot be one: a number that is not finite,
    /// or a matrix that is (nearly) singular.
    pub fn new(rows: [[f64; 3]; 3]) -> Result<Self, String> {
        if rows.iter().flatten().any(|v| !v.is_finite()) {
            return Err(format!(
                "a sensor-to-body matrix of finite numbers; found {rows:?}"
            ));
        }
        let singular = crate::Mat3::from_fn(|r, c| rows[r][c]).singular_values();
        let (smallest, largest) = (singular.min(), singular.max());
        if !SINGULAR_VALUES.contains(&smallest) || !SINGULAR_VALUES.contains(&largest) {
            return Err(format!(
                "an invertible sensor-to-body matrix whose singular values lie in {:e} to {:e}; found {rows:?}, whose singular values run from {smallest:.3e} to {largest:.3e}",
                SINGULAR_VALUES.start(),
                SINGULAR_VALUES.end()
            ));
        }
        Ok(Self { rows })
    }

    /// The transform of matrix `m`, or why it cannot be one ([`SensorToBody::new`]).
    pub fn from_matrix(m: &crate::Mat3) -> Result<Self, String> {
        Self::new(std::array::from_fn(|r| std::array::from_fn(|c| m[(r, c)])))
    }

    /// The matrix as a nalgebra matrix.
    pub fn matrix(&self) -> crate::Mat3 {
        crate::Mat3::from_fn(|r, c| self.rows[r][c])
    }

    /// The rows of the matrix.
    pub fn rows(&self) -> [[f64; 3]; 3] {
        self.rows
    }

    /// Whether the transform is the identity (a sensor read in the body frame, uncalibrated).
    pub fn is_identity(&self) -> bool {
        self.matrix() == crate::Mat3::identity()
    }

    /// A body-frame vector in the sensor's frame: `M⁻¹ · body`, by a QR solve. None only where
    /// the solve fails, which [`SensorToBody::new`]'s test of the singular values rules out.
    pub fn to_sensor(&self, body: Vec3) -> Option<Vec3> {
        self.matrix()
            .qr()
            .solve(&body)
            .filter(|v| v.iter().all(|x| x.is_finite()))
    }

    /// The transform written in `rec`'s [`COLUMN`], read from `path`: None where the column is
    /// absent or every cell empty; an error naming the row of a cell that is not one, or of one
    /// that differs from the rows before it.
    pub fn of_recording(rec: &Recording, path: &Path) -> Result<Option<Self>, CoreError> {
        Ok(rec
            .one_value_column(COLUMN, path, "a recording holds one magnetometer's frame")?
            .map(|(_, frame)| frame))
    }

    /// `rec` with `frame` written in every row of its [`COLUMN`] (replacing any), or the column
    /// removed where `frame` is None.
    pub fn write_into(frame: Option<Self>, rec: &mut Recording) {
        rec.set_one_value_column(COLUMN, frame);
    }
}

impl fmt::Display for SensorToBody {
    /// The nine numbers row by row, separated by spaces, each in the shortest form that reads
    /// back to the same bits.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let text: Vec<String> = self.rows.iter().flatten().map(|v| v.to_string()).collect();
        f.write_str(&text.join(" "))
    }
}

impl FromStr for SensorToBody {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        let numbers: Vec<f64> = s
            .split_whitespace()
            .map(|t| t.parse::<f64>())
            .collect::<Result<_, _>>()
            .map_err(|_| {
                format!("nine numbers, the sensor-to-body matrix row by row; found {s:?}")
            })?;
        let [a, b, c, d, e, f, g, h, i] = numbers[..] else {
            return Err(format!(
                "nine numbers, the sensor-to-body matrix row by row; found {} in {s:?}",
                numbers.len()
            ));
        };
        Self::new([[a, b, c], [d, e, f], [g, h, i]])
    }
}

impl TryFrom<[[f64; 3]; 3]> for SensorToBody {
    type Error = String;
    fn try_from(rows: [[f64; 3]; 3]) -> Result<Self, String> {
        Self::new(rows)
    }
}

impl From<SensorToBody> for [[f64; 3]; 3] {
    fn from(frame: SensorToBody) -> Self {
        frame.rows
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_transform_reads_back_to_the_same_bits_and_maps_back_to_the_sensor() {
        let rows = [
            [0.1 + 0.2, -1.0 / 3.0, 2e-7],
            [1.0, 0.9, -0.0125],
            [-0.04, 0.02, -1.1],
        ];
        let frame = SensorToBody::new(rows).unwrap();
        let back: SensorToBody = frame.to_string().parse().unwrap();
        assert_eq!(back.rows(), rows, "{frame}");
        let sensor = Vec3::new(0.3, -1.2, 4.5);
        let body = frame.matrix() * sensor;
        let again = frame.to_sensor(body).unwrap();
        assert!((again - sensor).norm() < 1e-12, "{again} against {sensor}");
        assert!(!frame.is_identity());
        assert!(
            SensorToBody::new([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
                .unwrap()
                .is_identity()
        );
    }

    #[test]
    fn a_singular_or_unfinished_transform_is_refused_with_what_was_found() {
        for bad in [
            "1 0 0 0 1 0 0 0",
            "1 0 0 0 1 0 0 0 1 0",
            "1 0 0 0 1 0 0 0 x",
            "1 0 0 0 1 0 0 0 NaN",
            "1 0 0 0 1 0 0 0 inf",
            "1 2 3 2 4 6 0 0 1",
            "1e-9 0 0 0 1 0 0 0 1",
            "1e-300 0 0 0 1e-300 0 0 0 1e-300",
            "1e4 0 0 0 1 0 0 0 1",
            "",
        ] {
            let e = bad.parse::<SensorToBody>().expect_err(bad);
            assert!(e.contains("found"), "{bad:?}: {e}");
        }
        let json = "[[1.0,0.0,0.0],[0.0,0.0,0.0],[0.0,0.0,1.0]]";
        assert!(serde_json::from_str::<SensorToBody>(json).is_err());
    }

    #[test]
    fn a_recording_holds_one_frame_and_says_where_another_begins() {
        let mut rec = Recording {
            t_s: vec![0.0, 0.1, 0.2],
            thr: vec![vec![0.0; 3]],
            overall_only: true,
            mag_ut: vec![Vec3::zeros(); 3],
            ..Recording::default()
        };
        let path = Path::new("r.csv");
        assert_eq!(SensorToBody::of_recording(&rec, path).ok(), Some(None));
        let frame: SensorToBody = "-1 0 0 0 -1 0 0 0 1".parse().unwrap();
        SensorToBody::write_into(Some(frame), &mut rec);
        assert_eq!(
            SensorToBody::of_recording(&rec, path).ok(),
            Some(Some(frame))
        );
        rec.extra[0].1[1] = "1 0 0 0 1 0 0 0 1".into();
        let e = SensorToBody::of_recording(&rec, path)
            .expect_err("two frames")
            .to_string();
        assert!(
            e.contains("row 2") && e.contains(COLUMN) && e.contains("-1 0 0"),
            "{e}"
        );
        SensorToBody::write_into(None, &mut rec);
        assert!(rec.extra.is_empty());
    }
}
