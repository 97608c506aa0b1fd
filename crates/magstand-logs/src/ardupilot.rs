//! ArduPilot messages to magstand streams.
//!
//! * `MAG` (instance from its `I` field, or `MAG2`/`MAG3` in older logs): milligauss, already
//!   offset-corrected and rotated to the body frame by the firmware; a sample it marked
//!   unhealthy (`Health` 0) is left out. The default instance is
//!   the first internal compass (`COMPASS_EXTERNAL`, `COMPASS_EXTERN2`, `COMPASS_EXTERN3` = 0).
//! * `RCOU` channels (`C1..` or, in older logs, `Ch1..`), motors located by
//!   `SERVOn_FUNCTION` = 33.. when set, mapped to 0..1 with `MOT_PWM_MIN`/`MOT_PWM_MAX`, or
//!   `RC3_MIN`/`RC3_MAX` when those are 0 (ArduPilot's own fallback).
//! * `BAT` or, in Copter 3.4 and older, `CURR`: volts and amperes.
//!
//! Every field is scaled as the log itself declares it (`FMT` type, `FMTU` unit and
//! multiplier; see [`crate::field_units`]): Copter 3.3 logs `CURR` in integer hundredths,
//! Copter 3.4 in float volts and amperes, and a fixed factor would be wrong for one of them.
//! * `ATT` roll, pitch, yaw in degrees; for an internal compass with the trim `AHRS_TRIM_*`
//!   added back (the attitude of the board, whose frame its `MAG` is in, rather than of the
//!   trimmed vehicle body); `EV` 10/11 armed/disarmed, 28/18 took off/landed;
//!   `GPS` position and GPS week time for the Earth-field model.
use magstand_core::magnetometer_frame::SensorToBody;
use magstand_core::magnetometer_slot::MagnetometerSlot;
use magstand_core::{Quat, Vec3};

use crate::LogsError;
use crate::contents::{LogContents, Series};
use crate::field_units::{self, Quantity};
use crate::import::ImportOptions;
use crate::streams::{Position, Stream, VehicleStreams, decimal_year, normalize_output};

const UT_PER_MILLIGAUSS: f64 = 0.1;

/// Reads the streams of an ArduPilot log.
pub fn streams(log: &LogContents, opts: &ImportOptions) -> Result<VehicleStreams, LogsError> {
    let mut out = VehicleStreams::default();
    let external = magnetometer(log, opts, &mut out)?;
    let channels = motors(log, opts, &mut out)?;
    // A sensor that is not fitted logs 0 throughout; VehicleStreams::drop_unmeasured_supply
    // leaves it out after both formats are read.
    let (bat, bat_name) = match log.series("BAT", 0) {
        Some(b) => (Some(b), "BAT"),
        None => (log.series("CURR", 0), "CURR"),
    };
    if let Some(b) = bat {
        out.bat_v = si_stream(log, b, bat_name, "Volt", Quantity::Voltage)?;
        out.bat_a = si_stream(log, b, bat_name, "Curr", Quantity::Current)?;
        out.notes.extend(crate::streams::other_batteries(
            &log.instances(bat_name),
            bat_name,
        ));
    }
    out.autopilot_throttle = autopilot_throttle(log, &mut out.notes);
    // ESC telemetry (BLHeli, DroneCAN): one ESC message per instance, current in A. An
    // instance is the servo output channel its ESC drives, counted from 0 (AP_ESC_Telem holds
    // one per servo channel; AP_BLHeli reports each through its channel's index), so each
    // motor's ESC is its channel's, not the motor's number.
    let esc_scale = field_units::scale(log, "ESC", "Curr", Quantity::Current)?;
    out.esc_a = channels
        .iter()
        .map_while(|&c| {
            let k = esc_scale?;
            log.series("ESC", u8::try_from(c - 1).ok()?)?
                .stream("Curr", |a| (a.is_finite() && a >= 0.0).then_some(a * k))
                .filter(|s| !s.is_empty())
        })
        .collect();
    if !out.esc_a.is_empty() {
        let n = out.esc_a.len();
        let instances: Vec<usize> = channels[..n].iter().map(|c| c - 1).collect();
        out.notes.push(format!(
            "per-ESC currents from ESC instances {instances:?} (the motors' output channels) for {n} motors, written as esc_1_a..esc_{n}_a"
        ));
    }
    if let Some(a) = log.series("ATT", 0)
        && let (Some(r), Some(p), Some(y)) = (a.field("Roll"), a.field("Pitch"), a.field("Yaw"))
    {
        let deg =
            |f: &str| field_units::scale(log, "ATT", f, Quantity::Angle).map(|k| k.unwrap_or(1.0));
        let (kr, kp, ky) = (deg("Roll")?, deg("Pitch")?, deg("Yaw")?);
        let [trim_x, trim_y, trim_z] = ahrs_trim_rad(log, external, &mut out.notes);
        out.attitude = Some(Stream::from_pairs((0..a.len()).map(|k| {
            let q = Quat::from_euler_angles(
                (r[k] * kr).to_radians() + trim_x,
                (p[k] * kp).to_radians() + trim_y,
                (y[k] * ky).to_radians() + trim_z,
            );
            (
                a.t_s[k],
                q.coords.iter().all(|c| c.is_finite()).then_some(q),
            )
        })));
    }
    let events = |on: i64, off: i64| {
        let s = Stream::from_pairs(
            log.events
                .iter()
                .filter_map(|&(t, id)| (id == on || id == off).then_some((t, Some(id == on)))),
        );
        (!s.is_empty()).then_some(s)
    };
    out.armed = events(10, 11);
    // 28 is NOT_LANDED (took off), 18 LAND_COMPLETE.
    out.landed = events(18, 28);
    out.position = position(log);
    Ok(out)
}

