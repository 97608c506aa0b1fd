//! A model as the parameters an autopilot loads, and as code for one's own firmware.
//!
//! PX4 and ArduPilot both correct with a straight line through the origin, per axis:
//! `m_corrected = m + C * p`, where `p` is the throttle (0..1) or the battery current. So the
//! exported coefficient is minus the fitted slope. The slope is the least-squares line through
//! the origin to the full model, fitted either over the model's recorded input range (evenly
//! spaced points from zero to the largest recorded input) or, given a recording, over its rows
//! (so the line is weighted the way the vehicle was actually flown, and a throttle model can be
//! exported per ampere and a current model per unit throttle). [`LinearFit`] says what the line
//! leaves: the RMS of the model minus the line, and the worst (and 95th percentile) apparent heading error it causes
//! on the model's own motors-off field.
//!
//! Units: PX4 `CAL_MAGn_{X,Y,Z}COMP` in gauss per unit throttle (`CAL_MAG_COMP_TYP` 1) or
//! gauss per kiloampere (`CAL_MAG_COMP_TYP` 2); ArduPilot `COMPASS_MOT_{X,Y,Z}` in milligauss
//! per unit throttle (`COMPASS_MOTCT` 1) or per ampere (`COMPASS_MOTCT` 2). 1 µT = 10 mG =
//! 0.01 G. ArduPilot adds its correction after rotating the reading to the body frame (firmware
//! without per-motor compensation before the compass's soft-iron matrix); PX4 adds it to the
//! reading as the driver published it, before its calibration's rotation and scale. Where the
//! model names that frame, each autopilot's line is written in it
//! ([`magstand_core::magnetometer_frame`], [`Autopilot::compensation_frame`]).
//!
//! The other targets: [`per_motor`] (ArduPilot's `COMPASS_PMOT*`), [`firmware`] (the full
//! model as a C header or a `no_std` Rust module) and [`json`] (a table and every figure, for
//! other tools).
use magstand_core::magnetometer_frame::SensorToBody;
use magstand_core::magnetometer_slot::MagnetometerSlot;
use magstand_core::{AXES, Recording, Vec3};
use magstand_ident::compatibility::ardupilot_interference_pct;
use magstand_ident::metrics::{heading_deg, heading_difference_deg, percentile};
use magstand_ident::{InputKind, Model};

use crate::LogsError;

pub mod adaptive_code;
pub mod firmware;
pub mod json;
pub mod per_motor;

pub use adaptive_code::{c_adaptive, rust_adaptive};
pub use firmware::{c_header, rust_module};

/// Points over the recorded range at which the line is fitted and judged.
const GRID: usize = 201;

/// What the autopilot's line multiplies.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LineInput {
    /// Overall throttle, 0..1 (PX4 `CAL_MAG_COMP_TYP` 1, ArduPilot `COMPASS_MOTCT` 1).
    Throttle,
    /// Battery current, A (PX4 `CAL_MAG_COMP_TYP` 2, ArduPilot `COMPASS_MOTCT` 2).
    Current,
}

impl LineInput {
    /// The input a model is fitted on, as a line input (a per-motor model's is the throttle).
    pub fn of(model: &Model) -> Self {
        match model.input.kind {
            InputKind::Current => LineInput::Current,
            InputKind::Throttle | InputKind::Motors => LineInput::Throttle,
        }
    }

    fn unit(self) -> &'static str {
        match self {
            LineInput::Current => "uT/A",
            LineInput::Throttle => "uT per unit throttle",
        }
    }
}

/// Where the line is fitted and judged.
#[derive(Clone, Copy)]
pub enum Span<'a> {
    /// Where the model was identified: the 21 quantiles of its identification rows' input
    /// (each standing for 5 % of the rows, so the line is fitted the way the vehicle was run),
    /// or, for a model file without them, evenly spaced inputs from zero to the top of its
    /// input range.
    ModelRange,
    /// The rows of a recording (its commands, and `bat_a` for a current line).
    Rows {
        /// The recording.
        recording: &'a Recording,
        /// Its name, for errors.
        origin: &'a str,
    },
}

