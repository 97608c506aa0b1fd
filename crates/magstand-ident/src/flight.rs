//! Identification from an ordinary flight log, without a test stand.
//!
//! In flight the reading is the Earth field turned by the attitude, plus the constant offset
//! of the sensor, plus the motor disturbance: `m = R^T e + b + d(u(t - delay)) + noise`, with
//! `R` the logged attitude (body to north-east-down), `e` the Earth field in north-east-down,
//! `b` per axis, and `u` the overall throttle or the current. With the attitude varying
//! independently of the throttle, one stacked least squares over all three axes separates
//! `e` (shared by the axes) from `b` and from a cubic per axis standing in for `d`; the delay
//! of the magnetometer stream is the one that minimizes the residual over a grid, refined by
//! golden section, in two steps: first the age of the magnetometer's samples at their time
//! stamps, which moves the attitude and the commands alike (the reading is the field at the
//! moment it was sampled); then, with the attitude held there, the delay of the disturbance
//! behind the commands (the motors' and the current's own lag on top of the sample's age).
//!
//! The result is a stand-equivalent recording: the Earth field's attitude dependence taken
//! out (`m - R^T e + e`, the reading as if the vehicle sat level facing north) and the inputs
//! moved by the delay, which the ordinary fit then models as usual. The sensor is assumed
//! calibrated (soft iron removed), as PX4 and ArduPilot log it.
use magstand_core::interpolation::{interpolate, locate, locate_increasing};
use magstand_core::{Quat, Recording, Vec3};
use nalgebra::Matrix3;

use crate::IdentError;
use crate::least_squares::{NormalEquations, SolveError};

/// Where the Earth field comes from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum EarthField {
    /// Fitted from the log itself (needs attitude changes).
    Fit,
    /// Known, north-east-down, µT (for example the World Magnetic Model at the log's place
    /// and date).
    Known(Vec3),
}

/// Which input the disturbance follows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FlightInput {
    /// Overall throttle.
    Throttle,
    /// Supply current `bat_a`.
    Current,
}

/// Settings of the flight preparation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FlightConfig {
    /// Earth field source.
    pub earth: EarthField,
    /// Input whose delay is estimated.
    pub input: FlightInput,
    /// Largest delay searched, s: the samples' age from 0 up to it, the commands' delay
    /// either way.
    pub max_delay_s: f64,
    /// Rows tilted further from level than this, degrees, are left out: a flip or a crash,
    /// where the vehicle is not flying on its motors as the model assumes.
    pub max_tilt_deg: f64,
}

impl Default for FlightConfig {
    fn default() -> Self {
        Self {
            earth: EarthField::Fit,
            input: FlightInput::Throttle,
            max_delay_s: 0.5,
            max_tilt_deg: DEFAULT_MAX_TILT_DEG,
        }
    }
}

/// Default of [`FlightConfig::max_tilt_deg`]: beyond the 30 to 70 degrees that multirotor
/// firmware lets a pilot lean (ArduPilot's ANGLE_MAX tops out at 80 degrees with 30 by
/// default), short of the 90 degrees at which a multirotor is on its side.
pub const DEFAULT_MAX_TILT_DEG: f64 = 75.0;

/// What the flight preparation found.
#[derive(Debug, Clone, PartialEq)]
pub struct FlightPrep {
    /// The stand-equivalent recording.
    pub recording: Recording,
    /// Earth field used, north-east-down, µT.
    pub earth_ned_ut: Vec3,
    /// Delay of the magnetometer behind the command stream, s: the inputs of the
    /// stand-equivalent recording are moved later by it. Negative where the commands are
    /// logged later than they act (the field changes before the logged command that causes
    /// it), searched as far that way as the other.
    pub delay_s: f64,
    /// Delay of the magnetometer behind the attitude stream, s: the age of its samples at their
    /// time stamps, by which the Earth field is turned.
    pub attitude_delay_s: f64,
    /// RMS residual of the stacked fit at that delay, µT.
    pub residual_rms_ut: f64,
    /// The eq. 9 reference the stacked fit implies: the stand-equivalent reading at input
    /// zero (sensor offset plus the Earth field at level, facing north). A log that never has
    /// every motor off (a flight logged from take-off) has no motors-off rows to average, and
    /// the fit uses this instead ([`crate::Dataset::from_recording_or`]). `None` when the
    /// input never comes near zero (its lowest value above a tenth of its highest): the
    /// reading at zero would then be an extrapolation of the cubic, and the eq. 9 reference
    /// is not to be guessed.
    pub reference_ut: Option<Vec3>,
    /// Largest tilt from level in the data, degrees, and the yaw range covered, degrees.
    pub attitude_span_deg: (f64, f64),
    /// What makes the result doubtful, in words (empty when nothing does).
    pub warnings: Vec<String>,
}

