//! What the numbers of a DataFlash field mean, read from the log itself.
//!
//! ArduPilot describes every message with a `FMT` record (a type character per field) and,
//! since about Copter 3.6, a `FMTU` record (a unit id and a multiplier id per field) that
//! `UNIT` and `MULT` records resolve to a label (`V`, `A`, `Gauss`, ...) and a factor. A value
//! times its multiplier is in the labelled unit. The type characters `c`, `C`, `e` and `E`
//! carry their own factor of 0.01, which the parser has already applied; as in pymavlink, a
//! `FMTU` multiplier is not applied to them a second time.
//!
//! Older logs have no `FMTU`. Their layouts are fixed by the firmware: the magnetometer in
//! milligauss, `CURR` volts and amperes as integers in hundredths (Copter 3.3 and older,
//! `IhhhHfh`) or as floats in volts and amperes (Copter 3.4, `Qfff...`), angles as `c`/`C`
//! hundredths of a degree or float degrees, outputs in microseconds. [`scale`] encodes that
//! rule, so that one message read in two layouts gives the same physical numbers.
use std::collections::BTreeMap;

use crate::LogsError;
use crate::contents::LogContents;

/// How one field is stored, from `FMT` and (when the log has it) `FMTU`.
#[derive(Debug, Clone, PartialEq)]
pub struct FieldUnit {
    /// The `FMT` type character (`h`, `f`, `c`, ...).
    pub type_char: char,
    /// The `UNIT` label declared by `FMTU`, when there is one.
    pub unit: Option<String>,
    /// The `MULT` factor declared by `FMTU`, when there is one and it is a factor (`-`, "no
    /// multiplier", and `?`, "unknown", are `None`).
    pub mult: Option<f64>,
}

/// Field layouts by message name, then field label.
pub type FieldUnits = BTreeMap<String, BTreeMap<String, FieldUnit>>;

/// The quantities magstand reads from ArduPilot logs, each with the unit it wants.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Quantity {
    /// Battery or ESC voltage, wanted in volts.
    Voltage,
    /// Battery or ESC current, wanted in amperes.
    Current,
    /// Magnetic flux density, wanted in microtesla.
    MagneticField,
    /// Angle, wanted in degrees.
    Angle,
    /// Servo/ESC output pulse, wanted in microseconds.
    Pulse,
}

impl Quantity {
    /// `UNIT` labels this quantity may be declared in, with the factor to magstand's unit.
    fn accepted(self) -> &'static [(&'static str, f64)] {
        match self {
            Quantity::Voltage => &[("V", 1.0)],
            Quantity::Current => &[("A", 1.0)],
            // 1 gauss = 100 µT.
            Quantity::MagneticField => &[("Gauss", 100.0), ("G", 100.0), ("mGauss", 0.1)],
            Quantity::Angle => &[
                ("deg", 1.0),
                ("degheading", 1.0),
                ("rad", 57.295_779_513_082_32),
            ],
            Quantity::Pulse => &[("us", 1.0), ("PWM", 1.0)],
        }
    }

    /// The factor to magstand's unit for a log without `FMTU`, from the firmware's fixed
    /// layouts (see the module documentation).
    fn legacy(self, type_char: char) -> f64 {
        let integer = matches!(type_char, 'b' | 'B' | 'h' | 'H' | 'i' | 'I' | 'q' | 'Q');
        match self {
            // Copter 3.3 and older: centivolts and centiamperes in integers.
            Quantity::Voltage | Quantity::Current if integer => 0.01,
            Quantity::Voltage | Quantity::Current => 1.0,
            // Milligauss, in integers and in floats alike.
            Quantity::MagneticField => 0.1,
            Quantity::Angle | Quantity::Pulse => 1.0,
        }
    }

    fn name(self) -> &'static str {
        match self {
            Quantity::Voltage => "a voltage",
            Quantity::Current => "a current",
            Quantity::MagneticField => "a magnetic field",
            Quantity::Angle => "an angle",
            Quantity::Pulse => "an output pulse width",
        }
    }
}

