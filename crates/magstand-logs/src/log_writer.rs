//! Recordings written as PX4 ULog and ArduPilot DataFlash logs, with the topics and messages
//! the importers read. They exist so that the round trip simulate -> log file -> import -> fit
//! can be checked against the simulator's truth, and so that other tools can open a magstand
//! run; they are not flight-controller logs (no estimator, no other sensors).
//!
//! Both logs carry the magnetometer at the recording's rows and the motor commands, battery,
//! attitude and states at the same instants, on a clock that starts at `t_s`.
use std::path::Path;

use magstand_core::atomic_file::{self, Staged};
use magstand_core::magnetometer_frame::SensorToBody;
use magstand_core::{Recording, Vec3};

use crate::LogsError;

/// How the vehicle should look in the log.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LogWriteOptions {
    /// Report the vehicle landed (a restrained stand) rather than flying.
    pub landed: bool,
    /// Magnetometer device id (PX4 `CAL_MAG0_ID`), any non-zero number.
    pub device_id: u32,
    /// The PX4 calibration the ULog carries for its magnetometer. Without one it is an
    /// internal sensor of a board mounted unturned, with no offsets or scale; with one, the
    /// readings are written as the driver would publish them, so that the calibration takes
    /// them back to the recording's field.
    pub px4_calibration: Option<Px4MagCalibration>,
    /// The PX4 release the ULog says wrote it (`ver_sw_release`, 0xAABBCCTT: major, minor,
    /// patch, type), where it should say one. Before 1.12 PX4's drivers applied the
    /// calibration's offsets and scale to `sensor_mag` themselves, and the log is written so.
    pub px4_release: Option<u32>,
    /// ArduPilot's `AHRS_TRIM_X`, `_Y`, `_Z` (rad) for the DataFlash log. The recording's
    /// attitude is the autopilot board's, in which `MAG` is logged; `ATT` is written as the
    /// estimators log it, its Euler angles less the trim.
    pub ardupilot_trim_rad: [f64; 3],
}

impl Default for LogWriteOptions {
    fn default() -> Self {
        Self {
            landed: true,
            device_id: 396_825,
            px4_calibration: None,
            px4_release: None,
            ardupilot_trim_rad: [0.0; 3],
        }
    }
}

/// A PX4 magnetometer calibration (`CAL_MAG0_*`), which takes a reading as the driver
/// published it to the body frame: `R · S · (raw − offset)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Px4MagCalibration {
    /// `CAL_MAG0_ROT`: a PX4 rotation from 0 to 40 (PX4's `Rotation` enum), or -1 for an
    /// internal sensor, which follows `board_rotation`.
    pub rotation: i32,
    /// `SENS_BOARD_ROT`, the board's rotation (the same codes).
    pub board_rotation: i32,
    /// `SENS_BOARD_{X,Y,Z}_OFF`, the board's fine trim after its rotation, degrees (roll,
    /// pitch, yaw), which an internal sensor turns with.
    pub board_trim_deg: [f64; 3],
    /// `CAL_MAG0_{X,Y,Z}OFF`, gauss.
    pub offset_g: [f64; 3],
    /// `CAL_MAG0_{X,Y,Z}SCALE`, the scale matrix's diagonal.
    pub scale: [f64; 3],
    /// `CAL_MAG0_{X,Y,Z}ODIAG`, its off-diagonal (xy, xz, yz).
    pub off_diagonal: [f64; 3],
}