/// Input column at each row, moved later by `delay_s` (linear interpolation over the rows;
/// held at the start).
fn delayed(t: &[f64], u: &[f64], delay_s: f64) -> Vec<f64> {
    locate_increasing(t, t.iter().map(|&x| x - delay_s))
        .into_iter()
        .map(|place| interpolate(u, place))
        .collect()
}

/// The attitude at time `x`, between the logged rows (the shorter turn between neighbours;
/// held at the ends).
fn attitude_at(t: &[f64], att: &[Quat], x: f64) -> Quat {
    let (k, f) = locate(t, x);
    if f == 0.0 {
        return att[k];
    }
    // The relative turn's rotation vector is the short way round, whatever the quaternions'
    // signs.
    let step = (att[k].inverse() * att[k + 1]).scaled_axis();
    att[k] * Quat::from_scaled_axis(step * f)
}

/// The rotation from north-east-down to the body at every row's time less `delay_s` (R^T).
fn to_body_at(t: &[f64], att: &[Quat], delay_s: f64) -> Vec<Matrix3<f64>> {
    t.iter()
        .map(|&x| {
            attitude_at(t, att, x - delay_s)
                .to_rotation_matrix()
                .matrix()
                .transpose()
        })
        .collect()
}

/// Regressors of the stacked fit: per axis an offset and a cubic in the input, then the
/// Earth field (3, when fitted). The Earth field comes last so that, when the attitude does
/// not vary, the solver names one of its columns as the dependent one.
const PER_AXIS: usize = 4;

/// Fits the stacked model at one delay.
/// `to_body[r]` is the rotation from north-east-down to the body frame at row `r` (R^T),
/// computed once for every delay tried.
fn stacked(
    rec: &Recording,
    to_body: &[Matrix3<f64>],
    u: &[f64],
    earth: EarthField,
    origin: &str,
) -> Result<Stacked, IdentError> {
    let scale = u.iter().fold(0.0f64, |m, v| m.max(v.abs())).max(1e-12);
    let ne = if earth == EarthField::Fit { 3 } else { 0 };
    let p = ne + 3 * PER_AXIS;
    let row = |r: usize, a: usize, x: &mut Vec<f64>| -> f64 {
        // Row a of R^T: how the north, east and down components reach body axis a.
        let rt = &to_body[r];
        x.clear();
        x.resize(p, 0.0);
        for j in 0..ne {
            x[3 * PER_AXIS + j] = rt[(a, j)];
        }
        let q = u[r] / scale;
        let base = a * PER_AXIS;
        x[base] = 1.0;
        x[base + 1] = q;
        x[base + 2] = q * q;
        x[base + 3] = q * q * q;
        match earth {
            EarthField::Fit => rec.mag_ut[r][a],
            EarthField::Known(e) => rec.mag_ut[r][a] - (rt * e)[a],
        }
    };
    let mut ne_acc = NormalEquations::new(p, 1);
    let mut x = Vec::with_capacity(p);
    for r in 0..rec.len() {
        for a in 0..3 {
            let y = row(r, a, &mut x);
            ne_acc.add(&x, &[y], 1.0);
        }
    }
    let coef = ne_acc.solve().map_err(|e| IdentError::Singular {
        origin: origin.to_string(),
        what: "Earth field and motor disturbance of a flight".into(),
        why: match e {
            SolveError::NoData => "no rows".into(),
            SolveError::Singular { column, .. } if column >= 3 * PER_AXIS => {
                "the attitude does not vary enough to tell the Earth field from the sensor offset (fly turns, or give the Earth field: `earth`, a reference model such as the World Magnetic Model)".into()
            }
            SolveError::Singular { .. } => {
                "the input does not vary enough (fewer than four distinct levels)".into()
            }
        },
    })?;
    let mut sse = 0.0;
    // Sum of products of consecutive residuals per axis, for their lag-1 autocorrelation.
    let mut lagged = 0.0;
    let mut previous = [f64::NAN; 3];
    for r in 0..rec.len() {
        for a in 0..3 {
            let y = row(r, a, &mut x);
            let fit: f64 = x
                .iter()
                .zip(coef.column(0).iter())
                .map(|(a, b)| a * b)
                .sum();
            let e = y - fit;
            sse += e * e;
            if previous[a].is_finite() {
                lagged += e * previous[a];
            }
            previous[a] = e;
        }
    }
    let (e, var) = match earth {
        EarthField::Fit => {
            // Residual variance times the diagonal of (X^T X)^-1: how well the attitude
            // changes separate the Earth field from the offsets.
            // In flight the residual is mostly slow misfit, not white noise: the variance is
            // inflated by (1 + rho) / (1 - rho) for the residuals' lag-1 autocorrelation rho,
            // the usual effective-sample-size correction.
            let dof = (3 * rec.len()).saturating_sub(p).max(1) as f64;
            let rho = if sse > 0.0 {
                (lagged / sse).clamp(0.0, 0.99)
            } else {
                0.0
            };
            let inflation = (1.0 + rho) / (1.0 - rho);
            let var = ne_acc
                .coefficient_variances()
                .ok()
                .map(|d| Vec3::from_fn(|j, _| d[3 * PER_AXIS + j] * sse / dof * inflation));
            (Vec3::from_fn(|j, _| coef[(3 * PER_AXIS + j, 0)]), var)
        }
        EarthField::Known(e) => (e, None),
    };
    Ok(Stacked {
        earth_ned_ut: e,
        rms_ut: (sse / (3 * rec.len()) as f64).sqrt(),
        earth_var: var,
        offset_ut: Vec3::from_fn(|a, _| coef[(a * PER_AXIS, 0)]),
    })
}

