//! What the importers need from a log, whatever its format: time series of numeric fields per
//! topic and instance, the parameters, ArduPilot's events, and how the file ended.
use std::collections::BTreeMap;
use std::path::PathBuf;

use crate::field_units::FieldUnits;
use crate::streams::Stream;

/// One topic instance: a time stamp per message and a column per numeric field.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Series {
    /// Time of each message on the log's own clock, s.
    pub t_s: Vec<f64>,
    /// Numeric fields by name, one value per message.
    pub fields: BTreeMap<String, Vec<f64>>,
}

impl Series {
    /// A field's values, if the topic has it.
    pub fn field(&self, name: &str) -> Option<&[f64]> {
        self.fields.get(name).map(|v| v.as_slice())
    }

    /// One field as a stream, each value mapped by `map` (`None` drops that message); `None`
    /// when the topic has no such field.
    pub fn stream<T>(&self, field: &str, map: impl Fn(f64) -> Option<T>) -> Option<Stream<T>> {
        let v = self.field(field)?;
        Some(Stream::from_pairs(
            self.t_s.iter().zip(v).map(|(&t, &x)| (t, map(x))),
        ))
    }

    /// Number of messages.
    pub fn len(&self) -> usize {
        self.t_s.len()
    }

    /// True when there are no messages.
    pub fn is_empty(&self) -> bool {
        self.t_s.is_empty()
    }

    /// Appends one message; fields not seen before start with NaN for the earlier messages.
    pub(crate) fn push(&mut self, t_s: f64, values: impl IntoIterator<Item = (String, f64)>) {
        let n = self.t_s.len();
        self.t_s.push(t_s);
        for (name, v) in values {
            let col = self.fields.entry(name).or_insert_with(|| vec![f64::NAN; n]);
            col.resize(n, f64::NAN);
            col.push(v);
        }
        for col in self.fields.values_mut() {
            col.resize(n + 1, f64::NAN);
        }
    }
}

/// Which log format a file was.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LogFormat {
    /// PX4 ULog.
    Ulog,
    /// ArduPilot DataFlash (.bin).
    DataFlash,
}

impl LogFormat {
    /// The format of log bytes, recognized by their first bytes (ULog's magic, a DataFlash
    /// message header).
    pub fn detect(bytes: &[u8]) -> Option<Self> {
        use magstand_core::input_file::{DATAFLASH_MAGIC, ULOG_MAGIC};
        if bytes.starts_with(ULOG_MAGIC) {
            Some(LogFormat::Ulog)
        } else if bytes.starts_with(DATAFLASH_MAGIC) {
            Some(LogFormat::DataFlash)
        } else {
            None
        }
    }

    /// Its usual name.
    pub fn name(self) -> &'static str {
        match self {
            LogFormat::Ulog => "ULog",
            LogFormat::DataFlash => "DataFlash",
        }
    }
}

/// A log reduced to what magstand reads from it.
#[derive(Debug, Clone, PartialEq)]
pub struct LogContents {
    /// Where it came from (for messages).
    pub path: PathBuf,
    /// Its format.
    pub format: LogFormat,
    /// Parameters, last value wins.
    pub params: BTreeMap<String, f64>,
    /// Topics (PX4) or message types (ArduPilot) by name, then by instance.
    pub topics: BTreeMap<String, BTreeMap<u8, Series>>,
    /// ArduPilot `EV` events: (time s, id), in log order.
    pub events: Vec<(f64, i64)>,
    /// ArduPilot `MSG` texts (firmware version, "Frame: QUAD", ...): (time s, text), in log
    /// order.
    pub texts: Vec<(f64, String)>,
    /// ULog information messages (`sys_name`, `ver_hw`, `ver_sw_release`, ...): text values as
    /// text, integers in decimal.
    pub info: BTreeMap<String, String>,
    /// `None` when the file ended cleanly; otherwise how it broke off. What came before is kept.
    pub damage: Option<String>,
    /// DataFlash field layouts and declared units by message name (empty for ULog, whose
    /// fields are typed floats in fixed units).
    pub field_units: FieldUnits,
}

