//! Recordings written as PX4 ULog and ArduPilot DataFlash logs, with the topics and messages
//! the importers read. They exist so that the round trip simulate -> log file -> import -> fit
//! can be checked against the simulator's truth, and so that other tools can open a magstand
//! run; they are not flight-controller logs (no estimator, no other sensors).
//!
//! Both logs carry the magnetometer at the recording's rows and the motor commands, battery,
//! attitude and states at the same instants, on a clock that starts at `t_s`.
use std::path::Path;

use magstand_core::{Recording, atomic_file};

use crate::LogsError;

/// How the vehicle should look in the log.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LogWriteOptions {
    /// Report the vehicle landed (a restrained stand) rather than flying.
    pub landed: bool,
    /// Magnetometer device id (PX4 `CAL_MAG0_ID`), any non-zero number.
    pub device_id: u32,
}

impl Default for LogWriteOptions {
    fn default() -> Self {
        Self {
            landed: true,
            device_id: 396_825,
        }
    }
}

fn micros(t_s: f64) -> u64 {
    (t_s * 1e6).round().max(0.0) as u64
}

fn check(rec: &Recording, path: &Path) -> Result<(), LogsError> {
    rec.check()?;
    if rec.overall_only {
        return Err(LogsError::Unusable {
            path: path.to_path_buf(),
            what: "a log needs per-motor commands (thr_1..thr_N), not the overall thr".into(),
        });
    }
    if rec.t_s.first().is_some_and(|t| *t < 0.0) {
        return Err(LogsError::Unusable {
            path: path.to_path_buf(),
            what: "log clocks start at zero: t_s must not be negative".into(),
        });
    }
    Ok(())
}

/// ULog message: 2-byte size, 1-byte type, payload.
fn ulog_msg(out: &mut Vec<u8>, kind: u8, payload: &[u8]) {
    out.extend_from_slice(&(payload.len() as u16).to_le_bytes());
    out.push(kind);
    out.extend_from_slice(payload);
}