/// What one stacked fit found.
#[derive(Clone, Copy)]
struct Stacked {
    /// The Earth field, north-east-down, µT.
    earth_ned_ut: Vec3,
    /// RMS residual, µT.
    rms_ut: f64,
    /// Variances of the fitted Earth field's components, when it was fitted.
    earth_var: Option<Vec3>,
    /// Per body axis, the sensor offset: the reading at input zero without the Earth field.
    offset_ut: Vec3,
}

/// Takes the Earth field out of a flight recording and estimates the stream delay.
pub fn prepare_flight(
    rec: &Recording,
    cfg: &FlightConfig,
    origin: &str,
) -> Result<FlightPrep, IdentError> {
    let data = |message: String| IdentError::Data {
        origin: origin.to_string(),
        message,
    };
    if !(cfg.max_delay_s.is_finite() && (0.0..=10.0).contains(&cfg.max_delay_s)) {
        return Err(IdentError::InvalidSetting {
            setting: crate::FitSetting::MaxDelayS,
            value: cfg.max_delay_s.to_string(),
            expected: "0..10 s".into(),
        });
    }
    if let EarthField::Known(e) = cfg.earth
        && !(e.iter().all(|v| v.is_finite()) && e.norm() > 1.0)
    {
        return Err(IdentError::InvalidSetting {
            setting: crate::FitSetting::Earth,
            value: format!("{e:?}"),
            expected: "a finite Earth field of more than 1 µT".into(),
        });
    }
    let att = rec.attitude.as_ref().ok_or_else(|| {
        data("a flight needs the attitude columns att_qw, att_qx, att_qy, att_qz (magstand import writes them)".into())
    })?;
    if rec.len() < 20 {
        return Err(data(format!(
            "{} rows; a flight fit needs at least 20",
            rec.len()
        )));
    }
    if !(cfg.max_tilt_deg.is_finite() && (0.0..=180.0).contains(&cfg.max_tilt_deg)) {
        return Err(IdentError::InvalidSetting {
            setting: crate::FitSetting::MaxTiltDeg,
            value: cfg.max_tilt_deg.to_string(),
            expected: "0..180 degrees".into(),
        });
    }
    let tilts: Vec<f64> = att.iter().map(tilt_deg).collect();
    let steep: Vec<usize> = (0..rec.len())
        .filter(|&r| tilts[r] > cfg.max_tilt_deg)
        .collect();
    if let (Some(&first), Some(&last)) = (steep.first(), steep.last()) {
        let level = rec.select_rows(|r| tilts[r] <= cfg.max_tilt_deg);
        let worst = steep.iter().map(|&r| tilts[r]).fold(0.0, f64::max);
        let note = format!(
            "{origin}: {} rows between {:.1} and {:.1} s are tilted beyond {:.0} deg (up to {worst:.0} deg: a flip or a crash) and are left out; a `max_tilt_deg` of 180 keeps them",
            steep.len(),
            rec.t_s[first],
            rec.t_s[last],
            cfg.max_tilt_deg
        );
        if level.len() < 20 {
            return Err(data(format!(
                "{note}, which leaves {} rows; a flight fit needs at least 20",
                level.len()
            )));
        }
        let all = FlightConfig {
            max_tilt_deg: 180.0,
            ..*cfg
        };
        let mut p = prepare_flight(&level, &all, origin)?;
        p.warnings.insert(0, note);
        return Ok(p);
    }
    let u: Vec<f64> = match cfg.input {
        FlightInput::Throttle => rec.overall_throttle_column(),
        FlightInput::Current => rec
            .bat_a
            .clone()
            .ok_or_else(|| data("the current `input` needs the bat_a column".into()))?,
    };
    // Grid over a delay, then golden section around the best grid point.
    let dt = rec.typical_interval_s().max(1e-6);
    let steps = ((cfg.max_delay_s / (dt / 2.0)).ceil() as usize).clamp(1, 60);
    let h = cfg.max_delay_s / steps as f64;
    // The samples' age is never negative; the commands' delay is, where they are logged later
    // than they act (the field changes before the logged command that causes it): its grid
    // runs as far the other way, with the same step.
    let search = |signed: bool, rms_at: &dyn Fn(f64) -> f64| {
        let (lo, points) = if signed {
            (-cfg.max_delay_s, 2 * steps + 1)
        } else {
            (0.0, steps + 1)
        };
        magstand_core::bounded_search::minimize(
            magstand_core::bounded_search::Grid {
                lo,
                hi: cfg.max_delay_s,
                points,
            },
            1e-4,
            20,
            rms_at,
        )
        .0
    };
    let rms = |r: Result<Stacked, IdentError>| r.map_or(f64::INFINITY, |r| r.rms_ut);
    // The fit at no delay comes first so that an error in the data is reported as such.
    let undelayed = to_body_at(&rec.t_s, att, 0.0);
    stacked(rec, &undelayed, &u, cfg.earth, origin)?;
    // The sample's age moves the attitude and the inputs together; the disturbance may lag
    // the commands further. Each delay is searched with the other held, from the two moved
    // together, until neither moves by more than a tenth of the grid step.
    let fit_at = |to_body: &[Matrix3<f64>], input: &[f64]| {
        rms(stacked(rec, to_body, input, cfg.earth, origin))
    };
    let mut attitude_delay_s = search(false, &|d| {
        fit_at(&to_body_at(&rec.t_s, att, d), &delayed(&rec.t_s, &u, d))
    });
    let mut delay_s = attitude_delay_s;
    for _ in 0..3 {
        // The held stream is turned or moved once per search, not at every delay tried.
        let held = to_body_at(&rec.t_s, att, attitude_delay_s);
        let command = search(true, &|d| fit_at(&held, &delayed(&rec.t_s, &u, d)));
        let input = delayed(&rec.t_s, &u, command);
        let attitude = search(false, &|d| fit_at(&to_body_at(&rec.t_s, att, d), &input));
        let moved = (command - delay_s)
            .abs()
            .max((attitude - attitude_delay_s).abs());
        (delay_s, attitude_delay_s) = (command, attitude);
        if moved <= 0.1 * h {
            break;
        }
    }
    let to_body = to_body_at(&rec.t_s, att, attitude_delay_s);
    let Stacked {
        earth_ned_ut: earth,
        rms_ut: rms,
        earth_var,
        offset_ut,
    } = stacked(
        rec,
        &to_body,
        &delayed(&rec.t_s, &u, delay_s),
        cfg.earth,
        origin,
    )?;

    let mut out = rec.clone();
    for m in out.thr.iter_mut() {
        *m = delayed(&rec.t_s, m, delay_s)
            .into_iter()
            .map(|v| v.clamp(0.0, 1.0))
            .collect();
    }
    // The logged supply is measured, motors' lag and all: it moves by the samples' age alone,
    // unless it is the input whose delay was searched.
    let supply_delay_s = match cfg.input {
        FlightInput::Current => delay_s,
        FlightInput::Throttle => attitude_delay_s,
    };
    if let Some(a) = out.bat_a.as_mut() {
        *a = delayed(&rec.t_s, a, supply_delay_s);
    }
    if let Some(v) = out.bat_v.as_mut() {
        *v = delayed(&rec.t_s, v, supply_delay_s);
    }
    for (r, m) in out.mag_ut.iter_mut().enumerate() {
        *m += earth - to_body[r] * earth;
    }
    if let Some(g) = out.truth.as_mut() {
        for (r, f) in g.field_ut.iter_mut().enumerate() {
            *f += earth - to_body[r] * earth;
        }
    }
    let tilt = tilts.iter().copied().fold(0.0, f64::max);
    let yaw_span = yaw_coverage_deg(att);
    let mut warnings = Vec::new();
    // The relative margin keeps rows exactly half the search apart from warning on rounding.
    // No search (a `max_delay_s` of 0) has no resolution to lack and no end to be at.
    let searched = cfg.max_delay_s > 0.0;
    if searched && dt > 0.5 * cfg.max_delay_s * (1.0 + 1e-9) {
        warnings.push(format!(
            "{origin}: the magnetometer rows are {dt:.2} s apart, so a delay below {:.2} s cannot be resolved; the delay found ({delay_s:.3} s) rests on interpolation between rows",
            cfg.max_delay_s
        ));
    }
    if let Some(var) = earth_var {
        let sd = inclination_sd_deg(earth, var);
        // Two standard errors of inclination beyond 2 degrees: the attitude changes do not
        // separate the Earth field from the offsets well enough to trust it.
        if !(2.0 * sd <= 2.0) {
            warnings.push(format!(
                "{origin}: the flight covers {yaw_span:.0} deg of heading (tilt up to {tilt:.0} deg), too little to tell the Earth field from the sensor offset: the fitted inclination {:.1} deg is uncertain by about {:.1} deg (2 standard errors); give the reference field as `earth` (the World Magnetic Model at the log's place and date)",
                earth.z.atan2(earth.xy().norm()).to_degrees(),
                2.0 * sd
            ));
        }
    }
    if searched && delay_s <= -cfg.max_delay_s + 0.5 * h {
        warnings.push(format!(
            "{origin}: the best delay is at the end of the search ({:.3} s): the commands are logged later than they act by more (raise `max_delay_s`), or the delay is not identifiable from this log",
            -cfg.max_delay_s
        ));
    }
    if searched && delay_s.max(attitude_delay_s) >= cfg.max_delay_s - 0.5 * h {
        warnings.push(format!(
            "{origin}: the best delay is at the end of the search ({:.3} s): the magnetometer lags more (raise `max_delay_s`), or the delay is not identifiable from this log",
            cfg.max_delay_s
        ));
    }
    Ok(FlightPrep {
        recording: out,
        earth_ned_ut: earth,
        delay_s,
        attitude_delay_s,
        residual_rms_ut: rms,
        reference_ut: {
            let (lo, hi) = u
                .iter()
                .fold((f64::INFINITY, 0.0f64), |(a, b), &v| (a.min(v), b.max(v)));
            (lo <= 0.1 * hi).then_some(offset_ut + earth)
        },
        attitude_span_deg: (tilt, yaw_span),
        warnings,
    })
}

