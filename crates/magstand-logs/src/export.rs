//! A model as the parameters an autopilot loads, and as code for one's own firmware.
//!
//! PX4 and ArduPilot both correct with a straight line through the origin, per axis:
//! `m_corrected = m + C * p`, where `p` is the throttle (0..1) or the battery current. So the
//! exported coefficient is minus the fitted slope. The slope is the least-squares line through
//! the origin to the full model over the recorded input range (evenly spaced points from zero
//! to the largest recorded input), and [`LinearFit`] says what that line leaves: the RMS of the
//! model minus the line over the range, and the worst apparent heading error it causes on the
//! model's own motors-off field.
//!
//! Units: PX4 `CAL_MAGn_{X,Y,Z}COMP` in gauss per unit throttle (`CAL_MAG_COMP_TYP` 1) or
//! gauss per kiloampere (`CAL_MAG_COMP_TYP` 2); ArduPilot `COMPASS_MOT_{X,Y,Z}` in milligauss
//! per unit throttle (`COMPASS_MOTCT` 1) or per ampere (`COMPASS_MOTCT` 2). 1 µT = 10 mG =
//! 0.01 G. Both apply the correction in the sensor frame before the board rotation; a model
//! fitted on body-frame data matches when the sensor is mounted without rotation.
use magstand_core::{AXES, Vec3};
use magstand_ident::metrics::{heading_deg, heading_difference_deg};
use magstand_ident::{InputKind, Model, Structure};

use crate::LogsError;

/// Points over the recorded range at which the line is fitted and judged.
const GRID: usize = 201;

/// The best straight line through the origin to a model, and what it costs.
#[derive(Debug, Clone, PartialEq)]
pub struct LinearFit {
    /// Input of the line: overall throttle (0..1) or supply current (A).
    pub input: InputKind,
    /// Largest input of the range the line was fitted over (1 for throttle; amperes).
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
}

/// Fits the line. Per-motor models are evaluated with every motor at the same command.
pub fn linear_approximation(model: &Model) -> Result<LinearFit, LogsError> {
    let spec = &model.input;
    let input = match spec.kind {
        InputKind::Current => InputKind::Current,
        InputKind::Throttle | InputKind::Motors => InputKind::Throttle,
    };
    let range_max = spec.hi;
    if !(range_max.is_finite() && range_max > 0.0) {
        return Err(LogsError::Export(format!(
            "the model's input range ends at {range_max}; a line needs a positive range"
        )));
    }
    let mut s = model.scratch();
    let points: Vec<(f64, Vec3)> = (0..GRID)
        .map(|i| {
            let x = range_max * i as f64 / (GRID - 1) as f64;
            (x, model.dist_at_input(x, &mut s))
        })
        .collect();
    let sxx: f64 = points.iter().map(|(x, _)| x * x).sum();
    let slope: [f64; 3] =
        std::array::from_fn(|a| points.iter().map(|(x, d)| x * d[a]).sum::<f64>() / sxx);
    let rms_left_ut = std::array::from_fn(|a| {
        (points
            .iter()
            .map(|(x, d)| (d[a] - slope[a] * x).powi(2))
            .sum::<f64>()
            / GRID as f64)
            .sqrt()
    });
    let reference = Vec3::from(model.reference_ut);
    let h0 = heading_deg(reference, None);
    let worst = |f: &dyn Fn(f64, Vec3) -> Vec3| {
        points
            .iter()
            .map(|(x, d)| heading_difference_deg(heading_deg(f(*x, *d), None), h0).abs())
            .fold(0.0, f64::max)
    };
    let line = Vec3::from(slope);
    Ok(LinearFit {
        input,
        range_max,
        slope,
        rms_left_ut,
        worst_heading_deg: worst(&|x, d| reference + d - line * x),
        uncompensated_heading_deg: worst(&|_, d| reference + d),
    })
}

