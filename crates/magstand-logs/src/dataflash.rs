//! ArduPilot DataFlash (.bin) logs read with the `ardupilot-binlog` crate.
//!
//! One guard sits in front of the crate: version 0.2.0 subtracts 3 from a message length that
//! a format (FMT) message declares without checking it, which panics on a corrupt FMT that
//! declares fewer than 3 bytes. Such a FMT cannot be valid, so its header is blanked before
//! parsing (see `sanitize`), and the crate skips it like any other garbage.
use std::collections::{BTreeMap, HashMap};
use std::io::Cursor;
use std::path::Path;
use std::sync::Arc;

use ardupilot_binlog::{MessageFormat, Reader};

use crate::LogsError;
use crate::contents::{LogContents, LogFormat};
use crate::field_units::{self, FieldUnit, FieldUnits};

/// Message types the ArduPilot import reads.
pub const MESSAGES: [&str; 10] = [
    "MAG", "RCOU", "BAT", "CURR", "ATT", "GPS", "ESC", "PARM", "EV", "CTUN",
];

const MAGIC: [u8; 2] = [0xA3, 0x95];
const FMT_TYPE: u8 = 0x80;

/// Blanks the header of every FMT message that declares a length below 3 bytes; returns how
/// many there were.
fn sanitize(bytes: &mut [u8]) -> usize {
    let mut n = 0;
    for i in 0..bytes.len().saturating_sub(4) {
        if bytes[i..i + 3] == [MAGIC[0], MAGIC[1], FMT_TYPE] && bytes[i + 4] < 3 {
            bytes[i + 1] = 0;
            n += 1;
        }
    }
    n
}

/// Splits `MAG2` into (`MAG`, instance 1); names without a digit are instance 0.
fn base_and_instance(name: &str) -> (&str, u8) {
    match name.char_indices().last() {
        Some((i, c)) if c.is_ascii_digit() && i > 0 => {
            (&name[..i], (c as u8 - b'0').saturating_sub(1))
        }
        _ => (name, 0),
    }
}

/// Field layouts of the messages magstand reads, with the units and multipliers their `FMTU`
/// declares (resolved through `UNIT` and `MULT`, or ArduPilot's standard ids when those
/// records are missing).
fn field_units(
    formats: &HashMap<u8, Arc<MessageFormat>>,
    fmtu: &BTreeMap<u8, (String, String)>,
    unit_labels: &BTreeMap<char, String>,
    multipliers: &BTreeMap<char, f64>,
) -> FieldUnits {
    let mut out = FieldUnits::new();
    // Sorted by type id so that, of two formats with one base name (MAG, MAG2), the same one
    // wins on every run.
    let mut sorted: Vec<_> = formats.iter().collect();
    sorted.sort_by_key(|(ty, _)| **ty);
    for (ty, f) in sorted {
        let (base, _) = base_and_instance(&f.name);
        if !MESSAGES.contains(&base) || out.contains_key(base) {
            continue;
        }
        let ids = fmtu.get(ty);
        let fields = f
            .labels
            .iter()
            .zip(f.format.chars())
            .enumerate()
            .map(|(i, (label, type_char))| {
                let unit_id = ids.and_then(|(u, _)| u.chars().nth(i));
                let mult_id = ids.and_then(|(_, m)| m.chars().nth(i));
                let unit = unit_id.and_then(|c| {
                    unit_labels
                        .get(&c)
                        .cloned()
                        .or_else(|| field_units::standard_unit(c).map(str::to_string))
                });
                // '-' (no multiplier) is logged as 0 and '?' (unknown) as 1: neither scales.
                let mult = mult_id
                    .filter(|c| !matches!(c, '-' | '?'))
                    .and_then(|c| {
                        multipliers
                            .get(&c)
                            .copied()
                            .or_else(|| field_units::standard_multiplier(c))
                    })
                    .filter(|m| m.is_finite() && *m != 0.0);
                (
                    label.clone(),
                    FieldUnit {
                        type_char,
                        unit,
                        mult,
                    },
                )
            })
            .collect();
        out.insert(base.to_string(), fields);
    }
    out
}