/// Figures of a compensation that mean something for a turning vehicle, where the stand's
/// heading error at fixed attitude and interference percentage do not.
#[derive(Debug, Clone, PartialEq)]
pub struct FlightFigures {
    /// Standard deviation of the field's magnitude over the rows, before and after, µT: a
    /// calibrated sensor reads the same magnitude at every attitude, so what spreads it is
    /// disturbance.
    pub norm_sd_ut: (f64, f64),
    /// RMS heading error, before and after, degrees: the horizontal direction of the reading
    /// turned to north-east-down by the logged attitude, against the Earth field's.
    pub heading_rms_deg: (f64, f64),
    /// Largest heading error, before and after, degrees.
    pub heading_max_deg: (f64, f64),
    /// The Earth field the headings are judged against, north-east-down, µT.
    pub earth_ned_ut: Vec3,
    /// Where that field came from ("fitted from the recording" or the caller's).
    pub earth_source: &'static str,
}

/// Whether a recording is a flight rather than a restrained stand: `magstand import` marked
/// flight rows, or the logged attitude varies (tilt beyond 10 degrees, or heading over more than
/// 45 degrees, where a stand's attitude only trembles).
pub fn is_flight(rec: &Recording) -> bool {
    let Some(att) = rec.attitude.as_ref() else {
        return false;
    };
    let marked = rec
        .extra_column("segment")
        .is_some_and(|v| v.iter().any(|s| s == "flight"));
    let tilt = att.iter().map(tilt_deg).fold(0.0, f64::max);
    marked || tilt > 10.0 || yaw_coverage_deg(att) > 45.0
}

