//! The streams an import needs, each on its own time base, as the format mappings ([`crate::px4`],
//! [`crate::ardupilot`]) produce them; [`crate::import`] puts them onto the magnetometer's
//! time stamps.
use magstand_core::{Quat, Vec3};

/// A stream of values with its own time stamps.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Stream<T> {
    /// Time of each value on the log's clock, s.
    pub t_s: Vec<f64>,
    /// The values.
    pub values: Vec<T>,
}

impl<T> Stream<T> {
    /// A stream from (time, value) pairs whose value exists, sorted by time as logged.
    pub fn from_pairs(pairs: impl IntoIterator<Item = (f64, Option<T>)>) -> Self {
        let mut s = Stream {
            t_s: Vec::new(),
            values: Vec::new(),
        };
        for (t, v) in pairs {
            if let Some(v) = v
                && t.is_finite()
            {
                s.t_s.push(t);
                s.values.push(v);
            }
        }
        s
    }

    /// Number of values.
    pub fn len(&self) -> usize {
        self.t_s.len()
    }

    /// True when empty.
    pub fn is_empty(&self) -> bool {
        self.t_s.is_empty()
    }
}

/// Position and date for the Earth-field model.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Position {
    /// Latitude, degrees north.
    pub lat_deg: f64,
    /// Longitude, degrees east.
    pub lon_deg: f64,
    /// Altitude above mean sea level, m.
    pub alt_m: f64,
    /// Date as a decimal year (2024.5 is early July 2024), when the log carries GPS time.
    pub year: Option<f64>,
}

/// Everything an import reads from one log.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct VehicleStreams {
    /// The chosen magnetometer, body frame, µT.
    pub mag_ut: Stream<Vec3>,
    /// The magnetometer's temperature, °C, when it reports one.
    pub mag_temp_c: Option<Stream<f64>>,
    /// The firmware's parameter set of the chosen magnetometer, where the log tells it.
    pub mag_slot: Option<magstand_core::magnetometer_slot::MagnetometerSlot>,
    /// The transform the import applied to take the chosen magnetometer's readings to the
    /// body frame, where the firmware adds its compensation before it (PX4's calibration).
    pub mag_to_body: Option<magstand_core::magnetometer_frame::SensorToBody>,
    /// Motor commands mapped to 0..1, one entry per motor.
    pub motors: Stream<Vec<f64>>,
    /// Battery voltage, V.
    pub bat_v: Option<Stream<f64>>,
    /// Battery current, A.
    pub bat_a: Option<Stream<f64>>,
    /// Each ESC's own current, A, in motor order (PX4 `esc_status`, ArduPilot `ESC`); empty
    /// when the ESCs do not report it.
    pub esc_a: Vec<Stream<f64>>,
    /// The autopilot's own throttle, 0..1: the collective thrust demand its power compensation
    /// multiplies (ArduPilot's `CTUN.ThO`), which its thrust curve maps to the motor outputs.
    pub autopilot_throttle: Option<Stream<f64>>,
    /// Attitude, body to north-east-down.
    pub attitude: Option<Stream<Quat>>,
    /// Armed state changes (or samples).
    pub armed: Option<Stream<bool>>,
    /// Landed state changes (or samples).
    pub landed: Option<Stream<bool>>,
    /// Where and when, from GPS.
    pub position: Option<Position>,
    /// What the mapping chose and why (instance, PWM range, motor count), for the summary.
    pub notes: Vec<String>,
}

impl VehicleStreams {
    /// Leaves out a supply channel that reads zero throughout: a log without a voltage or
    /// current sensor records 0, and a vehicle whose motors run cannot draw 0 A, so the zeros
    /// mean "not measured". Fitting a current model on them would be fitting noise against a
    /// constant; leaving the column out makes `fit --inputs current` say the current is
    /// missing, and the throttle is the input left.
    pub fn drop_unmeasured_supply(&mut self, source: &str) {
        // Below any real sensor's resolution: 0.5 V, 0.01 A.
        let zero = |s: &Option<Stream<f64>>, floor: f64| {
            s.as_ref()
                .is_some_and(|s| !s.values.is_empty() && s.values.iter().all(|v| v.abs() <= floor))
        };
        if zero(&self.bat_v, 0.5) {
            self.notes.push(format!(
                "{source}: the battery voltage is 0 throughout (not measured): bat_v is left out"
            ));
            self.bat_v = None;
        }
        // A voltage that reads 0 (or below) on some samples only (a monitor not yet measuring
        // at boot) is not measured there: those samples are left out, and the rows around them take
        // the nearest measured voltage, not a supply at 0 V.
        if let Some(v) = self.bat_v.as_mut() {
            let before = v.values.len();
            let kept: (Vec<f64>, Vec<f64>) = v
                .t_s
                .iter()
                .zip(&v.values)
                .filter(|(_, x)| **x > 0.5)
                .map(|(t, x)| (*t, *x))
                .unzip();
            (v.t_s, v.values) = kept;
            if v.values.len() < before {
                self.notes.push(format!(
                    "{source}: {} of {before} battery voltage samples read 0 V or below (not measured): left out, the rows around them take the nearest measured voltage",
                    before - v.values.len()
                ));
            }
        }
        if zero(&self.bat_a, 0.01) {
            self.notes.push(format!(
                "{source}: the battery current is 0 throughout (not measured): bat_a is left out; fit on the throttle"
            ));
            self.bat_a = None;
        }
    }
}