/// The recording as ULog bytes.
pub fn ulog_bytes(rec: &Recording, opts: &LogWriteOptions) -> Vec<u8> {
    let n = rec.motor_count();
    let mut out = Vec::new();
    out.extend_from_slice(b"ULog\x01\x12\x35");
    out.push(1);
    out.extend_from_slice(&0u64.to_le_bytes());
    // Flag bits: no compatibility flags, no appended data.
    ulog_msg(&mut out, b'B', &[0u8; 40]);
    let formats = [
        "sensor_mag:uint64_t timestamp;uint64_t timestamp_sample;uint32_t device_id;float x;float y;float z;float temperature;uint32_t error_count;".to_string(),
        format!("actuator_motors:uint64_t timestamp;uint64_t timestamp_sample;float[{n}] control;"),
        "battery_status:uint64_t timestamp;float voltage_v;float current_a;".to_string(),
        "vehicle_attitude:uint64_t timestamp;uint64_t timestamp_sample;float[4] q;".to_string(),
        "actuator_armed:uint64_t timestamp;bool armed;".to_string(),
        "vehicle_land_detected:uint64_t timestamp;bool landed;".to_string(),
    ];
    for f in &formats {
        ulog_msg(&mut out, b'F', f.as_bytes());
    }
    let info = |out: &mut Vec<u8>, key: &str, value: &[u8]| {
        let mut p = vec![key.len() as u8];
        p.extend_from_slice(key.as_bytes());
        p.extend_from_slice(value);
        ulog_msg(out, b'I', &p);
    };
    let sys = b"magstand";
    info(&mut out, &format!("char[{}] sys_name", sys.len()), sys);
    let params: [(&str, i32); 3] = [
        ("CAL_MAG0_ID", opts.device_id as i32),
        // -1: an internal magnetometer, in the board frame.
        ("CAL_MAG0_ROT", -1),
        ("CAL_MAG_COMP_TYP", 0),
    ];
    for (name, v) in params {
        let key = format!("int32_t {name}");
        let mut p = vec![key.len() as u8];
        p.extend_from_slice(key.as_bytes());
        p.extend_from_slice(&v.to_le_bytes());
        ulog_msg(&mut out, b'P', &p);
    }
    let topics = [
        "sensor_mag",
        "actuator_motors",
        "battery_status",
        "vehicle_attitude",
        "actuator_armed",
        "vehicle_land_detected",
    ];
    for (id, t) in topics.iter().enumerate() {
        let mut p = vec![0u8];
        p.extend_from_slice(&(id as u16).to_le_bytes());
        p.extend_from_slice(t.as_bytes());
        ulog_msg(&mut out, b'A', &p);
    }
    let data = |out: &mut Vec<u8>, id: u16, body: &[u8]| {
        let mut p = id.to_le_bytes().to_vec();
        p.extend_from_slice(body);
        ulog_msg(out, b'D', &p);
    };
    let f32s = |v: &mut Vec<u8>, xs: &[f64]| {
        for x in xs {
            v.extend_from_slice(&(*x as f32).to_le_bytes());
        }
    };
    for r in 0..rec.len() {
        let us = micros(rec.t_s[r]).to_le_bytes();
        let mut m = [us, us].concat();
        m.extend_from_slice(&opts.device_id.to_le_bytes());
        let g = rec.mag_ut[r] / 100.0;
        let temp = rec.temp_c.as_ref().map_or(f64::NAN, |c| c[r]);
        f32s(&mut m, &[g.x, g.y, g.z, temp]);
        m.extend_from_slice(&0u32.to_le_bytes());
        data(&mut out, 0, &m);
        let mut c = [us, us].concat();
        f32s(&mut c, &rec.motor_commands(r));
        data(&mut out, 1, &c);
        if let (Some(v), Some(a)) = (&rec.bat_v, &rec.bat_a) {
            let mut b = us.to_vec();
            f32s(&mut b, &[v[r], a[r]]);
            data(&mut out, 2, &b);
        }
        if let Some(q) = &rec.attitude {
            let q = q[r].quaternion();
            let mut b = [us, us].concat();
            f32s(&mut b, &[q.w, q.i, q.j, q.k]);
            data(&mut out, 3, &b);
        }
        if r == 0 {
            data(&mut out, 4, &[us.as_slice(), &[1]].concat());
            data(&mut out, 5, &[us.as_slice(), &[opts.landed as u8]].concat());
        }
    }
    out
}

/// DataFlash message header.
const HEAD: [u8; 2] = [0xA3, 0x95];

/// A FMT message defining `kind`.
fn fmt_msg(out: &mut Vec<u8>, kind: u8, name: &str, format: &str, labels: &str) {
    let size: usize = 3 + format
        .chars()
        .map(|c| match c {
            'B' | 'b' => 1,
            'H' | 'h' => 2,
            'f' | 'I' | 'i' => 4,
            'Q' | 'q' | 'd' => 8,
            'N' => 16,
            'Z' => 64,
            'n' => 4,
            _ => unreachable!("format characters are fixed in this file"),
        })
        .sum::<usize>();
    let fixed = |s: &str, len: usize| {
        let mut b = s.as_bytes().to_vec();
        b.resize(len, 0);
        b
    };
    out.extend_from_slice(&HEAD);
    out.push(0x80);
    out.push(kind);
    out.push(size as u8);
    out.extend(fixed(name, 4));
    out.extend(fixed(format, 16));
    out.extend(fixed(labels, 64));
}

