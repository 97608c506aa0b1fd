//! PX4 ULog files read with the `px4-ulog` crate (its streaming parser, so only the topics
//! magstand uses are kept in memory).
//!
//! One guard sits in front of the crate: version 0.6.1 slices message payloads by lengths
//! read from the payload itself (a parameter's key length, an info key length, the fixed
//! fields of a logging message) without checking them, and panics on a corrupt message whose
//! length field points past its end. `framing_scan` walks the message framing first: a
//! message whose own lengths are inconsistent, or of an unknown type, starts a stretch that
//! is skipped up to the next synchronisation message (or, with none after it, the file is
//! cut there), as pyulog does; the crate then reads what is left.
//!
//! The same walk drops data messages whose id no subscription registered (a flipped bit in a
//! real log's msg_id, as pyulog skips it): the crate stops at them, and everything after one
//! would be lost for a single bad message. What was skipped or cut is reported as damage.
use std::borrow::Cow;
use std::collections::{HashMap, HashSet};
use std::path::Path;

use px4_ulog::stream_parser::LogParser;
use px4_ulog::stream_parser::model::{DataMessage, FlattenedFieldType, ParameterMessage};

use crate::LogsError;
use crate::contents::{LogContents, LogFormat, Series};

/// The topics the PX4 import reads; everything else is skipped while parsing.
pub const TOPICS: [&str; 15] = [
    "sensor_mag",
    "vehicle_thrust_setpoint",
    "actuator_controls_0",
    "vehicle_magnetometer",
    "actuator_outputs",
    "actuator_motors",
    "battery_status",
    "vehicle_attitude",
    "actuator_armed",
    "vehicle_status",
    "vehicle_land_detected",
    "esc_status",
    "vehicle_gps_position",
    "sensor_gps",
    "vehicle_global_position",
];

/// How one logged message format is decoded: its numeric fields and where its time is.
struct Decoder {
    name: String,
    fields: Vec<(String, FlattenedFieldType, usize)>,
    time: Option<usize>,
}

fn decoder(msg: &DataMessage) -> Option<Decoder> {
    let name = msg.flattened_format.message_name();
    if !TOPICS.contains(&name) {
        return None;
    }
    let mut fields = Vec::new();
    let mut stamp = None;
    let mut sample = None;
    for f in msg.flattened_format.field_iter() {
        let n = &f.flattened_field_name;
        if n.starts_with("_padding") {
            continue;
        }
        let off = f.offset as usize;
        match n.as_str() {
            "timestamp" if f.field_type == FlattenedFieldType::UInt64 => stamp = Some(off),
            "timestamp_sample" if f.field_type == FlattenedFieldType::UInt64 => sample = Some(off),
            _ => {}
        }
        if f.field_type != FlattenedFieldType::Char {
            fields.push((n.clone(), f.field_type.clone(), off));
        }
    }
    Some(Decoder {
        name: name.to_string(),
        fields,
        // When the sample was taken, where the topic says; otherwise when it was published.
        time: sample.or(stamp),
    })
}

/// One little-endian value at `off`, or `None` past the end of the message.
fn value(data: &[u8], off: usize, ty: &FlattenedFieldType) -> Option<f64> {
    fn take<const N: usize>(data: &[u8], off: usize) -> Option<[u8; N]> {
        data.get(off..off.checked_add(N)?)?.try_into().ok()
    }
    use FlattenedFieldType as T;
    Some(match ty {
        T::Int8 => i8::from_le_bytes(take(data, off)?) as f64,
        T::UInt8 => u8::from_le_bytes(take(data, off)?) as f64,
        T::Bool => (take::<1>(data, off)?[0] != 0) as u8 as f64,
        T::Int16 => i16::from_le_bytes(take(data, off)?) as f64,
        T::UInt16 => u16::from_le_bytes(take(data, off)?) as f64,
        T::Int32 => i32::from_le_bytes(take(data, off)?) as f64,
        T::UInt32 => u32::from_le_bytes(take(data, off)?) as f64,
        T::Int64 => i64::from_le_bytes(take(data, off)?) as f64,
        T::UInt64 => u64::from_le_bytes(take(data, off)?) as f64,
        T::Float => f32::from_le_bytes(take(data, off)?) as f64,
        T::Double => f64::from_le_bytes(take(data, off)?),
        T::Char => return None,
    })
}

/// The payload of a ULog synchronisation message ('S'), which PX4 writes about once a second
/// so that a reader can find its way back into a damaged file.
const SYNC_MAGIC: [u8; 8] = [0x2F, 0x73, 0x13, 0x20, 0x25, 0x0C, 0xBB, 0x12];

/// What the framing walk found.
#[derive(Default)]
struct Framing {
    /// The offset of the first unreadable message with no synchronisation message after it
    /// (the file is cut there), and what was wrong.
    cut: Option<(usize, String)>,
    /// Byte ranges to leave out: data messages with an unregistered id, and unreadable
    /// stretches up to the next synchronisation message.
    skipped: Vec<std::ops::Range<usize>>,
    /// Of `skipped`: how many are single data messages with an unregistered id.
    unregistered: usize,
    /// The first problem found, for the report.
    first: Option<String>,
}

