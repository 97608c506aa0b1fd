//! PX4 topics to magstand streams.
//!
//! * `sensor_mag[N]` (gauss, as the driver published it) with the log's own calibration
//!   (`CAL_MAGn_{X,Y,Z}OFF`, `SCALE`, `ODIAG`, matched by `CAL_MAGn_ID` = `device_id`; before
//!   PX4 1.12 the driver had applied the offsets and scale itself, and only the rotation is) and
//!   rotation (`CAL_MAGn_ROT`; -1 marks an internal sensor, which follows `SENS_BOARD_ROT`) so
//!   the field is in the body frame as PX4's estimator sees it, before any power compensation.
//! * Motors: `actuator_motors` (0..1, PX4 1.13 on) when logged; otherwise `actuator_outputs`
//!   mapped with `PWM_MAIN_MINn`/`MAXn` (or the older `PWM_MIN`/`PWM_MAX`), motors located by
//!   `PWM_MAIN_FUNCn` = 101.. when set. UAVCAN outputs (a non-zero instance with
//!   `UAVCAN_ENABLE` >= 2) are raw 0..8191.
//! * `battery_status[0]`, `vehicle_attitude`, `actuator_armed` (or `vehicle_status`),
//!   `vehicle_land_detected`, and GPS position and UTC time for the Earth-field model.
use magstand_core::magnetometer_frame::SensorToBody;
use magstand_core::magnetometer_slot::MagnetometerSlot;
use magstand_core::{Quat, Vec3};

use crate::LogsError;
use crate::contents::{LogContents, Series};
use crate::import::ImportOptions;
use crate::streams::{Position, Stream, VehicleStreams, decimal_year, normalize_output};

const UT_PER_GAUSS: f64 = 100.0;

fn missing(log: &LogContents, what: &str, hint: &str) -> LogsError {
    LogsError::Missing {
        path: log.path.clone(),
        what: what.to_string(),
        hint: hint.to_string(),
    }
}

/// PX4's `Rotation` enum (`src/lib/conversion/rotation.h`, the MAVLink `MAV_SENSOR_ORIENTATION`
/// values): each code's roll, pitch and yaw in degrees, applied as PX4's `Dcmf(Eulerf(..))`
/// does (roll, then pitch, then yaw, about the body's fixed axes).
const PX4_ROTATIONS_DEG: [[f64; 3]; 41] = [
    [0.0, 0.0, 0.0],
    [0.0, 0.0, 45.0],
    [0.0, 0.0, 90.0],
    [0.0, 0.0, 135.0],
    [0.0, 0.0, 180.0],
    [0.0, 0.0, 225.0],
    [0.0, 0.0, 270.0],
    [0.0, 0.0, 315.0],
    [180.0, 0.0, 0.0],
    [180.0, 0.0, 45.0],
    [180.0, 0.0, 90.0],
    [180.0, 0.0, 135.0],
    [0.0, 180.0, 0.0],
    [180.0, 0.0, 225.0],
    [180.0, 0.0, 270.0],
    [180.0, 0.0, 315.0],
    [90.0, 0.0, 0.0],
    [90.0, 0.0, 45.0],
    [90.0, 0.0, 90.0],
    [90.0, 0.0, 135.0],
    [270.0, 0.0, 0.0],
    [270.0, 0.0, 45.0],
    [270.0, 0.0, 90.0],
    [270.0, 0.0, 135.0],
    [0.0, 90.0, 0.0],
    [0.0, 270.0, 0.0],
    [0.0, 180.0, 90.0],
    [0.0, 180.0, 270.0],
    [90.0, 90.0, 0.0],
    [180.0, 90.0, 0.0],
    [270.0, 90.0, 0.0],
    [90.0, 180.0, 0.0],
    [270.0, 180.0, 0.0],
    [90.0, 270.0, 0.0],
    [180.0, 270.0, 0.0],
    [270.0, 270.0, 0.0],
    [90.0, 180.0, 90.0],
    [90.0, 0.0, 270.0],
    [90.0, 68.0, 293.0],
    [0.0, 315.0, 0.0],
    [90.0, 315.0, 0.0],
];