impl LogContents {
    /// An empty log of `format` read from `path`.
    pub(crate) fn new(path: PathBuf, format: LogFormat) -> Self {
        Self {
            path,
            format,
            params: BTreeMap::new(),
            topics: BTreeMap::new(),
            events: Vec::new(),
            texts: Vec::new(),
            info: BTreeMap::new(),
            damage: None,
            field_units: FieldUnits::new(),
        }
    }

    /// One topic instance, if logged with at least one message.
    pub fn series(&self, topic: &str, instance: u8) -> Option<&Series> {
        self.topics
            .get(topic)
            .and_then(|m| m.get(&instance))
            .filter(|s| !s.is_empty())
    }

    /// The instances of a topic that have messages.
    pub fn instances(&self, topic: &str) -> Vec<u8> {
        self.topics
            .get(topic)
            .map(|m| {
                m.iter()
                    .filter(|(_, s)| !s.is_empty())
                    .map(|(i, _)| *i)
                    .collect()
            })
            .unwrap_or_default()
    }

    /// The text after `prefix` of the first `MSG` that starts with it ("Frame: " gives
    /// "QUAD/X").
    pub fn text_after(&self, prefix: &str) -> Option<&str> {
        self.texts
            .iter()
            .find_map(|(_, t)| t.strip_prefix(prefix))
            .map(str::trim)
    }

    /// The firmware that wrote the log, as it names itself: ArduPilot's first `MSG` of the
    /// form "ArduCopter V4.6.2 (1ebd4d99)" (or "APM:Copter V3.3-dev"), PX4's `sys_name` and
    /// `ver_sw_release` ("PX4 v1.14.0") with the board (`ver_hw`).
    pub fn firmware(&self) -> Option<String> {
        match self.format {
            LogFormat::DataFlash => self
                .texts
                .iter()
                .map(|(_, t)| t.trim())
                .find(|t| (t.starts_with("Ardu") || t.starts_with("APM:")) && t.contains(" V"))
                .map(str::to_string),
            LogFormat::Ulog => {
                let name = self.info.get("sys_name").map_or("PX4", String::as_str);
                let version = self
                    .info
                    .get("ver_sw_release")
                    .and_then(|v| v.parse::<u32>().ok())
                    .filter(|&v| v != 0)
                    .map(px4_release)
                    .or_else(|| {
                        let git = self.info.get("ver_sw")?;
                        Some(format!("git {}", git.get(..8).unwrap_or(git)))
                    })?;
                let board = self
                    .info
                    .get("ver_hw")
                    .map(|h| format!(" ({h})"))
                    .unwrap_or_default();
                Some(format!("{name} {version}{board}"))
            }
        }
    }

    /// The PX4 release that wrote a ULog (`ver_sw_release`): major, minor and patch; None
    /// for a DataFlash log or where the log does not say.
    pub fn px4_version(&self) -> Option<[u8; 3]> {
        if self.format != LogFormat::Ulog {
            return None;
        }
        let v = self.info.get("ver_sw_release")?.parse::<u32>().ok()?;
        let [major, minor, patch, _] = v.to_be_bytes();
        (v != 0).then_some([major, minor, patch])
    }

    /// The ArduPilot vehicle and release that wrote a DataFlash log, from its
    /// [`firmware`](LogContents::firmware) message: ("Copter", [4, 6, 2]) for "ArduCopter
    /// V4.6.2 (1ebd4d99)", ("Copter", [3, 3, 0]) for "APM:Copter V3.3-dev". None for a ULog
    /// or where the log does not say.
    pub fn ardupilot_version(&self) -> Option<(String, [u8; 3])> {
        if self.format != LogFormat::DataFlash {
            return None;
        }
        ardupilot_release(&self.firmware()?)
    }