/// The trim `AHRS_TRIM_X`, `_Y` and `_Z` (rad) that turns the logged attitude back to the
/// autopilot board's, the frame an internal compass's `MAG` is logged in; none for an
/// `external` compass.
///
/// `ATT` is the vehicle body's attitude: the estimators report their Euler angles less the
/// trim (`NavEKF2_core`/`NavEKF3_core::getEulerAngles`: `euler - get_trim()`). An internal
/// compass is turned only by the board orientation (`AP_Compass_Backend::rotate_field`), so it
/// measures in the board's frame: without the trim, a field turned by the logged attitude is
/// off by the trim's rotation, which moves with heading (1 degree of roll trim under 20 µT of
/// horizontal field: ±0.35 µT on z). Adding the trim back to the angles is the exact inverse of
/// the estimators' subtraction, which takes `AHRS_TRIM_Z` off the yaw too (documented as
/// unused, and 0 unless set by hand). An external compass is turned by its own
/// `COMPASS_ORIENT*`, which is relative to the vehicle, not to the board: the vehicle body's
/// attitude is its frame, as logged. One whose kind is not logged is taken as internal, as
/// the firmware does unless its driver finds it external. The trim is applied as logged, as
/// the estimators apply it; a non-finite one is taken as none, with a note.
fn ahrs_trim_rad(log: &LogContents, external: Option<bool>, notes: &mut Vec<String>) -> [f64; 3] {
    let mut trim = [0.0; 3];
    for (value, name) in trim
        .iter_mut()
        .zip(["AHRS_TRIM_X", "AHRS_TRIM_Y", "AHRS_TRIM_Z"])
    {
        match log.param(name) {
            None => {}
            Some(t) if t.is_finite() => *value = t,
            Some(t) => notes.push(format!(
                "{name} = {t} is not a number of radians: the attitude is taken untrimmed about that axis"
            )),
        }
    }
    if trim != [0.0; 3] && external == Some(true) {
        notes.push(
            "attitude as ATT logs it, the vehicle body's: the external compass is oriented to the vehicle (COMPASS_ORIENT*), not to the board whose AHRS_TRIM* ATT takes out".into(),
        );
        return [0.0; 3];
    }
    if trim != [0.0; 3] {
        let [x, y, z] = trim.map(f64::to_degrees);
        notes.push(format!(
            "attitude turned to the autopilot board's frame, in which MAG is logged: the trim added back to ATT's roll, pitch and yaw ({x:+.2}, {y:+.2}, {z:+.2} deg: AHRS_TRIM_X, _Y, _Z)"
        ));
    }
    trim
}

/// One field of `series` as a stream in magstand's unit for `quantity`, scaled as the log
/// declares it ([`field_units::scale`]); `None` when the message has no such field.
fn si_stream(
    log: &LogContents,
    series: &Series,
    message: &str,
    field: &str,
    quantity: Quantity,
) -> Result<Option<Stream<f64>>, LogsError> {
    let Some(k) = field_units::scale(log, message, field, quantity)? else {
        return Ok(None);
    };
    Ok(series.stream(field, |x| (x * k).is_finite().then_some(x * k)))
}

/// Reads the chosen compass's field into `out`; returns whether that compass is external
/// (`COMPASS_EXTERN*`), None where the log does not say.
fn magnetometer(
    log: &LogContents,
    opts: &ImportOptions,
    out: &mut VehicleStreams,
) -> Result<Option<bool>, LogsError> {
    let instances = log.instances("MAG");
    if instances.is_empty() {
        return Err(LogsError::Missing {
            path: log.path.clone(),
            what: "the magnetometer message MAG".into(),
            hint: "enable compass logging (LOG_BITMASK includes COMPASS)".into(),
        });
    }
    // Whether the compass of instance `i` is external: a parameter of its compass, which
    // from ArduPilot 4.0 need not be the instance's number (`compass_of_instance`).
    let external = |i: u8| {
        let name = match compass_of_instance(log, i)? {
            1 => "COMPASS_EXTERNAL".to_string(),
            n => format!("COMPASS_EXTERN{n}"),
        };
        log.param(&name)
    };
    let inst = match opts.mag {
        Some(m) if instances.contains(&m) => m,
        Some(m) => {
            return Err(LogsError::Unusable {
                path: log.path.clone(),
                what: format!(
                    "`mag` = {m}: the log has no compass instance {m} (MAG instances {:?}, 0 = MAG, 1 = MAG2, ...)",
                    instances
                ),
            });
        }
        None => instances
            .iter()
            .copied()
            .find(|&i| external(i) == Some(0.0))
            .unwrap_or(instances[0]),
    };
    out.notes.push(format!(
        "magnetometer: compass instance {inst} ({}){}",
        match external(inst) {
            Some(0.0) => "internal",
            Some(_) => "external",
            None => "internal or external not logged",
        },
        if opts.mag.is_none() {
            format!("; `mag` picks another of {instances:?}")
        } else {
            String::new()
        }
    ));
    out.mag_slot = compass_slot(log, inst, &mut out.notes);
    // A compass the firmware does not use for heading (`COMPASS_USE*` 0): a compensation
    // written for it changes nothing the vehicle flies on.
    if let Some(MagnetometerSlot::ArduPilotCompass(n)) = out.mag_slot {
        let use_param = format!("COMPASS_USE{}", compass_suffix(n as usize));
        if log.param(&use_param) == Some(0.0) {
            out.notes.push(format!(
                "magnetometer: compass {n} is not used for heading on this vehicle ({use_param} = 0): its exported compensation changes nothing until it is"
            ));
        }
    }
    let s = log.series("MAG", inst).expect("listed instance");
    let axes: Vec<&[f64]> = ["MagX", "MagY", "MagZ"]
        .iter()
        .map(|a| {
            s.field(a).ok_or_else(|| LogsError::Missing {
                path: log.path.clone(),
                what: format!("field {a} of the MAG message"),
                hint: "the import reads MagX, MagY, MagZ".into(),
            })
        })
        .collect::<Result<_, _>>()?;
    let k: Vec<f64> = ["MagX", "MagY", "MagZ"]
        .iter()
        .map(|a| {
            field_units::scale(log, "MAG", a, Quantity::MagneticField)
                .map(|k| k.unwrap_or(UT_PER_MILLIGAUSS))
        })
        .collect::<Result<_, _>>()?;
    out.mag_to_body = compensation_frame(log, out.mag_slot, &mut out.notes);
    // The logged field holds the applied compensation as the firmware added it: through the
    // soft-iron matrix where it added it before the matrix.
    let added = out
        .mag_to_body
        .map_or(magstand_core::Mat3::identity(), |f| f.matrix());
    let applied = applied_motor_compensation(log, s, out.mag_slot, &mut out.notes)?;
    // The firmware marks a sample of a compass it does not trust (`Health` 0: stale, or
    // failing its consistency checks); such a sample is not a reading of the field.
    let health = s.field("Health");
    let unhealthy = |r: usize| health.is_some_and(|h| h[r] == 0.0);
    let dropped = (0..s.len()).filter(|&r| unhealthy(r)).count();
    if dropped > 0 {
        out.notes.push(format!(
            "magnetometer: {dropped} of {} samples the firmware marked unhealthy (MAG Health 0) left out",
            s.len()
        ));
    }
    out.mag_ut = Stream::from_pairs((0..s.len()).map(|r| {
        if unhealthy(r) {
            return (s.t_s[r], None);
        }
        let mut v = Vec3::new(axes[0][r] * k[0], axes[1][r] * k[1], axes[2][r] * k[2]);
        if let Some((offset, k)) = &applied {
            v -= added
                * Vec3::new(
                    offset[0][r] * k[0],
                    offset[1][r] * k[1],
                    offset[2][r] * k[2],
                );
        }
        (s.t_s[r], v.iter().all(|x| x.is_finite()).then_some(v))
    }));
    Ok(external(inst).map(|e| e != 0.0))
}