/// PX4 parameters in the QGroundControl parameter-file format, for magnetometer `instance`.
pub fn px4_params(line: &LinearFit, instance: usize) -> String {
    // Gauss per unit throttle, or gauss per kA from µT per A.
    let (typ, scale, unit) = match line.input {
        InputKind::Current => (2, 0.01 * 1000.0, "G/kA"),
        _ => (1, 0.01, "G per unit throttle"),
    };
    let mut out = format!(
        "# PX4 magnetometer power compensation exported by magstand {}\n\
         # CAL_MAG_COMP_TYP {typ}: {}; coefficients in {unit}, minus the fitted slope\n\
         # (PX4 corrects with mag + coefficient x power).\n\
         # Vehicle-Id\tComponent-Id\tName\tValue\tType\n\
         1\t1\tCAL_MAG_COMP_TYP\t{typ}\t6\n",
        env!("CARGO_PKG_VERSION"),
        if typ == 2 {
            "current (battery 0)"
        } else {
            "throttle"
        }
    );
    for (a, axis) in ["X", "Y", "Z"].iter().enumerate() {
        out += &format!(
            "1\t1\tCAL_MAG{instance}_{axis}COMP\t{:.6}\t9\n",
            -line.slope[a] * scale
        );
    }
    out
}

/// ArduPilot parameters as a `.param` file (`NAME,VALUE` lines) for compass `instance` (1, 2
/// or 3).
pub fn ardupilot_params(line: &LinearFit, instance: usize) -> String {
    let (ct, unit) = match line.input {
        InputKind::Current => (2, "mG per A"),
        _ => (1, "mG per unit throttle"),
    };
    let suffix = if instance <= 1 {
        String::new()
    } else {
        instance.to_string()
    };
    let mut out = format!(
        "# ArduPilot compassmot parameters exported by magstand {}; {unit}, minus the fitted slope\n\
         # (ArduPilot corrects with field + COMPASS_MOT x {}).\n\
         COMPASS_MOTCT,{ct}\n",
        env!("CARGO_PKG_VERSION"),
        if ct == 2 { "current" } else { "throttle" }
    );
    for (a, axis) in ["X", "Y", "Z"].iter().enumerate() {
        out += &format!("COMPASS_MOT{suffix}_{axis},{:.3}\n", -line.slope[a] * 10.0);
    }
    out
}

/// One line per axis of what the line leaves, for the terminal.
pub fn describe(line: &LinearFit) -> String {
    let unit = match line.input {
        InputKind::Current => "uT/A",
        _ => "uT per unit throttle",
    };
    let mut out = format!(
        "best line through the origin over 0..{} ({unit}):\n",
        line.range_max
    );
    for (a, axis) in AXES.iter().enumerate() {
        out += &format!(
            "  {axis}: slope {:9.4}, leaves {:.3} uT RMS of the full model\n",
            line.slope[a], line.rms_left_ut[a]
        );
    }
    out += &format!(
        "worst apparent heading error: {:.2} deg uncompensated, {:.2} deg with the line, 0 with the full model\n",
        line.uncompensated_heading_deg, line.worst_heading_deg
    );
    out
}