/// Flight figures of `after` (the compensated readings of `rec`) against `rec`'s own, over
/// the rows tilted at most [`DEFAULT_MAX_TILT_DEG`] (a flip is not flight). The
/// Earth field is `earth` when given (a reference model), else fitted from `rec` by the stacked
/// fit of [`prepare_flight`], else the mean of the compensated readings turned to
/// north-east-down.
pub fn flight_figures(
    rec: &Recording,
    after: &[Vec3],
    earth: Option<Vec3>,
    origin: &str,
) -> Result<FlightFigures, IdentError> {
    let att = rec.attitude.as_ref().ok_or_else(|| IdentError::Data {
        origin: origin.to_string(),
        message: "flight figures need the attitude columns".into(),
    })?;
    let to_ned = |r: usize, m: Vec3| att[r] * m;
    // A flip or a crash is not flight: judged rows are those the flight fit keeps.
    let rows: Vec<usize> = (0..rec.len())
        .filter(|&r| tilt_deg(&att[r]) <= DEFAULT_MAX_TILT_DEG)
        .collect();
    if rows.is_empty() {
        return Err(IdentError::Data {
            origin: origin.to_string(),
            message: format!("every row is tilted beyond {DEFAULT_MAX_TILT_DEG} deg"),
        });
    }
    let (e, source) = match earth {
        Some(e) => (e, "given"),
        None => match prepare_flight(rec, &FlightConfig::default(), origin) {
            Ok(p) => (p.earth_ned_ut, "fitted from the recording"),
            Err(_) => (
                rows.iter().map(|&r| to_ned(r, after[r])).sum::<Vec3>() / rows.len() as f64,
                "the mean compensated reading",
            ),
        },
    };
    let norm_sd = |v: &mut dyn Iterator<Item = f64>| {
        let x: Vec<f64> = v.collect();
        let mean = x.iter().sum::<f64>() / x.len() as f64;
        (x.iter().map(|n| (n - mean).powi(2)).sum::<f64>() / x.len() as f64).sqrt()
    };
    let north = e.y.atan2(e.x);
    let heading_err = |r: usize, m: Vec3| {
        let h = to_ned(r, m);
        let d = (h.y.atan2(h.x) - north).to_degrees();
        (d + 180.0).rem_euclid(360.0) - 180.0
    };
    let errors = |ms: &dyn Fn(usize) -> Vec3| -> (f64, f64) {
        let e: Vec<f64> = rows.iter().map(|&r| heading_err(r, ms(r))).collect();
        let rms = (e.iter().map(|x| x * x).sum::<f64>() / e.len() as f64).sqrt();
        (rms, e.iter().fold(0.0f64, |m, x| m.max(x.abs())))
    };
    let before = errors(&|r| rec.mag_ut[r]);
    let after_e = errors(&|r| after[r]);
    Ok(FlightFigures {
        norm_sd_ut: (
            norm_sd(&mut rows.iter().map(|&r| rec.mag_ut[r].norm())),
            norm_sd(&mut rows.iter().map(|&r| after[r].norm())),
        ),
        heading_rms_deg: (before.0, after_e.0),
        heading_max_deg: (before.1, after_e.1),
        earth_ned_ut: e,
        earth_source: source,
    })
}