impl Px4MagCalibration {
    /// The transform from the sensor's frame to the body frame, with every parameter as the
    /// log stores it (single precision), or why there is none.
    fn sensor_to_body(&self, driver_calibrated: bool) -> Result<SensorToBody, String> {
        let f = |v: f64| v as f32 as f64;
        let trim = self.board_trim_deg.map(|d| f(d).to_radians());
        let (code, rotation, known) =
            crate::px4::px4_sensor_rotation(self.rotation.into(), self.board_rotation.into(), trim);
        if !known {
            return Err(format!("a PX4 rotation from 0 to 40; found {code}"));
        }
        let scale = match driver_calibrated {
            true => magstand_core::Mat3::identity(),
            false => crate::px4::px4_scale(self.scale.map(f), self.off_diagonal.map(f)),
        };
        SensorToBody::from_matrix(&(rotation.to_rotation_matrix().into_inner() * scale))
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
    if let Some(release) = opts.px4_release {
        info(&mut out, "uint32_t ver_sw_release", &release.to_le_bytes());
    }
    let cal = opts.px4_calibration;
    let mut params: Vec<(String, [u8; 4], &str)> = vec![
        (
            "CAL_MAG0_ID".into(),
            (opts.device_id as i32).to_le_bytes(),
            "int32_t",
        ),
        // -1: an internal magnetometer, in the board frame.
        (
            "CAL_MAG0_ROT".into(),
            cal.map_or(-1, |c| c.rotation).to_le_bytes(),
            "int32_t",
        ),
        ("CAL_MAG_COMP_TYP".into(), 0i32.to_le_bytes(), "int32_t"),
    ];
    if let Some(c) = cal {
        params.push((
            "SENS_BOARD_ROT".into(),
            c.board_rotation.to_le_bytes(),
            "int32_t",
        ));
        for (axis, trim) in ["X", "Y", "Z"].iter().zip(c.board_trim_deg) {
            let bytes = (trim as f32).to_le_bytes();
            params.push((format!("SENS_BOARD_{axis}_OFF"), bytes, "float"));
        }
        for (k, axis) in ["X", "Y", "Z"].iter().enumerate() {
            for (name, v) in [
                ("OFF", c.offset_g[k]),
                ("SCALE", c.scale[k]),
                ("ODIAG", c.off_diagonal[k]),
            ] {
                let bytes = (v as f32).to_le_bytes();
                params.push((format!("CAL_MAG0_{axis}{name}"), bytes, "float"));
            }
        }
    }
    for (name, v, ty) in params {
        let key = format!("{ty} {name}");
        let mut p = vec![key.len() as u8];
        p.extend_from_slice(key.as_bytes());
        p.extend_from_slice(&v);
        ulog_msg(&mut out, b'P', &p);
    }
    // The readings as the driver published them: the calibration's inverse of the field.
    let driver_calibrated = opts.px4_release.is_some_and(|r| {
        let [major, minor, patch, _] = r.to_be_bytes();
        crate::px4::calibrated_by_driver([major, minor, patch])
    });
    let frame = cal.map(|c| {
        let offset_g = match driver_calibrated {
            true => [0.0; 3],
            false => c.offset_g.map(|v| v as f32 as f64),
        };
        (c.sensor_to_body(driver_calibrated), offset_g)
    });
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
        let g = match &frame {
            Some((Ok(frame), offset_g)) => frame
                .to_sensor(rec.mag_ut[r] / 100.0)
                .map_or(Vec3::repeat(f64::NAN), |v| v + Vec3::from(*offset_g)),
            // A calibration the import will refuse: its field as it is.
            _ => rec.mag_ut[r] / 100.0,
        };
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

/// Type ids the builder gives the messages it defines itself.
const FMT_KIND: u8 = 0x80;
const PARM_KIND: u8 = 0xF0;
const FMTU_KIND: u8 = 0xF1;
const UNIT_KIND: u8 = 0xF2;
const MULT_KIND: u8 = 0xF3;
const MSG_KIND: u8 = 0xF4;

/// DataFlash bytes built message by message: formats (`FMT`, and the `FMTU`, `UNIT` and
/// `MULT` records that declare units), parameters and data rows encoded by their format.
///
/// It writes what ArduPilot writes, in any layout a firmware version used, so that the import
/// can be tested on layouts no real log at hand has.
///
/// ```
/// use magstand_logs::log_writer::DataflashBuilder;
/// let mut b = DataflashBuilder::new();
/// b.format(0x84, "CURR", "Qff", "TimeUS,Volt,Curr")
///     .row(0x84, &[1e6, 16.2, 12.5]);
/// let log = magstand_logs::dataflash::read_bytes(&b.into_bytes(), "curr.bin".as_ref())?;
/// assert_eq!(log.series("CURR", 0).unwrap().field("Curr"), Some(&[12.5][..]));
/// # Ok::<(), magstand_logs::LogsError>(())
/// ```
#[derive(Debug, Clone)]
pub struct DataflashBuilder {
    bytes: Vec<u8>,
    formats: std::collections::BTreeMap<u8, String>,
}

impl Default for DataflashBuilder {
    fn default() -> Self {
        Self::new()
    }
}

impl DataflashBuilder {
    /// A log holding only the format of `FMT` itself.
    pub fn new() -> Self {
        let mut b = Self {
            bytes: Vec::new(),
            formats: Default::default(),
        };
        b.format(FMT_KIND, "FMT", "BBnNZ", "Type,Length,Name,Format,Labels");
        b
    }

    /// Defines message type `kind` (a `FMT` record). Format characters: `bBhHiIqQfd` numbers,
    /// `cCeE` hundredths, `nNZ` text.
    ///
    /// # Panics
    /// On a format character outside that list: formats are written by the caller's code.
    pub fn format(&mut self, kind: u8, name: &str, format: &str, labels: &str) -> &mut Self {
        let size = 3 + format.chars().map(field_size).sum::<usize>();
        self.formats.insert(kind, format.to_string());
        self.bytes.extend_from_slice(&HEAD);
        self.bytes.push(FMT_KIND);
        self.bytes.push(kind);
        self.bytes.push(size as u8);
        self.bytes.extend(fixed(name, 4));
        self.bytes.extend(fixed(format, 16));
        self.bytes.extend(fixed(labels, 64));
        self
    }

    /// One message of type `kind`, its numeric fields encoded as its format says (hundredths
    /// for `cCeE`); text fields are left empty.
    ///
    /// # Panics
    /// When `kind` has no format.
    pub fn row(&mut self, kind: u8, values: &[f64]) -> &mut Self {
        let format = self.formats[&kind].clone();
        self.bytes.extend_from_slice(&HEAD);
        self.bytes.push(kind);
        let mut v = values.iter().copied();
        for c in format.chars() {
            let x = if matches!(c, 'n' | 'N' | 'Z') {
                0.0
            } else {
                v.next().unwrap_or(0.0)
            };
            encode(&mut self.bytes, c, x, "");
        }
        self
    }

    /// A parameter (`PARM`, defined on first use).
    pub fn param(&mut self, time_us: u64, name: &str, value: f64) -> &mut Self {
        self.define_once(PARM_KIND, "PARM", "QNf", "TimeUS,Name,Value");
        self.bytes.extend_from_slice(&HEAD);
        self.bytes.push(PARM_KIND);
        self.bytes.extend_from_slice(&time_us.to_le_bytes());
        self.bytes.extend(fixed(name, 16));
        self.bytes.extend_from_slice(&(value as f32).to_le_bytes());
        self
    }

    /// A text message (`MSG`, defined on first use), as the firmware writes its version and
    /// frame ("Frame: QUAD") at boot.
    pub fn text(&mut self, time_us: u64, text: &str) -> &mut Self {
        self.define_once(MSG_KIND, "MSG", "QZ", "TimeUS,Message");
        self.bytes.extend_from_slice(&HEAD);
        self.bytes.push(MSG_KIND);
        self.bytes.extend_from_slice(&time_us.to_le_bytes());
        self.bytes.extend(fixed(text, 64));
        self
    }

    /// Declares the unit and multiplier ids of `kind`'s fields (`FMTU`, defined on first use).
    pub fn units(&mut self, kind: u8, unit_ids: &str, mult_ids: &str) -> &mut Self {
        self.define_once(FMTU_KIND, "FMTU", "QBNN", "TimeUS,FmtType,UnitIds,MultIds");
        self.bytes.extend_from_slice(&HEAD);
        self.bytes.push(FMTU_KIND);
        self.bytes.extend_from_slice(&0u64.to_le_bytes());
        self.bytes.push(kind);
        self.bytes.extend(fixed(unit_ids, 16));
        self.bytes.extend(fixed(mult_ids, 16));
        self
    }

    /// Names unit id `id` (`UNIT`, defined on first use).
    pub fn unit(&mut self, id: char, label: &str) -> &mut Self {
        self.define_once(UNIT_KIND, "UNIT", "QbZ", "TimeUS,Id,Label");
        self.bytes.extend_from_slice(&HEAD);
        self.bytes.push(UNIT_KIND);
        self.bytes.extend_from_slice(&0u64.to_le_bytes());
        self.bytes.push(id as u8);
        self.bytes.extend(fixed(label, 64));
        self
    }

    /// Gives multiplier id `id` its factor (`MULT`, defined on first use).
    pub fn mult(&mut self, id: char, factor: f64) -> &mut Self {
        self.define_once(MULT_KIND, "MULT", "Qbd", "TimeUS,Id,Mult");
        self.bytes.extend_from_slice(&HEAD);
        self.bytes.push(MULT_KIND);
        self.bytes.extend_from_slice(&0u64.to_le_bytes());
        self.bytes.push(id as u8);
        self.bytes.extend_from_slice(&factor.to_le_bytes());
        self
    }

    /// The bytes written so far.
    pub fn into_bytes(self) -> Vec<u8> {
        self.bytes
    }

    fn define_once(&mut self, kind: u8, name: &str, format: &str, labels: &str) {
        if !self.formats.contains_key(&kind) {
            self.format(kind, name, format, labels);
        }
    }
}

fn field_size(c: char) -> usize {
    match c {
        'B' | 'b' => 1,
        'H' | 'h' | 'c' | 'C' => 2,
        'f' | 'I' | 'i' | 'e' | 'E' | 'n' => 4,
        'Q' | 'q' | 'd' => 8,
        'N' => 16,
        'Z' => 64,
        _ => panic!("format character {c:?} is not one the DataFlash builder writes"),
    }
}

fn fixed(s: &str, len: usize) -> Vec<u8> {
    let mut b = s.as_bytes().to_vec();
    b.resize(len, 0);
    b
}

fn encode(out: &mut Vec<u8>, c: char, x: f64, text: &str) {
    match c {
        'b' => out.push(x.round() as i8 as u8),
        'B' => out.push(x.round() as u8),
        'h' => out.extend((x.round() as i16).to_le_bytes()),
        'H' => out.extend((x.round() as u16).to_le_bytes()),
        'c' => out.extend(((x * 100.0).round() as i16).to_le_bytes()),
        'C' => out.extend(((x * 100.0).round() as u16).to_le_bytes()),
        'i' => out.extend((x.round() as i32).to_le_bytes()),
        'I' => out.extend((x.round() as u32).to_le_bytes()),
        'e' => out.extend(((x * 100.0).round() as i32).to_le_bytes()),
        'E' => out.extend(((x * 100.0).round() as u32).to_le_bytes()),
        'q' => out.extend((x.round() as i64).to_le_bytes()),
        'Q' => out.extend((x.round() as u64).to_le_bytes()),
        'f' => out.extend((x as f32).to_le_bytes()),
        'd' => out.extend(x.to_le_bytes()),
        _ => out.extend(fixed(text, field_size(c))),
    }
}

/// The recording as DataFlash bytes (current message layout: `TimeUS`, `MAG` with an
/// instance field, `RCOU` `C1..`, `BAT` in volts and amperes, `ATT` in degrees, units
/// declared by `FMTU`).
pub fn dataflash_bytes(rec: &Recording, opts: &LogWriteOptions) -> Vec<u8> {
    const MAG: u8 = 0x82;
    const RCOU: u8 = 0x83;
    const BAT: u8 = 0x84;
    const ATT: u8 = 0x85;
    const EV: u8 = 0x86;
    let n = rec.motor_count().min(14);
    let mut b = DataflashBuilder::new();
    b.format(MAG, "MAG", "QBfff", "TimeUS,I,MagX,MagY,MagZ");
    let rcou_fmt = format!("Q{}", "H".repeat(n));
    let rcou_labels = std::iter::once("TimeUS".to_string())
        .chain((1..=n).map(|c| format!("C{c}")))
        .collect::<Vec<_>>()
        .join(",");
    b.format(RCOU, "RCOU", &rcou_fmt, &rcou_labels)
        .format(BAT, "BAT", "QBff", "TimeUS,Inst,Volt,Curr")
        .format(ATT, "ATT", "Qfff", "TimeUS,Roll,Pitch,Yaw")
        .format(EV, "EV", "QB", "TimeUS,Id");
    // Units as ArduPilot declares them: the magnetometer in milligauss (gauss x 1e-3).
    b.unit('s', "s")
        .unit('#', "instance")
        .unit('G', "Gauss")
        .unit('v', "V")
        .unit('A', "A")
        .unit('d', "deg")
        .unit('Y', "us")
        .mult('-', 0.0)
        .mult('0', 1.0)
        .mult('C', 1e-3)
        .mult('F', 1e-6)
        .units(MAG, "s#GGG", "F-CCC")
        .units(
            RCOU,
            &format!("s{}", "Y".repeat(n)),
            &format!("F{}", "-".repeat(n)),
        )
        .units(BAT, "s#vA", "F-00")
        .units(ATT, "sddd", "F000");
    let t0 = micros(rec.t_s.first().copied().unwrap_or(0.0));
    let mut params: Vec<(String, f64)> = vec![
        ("MOT_PWM_MIN".into(), 1000.0),
        ("MOT_PWM_MAX".into(), 2000.0),
        ("COMPASS_EXTERNAL".into(), 0.0),
        ("COMPASS_MOTCT".into(), 0.0),
    ];
    params.extend((1..=n).map(|c| (format!("SERVO{c}_FUNCTION"), 32.0 + c as f64)));
    if opts.ardupilot_trim_rad != [0.0; 3] {
        params.extend(
            ["AHRS_TRIM_X", "AHRS_TRIM_Y", "AHRS_TRIM_Z"]
                .iter()
                .zip(opts.ardupilot_trim_rad)
                .map(|(name, t)| (name.to_string(), t)),
        );
    }
    for (name, v) in &params {
        b.param(t0, name, *v);
    }
    b.row(EV, &[t0 as f64, 10.0]);
    if !opts.landed {
        b.row(EV, &[t0 as f64, 28.0]);
    }
    for r in 0..rec.len() {
        let us = micros(rec.t_s[r]) as f64;
        let m = rec.mag_ut[r] * 10.0;
        b.row(MAG, &[us, 0.0, m.x, m.y, m.z]);
        let pwm: Vec<f64> = std::iter::once(us)
            .chain((0..n).map(|k| (1000.0 + 1000.0 * rec.thr[k][r]).round()))
            .collect();
        b.row(RCOU, &pwm);
        if let (Some(v), Some(a)) = (&rec.bat_v, &rec.bat_a) {
            b.row(BAT, &[us, 0.0, v[r], a[r]]);
        }
        if let Some(q) = &rec.attitude {
            let (roll, pitch, yaw) = q[r].euler_angles();
            let [tx, ty, tz] = opts.ardupilot_trim_rad;
            b.row(
                ATT,
                &[
                    us,
                    (roll - tx).to_degrees(),
                    (pitch - ty).to_degrees(),
                    (yaw - tz).to_degrees(),
                ],
            );
        }
    }
    b.into_bytes()
}

/// Writes the recording as a ULog file, atomically.
pub fn write_ulog(rec: &Recording, path: &Path, opts: &LogWriteOptions) -> Result<(), LogsError> {
    Ok(stage_ulog(rec, path, opts)?.commit()?)
}

/// Writes the recording as a ULog beside `path`, staged: nothing at `path` changes until
/// [`Staged::commit`].
pub fn stage_ulog(
    rec: &Recording,
    path: &Path,
    opts: &LogWriteOptions,
) -> Result<Staged, LogsError> {
    check(rec, path)?;
    Ok(atomic_file::stage_bytes(path, &ulog_bytes(rec, opts))?)
}

/// Writes the recording as a DataFlash file, atomically.
pub fn write_dataflash(
    rec: &Recording,
    path: &Path,
    opts: &LogWriteOptions,
) -> Result<(), LogsError> {
    Ok(stage_dataflash(rec, path, opts)?.commit()?)
}

/// Writes the recording as a DataFlash file beside `path`, staged: nothing at `path` changes
/// until [`Staged::commit`].
pub fn stage_dataflash(
    rec: &Recording,
    path: &Path,
    opts: &LogWriteOptions,
) -> Result<Staged, LogsError> {
    check(rec, path)?;
    Ok(atomic_file::stage_bytes(path, &dataflash_bytes(rec, opts))?)
}
