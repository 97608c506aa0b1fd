//! The model for other tools: a versioned JSON document with a table of the full model over its
//! input range and every exported figure.
//!
//! # Format (`magstand-export`, version 1)
//!
//! ```text
//! {
//!   "format": "magstand-export", "version": 1, "generator": "magstand 0.1.0",
//!   "model": {"method": "...", "input": "throttle"|"motors"|"current", "input_unit": "1"|"A",
//!             "reference_ut": [x, y, z],
//!             "magnetometer": "px4:N"|"ardupilot:N",    // absent where the model does not
//!                                                   // say: the sensor whose parameters the
//!                                                   // lines below are (CAL_MAGn, compass n;
//!                                                   // the keys are named as compass 1's)
//!             "magnetometer_to_body": [[..], [..], [..]]}, // absent where the model does not
//!                                                   // say: the matrix that took the sensor's
//!                                                   // readings to the body frame (PX4), or the
//!                                                   // soft-iron matrix older ArduPilot adds its
//!                                                   // compensation before: the coefficients of
//!                                                   // that autopilot are mapped back through it
//!   "table": {"input": [...],                       // 201 raw inputs, 0 .. top of range
//!             "dist_ut": [[...], [...], [...]],     // disturbance per axis (every motor at
//!                                                   // the same command for a per-motor model)
//!             "sd_ut": [[...], [...], [...]] | null},
//!   "linear": {"input": "throttle"|"current", "range_max": r, "slope_ut": [x, y, z],
//!              "rms_left_ut": [x, y, z], "worst_heading_deg": h, "uncompensated_heading_deg": h0,
//!              "p95_heading_deg": p, "uncompensated_p95_heading_deg": p0, // 95th percentiles
//!              "ardupilot_interference_pct": p,
//!              "px4": {"CAL_MAG_COMP_TYP": 1|2, "XCOMP": .., "YCOMP": .., "ZCOMP": ..},
//!              "ardupilot": {"COMPASS_MOTCT": 1|2, "COMPASS_MOT_X": .., "COMPASS_MOT_Y": ..,
//!                            "COMPASS_MOT_Z": ..}},
//!   "per_motor": {"COMPASS_PMOT_EXP": e, "compensation_mg": [[x, y, z], ...],
//!                 "rms_left_ut": [x, y, z], "worst_heading_deg": h, "p95_heading_deg": p} | null
//! }
//! ```
use serde::Serialize;
use std::collections::BTreeMap;

use magstand_ident::{InputKind, Model};

use super::per_motor::PerMotorFit;
use super::{Autopilot, LineInput, LinearFit, Samples, range_samples};
use crate::LogsError;

/// Format name of the document.
pub const FORMAT: &str = "magstand-export";
/// Document version.
pub const VERSION: u32 = 1;

#[derive(Serialize)]
struct Document<'a> {
    format: &'static str,
    version: u32,
    generator: String,
    model: ModelInfo<'a>,
    table: Table,
    linear: Linear,
    per_motor: Option<PerMotor>,
}

#[derive(Serialize)]
struct ModelInfo<'a> {
    method: &'a str,
    input: &'static str,
    input_unit: &'static str,
    reference_ut: [f64; 3],
    #[serde(skip_serializing_if = "Option::is_none")]
    magnetometer: Option<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    magnetometer_to_body: Option<[[f64; 3]; 3]>,
}

#[derive(Serialize)]
struct Table {
    input: Vec<f64>,
    dist_ut: [Vec<f64>; 3],
    sd_ut: Option<[Vec<f64>; 3]>,
}

#[derive(Serialize)]
struct Linear {
    input: &'static str,
    range_max: f64,
    slope_ut: [f64; 3],
    rms_left_ut: [f64; 3],
    worst_heading_deg: f64,
    uncompensated_heading_deg: f64,
    p95_heading_deg: f64,
    uncompensated_p95_heading_deg: f64,
    ardupilot_interference_pct: f64,
    px4: BTreeMap<&'static str, f64>,
    ardupilot: BTreeMap<&'static str, f64>,
}