/// A note where a log has more batteries than the first (`instances` of its battery topic
/// `source`): `bat_v` and `bat_a` are the first's, and where packs share the load the motors
/// draw the sum of their currents, so a current fit on the first alone is off by the share.
pub fn other_batteries(instances: &[u8], source: &str) -> Option<String> {
    (instances.len() > 1).then(|| {
        format!(
            "{source} has {} instances {instances:?}: bat_v and bat_a are instance {}'s; where the packs share the load, the motors draw the sum of their currents (fit on the throttle, or sum the currents into bat_a)",
            instances.len(),
            instances[0]
        )
    })
}

/// Decimal year of a Unix time in seconds (UTC; leap seconds do not matter at this precision).
pub fn decimal_year(unix_s: f64) -> f64 {
    let days = unix_s / 86_400.0;
    // Days from 1970-01-01 to 1 January of each year, by the Gregorian rule.
    let mut year = 1970i64;
    let mut start = 0.0;
    loop {
        let len = if (year % 4 == 0 && year % 100 != 0) || year % 400 == 0 {
            366.0
        } else {
            365.0
        };
        if days < start + len {
            return year as f64 + (days - start) / len;
        }
        start += len;
        year += 1;
    }
}

/// Maps a raw output to 0..1 over `[lo, hi]`, clamping; NaN (a disarmed output) is 0.
pub fn normalize_output(raw: f64, lo: f64, hi: f64) -> f64 {
    if raw.is_nan() {
        return 0.0;
    }
    ((raw - lo) / (hi - lo)).clamp(0.0, 1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A second battery is said, with which one the columns hold; one battery says nothing.
    #[test]
    fn more_batteries_than_the_first_are_said() {
        assert_eq!(other_batteries(&[0], "BAT"), None);
        let note = other_batteries(&[0, 1], "battery_status").expect("a note");
        assert!(
            note.contains("2 instances [0, 1]") && note.contains("instance 0's"),
            "{note}"
        );
    }

    /// A voltage that reads 0 on a few samples (a monitor not yet measuring at boot) keeps its
    /// measured samples only, with a note; one at 0 throughout is left out whole.
    #[test]
    fn voltage_samples_at_zero_are_not_measured() {
        let mut s = VehicleStreams {
            bat_v: Some(Stream::from_pairs(
                [
                    (0.0, 0.0),
                    (0.1, 0.0),
                    (0.2, 12.4),
                    (0.3, -1.0),
                    (0.4, 12.3),
                ]
                .map(|(t, v)| (t, Some(v))),
            )),
            ..VehicleStreams::default()
        };
        s.drop_unmeasured_supply("log.bin");
        let v = s.bat_v.as_ref().expect("measured samples remain");
        assert_eq!(
            (v.t_s.as_slice(), v.values.as_slice()),
            (&[0.2, 0.4][..], &[12.4, 12.3][..])
        );
        assert!(
            s.notes
                .iter()
                .any(|n| n.contains("3 of 5 battery voltage samples")),
            "{:?}",
            s.notes
        );
        let mut s = VehicleStreams {
            bat_v: Some(Stream::from_pairs([(0.0, Some(0.0)), (0.1, Some(0.2))])),
            ..VehicleStreams::default()
        };
        s.drop_unmeasured_supply("log.bin");
        assert!(s.bat_v.is_none() && s.notes.len() == 1, "{:?}", s.notes);
    }

    #[test]
    fn decimal_year_of_known_dates() {
        assert_eq!(decimal_year(0.0), 1970.0);
        // 2024-01-01T00:00:00Z = 1704067200; 2024 is a leap year, so 1 July is day 182.
        assert!((decimal_year(1_704_067_200.0) - 2024.0).abs() < 1e-9);
        let july = 1_704_067_200.0 + 182.0 * 86_400.0;
        assert!((decimal_year(july) - (2024.0 + 182.0 / 366.0)).abs() < 1e-9);
    }

    #[test]
    fn outputs_map_to_unit_range() {
        assert_eq!(normalize_output(1000.0, 1000.0, 2000.0), 0.0);
        assert_eq!(normalize_output(1500.0, 1000.0, 2000.0), 0.5);
        assert_eq!(normalize_output(900.0, 1000.0, 2000.0), 0.0);
        assert_eq!(normalize_output(f64::NAN, 1000.0, 2000.0), 0.0);
        assert_eq!(normalize_output(2100.0, 1000.0, 2000.0), 1.0);
    }
}