/// The best straight line through the origin to a model, and what it costs.
#[derive(Debug, Clone, PartialEq)]
pub struct LinearFit {
    /// Input of the line.
    pub input: LineInput,
    /// Largest input of the range the line was fitted over (throttle, or amperes).
    pub range_max: f64,
    /// Slope per axis, µT per unit throttle or per ampere.
    pub slope: [f64; 3],
    /// RMS over the range of the full model minus the line, per axis, µT.
    pub rms_left_ut: [f64; 3],
    /// Worst apparent heading error the line leaves over the range, degrees, on the model's
    /// motors-off field.
    pub worst_heading_deg: f64,
    /// The same with no compensation at all, for comparison.
    pub uncompensated_heading_deg: f64,
    /// The 95th percentile of the apparent heading error the line leaves, degrees.
    pub p95_heading_deg: f64,
    /// The same with no compensation at all.
    pub uncompensated_p95_heading_deg: f64,
}

impl LinearFit {
    /// The line with its slopes in the frame an autopilot adds its compensation in: each
    /// body-frame slope mapped back through `frame`, the transform from that frame to the body
    /// frame ([`Autopilot::compensation_frame`]); the line as it is where there is none or it
    /// is the identity. The other figures describe the line's fit, which the frame does not
    /// change.
    pub fn in_frame(&self, frame: Option<&SensorToBody>) -> Result<LinearFit, LogsError> {
        let Some(frame) = frame.filter(|f| !f.is_identity()) else {
            return Ok(self.clone());
        };
        let slope = frame.to_sensor(Vec3::from(self.slope)).ok_or_else(|| {
            LogsError::Export(format!(
                "the slopes {:?} could not be mapped back through the sensor-to-body matrix {frame}",
                self.slope
            ))
        })?;
        Ok(LinearFit {
            slope: slope.into(),
            ..self.clone()
        })
    }

    /// ArduPilot compassmot's interference figure for this line: the field change at the top
    /// of the range in percent of 530 mG (compassmot's own reference). ArduPilot's guidance:
    /// below 30 % fine, 30-60 % a grey zone, above 60 % unacceptable.
    pub fn ardupilot_interference_pct(&self) -> f64 {
        ardupilot_interference_pct(Vec3::from(self.slope) * self.range_max)
    }
}

/// Inputs and model disturbances at which an approximation is fitted and judged.
pub(crate) struct Samples {
    /// The line's input at each sample.
    pub x: Vec<f64>,
    /// The full model's disturbance at each sample, µT.
    pub dist: Vec<Vec3>,
}

/// The apparent heading error over samples on the model's motors-off field, for a correction
/// that leaves `left(k)` of the disturbance at sample k, degrees: the worst, and the 95th
/// percentile ([`percentile`], as a study's). Over a recording's rows the worst is often a transient no line
/// can follow (the motors spinning down after the commands fell to zero, where a line in the
/// command corrects nothing), so it can read the same with a line and without one; the
/// percentile says what most of the rows keep.
pub(crate) fn heading_errors_deg(
    reference: Vec3,
    n: usize,
    left: impl Fn(usize) -> Vec3,
) -> HeadingErrors {
    let h0 = heading_deg(reference, None);
    let mut errors: Vec<f64> = (0..n)
        .map(|k| heading_difference_deg(heading_deg(reference + left(k), None), h0).abs())
        .collect();
    errors.sort_by(f64::total_cmp);
    HeadingErrors {
        worst_deg: errors.last().copied().unwrap_or(0.0),
        p95_deg: if errors.is_empty() {
            0.0
        } else {
            percentile(&errors, 0.95)
        },
    }
}

/// The apparent heading errors a correction leaves over samples ([`heading_errors_deg`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct HeadingErrors {
    /// The worst, degrees.
    pub(crate) worst_deg: f64,
    /// The 95th percentile, degrees.
    pub(crate) p95_deg: f64,
}

/// The model at [`GRID`] evenly spaced raw inputs from zero to the top of its recorded range;
/// `purpose` names what needs them in the error for an empty range.
pub(crate) fn range_samples(model: &Model, purpose: &str) -> Result<Samples, LogsError> {
    let hi = model.input.hi;
    if !(hi.is_finite() && hi > 0.0) {
        return Err(LogsError::Export(format!(
            "the model's input range ends at {hi}; {purpose} needs a positive range"
        )));
    }
    Ok(Samples::at(
        model,
        (0..GRID)
            .map(|i| hi * i as f64 / (GRID - 1) as f64)
            .collect(),
    ))
}