/// Angle between the body's down axis and the vertical, degrees.
fn tilt_deg(q: &magstand_core::Quat) -> f64 {
    (q * Vec3::z()).angle(&Vec3::z()).to_degrees()
}

/// Standard error of the inclination of `e` (degrees) from the variances of its components,
/// by the delta method (covariances between components left out).
fn inclination_sd_deg(e: Vec3, var: Vec3) -> f64 {
    let h = e.xy().norm();
    let n2 = e.norm_squared();
    if h <= 0.0 || n2 <= 0.0 {
        return f64::INFINITY;
    }
    // I = atan2(z, h): dI/dx = -z x / (h n^2), dI/dy = -z y / (h n^2), dI/dz = h / n^2.
    let g = Vec3::new(-e.z * e.x / (h * n2), -e.z * e.y / (h * n2), h / n2);
    (g.x * g.x * var.x + g.y * g.y * var.y + g.z * g.z * var.z)
        .sqrt()
        .to_degrees()
}

/// Degrees of the compass rose covered by the headings of a set of attitudes (360 minus the
/// largest gap).
fn yaw_coverage_deg(att: &[magstand_core::Quat]) -> f64 {
    if att.is_empty() {
        return 0.0;
    }
    let mut v: Vec<f64> = att
        .iter()
        .map(|q| q.euler_angles().2.to_degrees().rem_euclid(360.0))
        .collect();
    v.sort_by(f64::total_cmp);
    let mut gap = 360.0 - (v[v.len() - 1] - v[0]);
    for w in v.windows(2) {
        gap = f64::max(gap, w[1] - w[0]);
    }
    360.0 - gap
}

#[cfg(test)]
mod tests {
    use super::*;
    use magstand_core::Quat;

    /// A synthetic flight: yawing and tilting, a known Earth field, an offset and a quadratic
    /// disturbance in a throttle that moves independently of the attitude, seen `delay_s` late.
    fn flight(delay_s: f64) -> (Recording, Vec3) {
        late_flight(0.0, delay_s)
    }

    /// [`flight`] with the magnetometer's samples `age_s` old at their stamps as well: the
    /// attitude they saw is `age_s` old, their disturbance `age_s + delay_s`.
    fn late_flight(age_s: f64, delay_s: f64) -> (Recording, Vec3) {
        let earth = Vec3::new(20.0, 2.0, 45.0);
        let b = Vec3::new(3.0, -4.0, 6.0);
        let n = 1200;
        let thr = |t: f64| 0.4 + 0.3 * (0.9 * t).sin() * (0.31 * t).cos();
        let mut rec = Recording {
            thr: vec![Vec::new()],
            attitude: Some(Vec::new()),
            ..Recording::default()
        };
        for k in 0..n {
            let t = k as f64 * 0.05;
            let q = |t: f64| {
                Quat::from_euler_angles(0.3 * (0.2 * t).sin(), 0.25 * (0.13 * t).cos(), 0.1 * t)
            };
            let u = thr(t - age_s - delay_s);
            let d = Vec3::new(8.0 * u * u, -5.0 * u, 12.0 * u * u);
            rec.t_s.push(t);
            rec.thr[0].push(thr(t));
            rec.mag_ut.push(q(t - age_s).inverse() * earth + b + d);
            rec.attitude.as_mut().unwrap().push(q(t));
        }
        (rec, earth)
    }