/// The motor compensation ArduPilot applied to the logged field, per message, and the scale of
/// its fields to µT: None where it applied none. ArduPilot logs its field after adding the
/// compensation of `COMPASS_MOTCT` (or the per-motor set) and logs what it added (`MOX`..`MOZ`,
/// `MOfsX`..`MOfsZ` in older logs). The import takes it back out, so that the recording holds
/// the whole disturbance: a line fitted to the rest would be exported as the whole of
/// `COMPASS_MOT*` and replace the vehicle's compensation by the part it left. Older firmware
/// (before per-motor compensation) added it before the soft-iron matrix, so there it is taken
/// out through that matrix ([`compensation_frame`]). Where the log has no such fields but the
/// parameters say a compensation was on, the recording holds only what it left, and a warning
/// says so.
#[allow(clippy::type_complexity)]
fn applied_motor_compensation<'a>(
    log: &LogContents,
    s: &'a Series,
    slot: Option<MagnetometerSlot>,
    notes: &mut Vec<String>,
) -> Result<Option<([&'a [f64]; 3], [f64; 3])>, LogsError> {
    let named = |names: [&'static str; 3]| {
        let [x, y, z] = names.map(|n| s.field(n));
        Some(([x?, y?, z?], names))
    };
    let found = named(["MOX", "MOY", "MOZ"]).or_else(|| named(["MOfsX", "MOfsY", "MOfsZ"]));
    let kind = log.param("COMPASS_MOTCT").unwrap_or(0.0);
    let per_motor = log.param("COMPASS_PMOT_EN").unwrap_or(0.0) != 0.0
        && slot == Some(MagnetometerSlot::ArduPilotCompass(1));
    let on = || {
        format!(
            "COMPASS_MOTCT {kind}{}",
            if per_motor { ", COMPASS_PMOT_EN 1" } else { "" }
        )
    };
    let Some((offset, names)) = found else {
        if kind != 0.0 || per_motor {
            notes.push(format!(
                "WARNING: ArduPilot's motor compensation was on ({}) and the log's MAG has no motor offsets to take it back out: part of the disturbance is already removed, by an amount the log does not say, and parameters exported from this recording would replace the vehicle's compensation by what it left",
                on()
            ));
        }
        return Ok(None);
    };
    let mut k = [0.0; 3];
    for (k, name) in k.iter_mut().zip(names) {
        *k = field_units::scale(log, "MAG", name, Quantity::MagneticField)?
            .unwrap_or(UT_PER_MILLIGAUSS);
    }
    let largest_ut = offset
        .iter()
        .zip(k)
        .flat_map(|(a, k)| a.iter().map(move |v| (v * k).abs()))
        .fold(0.0f64, f64::max);
    if !(largest_ut > 0.0) {
        return Ok(None);
    }
    notes.push(format!(
        "ArduPilot's motor compensation was applied in flight ({}, up to {largest_ut:.1} uT in {}..{}): taken back out, so the recording holds the whole disturbance and exported parameters replace the vehicle's",
        on(),
        names[0],
        names[2]
    ));
    Ok(Some((offset, k)))
}

/// The matrix ArduPilot takes a compass's field through after adding its motor compensation,
/// where its firmware does so: firmware before per-motor compensation adds the compensation
/// to the field with its offsets, then applies the soft-iron matrix (`COMPASS_DIA*` on the
/// diagonal, `COMPASS_ODI*` off it, of the compass of `slot`); later firmware adds it after
/// the matrix, to the field the log records, and needs none. A compensation for the older
/// firmware is then `−matrix⁻¹ · slope` (`export` writes it so), and the compensation it
/// applied entered the logged field through the matrix. Which firmware wrote the log:
/// [`adds_compensation_after_the_matrix`].
fn compensation_frame(
    log: &LogContents,
    slot: Option<MagnetometerSlot>,
    notes: &mut Vec<String>,
) -> Option<SensorToBody> {
    let MagnetometerSlot::ArduPilotCompass(n) = slot? else {
        return None;
    };
    if adds_compensation_after_the_matrix(log) {
        if log.param("COMPASS_PMOT_EN").is_none() {
            notes.push(format!(
                "this firmware ({}) has no COMPASS_PMOT_EN: it leaves per-motor compensation out (a board of 1 MB of flash or less), so `export --to ardupilot-per-motor` would write parameters it does not have; it adds COMPASS_MOT* after the soft-iron matrix, as `export --to ardupilot` writes them",
                log.firmware().unwrap_or_default()
            ));
        }
        return None;
    }
    let suffix = compass_suffix(n.into());
    let p = |name: &str, axis: &str| log.param(&format!("COMPASS_{name}{suffix}_{axis}"));
    let diagonal = ["X", "Y", "Z"].map(|a| p("DIA", a).unwrap_or(0.0));
    // The firmware takes a diagonal of zeros (never calibrated) for ones.
    let diagonal = if diagonal == [0.0; 3] {
        [1.0; 3]
    } else {
        diagonal
    };
    let [ox, oy, oz] = ["X", "Y", "Z"].map(|a| p("ODI", a).unwrap_or(0.0));
    let [dx, dy, dz] = diagonal;
    match SensorToBody::new([[dx, ox, oy], [ox, dy, oz], [oy, oz, dz]]) {
        Ok(frame) if frame.is_identity() => None,
        Ok(frame) => {
            notes.push(format!(
                "this firmware ({}) adds its motor compensation before compass {n}'s soft-iron matrix ({frame}, row by row; column `{}`): `export --to ardupilot` writes COMPASS_MOT* through it",
                log.firmware().map_or_else(
                    || "no COMPASS_PMOT_EN, and no firmware version in the log".to_string(),
                    |f| format!("{f}, before per-motor compensation")
                ),
                magstand_core::magnetometer_frame::COLUMN
            ));
            Some(frame)
        }
        Err(why) => {
            notes.push(format!(
                "warning: compass {n}'s soft-iron matrix (COMPASS_DIA{suffix}_*, COMPASS_ODI{suffix}_*) is not {why}: exported COMPASS_MOT* take it as the identity"
            ));
            None
        }
    }
}

/// Whether the firmware that wrote `log` adds its motor compensation after the soft-iron
/// matrix. Per-motor compensation came with that order (ArduPilot pull request 6448, 2017,
/// first released in Copter 3.6): a log with `COMPASS_PMOT_EN` has it. The parameter alone
/// does not tell the older firmware, though: later releases leave per-motor compensation out
/// of boards of 1 MB of flash or less (`AP_COMPASS_PMOT_ENABLED`), so the release the log
/// names decides first: 4.0 or later for any vehicle, Copter 3.6 or later.
fn adds_compensation_after_the_matrix(log: &LogContents) -> bool {
    let released_after = log
        .ardupilot_version()
        .map(|(vehicle, v)| v[0] >= 4 || (vehicle == "Copter" && v >= [3, 6, 0]));
    log.param("COMPASS_PMOT_EN").is_some() || released_after == Some(true)
}

/// What ArduPilot appends to a per-compass parameter's name for compass `n` (1 to 3): nothing
/// for the first (`COMPASS_MOT_X`, `COMPASS_DEV_ID`), the number for the others
/// (`COMPASS_MOT2_X`, `COMPASS_DEV_ID3`).
pub(crate) fn compass_suffix(n: usize) -> String {
    if n <= 1 { String::new() } else { n.to_string() }
}

/// The compass (1 to 3) whose parameters (`COMPASS_MOT*`, `COMPASS_EXTERN*`, ...) belong to
/// MAG instance `inst`. The log's instances follow the compasses' priorities
/// (`COMPASS_PRIOn_ID`, from ArduPilot 4.0), the parameters the order in which the compasses
/// were first found (`COMPASS_DEV_ID*`): where the log has both, the instance's device id names
/// its parameters. Older firmware has no priorities, and instance n is compass n + 1. None
/// where the priority's device has no parameters in the log, or beyond the third compass.
fn compass_of_instance(log: &LogContents, inst: u8) -> Option<u8> {
    match priority_device(log, inst) {
        None => (inst < 3).then_some(inst + 1),
        Some(id) => (1..=3u8).find(|&n| {
            log.param(&format!("COMPASS_DEV_ID{}", compass_suffix(n.into()))) == Some(id)
        }),
    }
}

/// The device id of MAG instance `inst` by its priority (`COMPASS_PRIOn_ID`), where the log
/// sets one.
fn priority_device(log: &LogContents, inst: u8) -> Option<f64> {
    log.param(&format!("COMPASS_PRIO{}_ID", inst as u16 + 1))
        .filter(|id| *id != 0.0)
}

/// [`compass_of_instance`] as a magnetometer slot, with a warning where there is none.
fn compass_slot(log: &LogContents, inst: u8, notes: &mut Vec<String>) -> Option<MagnetometerSlot> {
    let compass = compass_of_instance(log, inst);
    if compass.is_none() {
        notes.push(format!(
            "warning: compass instance {inst}{} has no COMPASS_MOT parameters the log names: `export` needs --instance for its parameters",
            priority_device(log, inst)
                .map(|id| format!(
                    " is device {id} (COMPASS_PRIO{}_ID), which no COMPASS_DEV_ID names; it",
                    inst as u16 + 1
                ))
                .unwrap_or_default()
        ));
    }
    compass.map(MagnetometerSlot::ArduPilotCompass)
}

/// The throttle ArduPilot's compass motor compensation multiplies (`COMPASS_MOTCT` 1):
/// `motors->get_throttle()`, the collective thrust demand, logged as `CTUN.ThO` (0..1; Copter
/// 3.3's `ThrOut` in thousandths). The motor outputs follow it through the thrust curve
/// (`MOT_THST_EXPO`), so a throttle line for the autopilot is fitted against it, not against
/// the outputs. None where the log has no `CTUN` or its values are not a throttle.
fn autopilot_throttle(log: &LogContents, notes: &mut Vec<String>) -> Option<Stream<f64>> {
    let s = log.series("CTUN", 0)?;
    let (name, values) = ["ThO", "ThrOut"]
        .into_iter()
        .find_map(|n| Some((n, s.field(n)?)))?;
    let largest = values
        .iter()
        .copied()
        .filter(|v| v.is_finite())
        .fold(0.0f64, f64::max);
    // Thousandths where any value is beyond a whole throttle (Copter 3.3), else the fraction.
    let scale = if largest > 1.0 { 1e-3 } else { 1.0 };
    if !(largest > 0.0 && largest * scale <= 1.0) {
        return None;
    }
    let stream = s
        .stream(name, |v| {
            let v = v * scale;
            (v.is_finite() && (0.0..=1.0).contains(&v)).then_some(v)
        })
        .filter(|st| !st.is_empty())?;
    notes.push(format!(
        "the autopilot's throttle (its thrust demand, which COMPASS_MOTCT 1 multiplies): CTUN.{name}{}, written as autopilot_throttle",
        if scale != 1.0 { " in thousandths" } else { "" }
    ));
    Some(stream)
}

/// Reads the motor outputs into `out`; returns each motor's servo output channel (1-based), in
/// motor order.
fn motors(
    log: &LogContents,
    opts: &ImportOptions,
    out: &mut VehicleStreams,
) -> Result<Vec<usize>, LogsError> {
    let Some(s) = log.series("RCOU", 0) else {
        return Err(LogsError::Missing {
            path: log.path.clone(),
            what: "the motor output message RCOU".into(),
            hint: "enable RCOUT logging (LOG_BITMASK)".into(),
        });
    };
    // Newer logs name channels C1.., older ones Ch1...
    let channel = |c: usize| {
        s.field(&format!("C{c}"))
            .or_else(|| s.field(&format!("Ch{c}")))
    };
    let logged: usize = (1..=32).take_while(|&c| channel(c).is_some()).count();
    let by_function: Vec<usize> = (0..12)
        .map_while(|k| {
            (1..=32).find(|c| log.param(&format!("SERVO{c}_FUNCTION")) == Some(33.0 + k as f64))
        })
        .collect();
    let positive = |n: &str| log.param(n).filter(|v| *v > 0.0);
    let (lo, hi, source) = match opts.pwm_range {
        Some((lo, hi)) => (lo, hi, "`pwm_range`"),
        None => match (positive("MOT_PWM_MIN"), positive("MOT_PWM_MAX")) {
            (Some(lo), Some(hi)) => (lo, hi, "MOT_PWM_MIN/MAX"),
            _ => match (positive("RC3_MIN"), positive("RC3_MAX")) {
                (Some(lo), Some(hi)) => (lo, hi, "RC3_MIN/MAX (MOT_PWM_MIN/MAX unset)"),
                _ => {
                    return Err(LogsError::Missing {
                        path: log.path.clone(),
                        what: "the motor PWM limits (MOT_PWM_MIN/MAX or RC3_MIN/MAX in PARM)"
                            .into(),
                        hint: "give `pwm_range` (MIN:MAX)".into(),
                    });
                }
            },
        },
    };
    if hi <= lo {
        return Err(LogsError::Unusable {
            path: log.path.clone(),
            what: format!("motor PWM range {lo}..{hi} from {source} is empty"),
        });
    }
    let frame_class = match log.param("FRAME_CLASS").map(|v| v as i64) {
        Some(1) => Some(4),
        Some(2) | Some(5) => Some(6),
        Some(3) | Some(4) => Some(8),
        Some(7) => Some(3),
        _ => None,
    };
    let frame_text = log.text_after("Frame: ");
    let (n, count_from) = if let Some(n) = opts.motors {
        (n, "`motors`".to_string())
    } else if !by_function.is_empty() {
        (by_function.len(), "SERVOn_FUNCTION".to_string())
    } else if let Some(n) = frame_class {
        (n, "FRAME_CLASS".to_string())
    } else if let Some(n) = frame_text.and_then(motors_of_frame) {
        (
            n,
            format!(
                "the firmware's \"Frame: {}\" message",
                frame_text.unwrap_or("")
            ),
        )
    } else if (3..=4).contains(&logged) {
        // Old logs without FRAME_CLASS may log only the motor channels of the frame.
        (logged, format!("the {logged} logged RCOU channels"))
    } else {
        let all: Vec<&[f64]> = (1..=logged.min(12)).filter_map(channel).collect();
        match motors_from_outputs(&all, lo, hi) {
            Some(n) => (
                n,
                format!(
                    "the outputs: RCOU channels 1..{n} move together in the motor range {lo}..{hi}, the others do not"
                ),
            ),
            None => {
                return Err(LogsError::Missing {
                    path: log.path.clone(),
                    what: format!(
                        "the motor count (no SERVOn_FUNCTION = 33.., no FRAME_CLASS, no \"Frame:\" message, and the {logged} RCOU channels do not show which ones drive motors)"
                    ),
                    hint: "give `motors` (the motor count)".into(),
                });
            }
        }
    };
    let channels: Vec<usize> = if by_function.len() >= n && opts.motors.is_none() {
        by_function[..n].to_vec()
    } else {
        (1..=n).collect()
    };
    let cols: Vec<&[f64]> = channels
        .iter()
        .map(|&c| {
            channel(c).ok_or_else(|| LogsError::Missing {
                path: log.path.clone(),
                what: format!("RCOU channel {c}"),
                hint: format!("the log has {logged} channels; check `motors`"),
            })
        })
        .collect::<Result<_, _>>()?;
    out.notes.push(format!(
        "motors: RCOU channels {channels:?}, PWM {lo}..{hi} from {source}; motor count from {count_from}"
    ));
    let us: Vec<f64> = channels
        .iter()
        .map(|c| {
            let name = if s.field(&format!("C{c}")).is_some() {
                format!("C{c}")
            } else {
                format!("Ch{c}")
            };
            field_units::scale(log, "RCOU", &name, Quantity::Pulse).map(|k| k.unwrap_or(1.0))
        })
        .collect::<Result<_, _>>()?;
    out.motors = Stream::from_pairs((0..s.len()).map(|r| {
        (
            s.t_s[r],
            Some(
                cols.iter()
                    .zip(&us)
                    .map(|(c, k)| normalize_output(c[r] * k, lo, hi))
                    .collect(),
            ),
        )
    }));
    Ok(channels)
}

/// Motor count of an ArduPilot frame name as the firmware prints it ("QUAD/X", "HEXA",
/// "OCTA_QUAD", "Y6B"); `None` for a frame that is not a multirotor of known count.
fn motors_of_frame(text: &str) -> Option<usize> {
    let class = text.split(['/', ' ']).next()?.to_ascii_uppercase();
    Some(match class.as_str() {
        "TRI" => 3,
        "QUAD" => 4,
        "HEXA" | "Y6" | "Y6B" | "Y6F" => 6,
        "OCTA" | "OCTAQUAD" | "OCTA_QUAD" => 8,
        "DECA" => 10,
        "DODECAHEXA" | "DODECA_HEXA" => 12,
        _ => return None,
    })
}

/// The motor count that the output channels themselves show, for logs that declare it
/// nowhere: ArduCopter puts its motors on the first channels, and while they spin every
/// motor sits in the motor PWM range and moves with the others (collective thrust), while a
/// gimbal, camera or unused channel sits still or moves on its own. The count is the longest
/// run of such channels from channel 1, when it is a frame's count (3, 4, 6, 8, 10, 12).
fn motors_from_outputs(channels: &[&[f64]], lo: f64, hi: f64) -> Option<usize> {
    let range = hi - lo;
    let first = *channels.first()?;
    // Rows where channel 1 drives a spinning motor.
    let active: Vec<usize> = (0..first.len())
        .filter(|&r| first[r] > lo + 0.05 * range && first[r] <= hi + 0.05 * range)
        .collect();
    if active.len() < 20 || channels.len() < 3 {
        return None;
    }
    let column = |c: &[f64]| active.iter().map(|&r| c[r]).collect::<Vec<f64>>();
    // The collective: the mean of the first three channels, which every frame drives.
    let cols: Vec<Vec<f64>> = channels.iter().map(|c| column(c)).collect();
    let collective: Vec<f64> = (0..active.len())
        .map(|k| (cols[0][k] + cols[1][k] + cols[2][k]) / 3.0)
        .collect();
    let motor_like = |c: &[f64]| {
        let in_range = c
            .iter()
            .filter(|v| (lo - 0.05 * range..=hi + 0.05 * range).contains(*v))
            .count();
        let mean = c.iter().sum::<f64>() / c.len() as f64;
        let sd = (c.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / c.len() as f64).sqrt();
        in_range as f64 >= 0.95 * c.len() as f64
            && sd > 0.01 * range
            && correlation(c, &collective).is_some_and(|r| r > 0.3)
    };
    let n = cols.iter().take_while(|c| motor_like(c)).count();
    [3, 4, 6, 8, 10, 12].contains(&n).then_some(n)
}

/// Pearson correlation; `None` when either column is constant.
fn correlation(a: &[f64], b: &[f64]) -> Option<f64> {
    let n = a.len() as f64;
    let (ma, mb) = (a.iter().sum::<f64>() / n, b.iter().sum::<f64>() / n);
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        sab += (x - ma) * (y - mb);
        saa += (x - ma).powi(2);
        sbb += (y - mb).powi(2);
    }
    (saa > 0.0 && sbb > 0.0).then(|| sab / (saa * sbb).sqrt())
}