impl Samples {
    /// The model's disturbance at the raw inputs `x`.
    fn at(model: &Model, x: Vec<f64>) -> Self {
        let mut s = model.scratch();
        let dist = x.iter().map(|&v| model.dist_at_input(v, &mut s)).collect();
        Samples { x, dist }
    }
}

fn samples(model: &Model, input: LineInput, span: Span) -> Result<Samples, LogsError> {
    match span {
        Span::ModelRange => {
            if input != LineInput::of(model) {
                return Err(LogsError::Export(format!(
                    "the model's input is {:?}; a line per {} needs the recording it applies to (a `recording`{})",
                    model.input.kind,
                    match input {
                        LineInput::Current => "ampere",
                        LineInput::Throttle => "unit throttle",
                    },
                    match input {
                        LineInput::Current => ", with a bat_a column",
                        LineInput::Throttle => "",
                    }
                )));
            }
            match &model.identified {
                // The quantiles of the identification inputs, in raw units.
                Some(r) => Ok(Samples::at(
                    model,
                    r.quantiles
                        .iter()
                        .map(|&q| model.input.denormalize(q))
                        .collect(),
                )),
                None => range_samples(model, "a line"),
            }
        }
        Span::Rows { recording, origin } => {
            model
                .input
                .check_recording(recording, origin)
                .map_err(|e| LogsError::Export(e.to_string()))?;
            let x = input_column(recording, origin, input)?;
            Ok(Samples {
                x,
                dist: model.dist_column(recording),
            })
        }
    }
}

/// Fits the line through the origin to the model along `input` over `span`. Per-motor models
/// are evaluated with every motor at the same command over the model range, and at each row's
/// own commands over a recording.
pub fn linear_approximation(
    model: &Model,
    input: LineInput,
    span: Span,
) -> Result<LinearFit, LogsError> {
    let Samples { x, dist } = samples(model, input, span)?;
    line_through(&x, &dist, Vec3::from(model.reference_ut), input)
}

/// The line through the origin of any model's predicted disturbance `dist_ut` at the rows of
/// `rec` (named `origin`) along `input`: what [`linear_approximation`] does over a recording,
/// for a model that predicts from the recording's commands (the stand's physics).
/// `reference_ut` is the model's motors-off field, for the heading figures.
pub fn line_over_prediction(
    dist_ut: &[Vec3],
    reference_ut: Vec3,
    rec: &Recording,
    origin: &str,
    input: LineInput,
) -> Result<LinearFit, LogsError> {
    let x = input_column(rec, origin, input)?;
    line_through(&x, dist_ut, reference_ut, input)
}

/// The line's input at each row of `rec` (named `origin`). The throttle is the autopilot's
/// own where the import wrote it ([`magstand_core::AUTOPILOT_THROTTLE`]): the thrust demand
/// the autopilot's compensation multiplies, which its thrust curve maps to the motor commands;
/// otherwise the mean motor command, which is the stand's throttle. The current is `bat_a`.
pub fn input_column(
    rec: &Recording,
    origin: &str,
    input: LineInput,
) -> Result<Vec<f64>, LogsError> {
    match input {
        LineInput::Throttle => Ok(rec
            .autopilot_throttle(std::path::Path::new(origin))
            .map_err(|e| LogsError::Export(e.to_string()))?
            .unwrap_or_else(|| rec.overall_throttle_column())),
        LineInput::Current => rec.bat_a.clone().ok_or_else(|| {
            LogsError::Export(format!(
                "{origin}: a line per ampere needs the supply current, but the recording has no `bat_a` column"
            ))
        }),
    }
}