    #[test]
    fn recovers_earth_field_and_delay_from_a_noiseless_flight() {
        let (rec, earth) = flight(0.1);
        let p = prepare_flight(&rec, &FlightConfig::default(), "synthetic").unwrap();
        assert!(
            (p.earth_ned_ut - earth).norm() < 0.05,
            "{:?} at attitude delay {}",
            p.earth_ned_ut,
            p.attitude_delay_s
        );
        assert!(
            (p.delay_s - 0.1).abs() < 0.01,
            "{} {}",
            p.delay_s,
            p.attitude_delay_s
        );
        assert!(p.warnings.is_empty(), "{:?}", p.warnings);
        // The stand-equivalent reading no longer depends on the attitude: it is e + b + d.
        let u = p.recording.thr[0][600];
        let expect =
            earth + Vec3::new(3.0, -4.0, 6.0) + Vec3::new(8.0 * u * u, -5.0 * u, 12.0 * u * u);
        assert!(
            (p.recording.mag_ut[600] - expect).norm() < 0.1,
            "{:?} vs {expect:?}",
            p.recording.mag_ut[600]
        );
    }

    /// Asserts that a [`late_flight`] of `age_s` and `delay_s` is prepared with both delays
    /// (the attitude's `age_s`, the commands' their sum) and the Earth field recovered, and
    /// no warning.
    fn assert_both_delays_recovered(age_s: f64, delay_s: f64) {
        let (rec, earth) = late_flight(age_s, delay_s);
        let p = prepare_flight(&rec, &FlightConfig::default(), "late").unwrap();
        let command_s = age_s + delay_s;
        assert!(
            (p.attitude_delay_s - age_s).abs() < 0.01 && (p.delay_s - command_s).abs() < 0.01,
            "samples {age_s} s old, disturbance {delay_s} s behind them: attitude delay {} s \
             ({age_s} expected), command delay {} s ({command_s} expected)",
            p.attitude_delay_s,
            p.delay_s
        );
        assert!(
            (p.earth_ned_ut - earth).norm() < 0.05 && p.residual_rms_ut < 0.05,
            "{:?} vs {earth:?}, residual {} µT",
            p.earth_ned_ut,
            p.residual_rms_ut
        );
        assert!(p.warnings.is_empty(), "{:?}", p.warnings);
    }

    #[test]
    fn samples_stamped_late_move_the_attitude_and_the_commands_alike() {
        // Before the attitude was delayed too, a late stream left the Earth field's turning
        // 0.15 s out of step: tens of µT of residual at every turn, and a delay between.
        assert_both_delays_recovered(0.15, 0.05);
    }

    #[test]
    fn commands_logged_late_are_a_negative_command_delay() {
        // Commands stamped 0.15 s after they acted: the field changes before the logged
        // command that causes it. A search from zero up held the delay at zero and left the
        // timing's misfit in the stand-equivalent recording.
        assert_both_delays_recovered(0.0, -0.15);
        assert_both_delays_recovered(0.1, -0.25);
    }

    #[test]
    fn no_delay_searched_is_no_delay_and_no_warning() {
        // With the commands' delay signed, a `max_delay_s` of 0 sat at both ends of its
        // search and warned twice, and below the row spacing once more.
        let (rec, _) = late_flight(0.0, 0.0);
        let none = FlightConfig {
            max_delay_s: 0.0,
            ..FlightConfig::default()
        };
        let p = prepare_flight(&rec, &none, "on-time").unwrap();
        assert!(
            p.delay_s == 0.0 && p.attitude_delay_s == 0.0 && p.warnings.is_empty(),
            "{} {} {:?}",
            p.delay_s,
            p.attitude_delay_s,
            p.warnings
        );
    }