fn c_array(values: impl Iterator<Item = f64>) -> String {
    values
        .map(|v| format!("{v:e}"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// The full model as a dependency-free C header (C99, `math.h` only): the disturbance and the
/// noise sd at a raw input, per axis, in µT. Per-motor models are refused (their inputs are the
/// four commands, not one).
pub fn c_header(model: &Model) -> Result<String, LogsError> {
    let (centers, widths, coef) = local_linear_parts(model)?;
    let m = centers.len();
    let spec = &model.input;
    let (knots, sd) = match &model.sd {
        Some(s) => (s.knots.clone(), s.sd_ut.clone()),
        None => (vec![0.0, 1.0], [vec![0.0; 2], vec![0.0; 2], vec![0.0; 2]]),
    };
    let mut h = format!(
        "/* magstand model (method {}, input {:?}) exported by magstand {}.\n\
         * magstand_dist(raw, out) writes the predicted disturbance in uT per axis (x, y, z) at a raw\n\
         * input (overall throttle 0..1, or supply current in A); subtract it from the reading.\n\
         * magstand_sd(raw, out) writes the predicted noise standard deviation in uT.\n\
         * No dependencies but math.h; no allocation; reentrant. */\n\
         #ifndef MAGSTAND_MODEL_H\n#define MAGSTAND_MODEL_H\n#include <math.h>\n\n",
        model.method,
        spec.kind,
        env!("CARGO_PKG_VERSION")
    );
    h += &format!(
        "#define MAGSTAND_MODELS {m}\n#define MAGSTAND_KNOTS {}\n\
         static const double magstand_lo = {:e}, magstand_hi = {:e}, magstand_off_raw = {:e};\n\
         static const double magstand_centers[MAGSTAND_MODELS] = {{{}}};\n\
         static const double magstand_widths[MAGSTAND_MODELS] = {{{}}};\n",
        knots.len(),
        spec.lo,
        spec.hi,
        spec.off_raw,
        c_array(centers.iter().copied()),
        c_array(widths.iter().copied()),
    );
    h += "/* [axis][model][slope, intercept] over the normalized input */\n";
    h += "static const double magstand_coef[3][MAGSTAND_MODELS][2] = {";
    h += &(0..3)
        .map(|a| {
            format!(
                "{{{}}}",
                (0..m)
                    .map(|i| format!("{{{}}}", c_array(coef[a][i].iter().copied())))
                    .collect::<Vec<_>>()
                    .join(", ")
            )
        })
        .collect::<Vec<_>>()
        .join(", ");
    h += "};\n";
    h += &format!(
        "static const double magstand_knots[MAGSTAND_KNOTS] = {{{}}};\n\
         static const double magstand_sd_ut[3][MAGSTAND_KNOTS] = {{{}}};\n\n",
        c_array(knots.iter().copied()),
        sd.iter()
            .map(|v| format!("{{{}}}", c_array(v.iter().copied())))
            .collect::<Vec<_>>()
            .join(", ")
    );
    h += r#"static void magstand_output(double raw, double out[3]) {
    double u = (raw - magstand_lo) / (magstand_hi - magstand_lo);
    double w[MAGSTAND_MODELS], min_e = INFINITY, sum = 0.0;
    int i, a;
    for (i = 0; i < MAGSTAND_MODELS; i++) {
        double d = magstand_widths[i] * (magstand_centers[i] - u);
        w[i] = d * d;
        if (w[i] < min_e) min_e = w[i];
    }
    for (i = 0; i < MAGSTAND_MODELS; i++) { w[i] = exp(min_e - w[i]); sum += w[i]; }
    for (a = 0; a < 3; a++) {
        out[a] = 0.0;
        for (i = 0; i < MAGSTAND_MODELS; i++)
            out[a] += w[i] / sum * (magstand_coef[a][i][0] * u + magstand_coef[a][i][1]);
    }
}

static inline void magstand_dist(double raw, double out[3]) {
    double off[3];
    int a;
    magstand_output(raw, out);
    magstand_output(magstand_off_raw, off);
    for (a = 0; a < 3; a++) out[a] -= off[a];
}

static inline void magstand_sd(double raw, double out[3]) {
    double u = (raw - magstand_lo) / (magstand_hi - magstand_lo);
    int k = 1, a;
    double f;
    if (u <= magstand_knots[0]) { for (a = 0; a < 3; a++) out[a] = magstand_sd_ut[a][0]; return; }
    if (u >= magstand_knots[MAGSTAND_KNOTS - 1]) {
        for (a = 0; a < 3; a++) out[a] = magstand_sd_ut[a][MAGSTAND_KNOTS - 1];
        return;
    }
    while (magstand_knots[k] <= u) k++;
    f = (u - magstand_knots[k - 1]) / (magstand_knots[k] - magstand_knots[k - 1]);
    for (a = 0; a < 3; a++) out[a] = (1.0 - f) * magstand_sd_ut[a][k - 1] + f * magstand_sd_ut[a][k];
}

#endif /* MAGSTAND_MODEL_H */
"#;
    Ok(h)
}

type Parts = (Vec<f64>, Vec<f64>, [Vec<Vec<f64>>; 3]);

/// Centres, widths and per-axis local-line coefficients of a one-input local linear model;
/// other models are refused with the reason.
fn local_linear_parts(model: &Model) -> Result<Parts, LogsError> {
    if model.input.kind == InputKind::Motors {
        return Err(LogsError::Export(
            "a per-motor model takes every motor's command; the C export takes one input (fit with --inputs throttle or current)".into(),
        ));
    }
    match &model.structure {
        Structure::LocalLinear(net) => Ok((
            net.partition.centers().to_vec(),
            net.partition.widths().to_vec(),
            net.coefficients.clone(),
        )),
        Structure::Polynomial { .. } => Err(LogsError::Export(format!(
            "the C export writes local linear models; `{}` is a polynomial (export it with --to px4 or ardupilot)",
            model.method
        ))),
    }
}