/// The least-squares line through the origin of `dist` against `x`, checked for the autopilots'
/// range, with what it leaves.
fn line_through(
    x: &[f64],
    dist: &[Vec3],
    reference: Vec3,
    input: LineInput,
) -> Result<LinearFit, LogsError> {
    let n = x.len();
    let sxx: f64 = x.iter().map(|v| v * v).sum();
    let range_max = x.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    if !(sxx.is_finite() && sxx > 0.0) {
        return Err(LogsError::Export(format!(
            "the {input:?} input is zero (or not finite) everywhere in the range; no line can be fitted"
        )));
    }
    let slope: [f64; 3] =
        std::array::from_fn(|a| x.iter().zip(dist).map(|(v, d)| v * d[a]).sum::<f64>() / sxx);
    // A firmware parameter is the worst place for a wrong number: the slope must be finite
    // and inside ArduPilot's documented COMPASS_MOT range (+-1000 mG per unit throttle or per
    // A; the same field per unit is PX4's +-1 G or +-1000 G/kA).
    if let Some(a) =
        (0..3).find(|&a| !(slope[a].is_finite() && (slope[a] * 10.0).abs() <= MAX_COMPASS_MOT_MG))
    {
        return Err(LogsError::Export(format!(
            "the line's {} slope is {:e} {}: outside the +-{MAX_COMPASS_MOT_MG} mG per unit the autopilots accept; the model does not describe a real vehicle (check the model file)",
            ["x", "y", "z"][a],
            slope[a],
            input.unit()
        )));
    }
    let line = Vec3::from(slope);
    let rms_left_ut = std::array::from_fn(|a| {
        (x.iter()
            .zip(dist)
            .map(|(v, d)| (d[a] - slope[a] * v).powi(2))
            .sum::<f64>()
            / n as f64)
            .sqrt()
    });
    let with_line = heading_errors_deg(reference, n, |k| dist[k] - line * x[k]);
    let without = heading_errors_deg(reference, n, |k| dist[k]);
    Ok(LinearFit {
        input,
        range_max,
        slope,
        rms_left_ut,
        worst_heading_deg: with_line.worst_deg,
        uncompensated_heading_deg: without.worst_deg,
        p95_heading_deg: with_line.p95_deg,
        uncompensated_p95_heading_deg: without.p95_deg,
    })
}

/// ArduPilot's documented range of `COMPASS_MOT_{X,Y,Z}`, mG per unit throttle or per A.
pub const MAX_COMPASS_MOT_MG: f64 = 1000.0;

/// An autopilot's parameter values for a line: the type parameter and the three coefficients,
/// in the autopilot's units and sign.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AutopilotLine {
    /// `CAL_MAG_COMP_TYP` (PX4) or `COMPASS_MOTCT` (ArduPilot): 1 throttle, 2 current.
    pub kind: u8,
    /// Coefficients per axis: minus the slope, in G per unit throttle or per kA (PX4), mG per
    /// unit throttle or per A (ArduPilot).
    pub coefficients: [f64; 3],
}

impl LinearFit {
    /// PX4's `CAL_MAG_COMP_TYP` and `CAL_MAGn_{X,Y,Z}COMP`.
    pub fn px4(&self) -> AutopilotLine {
        // Gauss per unit throttle, or gauss per kA from µT per A.
        let (kind, scale) = match self.input {
            LineInput::Current => (2, 0.01 * 1000.0),
            LineInput::Throttle => (1, 0.01),
        };
        AutopilotLine {
            kind,
            coefficients: self.slope.map(|s| -s * scale),
        }
    }

    /// ArduPilot's `COMPASS_MOTCT` and `COMPASS_MOT_{X,Y,Z}`.
    pub fn ardupilot(&self) -> AutopilotLine {
        AutopilotLine {
            kind: match self.input {
                LineInput::Current => 2,
                LineInput::Throttle => 1,
            },
            coefficients: self.slope.map(|s| -s * 10.0),
        }
    }
}

/// An autopilot whose straight-line compensation magstand exports.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Autopilot {
    /// PX4 power compensation: `CAL_MAG_COMP_TYP`, `CAL_MAGn_{X,Y,Z}COMP` (n from 0 to 3).
    Px4,
    /// ArduPilot compassmot: `COMPASS_MOTCT`, `COMPASS_MOT{,2,3}_{X,Y,Z}` (compass 1 to 3).
    ArduPilot,
}

impl Autopilot {
    /// The frame this autopilot adds a magnetometer's compensation in, as the transform to
    /// the body frame of a model fitted on it: `frame` (the model's `magnetometer_to_body`)
    /// where the model's magnetometer `slot` is this autopilot's or is not named; None (the
    /// body frame) where it is the other autopilot's, whose frame says nothing of this one's.
    pub fn compensation_frame(
        self,
        slot: Option<MagnetometerSlot>,
        frame: Option<SensorToBody>,
    ) -> Option<SensorToBody> {
        match (self, slot) {
            (Autopilot::Px4, Some(MagnetometerSlot::ArduPilotCompass(_)))
            | (Autopilot::ArduPilot, Some(MagnetometerSlot::Px4CalMag(_))) => None,
            _ => frame,
        }
    }