/// A PX4 `Rotation` enum value (0 to 40) as a rotation from the sensor to the body frame.
pub(crate) fn px4_rotation(code: i64) -> Option<Quat> {
    let [roll, pitch, yaw] = *PX4_ROTATIONS_DEG.get(usize::try_from(code).ok()?)?;
    Some(Quat::from_euler_angles(
        roll.to_radians(),
        pitch.to_radians(),
        yaw.to_radians(),
    ))
}

/// The rotation PX4's calibration takes a magnetometer's reading to the body frame by, for
/// `CAL_MAGn_ROT` = `code`: that rotation of PX4's table, or for an internal sensor (-1) the
/// board's, `board_rotation`, followed by the board's trim `board_trim_rad` (roll, pitch, yaw;
/// `SENS_BOARD_{X,Y,Z}_OFF`). Returns the code of the table it used, the rotation, and whether
/// that code is in the table (where it is not, the table's part is left out).
pub(crate) fn px4_sensor_rotation(
    code: i64,
    board_rotation: i64,
    board_trim_rad: [f64; 3],
) -> (i64, Quat, bool) {
    let internal = code == -1;
    let used = if internal { board_rotation } else { code };
    let table = px4_rotation(used);
    let rotation = table.unwrap_or_else(Quat::identity);
    let rotation = match internal {
        true => {
            let [x, y, z] = board_trim_rad;
            Quat::from_euler_angles(x, y, z) * rotation
        }
        false => rotation,
    };
    (used, rotation, table.is_some())
}

/// PX4's scale matrix of a magnetometer calibration: its diagonal (`CAL_MAGn_{X,Y,Z}SCALE`) and
/// off-diagonal (`CAL_MAGn_{X,Y,Z}ODIAG`: xy, xz, yz).
pub(crate) fn px4_scale([xs, ys, zs]: [f64; 3], [xo, yo, zo]: [f64; 3]) -> magstand_core::Mat3 {
    magstand_core::Mat3::new(xs, xo, yo, xo, ys, zo, yo, zo, zs)
}

/// Whether PX4 `version` (major, minor, patch) applied a magnetometer's calibration offsets
/// and scale in its driver, to `sensor_mag` itself: before 1.12 (`PX4Magnetometer`); from
/// 1.12 the sensors module applies them.
pub(crate) fn calibrated_by_driver([major, minor, _]: [u8; 3]) -> bool {
    (major, minor) < (1, 12)
}

/// Reads the streams of a PX4 log.
pub fn streams(log: &LogContents, opts: &ImportOptions) -> Result<VehicleStreams, LogsError> {
    let mut out = VehicleStreams::default();
    magnetometer(log, opts, &mut out)?;
    motors(log, opts, &mut out)?;
    if let Some(b) = log.series("battery_status", 0) {
        out.bat_v = scalar(b, "voltage_v", |v| v > 0.5);
        // PX4 logs -1 for a current it does not measure.
        out.bat_a = scalar(b, "current_a", |a| a >= 0.0);
        out.notes.extend(crate::streams::other_batteries(
            &log.instances("battery_status"),
            "battery_status",
        ));
    }
    if let Some(e) = log.series("esc_status", 0) {
        let motor_count = out.motors.values.first().map_or(0, |m| m.len());
        let entries = esc_entries_of_motors(e, motor_count);
        out.esc_a = entries
            .iter()
            .map_while(|&i| scalar(e, &format!("esc[{i}].esc_current"), |a| a >= 0.0))
            .collect();
        if !out.esc_a.is_empty() {
            let n = out.esc_a.len();
            out.notes.push(format!(
                "per-ESC currents from esc_status entries {:?} for {n} motors, written as esc_1_a..esc_{n}_a",
                &entries[..n]
            ));
        }
    }
    out.autopilot_throttle = autopilot_throttle(log, &mut out.notes);
    if let Some(a) = log.series("vehicle_attitude", 0) {
        let q: Vec<Option<&[f64]>> = (0..4).map(|i| a.field(&format!("q[{i}]"))).collect();
        if q.iter().all(|c| c.is_some()) {
            let q: Vec<&[f64]> = q.into_iter().flatten().collect();
            out.attitude = Some(Stream::from_pairs((0..a.len()).map(|r| {
                let v = nalgebra::Quaternion::new(q[0][r], q[1][r], q[2][r], q[3][r]);
                let ok = v.norm().is_finite() && (v.norm() - 1.0).abs() < 0.01;
                (a.t_s[r], ok.then(|| Quat::from_quaternion(v)))
            })));
        }
    }
    out.armed = log
        .series("actuator_armed", 0)
        .and_then(|s| s.stream("armed", |v| Some(v != 0.0)))
        .or_else(|| {
            // vehicle_status.arming_state 2 is ARMED.
            log.series("vehicle_status", 0)
                .and_then(|s| s.stream("arming_state", |v| Some(v == 2.0)))
        });
    out.landed = log
        .series("vehicle_land_detected", 0)
        .and_then(|s| s.stream("landed", |v| Some(v != 0.0)));
    out.position = position(log);
    Ok(out)
}

