//! Which of an autopilot's magnetometer parameter sets a recording's magnetometer belongs to,
//! carried from `import` through `fit` to `export`, so that a compensation fitted on one
//! compass is never written into another's parameters.
//!
//! A vehicle has up to three or four magnetometers, each with its own compensation parameters
//! (PX4's `CAL_MAGn_*COMP`, ArduPilot's `COMPASS_MOT*`), and the internal one the motors
//! disturb is often not the first. `import` writes the slot of the magnetometer it read in the
//! recording's `mag_slot` column, the same in every row; a recording without it (a test
//! stand's) has no slot, and `export` then takes the instance the user gives.
//!
//! # Example
//! ```
//! use magstand_core::magnetometer_slot::MagnetometerSlot;
//!
//! let slot: MagnetometerSlot = "ardupilot:2".parse().unwrap();
//! assert_eq!(slot, MagnetometerSlot::ArduPilotCompass(2));
//! assert_eq!(slot.to_string(), "ardupilot:2");
//! assert!("ardupilot:0".parse::<MagnetometerSlot>().is_err());
//! ```
use std::fmt;
use std::path::Path;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

use crate::{CoreError, Recording};

/// The recording column that holds the slot.
pub const COLUMN: &str = "mag_slot";

/// A magnetometer's parameter set in its autopilot, numbered as `magstand export --instance`
/// numbers it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(try_from = "String", into = "String")]
pub enum MagnetometerSlot {
    /// PX4's calibration slot `CAL_MAGn` (n from 0 to 3), the one whose `CAL_MAGn_ID` is the
    /// sensor's device id.
    Px4CalMag(u8),
    /// ArduPilot's compass n (1 to 3): the parameters `COMPASS_MOT_*` (1), `COMPASS_MOT2_*`,
    /// `COMPASS_MOT3_*`.
    ArduPilotCompass(u8),
}

impl MagnetometerSlot {
    /// The slot's number as `export --instance` takes it.
    pub fn instance(self) -> usize {
        match self {
            Self::Px4CalMag(n) | Self::ArduPilotCompass(n) => n as usize,
        }
    }

    /// The parameters the slot names, for messages: `CAL_MAG1` or `ArduPilot compass 2`.
    pub fn describe(self) -> String {
        match self {
            Self::Px4CalMag(n) => format!("PX4's CAL_MAG{n}"),
            Self::ArduPilotCompass(n) => format!("ArduPilot's compass {n}"),
        }
    }

    /// The slot written in `rec`'s [`COLUMN`], read from `path`: None where the column is
    /// absent or every cell empty. Cells must all hold the same slot: a recording joined from
    /// two magnetometers has no one slot.
    pub fn of_recording(rec: &Recording, path: &Path) -> Result<Option<Self>, CoreError> {
        Ok(Self::first_of_recording(rec, path)?.map(|(_, s)| s))
    }

    /// [`MagnetometerSlot::of_recording`], with the first row (from 0) that holds it.
    fn first_of_recording(
        rec: &Recording,
        path: &Path,
    ) -> Result<Option<(usize, Self)>, CoreError> {
        rec.one_value_column(COLUMN, path, "a recording holds one magnetometer")
    }

    /// The magnetometer of a model fitted on `fitted_on` and applied to `rec` (read from
    /// `path`): the model's, or where it does not say, the recording's. A recording of another
    /// sensor is refused at its first row: the model's compensation would correct that sensor by
    /// a field it does not see.
    pub fn agreeing_with(
        fitted_on: Option<Self>,
        rec: &Recording,
        path: &Path,
    ) -> Result<Option<Self>, CoreError> {
        match (fitted_on, Self::first_of_recording(rec, path)?) {
            (Some(m), Some((row, r))) if m != r => Err(CoreError::BadCell {
                path: path.to_path_buf(),
                row: row + 1,
                column: COLUMN.into(),
                found: r.to_string(),
                expected: format!(
                    "the magnetometer the model was fitted on, {m} ({}): this recording is of another sensor",
                    m.describe()
                ),
            }),
            (m, r) => Ok(m.or(r.map(|(_, s)| s))),
        }
    }

