//! Stage 0 for flight logs: a recording with attitude whose vehicle flew is diagnosed on a
//! baseline that takes out the Earth field turned by the logged attitude, the sensor offset
//! and the magnetometer's delay behind the attitude and the commands. That is the flight preparation of
//! `magstand fit --earth fit` ([`magstand_ident::flight::prepare_flight`]), used as it is; its
//! stand-equivalent recording is then diagnosed like a stand's.
//!
//! Only the rows with the motors running are kept (the `segment` column of `magstand import`:
//! `off` rows are left out), and a gap between flights is a boundary between stretches of
//! data ([`magstand_core::held_out::Split`]), not a long sample interval.
use magstand_core::Recording;
use magstand_ident::flight::{FlightConfig, is_flight, prepare_flight};

use crate::DiagnoseError;
use crate::effects::Param;

/// What the flight stage gives the diagnosis.
pub(crate) struct FlightBaseline {
    /// The stand-equivalent recording (Earth field's attitude dependence out, inputs delayed).
    pub(crate) recording: Recording,
    /// The flight constants calibrated with the baseline: Earth field and delay.
    pub(crate) calibration: Vec<Param>,
    /// What makes the preparation doubtful, in words.
    pub(crate) warnings: Vec<String>,
}

/// The segment column `magstand import` writes, when present.
fn segments(rec: &Recording) -> Option<&[String]> {
    rec.extra_column("segment")
}

/// The flight baseline of `rec`, or `None` for a stand recording (no attitude, or an attitude
/// that only trembles). A recording marked as flying without the attitude to turn the Earth
/// field by is refused.
pub(crate) fn flight_baseline(
    rec: &Recording,
    origin: &str,
) -> Result<Option<FlightBaseline>, DiagnoseError> {
    let bad = |message: String| DiagnoseError::Recording {
        origin: origin.into(),
        message,
    };
    let marked = segments(rec).is_some_and(|s| s.iter().any(|k| k == "flight"));
    if rec.attitude.is_none() {
        if marked {
            return Err(bad(
                "rows are marked `flight` but there are no attitude columns (att_qw, att_qx, att_qy, att_qz): in flight the Earth field turns with the vehicle, and a diagnosis without the attitude would name that turning as motor physics; import the log with its attitude, or diagnose a stand recording".into(),
            ));
        }
        return Ok(None);
    }
    if !is_flight(rec) {
        return Ok(None);
    }
    let selected;
    let running = match segments(rec) {
        Some(s) => {
            selected = rec.select_rows(|r| s[r] != "off");
            &selected
        }
        None => rec,
    };
    let prep = prepare_flight(running, &FlightConfig::default(), origin)
        .map_err(|e| bad(format!("the flight baseline cannot be fitted: {e}")))?;
    let e = prep.earth_ned_ut;
    let calibration = vec![
        Param::new("flight.earth_n_ut", e.x, None, "µT"),
        Param::new("flight.earth_e_ut", e.y, None, "µT"),
        Param::new("flight.earth_d_ut", e.z, None, "µT"),
        Param::new(
            "flight.mag_delay_s",
            prep.attitude_delay_s,
            None,
            "s (the magnetometer's samples behind the attitude: their age at their time stamps)",
        ),
        Param::new(
            "flight.command_delay_s",
            prep.delay_s,
            None,
            "s (magnetometer behind the commands: the samples' age and the motors' lag; negative where the commands are logged after they act)",
        ),
    ];
    Ok(Some(FlightBaseline {
        recording: prep.recording,
        calibration,
        warnings: prep.warnings,
    }))
}