/// The `esc_status` entry of each of the first `motor_count` motors, in motor order, as far
/// as they are known. An entry names the motor it drives by `actuator_function` (101 for
/// Motor1, PX4's `ACTUATOR_FUNCTION_MOTOR1`, from 1.13), which need not be its index: the
/// ESCs of a CAN bus or a DShot output group come in the order of their addresses or outputs.
/// Logs without that field (or with it 0, unknown) list them in motor order. Only the first
/// `esc_count` entries are in use.
fn esc_entries_of_motors(e: &Series, motor_count: usize) -> Vec<usize> {
    const MOTOR1: f64 = 101.0;
    let count = e
        .field("esc_count")
        .map_or(0, |c| c.iter().copied().fold(0.0, f64::max) as usize);
    // Each entry's function: its largest logged value (0 while the ESC is unknown).
    let functions: Vec<Option<f64>> = (0..count)
        .map(|j| {
            e.field(&format!("esc[{j}].actuator_function"))
                .map(|f| f.iter().copied().fold(0.0, f64::max))
        })
        .collect();
    if functions.iter().any(|f| f.is_some_and(|f| f >= MOTOR1)) {
        (0..motor_count)
            .map_while(|k| functions.iter().position(|f| *f == Some(MOTOR1 + k as f64)))
            .collect()
    } else {
        (0..count.min(motor_count)).collect()
    }
}

/// A finite, valid scalar field as a stream; `None` when no message has one.
fn scalar(s: &Series, field: &str, valid: impl Fn(f64) -> bool) -> Option<Stream<f64>> {
    s.stream(field, |x| (x.is_finite() && valid(x)).then_some(x))
        .filter(|st| !st.is_empty())
}

/// The throttle PX4's power compensation multiplies (`CAL_MAG_COMP_TYP` 1): the collective
/// thrust setpoint's magnitude (`vehicle_thrust_setpoint`, from 1.13), or the throttle of
/// `actuator_controls_0` in older logs. The motor outputs follow it through the thrust model
/// (`THR_MDL_FAC`), so a throttle line for PX4 is fitted against it, not against the outputs.
/// None where the log has neither or its values are not a throttle.
fn autopilot_throttle(log: &LogContents, notes: &mut Vec<String>) -> Option<Stream<f64>> {
    let as_throttle = |v: f64| (v.is_finite() && (0.0..=1.0).contains(&v)).then_some(v);
    let (stream, source) = if let Some(s) = log.series("vehicle_thrust_setpoint", 0) {
        let axes: Vec<&[f64]> = (0..3)
            .map(|i| s.field(&format!("xyz[{i}]")))
            .collect::<Option<_>>()?;
        let magnitude = |r: usize| axes.iter().map(|a| a[r] * a[r]).sum::<f64>().sqrt();
        (
            Stream::from_pairs((0..s.t_s.len()).map(|r| (s.t_s[r], as_throttle(magnitude(r))))),
            "vehicle_thrust_setpoint (the magnitude of xyz)",
        )
    } else {
        let s = log.series("actuator_controls_0", 0)?;
        (
            s.stream("control[3]", as_throttle)?,
            "actuator_controls_0.control[3]",
        )
    };
    let moving = stream.values.iter().any(|v| *v > 0.0);
    if stream.is_empty() || !moving {
        return None;
    }
    notes.push(format!(
        "the autopilot's throttle (its thrust setpoint, which CAL_MAG_COMP_TYP 1 multiplies): {source}, written as autopilot_throttle"
    ));
    Some(stream)
}