/// Walks the message framing. A data message whose msg_id no add-subscription registered is
/// left out on its own (its size is intact, only the id is bad); a message that cannot be
/// read (an unknown type, or lengths that do not fit its size) starts a stretch that is left
/// out up to the next synchronisation message, as pyulog does; with no synchronisation message
/// after it, the file is cut there.
fn framing_scan(bytes: &[u8]) -> Framing {
    let mut out = Framing::default();
    let mut registered: HashSet<u16> = HashSet::new();
    let mut i = 16;
    while i + 3 <= bytes.len() {
        let size = u16::from_le_bytes([bytes[i], bytes[i + 1]]) as usize;
        let kind = bytes[i + 2];
        let Some(payload) = bytes.get(i + 3..i + 3 + size) else {
            return out; // a truncated last message: the parser reports it
        };
        let key = |at: usize| payload.get(at).map(|k| at + 1 + *k as usize);
        let id = |at: usize| u16::from_le_bytes([payload[at], payload[at + 1]]);
        let ok = match kind {
            b'B' => size >= 40,
            b'A' => size >= 3,
            b'D' | b'R' | b'O' => size >= 2,
            b'S' => size >= 8,
            b'L' => size >= 9,
            b'C' => size >= 11,
            b'I' | b'P' => key(0).is_some_and(|end| end <= size),
            b'M' | b'Q' => size >= 2 && key(1).is_some_and(|end| end <= size),
            b'F' => true,
            _ => false,
        };
        if !ok {
            let what = if b"BADROSLCIPMQF".contains(&kind) {
                format!(
                    "a malformed '{}' message at byte {i} (its lengths do not fit its {size} bytes)",
                    kind as char
                )
            } else {
                format!("an unreadable message (type byte {kind:#04x}) at byte {i}")
            };
            let resume = bytes[i + 3..]
                .windows(SYNC_MAGIC.len())
                .position(|w| w == SYNC_MAGIC)
                .map(|p| i + 3 + p - 3)
                .filter(|&s| bytes[s..s + 3] == [8, 0, b'S']);
            match resume {
                // Before the data section there is nothing to resynchronise to.
                Some(s) if !registered.is_empty() => {
                    out.first.get_or_insert(what);
                    out.skipped.push(i..s);
                    i = s;
                    continue;
                }
                _ => {
                    out.cut = Some((i, what));
                    return out;
                }
            }
        }
        match kind {
            b'A' => {
                registered.insert(id(1));
            }
            b'R' => {
                registered.remove(&id(0));
            }
            b'D' if !registered.contains(&id(0)) => {
                out.first.get_or_insert_with(|| {
                    format!(
                        "a data message with msg_id {} that no subscription registered at byte {i}",
                        id(0)
                    )
                });
                out.unregistered += 1;
                out.skipped.push(i..i + 3 + size);
            }
            _ => {}
        }
        i += 3 + size;
    }
    out
}

/// `bytes` without the given ranges (sorted, disjoint), borrowed when there are none.
fn without<'a>(bytes: &'a [u8], ranges: &[std::ops::Range<usize>]) -> Cow<'a, [u8]> {
    if ranges.is_empty() {
        return Cow::Borrowed(bytes);
    }
    let mut kept = Vec::with_capacity(bytes.len());
    let mut from = 0;
    for r in ranges {
        kept.extend_from_slice(&bytes[from..r.start]);
        from = r.end;
    }
    kept.extend_from_slice(&bytes[from..]);
    Cow::Owned(kept)
}