    #[test]
    fn a_flight_without_turns_cannot_fit_the_earth_field() {
        let (mut rec, _) = flight(0.0);
        for q in rec.attitude.as_mut().unwrap() {
            *q = Quat::identity();
        }
        let e = prepare_flight(&rec, &FlightConfig::default(), "still.csv")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("still.csv") && e.contains("attitude does not vary"),
            "{e}"
        );
        let known = FlightConfig {
            earth: EarthField::Known(Vec3::new(20.0, 2.0, 45.0)),
            ..FlightConfig::default()
        };
        assert!(prepare_flight(&rec, &known, "still.csv").is_ok());
    }

    #[test]
    fn a_delay_beyond_the_search_or_below_the_row_spacing_is_flagged() {
        // Seen 0.3 s late, or the commands logged 0.3 s late, searched up to 0.1 s either
        // way: the best delay sits at that end of the search.
        let cfg = FlightConfig {
            max_delay_s: 0.1,
            ..FlightConfig::default()
        };
        for (delay_s, says) in [
            (0.3, "the magnetometer lags more"),
            (-0.3, "logged later than they act"),
        ] {
            let (rec, _) = flight(delay_s);
            let p = prepare_flight(&rec, &cfg, "late").unwrap();
            assert!(
                p.warnings.len() == 1 && p.warnings[0].contains(says),
                "{delay_s} s: {} {:?}",
                p.delay_s,
                p.warnings
            );
        }
        let (rec, _) = flight(0.3);
        // Rows 1 s apart (as in PX4 logs at 1 Hz) cannot resolve a delay under 0.5 s.
        let sparse = rec.select_rows(|r| r % 20 == 0);
        let p = prepare_flight(&sparse, &FlightConfig::default(), "sparse").unwrap();
        assert!(
            p.warnings.iter().any(|w| w.contains("cannot be resolved")),
            "{:?}",
            p.warnings
        );
    }

    /// A flight with `yaw_amp_rad` of heading swing and `tilt_rad` of roll and pitch, read
    /// with 0.5 µT of (deterministic, pseudo-random) noise and a slow 1.5 µT drift that no
    /// model term follows (as a warming board or a wandering offset does in a real log).
    fn swinging_flight(yaw_amp_rad: f64, tilt_rad: f64) -> Recording {
        let earth = Vec3::new(20.0, 2.0, 45.0);
        let b = Vec3::new(3.0, -4.0, 6.0);
        let mut state = 0x2545_f491_4f6c_dd1d_u64;
        let mut noise = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
        };
        let mut rec = Recording {
            thr: vec![Vec::new()],
            attitude: Some(Vec::new()),
            ..Recording::default()
        };
        for k in 0..1200 {
            let t = k as f64 * 0.05;
            let q = Quat::from_euler_angles(
                tilt_rad * (0.2 * t).sin(),
                tilt_rad * (0.13 * t).cos(),
                yaw_amp_rad * (0.05 * t).sin(),
            );
            let u = 0.4 + 0.3 * (0.9 * t).sin() * (0.31 * t).cos();
            let d = Vec3::new(8.0 * u * u, -5.0 * u, 12.0 * u * u);
            let n = Vec3::new(noise(), noise(), noise()) * 1.7
                + Vec3::new(1.5, -1.0, 1.2) * (0.07 * t + 1.0).sin();
            rec.t_s.push(t);
            rec.thr[0].push(u);
            rec.mag_ut.push(q.inverse() * earth + b + d + n);
            rec.attitude.as_mut().unwrap().push(q);
        }
        rec
    }

    /// Regression: a flight that covered 8 degrees of heading fitted an inclination of 76.8
    /// degrees where the site's model gave 66.9, and nothing was said. The uncertainty of the
    /// fitted inclination is now checked and reported.
    #[test]
    fn too_little_turning_to_separate_the_earth_field_is_said() {
        let narrow = prepare_flight(
            &swinging_flight(4f64.to_radians(), 1f64.to_radians()),
            &FlightConfig::default(),
            "narrow",
        )
        .unwrap();
        assert!(
            narrow
                .warnings
                .iter()
                .any(|w| w.contains("too little to tell the Earth field") && w.contains("`earth`")),
            "{:?}",
            narrow.warnings
        );
        let wide =
            prepare_flight(&swinging_flight(3.0, 0.3), &FlightConfig::default(), "wide").unwrap();
        assert!(
            wide.warnings.iter().all(|w| !w.contains("Earth field")),
            "{:?}",
            wide.warnings
        );
        assert!(
            // The unmodelled drift moves it by about a microtesla.
            (wide.earth_ned_ut - Vec3::new(20.0, 2.0, 45.0)).norm() < 2.0,
            "{:?}",
            wide.earth_ned_ut
        );
    }

    /// Regression: rows of a flip (tilt up to 178 degrees in log171) went into the flight fit
    /// unannounced. They are now left out by default, with a warning.
    #[test]
    fn rows_of_a_flip_are_left_out_and_said() {
        let mut rec = swinging_flight(3.0, 0.3);
        let att = rec.attitude.as_mut().unwrap();
        for q in att[1100..].iter_mut() {
            *q = Quat::from_euler_angles(std::f64::consts::PI * 0.95, 0.0, 0.0);
        }
        let p = prepare_flight(&rec, &FlightConfig::default(), "flip").unwrap();
        assert_eq!(p.recording.len(), 1100);
        assert!(
            p.warnings[0].contains("100 rows") && p.warnings[0].contains("171 deg"),
            "{:?}",
            p.warnings
        );
        let keep = FlightConfig {
            max_tilt_deg: 180.0,
            ..FlightConfig::default()
        };
        assert_eq!(
            prepare_flight(&rec, &keep, "flip").unwrap().recording.len(),
            1200
        );
        let bad = FlightConfig {
            max_tilt_deg: f64::NAN,
            ..FlightConfig::default()
        };
        assert!(prepare_flight(&rec, &bad, "flip").is_err());
    }
}