fn magnetometer(
    log: &LogContents,
    opts: &ImportOptions,
    out: &mut VehicleStreams,
) -> Result<(), LogsError> {
    let instances = log.instances("sensor_mag");
    if instances.is_empty() {
        return vehicle_magnetometer(log, opts, out);
    }
    // Calibration slot of each instance: CAL_MAGk_ID equals the instance's device_id.
    let slot = |inst: u8| -> Option<usize> {
        let id = log
            .series("sensor_mag", inst)?
            .field("device_id")?
            .first()?;
        (0..4).find(|k| log.param(&format!("CAL_MAG{k}_ID")) == Some(*id))
    };
    let internal =
        |inst: u8| slot(inst).and_then(|k| log.param(&format!("CAL_MAG{k}_ROT"))) == Some(-1.0);
    let inst = match opts.mag {
        Some(m) => {
            if !instances.contains(&m) {
                return Err(LogsError::Unusable {
                    path: log.path.clone(),
                    what: format!(
                        "`mag` = {m}: sensor_mag has no instance {m}; the log has {}",
                        list(&instances)
                    ),
                });
            }
            out.notes
                .push(format!("magnetometer: sensor_mag[{m}] (`mag`)"));
            m
        }
        None => match instances.iter().copied().find(|&i| internal(i)) {
            Some(i) => {
                out.notes.push(format!(
                    "magnetometer: sensor_mag[{i}], the first internal one (CAL_MAG{}_ROT = -1); `mag` picks another of {}",
                    slot(i).unwrap_or(0),
                    list(&instances)
                ));
                i
            }
            None => {
                let i = instances[0];
                out.notes.push(format!(
                    "magnetometer: sensor_mag[{i}] (no instance is marked internal); `mag` picks another of {}",
                    list(&instances)
                ));
                i
            }
        },
    };
    // Its compensation belongs to the calibration slot whose id is the sensor's.
    let calibration = slot(inst);
    out.mag_slot = calibration.map(|k| MagnetometerSlot::Px4CalMag(k as u8));
    // A priority of 0 disables the sensor: PX4 takes no heading from it, and a compensation
    // written for it changes nothing the vehicle flies on.
    if let Some(k) = calibration
        && log.param(&format!("CAL_MAG{k}_PRIO")) == Some(0.0)
    {
        let enabled: Vec<u8> = instances
            .iter()
            .copied()
            .filter(|&i| {
                slot(i).is_some_and(|j| log.param(&format!("CAL_MAG{j}_PRIO")) != Some(0.0))
            })
            .collect();
        out.notes.push(format!(
            "magnetometer: sensor_mag[{inst}] is disabled on this vehicle (CAL_MAG{k}_PRIO = 0): PX4 takes no heading from it, and its exported compensation changes nothing until it is enabled{}",
            if enabled.is_empty() {
                String::new()
            } else {
                format!("; the enabled ones are sensor_mag {} (`mag`)", list(&enabled))
            }
        ));
    }
    let s = log.series("sensor_mag", inst).expect("listed instance");
    let axes: Vec<&[f64]> = ["x", "y", "z"]
        .iter()
        .map(|a| {
            s.field(a).ok_or_else(|| {
                missing(
                    log,
                    &format!("sensor_mag[{inst}].{a}"),
                    "the topic has no field for this axis",
                )
            })
        })
        .collect::<Result<_, _>>()?;
    let (offset, scale, rotation) = match calibration {
        Some(k) => {
            let p =
                |n: &str, default: f64| log.param(&format!("CAL_MAG{k}_{n}")).unwrap_or(default);
            let off = Vec3::new(p("XOFF", 0.0), p("YOFF", 0.0), p("ZOFF", 0.0));
            let scale = px4_scale(
                [p("XSCALE", 1.0), p("YSCALE", 1.0), p("ZSCALE", 1.0)],
                [p("XODIAG", 0.0), p("YODIAG", 0.0), p("ZODIAG", 0.0)],
            );
            // Before PX4 1.12 the driver applied the offsets and scale to sensor_mag itself;
            // the rotation (and, before it, the power compensation) came after.
            let driver_calibrated = log.px4_version().is_some_and(calibrated_by_driver);
            let (off, scale) = match driver_calibrated {
                true => (Vec3::zeros(), nalgebra::Matrix3::identity()),
                false => (off, scale),
            };
            // An internal sensor turns with the board, whose fine trim (degrees, roll pitch
            // yaw) PX4 applies after the board's rotation.
            let rotation = p("ROT", -1.0) as i64;
            let internal = rotation == -1;
            let trim = ["X", "Y", "Z"].map(|a| {
                log.param(&format!("SENS_BOARD_{a}_OFF"))
                    .unwrap_or(0.0)
                    .to_radians()
            });
            let board = log.param("SENS_BOARD_ROT").unwrap_or(0.0) as i64;
            let (code, rot, known) = px4_sensor_rotation(rotation, board, trim);
            if !known {
                out.notes.push(format!(
                    "warning: rotation {code} of CAL_MAG{k} is not one of PX4's (0 to 40); the field stays in the sensor frame"
                ));
            }
            let trimmed = match internal && trim.iter().any(|t| *t != 0.0) {
                true => format!(
                    ", the board's trim SENS_BOARD_X/Y/Z_OFF {:.2} {:.2} {:.2} deg",
                    trim[0].to_degrees(),
                    trim[1].to_degrees(),
                    trim[2].to_degrees()
                ),
                false => String::new(),
            };
            out.notes.push(match driver_calibrated {
                true => format!(
                    "calibration CAL_MAG{k}: its offsets and scale were applied by the driver of this PX4 (before 1.12), its rotation {code}{trimmed} applied here"
                ),
                false => format!(
                    "calibration CAL_MAG{k} applied (offsets, scale, rotation {code}{trimmed})"
                ),
            });
            // PX4 adds its power compensation before this transform: `export` maps the
            // body-frame coefficients back through it.
            out.mag_to_body = match SensorToBody::from_matrix(
                &(rot.to_rotation_matrix().into_inner() * scale),
            ) {
                Ok(frame) => {
                    if !frame.is_identity() {
                        out.notes.push(format!(
                            "the readings were taken to the body frame by {frame} (row by row; column `{}`): `export --to px4` writes the compensation in the sensor's own frame, where PX4 adds it",
                            magstand_core::magnetometer_frame::COLUMN
                        ));
                    }
                    Some(frame)
                }
                Err(why) => {
                    out.notes.push(format!(
                        "warning: CAL_MAG{k}'s rotation and scale are not {why}: `export --to px4` cannot write a compensation for this sensor"
                    ));
                    None
                }
            };
            (off, scale, rot)
        }
        None => {
            out.notes.push(
                "no CAL_MAGn_ID matches this sensor: the field is as the driver published it, uncalibrated".into(),
            );
            (
                Vec3::zeros(),
                nalgebra::Matrix3::identity(),
                Quat::identity(),
            )
        }
    };
    out.mag_ut = Stream::from_pairs((0..s.len()).map(|r| {
        let raw = Vec3::new(axes[0][r], axes[1][r], axes[2][r]);
        let body = rotation * (scale * (raw - offset)) * UT_PER_GAUSS;
        (s.t_s[r], body.iter().all(|v| v.is_finite()).then_some(body))
    }));
    out.mag_temp_c = scalar(s, "temperature", |c| (-60.0..150.0).contains(&c))
        .filter(|t| t.len() == out.mag_ut.len());
    Ok(())
}