    /// The magnetometer instances the autopilot numbers.
    pub fn instances(self) -> std::ops::RangeInclusive<usize> {
        match self {
            Autopilot::Px4 => 0..=3,
            Autopilot::ArduPilot => 1..=3,
        }
    }

    /// The parameter names for magnetometer `instance`: the type, then x, y and z.
    pub fn parameter_names(self, instance: usize) -> [String; 4] {
        match self {
            Autopilot::Px4 => [
                "CAL_MAG_COMP_TYP".into(),
                format!("CAL_MAG{instance}_XCOMP"),
                format!("CAL_MAG{instance}_YCOMP"),
                format!("CAL_MAG{instance}_ZCOMP"),
            ],
            Autopilot::ArduPilot => {
                let suffix = crate::ardupilot::compass_suffix(instance);
                [
                    "COMPASS_MOTCT".into(),
                    format!("COMPASS_MOT{suffix}_X"),
                    format!("COMPASS_MOT{suffix}_Y"),
                    format!("COMPASS_MOT{suffix}_Z"),
                ]
            }
        }
    }

    /// The parameters for `line` on magnetometer `instance`, named as in
    /// [`parameter_names`](Self::parameter_names), with the values the parameter file holds
    /// (rounded as written there).
    pub fn parameters(self, line: &LinearFit, instance: usize) -> [(String, f64); 4] {
        let (p, digits) = match self {
            Autopilot::Px4 => (line.px4(), 6),
            Autopilot::ArduPilot => (line.ardupilot(), 3),
        };
        let written = |v: f64| -> f64 {
            format!("{v:.digits$}")
                .parse()
                .expect("a formatted finite number parses")
        };
        let [kind, x, y, z] = self.parameter_names(instance);
        [
            (kind, f64::from(p.kind)),
            (x, written(p.coefficients[0])),
            (y, written(p.coefficients[1])),
            (z, written(p.coefficients[2])),
        ]
    }
}

/// PX4 parameters in the QGroundControl parameter-file format, for magnetometer `instance`.
///
/// `frame` is the transform that took the magnetometer's readings to the body frame the line
/// was fitted in (a model's `magnetometer_to_body`): PX4 adds its compensation to the reading
/// before its calibration's rotation and scale, so the coefficients are written in the
/// sensor's own frame, `−frame⁻¹ · slope`. Without it the sensor is taken to read in the body
/// frame (a test stand's magnetometer, or a calibration without rotation or scale).
pub fn px4_params(
    line: &LinearFit,
    instance: usize,
    frame: Option<&SensorToBody>,
) -> Result<String, LogsError> {
    let (power, unit) = match line.input {
        LineInput::Current => ("current (battery 0)", "G/kA"),
        LineInput::Throttle => ("throttle", "G per unit throttle"),
    };
    let frame_note = match frame.filter(|f| !f.is_identity()) {
        Some(f) => format!(
            "# In the sensor's own frame, where PX4 adds them: the body-frame slopes mapped back\n\
             # through the calibration's rotation and scale the log had (sensor to body,\n\
             # row by row: {f}). A new calibration leaves them as they are.\n"
        ),
        None => "# In the body frame: PX4 adds them in the sensor's own frame, which this is where the\n\
                 # sensor's calibration has no rotation or scale (the model names none).\n"
            .to_string(),
    };
    let [(kind_name, kind), coefficients @ ..] =
        Autopilot::Px4.parameters(&line.in_frame(frame)?, instance);
    let mut out = format!(
        "# PX4 magnetometer power compensation exported by magstand {}\n\
         # {kind_name} {kind}: {power}; coefficients in {unit}, minus the fitted slope\n\
         # (PX4 corrects with mag + coefficient x power).\n\
         {frame_note}\
         # CAL_MAG_COMP_TYP is shared by every magnetometer: another one's CAL_MAGn_*COMP on\n\
         # the vehicle must be in these units (fitted on the same input) or 0.\n\
         # Vehicle-Id\tComponent-Id\tName\tValue\tType\n\
         1\t1\t{kind_name}\t{kind}\t6\n",
        env!("CARGO_PKG_VERSION"),
    );
    for (name, value) in coefficients {
        out += &format!("1\t1\t{name}\t{value:.6}\t9\n");
    }
    Ok(out)
}