/// Reads ULog bytes; `path` names them in messages.
///
/// A file that breaks off or holds a malformed message after its definitions keeps what came
/// before and says where it broke in [`LogContents::damage`]; a file whose header or
/// definitions cannot be read is an error.
pub fn read_bytes(bytes: &[u8], path: &Path) -> Result<LogContents, LogsError> {
    let mut out = LogContents::new(path.to_path_buf(), LogFormat::Ulog);
    let corrupt = |what: String| LogsError::Corrupt {
        path: path.to_path_buf(),
        format: "ULog",
        what,
    };
    if bytes.len() < 16 || &bytes[..7] != b"ULog\x01\x12\x35" {
        return Err(corrupt(
            "the file does not start with the ULog magic bytes".into(),
        ));
    }
    let Framing {
        cut: guard,
        skipped,
        unregistered,
        first,
    } = framing_scan(bytes);
    let bytes = &bytes[..guard.as_ref().map_or(bytes.len(), |(cut, _)| *cut)];
    let skipped_bytes: usize = skipped.iter().map(|r| r.len()).sum();
    let skipped_what = first.map(|first| {
        format!(
            "{} stretch(es) of {skipped_bytes} bytes skipped ({unregistered} data message(s) with an unregistered msg_id, the rest unreadable up to the next sync message; the first: {first})",
            skipped.len()
        )
    });
    let bytes = without(bytes, &skipped);
    let bytes: &[u8] = &bytes;
    let mut decoders: HashMap<u16, Option<Decoder>> = HashMap::new();
    let topics = &mut out.topics;
    let mut messages = 0usize;
    let mut on_data = |msg: &DataMessage| {
        messages += 1;
        let entry = decoders.entry(msg.msg_id).or_insert_with(|| decoder(msg));
        // A message id may be reused for another format after a remove message.
        if entry
            .as_ref()
            .is_some_and(|d| d.name != msg.flattened_format.message_name())
        {
            *entry = decoder(msg);
        }
        let Some(d) = entry.as_ref() else { return };
        let Some(t_us) = d
            .time
            .and_then(|o| value(msg.data, o, &FlattenedFieldType::UInt64))
        else {
            return;
        };
        let series: &mut Series = topics
            .entry(d.name.clone())
            .or_default()
            .entry(msg.multi_id.value())
            .or_default();
        series.push(
            t_us * 1e-6,
            d.fields
                .iter()
                .filter_map(|(n, ty, o)| Some((n.clone(), value(msg.data, *o, ty)?))),
        );
    };
    let params = &mut out.params;
    let mut on_param = |p: &ParameterMessage| match p {
        ParameterMessage::Float(n, v, _) => {
            params.insert(n.to_string(), *v as f64);
        }
        ParameterMessage::Int32(n, v, _) => {
            params.insert(n.to_string(), *v as f64);
        }
    };
    let info = &mut out.info;
    let mut on_info = |m: &px4_ulog::stream_parser::model::InfoMessage| {
        let value = match m.type_str {
            "uint32_t" => m
                .value
                .get(..4)
                .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]).to_string()),
            "int32_t" => m
                .value
                .get(..4)
                .map(|b| i32::from_le_bytes([b[0], b[1], b[2], b[3]]).to_string()),
            t if t.starts_with("char") => Some(
                String::from_utf8_lossy(m.value)
                    .trim_end_matches('\0')
                    .to_string(),
            ),
            _ => None,
        };
        if let Some(v) = value {
            info.insert(m.key.to_string(), v);
        }
    };
    let mut parser = LogParser::default();
    parser.set_info_message_callback(&mut on_info);
    parser.set_data_message_callback(&mut on_data);
    parser.set_parameter_message_callback(&mut on_param);
    let result = parser.consume_bytes(bytes);
    let in_data = parser.in_data();
    let leftover = parser.has_leftover();
    drop(parser);
    out.damage = match result {
        Err(e) if !in_data => return Err(corrupt(format!("in its header or definitions: {e}"))),
        Ok(()) if !in_data && guard.is_some() => {
            return Err(corrupt(format!(
                "in its header or definitions: {}",
                guard.map(|g| g.1).unwrap_or_default()
            )));
        }
        Err(e) => Some(format!(
            "a malformed message after {messages} good data messages ({}); the data before it is kept",
            // The parser's description ends with a debug dump of the format: keep the sentence.
            e.description
                .split(", format:")
                .next()
                .unwrap_or("")
                .chars()
                .take(160)
                .collect::<String>()
        )),
        Ok(()) if !in_data => {
            return Err(corrupt(
                "the file ends before its data section begins".into(),
            ));
        }
        Ok(()) if leftover => Some(format!(
            "the file ends inside a message (truncated) after {messages} data messages; the data before it is kept"
        )),
        Ok(()) if guard.is_some() => Some(format!(
            "{} after {messages} good data messages; the data before it is kept",
            guard.map(|g| g.1).unwrap_or_default()
        )),
        Ok(()) => None,
    };
    if let Some(what) = skipped_what {
        out.damage = Some(match out.damage.take() {
            Some(d) => format!("{what}; {d}"),
            None => format!("{what}; the rest is kept"),
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn header() -> Vec<u8> {
        let mut b = b"ULog\x01\x12\x35\x01".to_vec();
        b.extend_from_slice(&0u64.to_le_bytes());
        b.extend_from_slice(&40u16.to_le_bytes());
        b.push(b'B');
        b.extend_from_slice(&[0; 40]);
        b
    }

    /// Regression: a parameter message whose key length points past its end panicked inside
    /// px4-ulog 0.6.1 (a slice out of range) instead of being reported. Found by the
    /// corrupted-log proptest.
    #[test]
    fn a_parameter_with_an_impossible_key_length_is_corruption_not_a_panic() {
        let mut b = header();
        b.extend_from_slice(&5u16.to_le_bytes());
        b.push(b'P');
        b.extend_from_slice(&[237, b'a', b'b', b'c', b'd']);
        let e = read_bytes(&b, Path::new("p.ulg")).unwrap_err().to_string();
        assert!(
            e.contains("p.ulg") && e.contains("'P' message at byte 59"),
            "{e}"
        );
    }

    #[test]
    fn a_file_that_is_not_ulog_is_named() {
        let e = read_bytes(b"hello world, not a log", Path::new("x.ulg"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("x.ulg") && e.contains("magic"), "{e}");
    }
}