/// Older logs carry only `vehicle_magnetometer`: calibrated, in the body frame, the sensor the
/// estimator selected, and after any power compensation PX4 already applied.
fn vehicle_magnetometer(
    log: &LogContents,
    opts: &ImportOptions,
    out: &mut VehicleStreams,
) -> Result<(), LogsError> {
    let instances = log.instances("vehicle_magnetometer");
    let inst = opts.mag.unwrap_or(0);
    let Some(s) = log.series("vehicle_magnetometer", inst) else {
        return Err(if instances.is_empty() {
            missing(
                log,
                "a magnetometer topic (sensor_mag or vehicle_magnetometer)",
                "log sensor_mag (the default logging profile of PX4 1.12 on has it)",
            )
        } else {
            LogsError::Unusable {
                path: log.path.clone(),
                what: format!(
                    "`mag` = {inst}: vehicle_magnetometer has no instance {inst}; the log has {}",
                    list(&instances)
                ),
            }
        });
    };
    let axes: Vec<&[f64]> = (0..3)
        .map(|a| {
            s.field(&format!("magnetometer_ga[{a}]")).ok_or_else(|| {
                missing(
                    log,
                    &format!("vehicle_magnetometer.magnetometer_ga[{a}]"),
                    "the topic has no field for this axis",
                )
            })
        })
        .collect::<Result<_, _>>()?;
    let comp = log.param("CAL_MAG_COMP_TYP").unwrap_or(0.0);
    out.notes.push(format!(
        "magnetometer: vehicle_magnetometer[{inst}] (no sensor_mag in this log): calibrated, body frame{}",
        if comp != 0.0 {
            format!("; WARNING: PX4 power compensation was on (CAL_MAG_COMP_TYP {comp}), so part of the disturbance is already removed")
        } else {
            String::new()
        }
    ));
    out.mag_ut = Stream::from_pairs((0..s.len()).map(|r| {
        let v = Vec3::new(axes[0][r], axes[1][r], axes[2][r]) * UT_PER_GAUSS;
        (s.t_s[r], v.iter().all(|x| x.is_finite()).then_some(v))
    }));
    Ok(())
}

