//! PX4 ULog files read with the `px4-ulog` crate (its streaming parser, so only the topics
//! magstand uses are kept in memory).
use std::collections::HashMap;
use std::path::Path;

use px4_ulog::stream_parser::LogParser;
use px4_ulog::stream_parser::model::{DataMessage, FlattenedFieldType, ParameterMessage};

use crate::LogsError;
use crate::contents::{LogContents, LogFormat, Series};

/// The topics the PX4 import reads; everything else is skipped while parsing.
pub const TOPICS: [&str; 13] = [
    "sensor_mag",
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

/// Reads a ULog file.
pub fn read_file(path: &Path) -> Result<LogContents, LogsError> {
    let bytes = std::fs::read(path).map_err(|source| LogsError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    read_bytes(&bytes, path)
}

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
    let mut parser = LogParser::default();
    parser.set_data_message_callback(&mut on_data);
    parser.set_parameter_message_callback(&mut on_param);
    let result = parser.consume_bytes(bytes);
    let in_data = parser.in_data();
    let leftover = parser.has_leftover();
    drop(parser);
    out.damage = match result {
        Err(e) if !in_data => return Err(corrupt(format!("in its header or definitions: {e}"))),
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
        Ok(()) => None,
    };
    Ok(out)
}