#[derive(Serialize)]
struct PerMotor {
    #[serde(rename = "COMPASS_PMOT_EXP")]
    expo: f64,
    compensation_mg: Vec<[f64; 3]>,
    rms_left_ut: [f64; 3],
    worst_heading_deg: f64,
    p95_heading_deg: f64,
}

/// The document for a model, its line and (when fitted) ArduPilot's per-motor form.
pub fn export_json(
    model: &Model,
    line: &LinearFit,
    per_motor: Option<&PerMotorFit>,
) -> Result<String, LogsError> {
    let Samples { x: input, dist } = range_samples(model, "the table")?;
    let column = |v: &[magstand_core::Vec3], a: usize| v.iter().map(|d| d[a]).collect::<Vec<_>>();
    let sd = model.sd.as_ref().map(|m| {
        let v: Vec<_> = input
            .iter()
            .map(|&r| m.sd(model.input.normalize(r)))
            .collect();
        std::array::from_fn(|a| column(&v, a))
    });
    // Each autopilot's coefficients in the frame it adds them in (see `px4_params`).
    let in_frame = |autopilot: Autopilot| {
        line.in_frame(
            autopilot
                .compensation_frame(model.magnetometer, model.magnetometer_to_body)
                .as_ref(),
        )
    };
    let (px4, ap) = (
        in_frame(Autopilot::Px4)?.px4(),
        in_frame(Autopilot::ArduPilot)?.ardupilot(),
    );
    let doc = Document {
        format: FORMAT,
        version: VERSION,
        generator: format!("magstand {}", env!("CARGO_PKG_VERSION")),
        model: ModelInfo {
            method: &model.method,
            input: match model.input.kind {
                InputKind::Throttle => "throttle",
                InputKind::Motors => "motors",
                InputKind::Current => "current",
            },
            input_unit: match model.input.kind {
                InputKind::Current => "A",
                _ => "1",
            },
            reference_ut: model.reference_ut,
            magnetometer: model.magnetometer.map(|m| m.to_string()),
            magnetometer_to_body: model.magnetometer_to_body.map(|f| f.rows()),
        },
        table: Table {
            dist_ut: std::array::from_fn(|a| column(&dist, a)),
            input,
            sd_ut: sd,
        },
        linear: Linear {
            input: match line.input {
                LineInput::Throttle => "throttle",
                LineInput::Current => "current",
            },
            range_max: line.range_max,
            slope_ut: line.slope,
            rms_left_ut: line.rms_left_ut,
            worst_heading_deg: line.worst_heading_deg,
            uncompensated_heading_deg: line.uncompensated_heading_deg,
            p95_heading_deg: line.p95_heading_deg,
            uncompensated_p95_heading_deg: line.uncompensated_p95_heading_deg,
            ardupilot_interference_pct: line.ardupilot_interference_pct(),
            px4: BTreeMap::from([
                ("CAL_MAG_COMP_TYP", px4.kind as f64),
                ("XCOMP", px4.coefficients[0]),
                ("YCOMP", px4.coefficients[1]),
                ("ZCOMP", px4.coefficients[2]),
            ]),
            ardupilot: BTreeMap::from([
                ("COMPASS_MOTCT", ap.kind as f64),
                ("COMPASS_MOT_X", ap.coefficients[0]),
                ("COMPASS_MOT_Y", ap.coefficients[1]),
                ("COMPASS_MOT_Z", ap.coefficients[2]),
            ]),
        },
        per_motor: per_motor.map(|p| PerMotor {
            expo: p.expo,
            compensation_mg: p.compensation_mg.clone(),
            rms_left_ut: p.rms_left_ut,
            worst_heading_deg: p.worst_heading_deg,
            p95_heading_deg: p.p95_heading_deg,
        }),
    };
    serde_json::to_string_pretty(&doc)
        .map(|mut t| {
            t.push('\n');
            t
        })
        .map_err(|e| LogsError::Export(format!("writing JSON: {e}")))
}