fn list(instances: &[u8]) -> String {
    let v: Vec<String> = instances.iter().map(|i| i.to_string()).collect();
    format!("instance(s) {}", v.join(", "))
}

fn motors(
    log: &LogContents,
    opts: &ImportOptions,
    out: &mut VehicleStreams,
) -> Result<(), LogsError> {
    if opts.outputs.is_none()
        && let Some(m) = log.series("actuator_motors", 0)
    {
        let cols: Vec<&[f64]> = (0..16)
            .map_while(|i| m.field(&format!("control[{i}]")))
            .take_while(|c| c.iter().any(|v| v.is_finite()))
            .collect();
        let n = opts.motors.unwrap_or(cols.len());
        if n == 0 || n > cols.len() {
            return Err(LogsError::Unusable {
                path: log.path.clone(),
                what: format!(
                    "actuator_motors has {} motor channel(s) with values; {n} requested",
                    cols.len()
                ),
            });
        }
        out.notes.push(format!(
            "motors: actuator_motors control[0..{n}] (0..1; NaN, disarmed, is 0)"
        ));
        out.motors = Stream::from_pairs((0..m.len()).map(|r| {
            (
                m.t_s[r],
                Some(
                    cols[..n]
                        .iter()
                        .map(|c| normalize_output(c[r], 0.0, 1.0))
                        .collect(),
                ),
            )
        }));
        return Ok(());
    }
    let instances = log.instances("actuator_outputs");
    if instances.is_empty() {
        return Err(missing(
            log,
            "motor outputs (actuator_motors or actuator_outputs)",
            "the import needs the motor commands",
        ));
    }
    let inst = match opts.outputs {
        Some(i) if instances.contains(&i) => i,
        Some(i) => {
            return Err(LogsError::Unusable {
                path: log.path.clone(),
                what: format!(
                    "`outputs` = {i}: actuator_outputs has no instance {i}; the log has {}",
                    list(&instances)
                ),
            });
        }
        // The first instance whose first output moves: instance 0 is often an idle PWM bank
        // when the ESCs are on a bus.
        None => instances
            .iter()
            .copied()
            .find(|&i| {
                log.series("actuator_outputs", i)
                    .and_then(|s| s.field("output[0]"))
                    .is_some_and(|c| {
                        let (lo, hi) = c
                            .iter()
                            .fold((f64::MAX, f64::MIN), |(a, b), &v| (a.min(v), b.max(v)));
                        hi - lo > 1.0
                    })
            })
            .unwrap_or(instances[0]),
    };
    let s = log
        .series("actuator_outputs", inst)
        .expect("listed instance");
    // Motor k on channel c: PWM_MAIN_FUNCc = 101 + k when the log has output functions.
    let by_function: Vec<usize> = (0..16)
        .map_while(|k| {
            (1..=16).find(|c| log.param(&format!("PWM_MAIN_FUNC{c}")) == Some(101.0 + k as f64))
        })
        .map(|c| c - 1)
        .collect();
    let airframe_motors = match log.param("MAV_TYPE").map(|v| v as i64) {
        Some(2) => Some(4),
        Some(13) => Some(6),
        Some(14) => Some(8),
        Some(15) => Some(3),
        _ => None,
    };
    let n = match (opts.motors, by_function.len(), airframe_motors) {
        (Some(n), _, _) => n,
        (None, f, _) if f > 0 => f,
        (None, _, Some(n)) => n,
        _ => {
            return Err(missing(
                log,
                "the motor count (no PWM_MAIN_FUNCn = 101.. and no multirotor MAV_TYPE)",
                "give `motors` (the motor count)",
            ));
        }
    };
    let channels: Vec<usize> = if by_function.len() >= n && opts.motors.is_none() {
        by_function[..n].to_vec()
    } else {
        (0..n).collect()
    };
    let cols: Vec<&[f64]> = channels
        .iter()
        .map(|c| {
            s.field(&format!("output[{c}]")).ok_or_else(|| {
                missing(
                    log,
                    &format!("actuator_outputs[{inst}].output[{c}]"),
                    "fewer outputs than motors; check `motors`",
                )
            })
        })
        .collect::<Result<_, _>>()?;
    let uavcan = inst > 0 && log.param("UAVCAN_ENABLE").is_some_and(|v| v >= 2.0);
    let ranges: Vec<(f64, f64)> = channels
        .iter()
        .map(|&c| {
            if let Some(r) = opts.pwm_range {
                return Ok(r);
            }
            if uavcan {
                return Ok((0.0, 8191.0));
            }
            let ch = c + 1;
            let pair = |lo: &str, hi: &str| Some((log.param(lo)?, log.param(hi)?));
            pair(&format!("PWM_MAIN_MIN{ch}"), &format!("PWM_MAIN_MAX{ch}"))
                .or_else(|| pair("PWM_MIN", "PWM_MAX"))
                .filter(|(lo, hi)| hi > lo)
                .ok_or_else(|| {
                    missing(
                        log,
                        &format!("the PWM limits of output {ch} (PWM_MAIN_MIN{ch}/PWM_MAIN_MAX{ch} or PWM_MIN/PWM_MAX)"),
                        "give `pwm_range` (MIN:MAX)",
                    )
                })
        })
        .collect::<Result<_, _>>()?;
    out.notes.push(format!(
        "motors: actuator_outputs[{inst}] channels {:?}, range {}",
        channels.iter().map(|c| c + 1).collect::<Vec<_>>(),
        if opts.pwm_range.is_some() {
            "from `pwm_range`".to_string()
        } else if uavcan {
            "UAVCAN raw 0..8191".to_string()
        } else {
            format!("{:?} from the log's PWM parameters", ranges[0])
        }
    ));
    out.motors = Stream::from_pairs((0..s.len()).map(|r| {
        (
            s.t_s[r],
            Some(
                cols.iter()
                    .zip(&ranges)
                    .map(|(c, (lo, hi))| normalize_output(c[r], *lo, *hi))
                    .collect(),
            ),
        )
    }));
    Ok(())
}