/// Reads DataFlash bytes; `path` names them in messages.
///
/// Bytes the parser had to skip (corruption, a truncated last message) are counted and
/// reported in [`LogContents::damage`]; the messages around them are kept.
pub fn read_bytes(bytes: &[u8], path: &Path) -> Result<LogContents, LogsError> {
    let mut out = LogContents::new(path.to_path_buf(), LogFormat::DataFlash);
    if bytes.len() < 3 || bytes[..2] != MAGIC {
        return Err(LogsError::Corrupt {
            path: path.to_path_buf(),
            format: "DataFlash",
            what: "the file does not start with a DataFlash message header (0xA3 0x95)".into(),
        });
    }
    let mut clean = bytes.to_vec();
    let blanked = sanitize(&mut clean);
    let mut reader = Reader::new(Cursor::new(clean));
    let mut now_s = f64::NAN;
    let mut parsed_bytes = 0usize;
    let mut entries = 0usize;
    let mut fmtu: BTreeMap<u8, (String, String)> = BTreeMap::new();
    let mut unit_labels: BTreeMap<char, String> = BTreeMap::new();
    let mut multipliers: BTreeMap<char, f64> = BTreeMap::new();
    while let Some(item) = reader.next() {
        let Ok(entry) = item else { continue };
        entries += 1;
        parsed_bytes += reader
            .formats()
            .get(&entry.msg_type)
            .map_or(0, |f| f.msg_len as usize);
        let t = match entry.timestamp_usec {
            Some(us) => Some(us as f64 * 1e-6),
            None => entry.get_f64("TimeMS").map(|ms| ms * 1e-3),
        };
        if let Some(t) = t.filter(|t| t.is_finite()) {
            now_s = t;
        }
        match entry.name.as_str() {
            "FMTU" => {
                if let (Some(ty), Some(u), Some(m)) = (
                    entry.get_f64("FmtType"),
                    entry.get_str("UnitIds"),
                    entry.get_str("MultIds"),
                ) {
                    fmtu.insert(ty as u8, (u.to_string(), m.to_string()));
                }
                continue;
            }
            "UNIT" => {
                if let (Some(id), Some(label)) = (entry.get_f64("Id"), entry.get_str("Label")) {
                    unit_labels.insert(id as u8 as char, label.to_string());
                }
                continue;
            }
            "MSG" => {
                if let Some(text) = entry.get_str("Message") {
                    out.texts.push((now_s, text.to_string()));
                }
                continue;
            }
            "MULT" => {
                if let (Some(id), Some(m)) = (entry.get_f64("Id"), entry.get_f64("Mult")) {
                    multipliers.insert(id as u8 as char, m);
                }
                continue;
            }
            _ => {}
        }
        let (base, digit_instance) = base_and_instance(&entry.name);
        if !MESSAGES.contains(&base) {
            continue;
        }
        match base {
            "PARM" => {
                if let (Some(n), Some(v)) = (entry.get_str("Name"), entry.get_f64("Value")) {
                    out.params.insert(n.to_string(), v);
                }
                continue;
            }
            // Events carry no time of their own: they happened at the last time stamp seen.
            "EV" => {
                if let Some(id) = entry.get_f64("Id") {
                    out.events.push((now_s, id as i64));
                }
                continue;
            }
            _ => {}
        }
        let Some(t) = t else { continue };
        let instance = ["I", "Instance", "Inst"]
            .iter()
            .find_map(|k| entry.get_f64(k))
            .map_or(digit_instance, |i| i.clamp(0.0, 255.0) as u8);
        out.topics
            .entry(base.to_string())
            .or_default()
            .entry(instance)
            .or_default()
            .push(
                t,
                entry
                    .fields()
                    .filter_map(|(k, v)| Some((k.to_string(), v.as_f64()?))),
            );
    }
    out.field_units = field_units(reader.formats(), &fmtu, &unit_labels, &multipliers);
    if entries == 0 {
        return Err(LogsError::Corrupt {
            path: path.to_path_buf(),
            format: "DataFlash",
            what: "no message could be parsed".into(),
        });
    }
    let skipped = bytes.len().saturating_sub(parsed_bytes);
    if skipped > 0 || blanked > 0 {
        out.damage = Some(format!(
            "{skipped} of {} bytes could not be parsed (corrupt or truncated){}; the {entries} messages around them are kept",
            bytes.len(),
            if blanked > 0 {
                format!(", including {blanked} format messages with impossible lengths")
            } else {
                String::new()
            }
        ));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn message_names_split_into_base_and_instance() {
        assert_eq!(base_and_instance("MAG"), ("MAG", 0));
        assert_eq!(base_and_instance("MAG2"), ("MAG", 1));
        assert_eq!(base_and_instance("MAG3"), ("MAG", 2));
        assert_eq!(base_and_instance("ATT"), ("ATT", 0));
    }

    /// Regression: a FMT message declaring a length below 3 panicked inside ardupilot-binlog
    /// 0.2.0 (`msg_len - 3` underflow). It must be an ordinary, reported corruption.
    #[test]
    fn impossible_format_length_is_corruption_not_a_panic() {
        let mut bytes = vec![0xA3, 0x95, 0x80, 0x81, 0x02];
        bytes.extend_from_slice(b"XXXX");
        bytes.resize(89, 0);
        bytes.extend_from_slice(&[0xA3, 0x95, 0x81, 1, 2, 3]);
        let r = read_bytes(&bytes, Path::new("bad.bin"));
        match r {
            Ok(c) => assert!(c.damage.is_some(), "{c:?}"),
            Err(e) => assert!(e.to_string().contains("bad.bin"), "{e}"),
        }
    }
}