/// The factor that turns the parsed values of `message.field` into magstand's unit for
/// `quantity` (volts, amperes, microtesla, degrees, microseconds).
///
/// `Ok(None)` when the log has no format for that field (it is not logged); an error when the
/// log declares the field in a unit that is not `quantity`, because reading it anyway would
/// give numbers that look right and are not.
pub fn scale(
    log: &LogContents,
    message: &str,
    field: &str,
    quantity: Quantity,
) -> Result<Option<f64>, LogsError> {
    let Some(fu) = log.field_units.get(message).and_then(|m| m.get(field)) else {
        return Ok(None);
    };
    let own_multiplier = matches!(fu.type_char, 'c' | 'C' | 'e' | 'E');
    let Some(unit) = fu
        .unit
        .as_deref()
        .filter(|u| !u.is_empty() && *u != "UNKNOWN")
    else {
        return Ok(Some(quantity.legacy(fu.type_char)));
    };
    let Some(&(_, to_ours)) = quantity.accepted().iter().find(|(u, _)| *u == unit) else {
        return Err(LogsError::Unusable {
            path: log.path.clone(),
            what: format!(
                "{message}.{field} is declared in '{unit}' by the log's FMTU, but magstand reads it as {} (expected {})",
                quantity.name(),
                quantity
                    .accepted()
                    .iter()
                    .map(|(u, _)| format!("'{u}'"))
                    .collect::<Vec<_>>()
                    .join(" or ")
            ),
        });
    };
    let mult = if own_multiplier {
        1.0
    } else {
        fu.mult.unwrap_or(1.0)
    };
    Ok(Some(mult * to_ours))
}

/// `MULT` ids ArduPilot uses, for logs whose `MULT` records were lost (a truncated start).
pub(crate) fn standard_multiplier(id: char) -> Option<f64> {
    Some(match id {
        '2' => 1e2,
        '1' => 1e1,
        '0' => 1.0,
        'A' => 1e-1,
        'B' => 1e-2,
        'C' => 1e-3,
        'D' => 1e-4,
        'E' => 1e-5,
        'F' => 1e-6,
        'G' => 1e-7,
        'I' => 1e-9,
        '!' => 3.6,
        '/' => 3600.0,
        _ => return None,
    })
}

/// `UNIT` ids of the quantities magstand reads, for logs whose `UNIT` records were lost.
pub(crate) fn standard_unit(id: char) -> Option<&'static str> {
    Some(match id {
        'v' => "V",
        'A' => "A",
        'G' => "Gauss",
        'd' => "deg",
        'h' => "degheading",
        'r' => "rad",
        'Y' => "us",
        _ => return None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contents::LogFormat;
    use std::path::PathBuf;

    fn log_with(message: &str, field: &str, fu: FieldUnit) -> LogContents {
        let mut log = LogContents::new(PathBuf::from("x.bin"), LogFormat::DataFlash);
        log.field_units
            .entry(message.into())
            .or_default()
            .insert(field.into(), fu);
        log
    }

    fn fu(type_char: char, unit: Option<&str>, mult: Option<f64>) -> FieldUnit {
        FieldUnit {
            type_char,
            unit: unit.map(str::to_string),
            mult,
        }
    }

    #[test]
    fn legacy_integers_are_hundredths_and_floats_are_si() {
        for (t, want) in [('h', 0.01), ('H', 0.01), ('f', 1.0), ('c', 1.0)] {
            let log = log_with("CURR", "Curr", fu(t, None, None));
            let k = scale(&log, "CURR", "Curr", Quantity::Current).unwrap();
            assert_eq!(k, Some(want), "type {t}");
        }
    }

    #[test]
    fn declared_multiplier_applies_except_to_self_scaled_types() {
        let log = log_with("BAT", "Volt", fu('H', Some("V"), Some(0.01)));
        assert_eq!(
            scale(&log, "BAT", "Volt", Quantity::Voltage).unwrap(),
            Some(0.01)
        );
        let log = log_with("ESC", "Temp", fu('c', Some("A"), Some(0.01)));
        assert_eq!(
            scale(&log, "ESC", "Temp", Quantity::Current).unwrap(),
            Some(1.0)
        );
        let log = log_with("MAG", "MagX", fu('h', Some("Gauss"), Some(1e-3)));
        let k = scale(&log, "MAG", "MagX", Quantity::MagneticField)
            .unwrap()
            .unwrap();
        assert!((k - 0.1).abs() < 1e-12, "{k}");
    }

    #[test]
    fn a_field_in_another_unit_is_refused_with_its_name() {
        let log = log_with("CURR", "Curr", fu('f', Some("V"), None));
        let e = scale(&log, "CURR", "Curr", Quantity::Current)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("x.bin") && e.contains("CURR.Curr") && e.contains("'A'"),
            "{e}"
        );
    }

    #[test]
    fn a_field_not_logged_has_no_scale() {
        let log = log_with("CURR", "Curr", fu('f', None, None));
        assert_eq!(
            scale(&log, "CURR", "Volt", Quantity::Voltage).unwrap(),
            None
        );
    }
}