fn position(log: &LogContents) -> Option<Position> {
    for topic in ["vehicle_gps_position", "sensor_gps"] {
        let Some(s) = log.series(topic, 0) else {
            continue;
        };
        // PX4 1.14 on logs degrees; earlier versions 1e-7 degrees as integers.
        let (lat, lon, scale) = match (s.field("latitude_deg"), s.field("longitude_deg")) {
            (Some(a), Some(o)) => (a, o, 1.0),
            _ => (s.field("lat")?, s.field("lon")?, 1e-7),
        };
        let alt = s
            .field("altitude_msl_m")
            .map(|a| (a, 1.0))
            .or_else(|| s.field("alt").map(|a| (a, 1e-3)));
        let fix = s.field("fix_type");
        let r = (0..s.len())
            .rev()
            .find(|&r| lat[r] != 0.0 && lon[r] != 0.0 && fix.is_none_or(|f| f[r] >= 3.0))?;
        let utc = s.field("time_utc_usec").map(|u| u[r]).filter(|u| *u > 1e15);
        return Some(Position {
            lat_deg: lat[r] * scale,
            lon_deg: lon[r] * scale,
            alt_m: alt.map_or(0.0, |(a, k)| a[r] * k),
            year: utc.map(|u| decimal_year(u * 1e-6)),
        });
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An esc_status entry names its motor by `actuator_function` (101 = Motor1): ESCs listed
    /// in the order of their bus addresses go to their own motors; a log without the field
    /// (or with it 0) lists them in motor order; only `esc_count` entries are read.
    #[test]
    fn esc_entries_follow_their_actuator_function() {
        let series = |fields: &[(&str, f64)]| Series {
            t_s: vec![0.0],
            fields: fields
                .iter()
                .map(|(name, v)| (name.to_string(), vec![*v]))
                .collect(),
        };
        let permuted = series(&[
            ("esc_count", 4.0),
            ("esc[0].actuator_function", 103.0),
            ("esc[1].actuator_function", 101.0),
            ("esc[2].actuator_function", 104.0),
            ("esc[3].actuator_function", 102.0),
        ]);
        assert_eq!(esc_entries_of_motors(&permuted, 4), [1, 3, 0, 2]);
        // A hexacopter's fifth motor without an ESC that reports: the four known.
        assert_eq!(esc_entries_of_motors(&permuted, 6), [1, 3, 0, 2]);
        let unknown = series(&[
            ("esc_count", 3.0),
            ("esc[0].actuator_function", 0.0),
            ("esc[1].actuator_function", 0.0),
            ("esc[2].actuator_function", 0.0),
        ]);
        assert_eq!(esc_entries_of_motors(&unknown, 4), [0, 1, 2]);
        let older = series(&[("esc_count", 4.0)]);
        assert_eq!(esc_entries_of_motors(&older, 4), [0, 1, 2, 3]);
    }

    /// Every PX4 rotation is a proper rotation; codes 0 to 15 are a yaw in steps of 45 degrees
    /// after (from 8 on) a roll of 180, and the others turn the axes as their names say.
    #[test]
    fn px4_rotations_turn_the_axes_as_their_names_say() {
        let (x, y, z) = (Vec3::x(), Vec3::y(), Vec3::z());
        for code in 0..=15i64 {
            let (roll, steps) = if code < 8 {
                (0.0, code)
            } else {
                (180.0f64, code - 8)
            };
            let want =
                Quat::from_euler_angles(roll.to_radians(), 0.0, (45.0 * steps as f64).to_radians());
            let got = px4_rotation(code).unwrap();
            assert!(
                got.angle_to(&want) < 1e-12,
                "code {code}: {got:?} against {want:?}"
            );
        }
        let turns = [
            (16, y, z),  // ROLL_90: y to z
            (20, y, -z), // ROLL_270
            (24, z, x),  // PITCH_90: z to x
            (25, z, -x), // PITCH_270
            (26, x, -y), // PITCH_180_YAW_90: x to -x, then -x to -y
        ];
        for (code, from, to) in turns {
            let got = px4_rotation(code).unwrap() * from;
            assert!(
                (got - to).norm() < 1e-12,
                "code {code}: {from} goes to {got}, not {to}"
            );
        }
        for code in 0..=40 {
            let m = px4_rotation(code)
                .unwrap()
                .to_rotation_matrix()
                .into_inner();
            assert!(
                (m * m.transpose() - magstand_core::Mat3::identity())
                    .abs()
                    .max()
                    < 1e-12
                    && (m.determinant() - 1.0).abs() < 1e-12,
                "code {code}: {m}"
            );
        }
        assert!(px4_rotation(41).is_none() && px4_rotation(-2).is_none());
    }
}