/// The recording as DataFlash bytes (current message layout: `TimeUS`, `MAG` with an
/// instance field, `RCOU` `C1..`, `BAT` in volts and amperes, `ATT` in degrees).
pub fn dataflash_bytes(rec: &Recording, opts: &LogWriteOptions) -> Vec<u8> {
    let n = rec.motor_count().min(14);
    let mut out = Vec::new();
    fmt_msg(
        &mut out,
        0x80,
        "FMT",
        "BBnNZ",
        "Type,Length,Name,Format,Labels",
    );
    fmt_msg(&mut out, 0x81, "PARM", "QNf", "TimeUS,Name,Value");
    fmt_msg(&mut out, 0x82, "MAG", "QBfff", "TimeUS,I,MagX,MagY,MagZ");
    let rcou_fmt = format!("Q{}", "H".repeat(n));
    let rcou_labels = std::iter::once("TimeUS".to_string())
        .chain((1..=n).map(|c| format!("C{c}")))
        .collect::<Vec<_>>()
        .join(",");
    fmt_msg(&mut out, 0x83, "RCOU", &rcou_fmt, &rcou_labels);
    fmt_msg(&mut out, 0x84, "BAT", "QBff", "TimeUS,Inst,Volt,Curr");
    fmt_msg(&mut out, 0x85, "ATT", "Qfff", "TimeUS,Roll,Pitch,Yaw");
    fmt_msg(&mut out, 0x86, "EV", "QB", "TimeUS,Id");
    let t0 = micros(rec.t_s.first().copied().unwrap_or(0.0));
    let mut params: Vec<(String, f64)> = vec![
        ("MOT_PWM_MIN".into(), 1000.0),
        ("MOT_PWM_MAX".into(), 2000.0),
        ("COMPASS_EXTERNAL".into(), 0.0),
        ("COMPASS_MOTCT".into(), 0.0),
    ];
    params.extend((1..=n).map(|c| (format!("SERVO{c}_FUNCTION"), 32.0 + c as f64)));
    for (name, v) in &params {
        out.extend_from_slice(&HEAD);
        out.push(0x81);
        out.extend_from_slice(&t0.to_le_bytes());
        let mut b = name.as_bytes().to_vec();
        b.resize(16, 0);
        out.extend(b);
        out.extend_from_slice(&(*v as f32).to_le_bytes());
    }
    let ev = |out: &mut Vec<u8>, us: u64, id: u8| {
        out.extend_from_slice(&HEAD);
        out.push(0x86);
        out.extend_from_slice(&us.to_le_bytes());
        out.push(id);
    };
    ev(&mut out, t0, 10);
    if !opts.landed {
        ev(&mut out, t0, 28);
    }
    for r in 0..rec.len() {
        let us = micros(rec.t_s[r]);
        out.extend_from_slice(&HEAD);
        out.push(0x82);
        out.extend_from_slice(&us.to_le_bytes());
        out.push(0);
        // Milligauss.
        for k in 0..3 {
            out.extend_from_slice(&((rec.mag_ut[r][k] * 10.0) as f32).to_le_bytes());
        }
        out.extend_from_slice(&HEAD);
        out.push(0x83);
        out.extend_from_slice(&us.to_le_bytes());
        for m in 0..n {
            let pwm = (1000.0 + 1000.0 * rec.thr[m][r]).round() as u16;
            out.extend_from_slice(&pwm.to_le_bytes());
        }
        if let (Some(v), Some(a)) = (&rec.bat_v, &rec.bat_a) {
            out.extend_from_slice(&HEAD);
            out.push(0x84);
            out.extend_from_slice(&us.to_le_bytes());
            out.push(0);
            out.extend_from_slice(&(v[r] as f32).to_le_bytes());
            out.extend_from_slice(&(a[r] as f32).to_le_bytes());
        }
        if let Some(q) = &rec.attitude {
            let (roll, pitch, yaw) = q[r].euler_angles();
            out.extend_from_slice(&HEAD);
            out.push(0x85);
            out.extend_from_slice(&us.to_le_bytes());
            for a in [roll, pitch, yaw] {
                out.extend_from_slice(&(a.to_degrees() as f32).to_le_bytes());
            }
        }
    }
    out
}

/// Writes the recording as a ULog file, atomically.
pub fn write_ulog(rec: &Recording, path: &Path, opts: &LogWriteOptions) -> Result<(), LogsError> {
    check(rec, path)?;
    write(path, &ulog_bytes(rec, opts))
}

/// Writes the recording as a DataFlash file, atomically.
pub fn write_dataflash(
    rec: &Recording,
    path: &Path,
    opts: &LogWriteOptions,
) -> Result<(), LogsError> {
    check(rec, path)?;
    write(path, &dataflash_bytes(rec, opts))
}

fn write(path: &Path, bytes: &[u8]) -> Result<(), LogsError> {
    Ok(atomic_file::write_bytes(path, bytes)?)
}