fn position(log: &LogContents) -> Option<Position> {
    let s = log.series("GPS", 0)?;
    let (lat, lon) = (s.field("Lat")?, s.field("Lng")?);
    let status = s.field("Status");
    let r = (0..s.len())
        .rev()
        .find(|&r| lat[r] != 0.0 && status.is_none_or(|st| st[r] >= 3.0))?;
    // GPS time: week number and milliseconds of the week (GWk/GMS, or Week/T in old logs).
    let week = s.field("GWk").or_else(|| s.field("Week")).map(|w| w[r]);
    let ms = s.field("GMS").or_else(|| s.field("T")).map(|m| m[r]);
    // The GPS epoch, 1980-01-06, is Unix time 315964800; leap seconds do not matter here.
    let year = match (week, ms) {
        (Some(w), Some(ms)) if w > 0.0 => {
            Some(decimal_year(315_964_800.0 + w * 604_800.0 + ms * 1e-3))
        }
        _ => None,
    };
    // Older logs store 1e-7 degrees as integers.
    let deg = |v: f64| if v.abs() > 360.0 { v * 1e-7 } else { v };
    Some(Position {
        lat_deg: deg(lat[r]),
        lon_deg: deg(lon[r]),
        alt_m: s.field("Alt").map_or(0.0, |a| a[r]),
        year,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The trim turns an internal compass's attitude (or one whose kind is not logged) back to
    /// the board's; an external compass keeps the vehicle body's, and a non-finite trim is none.
    #[test]
    fn the_ahrs_trim_applies_to_an_internal_compass_only() {
        let mut log = LogContents::new("a.bin".into(), crate::contents::LogFormat::DataFlash);
        let mut notes = Vec::new();
        assert_eq!(ahrs_trim_rad(&log, Some(false), &mut notes), [0.0; 3]);
        assert!(notes.is_empty(), "{notes:?}");
        log.params.insert("AHRS_TRIM_X".into(), 0.02);
        log.params.insert("AHRS_TRIM_Y".into(), -0.005);
        for kind in [Some(false), None] {
            assert_eq!(
                ahrs_trim_rad(&log, kind, &mut notes),
                [0.02, -0.005, 0.0],
                "{kind:?}"
            );
        }
        assert!(
            notes.iter().all(|n| n.contains("+1.15, -0.29, +0.00 deg")),
            "{notes:?}"
        );
        notes.clear();
        assert_eq!(ahrs_trim_rad(&log, Some(true), &mut notes), [0.0; 3]);
        assert!(
            notes.len() == 1 && notes[0].contains("external"),
            "{notes:?}"
        );
        notes.clear();
        log.params.insert("AHRS_TRIM_X".into(), f64::NAN);
        assert_eq!(
            ahrs_trim_rad(&log, Some(false), &mut notes),
            [0.0, -0.005, 0.0]
        );
        assert!(notes[0].contains("AHRS_TRIM_X = NaN"), "{notes:?}");
    }

    /// From ArduPilot 4.0 the MAG instances follow the priorities and the `COMPASS_MOT*`
    /// parameters the detection order: the instance's device id names its compass. Without
    /// priorities instance n is compass n + 1, and a priority's device without parameters has
    /// no compass (and a warning).
    #[test]
    fn a_mag_instance_is_matched_to_its_compass_through_the_priorities() {
        let mut log = LogContents::new("a.bin".into(), crate::contents::LogFormat::DataFlash);
        let mut notes = Vec::new();
        assert_eq!(
            compass_slot(&log, 1, &mut notes),
            Some(MagnetometerSlot::ArduPilotCompass(2))
        );
        // There are three compasses' parameters: a fourth instance has none.
        assert_eq!(compass_slot(&log, 3, &mut notes), None);
        assert!(
            notes.len() == 1 && notes[0].contains("instance 3"),
            "{notes:?}"
        );
        notes.clear();
        // Priority 1 is the device found second, priority 2 the one found first.
        for (name, value) in [
            ("COMPASS_DEV_ID", 97539.0),
            ("COMPASS_DEV_ID2", 131874.0),
            ("COMPASS_PRIO1_ID", 131874.0),
            ("COMPASS_PRIO2_ID", 97539.0),
            ("COMPASS_PRIO3_ID", 590114.0),
        ] {
            log.params.insert(name.into(), value);
        }
        assert_eq!(
            compass_slot(&log, 0, &mut notes),
            Some(MagnetometerSlot::ArduPilotCompass(2))
        );
        assert_eq!(
            compass_slot(&log, 1, &mut notes),
            Some(MagnetometerSlot::ArduPilotCompass(1))
        );
        assert!(notes.is_empty(), "{notes:?}");
        assert_eq!(compass_slot(&log, 2, &mut notes), None);
        assert!(notes.len() == 1 && notes[0].contains("590114"), "{notes:?}");
    }

    /// From ArduPilot 4.0 an instance is external by its compass's parameter, not by its own
    /// number: the default magnetometer is the first instance whose compass is internal.
    #[test]
    fn the_default_magnetometer_is_internal_by_its_compass() {
        let field = [
            ("MagX", [100.0, 300.0]),
            ("MagY", [0.0, 0.0]),
            ("MagZ", [-50.0, -50.0]),
        ];
        let mut log = one_compass(
            &field,
            &[
                ("COMPASS_DEV_ID", 11.0),
                ("COMPASS_DEV_ID2", 22.0),
                ("COMPASS_PRIO1_ID", 22.0),
                ("COMPASS_PRIO2_ID", 11.0),
                ("COMPASS_EXTERNAL", 0.0),
                ("COMPASS_EXTERN2", 1.0),
            ],
        );
        let second = log.topics["MAG"][&0].clone();
        log.topics.get_mut("MAG").expect("MAG").insert(1, second);
        let mut out = VehicleStreams::default();
        magnetometer(&log, &ImportOptions::default(), &mut out).expect("imported");
        // Instance 0 is compass 2 (external), instance 1 compass 1 (internal).
        assert_eq!(out.mag_slot, Some(MagnetometerSlot::ArduPilotCompass(1)));
        assert!(
            out.notes
                .iter()
                .any(|n| n.contains("compass instance 1 (internal)")),
            "{:?}",
            out.notes
        );
    }

    /// A log of one compass, instance 0, whose MAG holds `fields` over two messages.
    fn one_compass(fields: &[(&str, [f64; 2])], params: &[(&str, f64)]) -> LogContents {
        let mut log = LogContents::new("a.bin".into(), crate::contents::LogFormat::DataFlash);
        let series = Series {
            t_s: vec![1.0, 1.1],
            fields: fields
                .iter()
                .map(|(n, v)| (n.to_string(), v.to_vec()))
                .collect(),
        };
        log.topics
            .insert("MAG".into(), [(0u8, series)].into_iter().collect());
        for (n, v) in params {
            log.params.insert(n.to_string(), *v);
        }
        log
    }

    /// ArduPilot logs its field with the motor compensation it applied added, and what it
    /// added beside it: the import takes that back out (the whole disturbance is what a fit
    /// must see, or an export replaces the vehicle's compensation by what it left). Without
    /// the offsets in the log, a compensation that was on is a warning.
    #[test]
    fn the_motor_compensation_ardupilot_applied_is_taken_back_out() {
        let field = [
            ("MagX", [100.0, 300.0]),
            ("MagY", [0.0, 0.0]),
            ("MagZ", [-50.0, -50.0]),
        ];
        let mut with: Vec<_> = field.to_vec();
        with.extend([
            ("MOX", [0.0, 120.0]),
            ("MOY", [0.0, -40.0]),
            ("MOZ", [0.0, 0.0]),
        ]);
        let log = one_compass(&with, &[("COMPASS_MOTCT", 1.0)]);
        let mut out = VehicleStreams::default();
        magnetometer(&log, &ImportOptions::default(), &mut out).expect("imported");
        // 1 mG = 0.1 uT; the second message had 120 and -40 mG added.
        let want = [Vec3::new(10.0, 0.0, -5.0), Vec3::new(18.0, 4.0, -5.0)];
        for (got, want) in out.mag_ut.values.iter().zip(want) {
            assert!((got - want).norm() < 1e-9, "{got:?} against {want:?}");
        }
        assert!(
            out.notes.iter().any(|n| n.contains("taken back out")),
            "{:?}",
            out.notes
        );
        let log = one_compass(&field, &[("COMPASS_MOTCT", 2.0)]);
        let mut out = VehicleStreams::default();
        magnetometer(&log, &ImportOptions::default(), &mut out).expect("imported");
        assert!((out.mag_ut.values[1] - Vec3::new(30.0, 0.0, -5.0)).norm() < 1e-9);
        assert!(
            out.notes
                .iter()
                .any(|n| n.starts_with("WARNING") && n.contains("COMPASS_MOTCT 2")),
            "{:?}",
            out.notes
        );
    }

    /// Firmware without per-motor compensation (no `COMPASS_PMOT_EN`) adds its motor
    /// compensation before the compass's soft-iron matrix: the compensation it applied entered
    /// the logged field through that matrix and is taken out through it, and the matrix is the
    /// frame `export` writes `COMPASS_MOT*` in. Later firmware adds it after the matrix: the
    /// logged offsets come out as they are, and there is no frame. A later release named in
    /// the log is later firmware with or without the parameter (regression: such a log from
    /// a board of 1 MB of flash, which leaves per-motor compensation out, was taken for the
    /// older firmware, and its exported `COMPASS_MOT*` went through the soft-iron matrix).
    #[test]
    fn older_firmware_adds_its_compensation_before_the_soft_iron_matrix() {
        let with = [
            ("MagX", [100.0, 300.0]),
            ("MagY", [0.0, 0.0]),
            ("MagZ", [-50.0, -50.0]),
            ("MOX", [0.0, 120.0]),
            ("MOY", [0.0, -40.0]),
            ("MOZ", [0.0, 10.0]),
        ];
        let matrix = [
            ("COMPASS_DIA_X", 0.95),
            ("COMPASS_DIA_Y", 1.05),
            ("COMPASS_DIA_Z", 1.0),
            ("COMPASS_ODI_X", -0.02),
            ("COMPASS_ODI_Y", 0.01),
            ("COMPASS_ODI_Z", 0.03),
            ("COMPASS_MOTCT", 1.0),
        ];
        let m = magstand_core::Mat3::new(0.95, -0.02, 0.01, -0.02, 1.05, 0.03, 0.01, 0.03, 1.0);
        let added = m * Vec3::new(12.0, -4.0, 1.0);
        let log = one_compass(&with, &matrix);
        let mut out = VehicleStreams::default();
        magnetometer(&log, &ImportOptions::default(), &mut out).expect("imported");
        let frame = out.mag_to_body.expect("a frame for older firmware");
        assert!((frame.matrix() - m).abs().max() < 1e-15, "{frame}");
        let want = Vec3::new(30.0, 0.0, -5.0) - added;
        let got = out.mag_ut.values[1];
        assert!((got - want).norm() < 1e-9, "{got:?} against {want:?}");
        assert!(
            out.notes.iter().any(|n| n.contains("soft-iron")),
            "{:?}",
            out.notes
        );
        // Firmware with per-motor compensation (the parameter is logged, on or off).
        let mut later = matrix.to_vec();
        later.push(("COMPASS_PMOT_EN", 0.0));
        let log = one_compass(&with, &later);
        let mut out = VehicleStreams::default();
        magnetometer(&log, &ImportOptions::default(), &mut out).expect("imported");
        assert_eq!(out.mag_to_body, None);
        let want = Vec3::new(30.0, 0.0, -5.0) - Vec3::new(12.0, -4.0, 1.0);
        let got = out.mag_ut.values[1];
        assert!((got - want).norm() < 1e-9, "{got:?} against {want:?}");
        // A later release without the parameter (per-motor compensation left out of a board
        // of 1 MB of flash): the release decides; an older one named keeps the frame.
        for (firmware, older) in [
            ("ArduCopter V4.5.7 (2a3dc4b7)", false),
            ("ArduPlane V4.0.0", false),
            ("ArduCopter V3.6.12 (e4e5b8a5)", false),
            ("APM:Copter V3.5.7 (b11c6af3)", true),
            ("APM:Copter V3.3-dev", true),
        ] {
            let mut log = one_compass(&with, &matrix);
            log.texts.push((0.5, firmware.to_string()));
            let mut out = VehicleStreams::default();
            magnetometer(&log, &ImportOptions::default(), &mut out).expect("imported");
            assert_eq!(
                out.mag_to_body.is_some(),
                older,
                "{firmware}: {:?}",
                out.notes
            );
            let applied = if older {
                added
            } else {
                Vec3::new(12.0, -4.0, 1.0)
            };
            let got = out.mag_ut.values[1];
            let want = Vec3::new(30.0, 0.0, -5.0) - applied;
            assert!(
                (got - want).norm() < 1e-9,
                "{firmware}: {got:?} against {want:?}"
            );
            assert_eq!(
                out.notes
                    .iter()
                    .any(|n| n.contains(firmware) && n.contains("before compass")),
                older,
                "{firmware}: {:?}",
                out.notes
            );
            assert_eq!(
                out.notes
                    .iter()
                    .any(|n| n.contains(firmware) && n.contains("per-motor compensation out")),
                !older,
                "{firmware}: {:?}",
                out.notes
            );
        }
        // A diagonal never calibrated (zeros) is the firmware's identity: no frame.
        let log = one_compass(&with, &[("COMPASS_DIA_X", 0.0), ("COMPASS_MOTCT", 1.0)]);
        let mut out = VehicleStreams::default();
        magnetometer(&log, &ImportOptions::default(), &mut out).expect("imported");
        assert_eq!(out.mag_to_body, None);
    }

    /// The autopilot's throttle is read from `CTUN`: 4.x's `ThO` as a fraction, Copter 3.3's
    /// `ThrOut` in thousandths; values that are not a throttle leave it out.
    #[test]
    fn the_autopilots_throttle_is_read_in_either_unit() {
        let log = |name: &str, v: [f64; 3]| {
            let mut log = LogContents::new("a.bin".into(), crate::contents::LogFormat::DataFlash);
            let series = Series {
                t_s: vec![1.0, 2.0, 3.0],
                fields: [(name.to_string(), v.to_vec())].into_iter().collect(),
            };
            log.topics
                .insert("CTUN".into(), [(0u8, series)].into_iter().collect());
            log
        };
        let mut notes = Vec::new();
        let got = |l: &LogContents, notes: &mut Vec<String>| {
            autopilot_throttle(l, notes).map(|s| s.values)
        };
        assert_eq!(
            got(&log("ThO", [0.0, 0.25, 0.5]), &mut notes),
            Some(vec![0.0, 0.25, 0.5])
        );
        assert_eq!(
            got(&log("ThrOut", [0.0, 375.0, 500.0]), &mut notes),
            Some(vec![0.0, 0.375, 0.5])
        );
        assert!(
            notes.len() == 2 && notes[1].contains("thousandths"),
            "{notes:?}"
        );
        assert_eq!(got(&log("ThO", [0.0, 0.0, 0.0]), &mut notes), None);
        assert_eq!(got(&log("ThO", [0.0, 5000.0, 1.0]), &mut notes), None);
    }
}