    /// A parameter's value.
    pub fn param(&self, name: &str) -> Option<f64> {
        self.params.get(name).copied()
    }
}

/// The vehicle and release of an ArduPilot firmware message ("ArduCopter V4.6.2 (1ebd4d99)",
/// "APM:Copter V3.3-dev", "ArduPlane V4.1.0beta2"): missing minor or patch numbers are 0.
fn ardupilot_release(message: &str) -> Option<(String, [u8; 3])> {
    let mut words = message.split_whitespace();
    let name = words.next()?;
    let vehicle = name
        .strip_prefix("Ardu")
        .or_else(|| name.strip_prefix("APM:"))
        .filter(|v| !v.is_empty())?;
    let version = words.next()?.strip_prefix(['V', 'v'])?;
    let mut numbers = version.split('.').map(|part| {
        part.split(|c: char| !c.is_ascii_digit())
            .next()
            .unwrap_or("")
    });
    let major = numbers.next()?.parse().ok()?;
    let mut next = || numbers.next().and_then(|n| n.parse().ok()).unwrap_or(0);
    Some((vehicle.to_string(), [major, next(), next()]))
}

/// PX4's `ver_sw_release` (0xAABBCCTT: major, minor, patch, type) as "v1.14.0", with the
/// type when it is not a release (0xFF): PX4's firmware types are dev (0), alpha (64),
/// beta (128) and release candidate (192).
fn px4_release(v: u32) -> String {
    let [major, minor, patch, kind] = v.to_be_bytes();
    let suffix = match kind {
        255 => String::new(),
        192..=254 => "-rc".into(),
        128..=191 => "-beta".into(),
        64..=127 => "-alpha".into(),
        _ => "-dev".into(),
    };
    format!("v{major}.{minor}.{patch}{suffix}")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn px4_release_numbers_read_as_px4_prints_them() {
        // From the logs of tests/data/real-logs: a v1.14.0 release and a v1.17.0 candidate.
        assert_eq!(px4_release(0x010E_00FF), "v1.14.0");
        assert_eq!(px4_release(0x0111_00C0), "v1.17.0-rc");
        assert_eq!(px4_release(0x0109_0000), "v1.9.0-dev");
    }

    #[test]
    fn ardupilot_releases_read_as_the_firmware_prints_them() {
        let read = ardupilot_release;
        // The two real logs of tests/data/real-logs, then other spellings.
        assert_eq!(
            read("ArduCopter V4.6.2 (1ebd4d99)"),
            Some(("Copter".into(), [4, 6, 2]))
        );
        assert_eq!(
            read("APM:Copter V3.3-dev"),
            Some(("Copter".into(), [3, 3, 0]))
        );
        assert_eq!(
            read("APM:Copter V3.5.7 (b11c6af3)"),
            Some(("Copter".into(), [3, 5, 7]))
        );
        assert_eq!(
            read("ArduPlane V4.1.0beta2"),
            Some(("Plane".into(), [4, 1, 0]))
        );
        assert_eq!(read("ArduRover v2.51"), Some(("Rover".into(), [2, 51, 0])));
        assert_eq!(read("Frame: QUAD"), None);
        assert_eq!(read("ArduCopter"), None);
        assert_eq!(read("ArduCopter Vx"), None);
    }

    #[test]
    fn fields_appearing_late_are_padded_with_nan() {
        let mut s = Series::default();
        s.push(0.0, [("a".to_string(), 1.0)]);
        s.push(1.0, [("a".to_string(), 2.0), ("b".to_string(), 5.0)]);
        s.push(2.0, [("b".to_string(), 6.0)]);
        assert_eq!(s.field("a").unwrap()[..2], [1.0, 2.0]);
        assert!(s.field("a").unwrap()[2].is_nan());
        assert!(s.field("b").unwrap()[0].is_nan());
        assert_eq!(s.field("b").unwrap()[1..], [5.0, 6.0]);
    }
}