/// ArduPilot parameters as a `.param` file (`NAME,VALUE` lines) for compass `instance` (1, 2
/// or 3).
///
/// `frame` is the compass's soft-iron matrix where the firmware adds its compensation before
/// it (firmware without per-motor compensation; a model's `magnetometer_to_body` of an
/// ArduPilot log): the coefficients are then `−frame⁻¹ · slope`. Later firmware adds it to the
/// field the log records, and takes minus the slope.
pub fn ardupilot_params(
    line: &LinearFit,
    instance: usize,
    frame: Option<&SensorToBody>,
) -> Result<String, LogsError> {
    let (power, unit) = match line.input {
        LineInput::Current => ("current", "mG per A"),
        LineInput::Throttle => ("throttle", "mG per unit throttle"),
    };
    let frame_note = frame
        .filter(|f| !f.is_identity())
        .map(|f| {
            format!(
                "# Mapped back through the compass's soft-iron matrix ({f}, row by row): this\n\
                 # firmware adds its compensation before that matrix.\n"
            )
        })
        .unwrap_or_default();
    let [(kind_name, kind), coefficients @ ..] =
        Autopilot::ArduPilot.parameters(&line.in_frame(frame)?, instance);
    let mut out = format!(
        "# ArduPilot compassmot parameters exported by magstand {}; {unit}, minus the fitted slope\n\
         # (ArduPilot corrects with field + COMPASS_MOT x {power}).\n\
         {frame_note}\
         # COMPASS_MOTCT is shared by every compass: another one's COMPASS_MOT* on the vehicle\n\
         # must be in these units (fitted on the same input) or 0.\n\
         {kind_name},{kind}\n",
        env!("CARGO_PKG_VERSION"),
    );
    for (name, value) in coefficients {
        out += &format!("{name},{value:.3}\n");
    }
    Ok(out)
}

/// One line per axis of what the line leaves, and the autopilots' own figures, for the
/// terminal.
pub fn describe(line: &LinearFit) -> String {
    let mut out = format!(
        "best line through the origin over 0..{:.3} ({}):\n",
        line.range_max,
        line.input.unit()
    );
    for (a, axis) in AXES.iter().enumerate() {
        out += &format!(
            "  {axis}: slope {:9.4}, leaves {:.3} uT RMS of the full model\n",
            line.slope[a], line.rms_left_ut[a]
        );
    }
    out += &format!(
        "apparent heading error, worst / 95th percentile: {:.2} / {:.2} deg uncompensated, {:.2} / {:.2} deg with the line, 0 with the full model\n\
         ArduPilot compassmot interference at the top of the range: {:.0} % of 530 mG (ArduPilot: <30 % fine, 30-60 % grey zone, >60 % unacceptable)\n",
        line.uncompensated_heading_deg,
        line.uncompensated_p95_heading_deg,
        line.worst_heading_deg,
        line.p95_heading_deg,
        line.ardupilot_interference_pct()
    );
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A disturbance across a northward field of 20 µT that turns its heading by 1, 2, .. 80
    /// degrees at samples 0 .. 79: the worst is 80 degrees and the 95th percentile 76.05
    /// (0.05 of the way from the 76th of 80 to the 77th).
    #[test]
    fn heading_errors_are_the_worst_and_the_95th_percentile() {
        let reference = Vec3::new(20.0, 0.0, 40.0);
        let across = |k: usize| Vec3::new(0.0, 20.0 * ((k + 1) as f64).to_radians().tan(), 0.0);
        let e = heading_errors_deg(reference, 80, across);
        assert!((e.worst_deg - 80.0).abs() < 1e-9, "{e:?}");
        assert!((e.p95_deg - 76.05).abs() < 1e-9, "{e:?}");
        // In reverse order, the same figures; none for no samples.
        assert_eq!(heading_errors_deg(reference, 80, |k| across(79 - k)), e);
        let none = heading_errors_deg(reference, 0, across);
        assert_eq!((none.worst_deg, none.p95_deg), (0.0, 0.0));
    }
}