    /// `rec` with `slot` written in every row of its [`COLUMN`] (replacing any), or the column
    /// removed where `slot` is None.
    pub fn write_into(slot: Option<Self>, rec: &mut Recording) {
        rec.set_one_value_column(COLUMN, slot);
    }
}

impl fmt::Display for MagnetometerSlot {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Px4CalMag(n) => write!(f, "px4:{n}"),
            Self::ArduPilotCompass(n) => write!(f, "ardupilot:{n}"),
        }
    }
}

impl FromStr for MagnetometerSlot {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        let expected = || {
            format!(
                "a magnetometer slot, `px4:N` (CAL_MAGn, 0 to 3) or `ardupilot:N` (compass 1 to 3); found {s:?}"
            )
        };
        let (firmware, n) = s.split_once(':').ok_or_else(expected)?;
        let n: u8 = n.parse().map_err(|_| expected())?;
        match firmware {
            "px4" if n <= 3 => Ok(Self::Px4CalMag(n)),
            "ardupilot" if (1..=3).contains(&n) => Ok(Self::ArduPilotCompass(n)),
            _ => Err(expected()),
        }
    }
}

impl TryFrom<String> for MagnetometerSlot {
    type Error = String;
    fn try_from(s: String) -> Result<Self, String> {
        s.parse()
    }
}

impl From<MagnetometerSlot> for String {
    fn from(s: MagnetometerSlot) -> String {
        s.to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_slot_reads_back_as_written_and_out_of_range_numbers_are_refused() {
        for slot in [
            MagnetometerSlot::Px4CalMag(0),
            MagnetometerSlot::Px4CalMag(3),
            MagnetometerSlot::ArduPilotCompass(1),
            MagnetometerSlot::ArduPilotCompass(3),
        ] {
            assert_eq!(slot.to_string().parse::<MagnetometerSlot>(), Ok(slot));
        }
        for bad in [
            "px4:4",
            "ardupilot:0",
            "ardupilot:4",
            "px4",
            "nuttx:1",
            "px4:-1",
            "",
        ] {
            assert!(bad.parse::<MagnetometerSlot>().is_err(), "{bad:?} parsed");
        }
    }

    #[test]
    fn a_recording_holds_one_slot_and_says_where_another_begins() {
        let mut rec = Recording {
            t_s: vec![0.0, 0.1, 0.2],
            thr: vec![vec![0.0; 3]],
            overall_only: true,
            mag_ut: vec![nalgebra::Vector3::zeros(); 3],
            ..Recording::default()
        };
        let path = Path::new("r.csv");
        assert_eq!(MagnetometerSlot::of_recording(&rec, path).ok(), Some(None));
        MagnetometerSlot::write_into(Some(MagnetometerSlot::ArduPilotCompass(2)), &mut rec);
        assert_eq!(
            MagnetometerSlot::of_recording(&rec, path).ok(),
            Some(Some(MagnetometerSlot::ArduPilotCompass(2)))
        );
        rec.extra[0].1[2] = "ardupilot:1".into();
        let e = MagnetometerSlot::of_recording(&rec, path)
            .expect_err("two slots")
            .to_string();
        assert!(
            e.contains("row 3") && e.contains("mag_slot") && e.contains("ardupilot:2"),
            "{e}"
        );
        rec.extra[0].1[2] = "ardupilot:2".into();
        let model = Some(MagnetometerSlot::ArduPilotCompass(3));
        let e = MagnetometerSlot::agreeing_with(model, &rec, path)
            .expect_err("another sensor")
            .to_string();
        assert!(
            e.contains("row 1") && e.contains("ardupilot:3") && e.contains("another sensor"),
            "{e}"
        );
        assert_eq!(
            MagnetometerSlot::agreeing_with(None, &rec, path).ok(),
            Some(Some(MagnetometerSlot::ArduPilotCompass(2)))
        );
        MagnetometerSlot::write_into(None, &mut rec);
        assert!(rec.extra.is_empty(), "{:?}", rec.extra);
        assert_eq!(
            MagnetometerSlot::agreeing_with(model, &rec, path).ok(),
            Some(model)
        );
    }
}
