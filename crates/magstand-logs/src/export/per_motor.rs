//! ArduPilot's per-motor compass compensation (`COMPASS_PMOT_EN`, `COMPASS_PMOT_EXP`,
//! `COMPASS_PMOTn_{X,Y,Z}`), fitted to a per-motor model over a recording's rows.
//!
//! ArduPilot 4.x (`Compass_PerMotor`) adds to the first compass's field the offset
//! `sum_i c_i (p_i V)^e`, where `p_i` is motor i's demand (0..1 over the ESC range, as in a
//! recording's motor columns), `V` the low-passed battery voltage, `e` = `COMPASS_PMOT_EXP`
//! and `c_i` = `COMPASS_PMOTi_*` in milligauss. So `c_i` is minus the fitted per-motor
//! coefficient. The exponent is found by a grid and a golden-section search over ArduPilot's
//! range (0..2), the coefficients by least squares at each exponent. Newer ArduPilot master
//! scales by motor power times battery current instead; this writes the 4.x form.
use magstand_core::{Recording, Vec3};
use magstand_ident::InputKind;
use magstand_ident::Model;
use magstand_ident::least_squares::{NormalEquations, SolveError};

use super::heading_errors_deg;
use crate::LogsError;

/// Motors ArduPilot's per-motor compensation covers.
pub const MAX_MOTORS: usize = 4;

/// The exponent search range (ArduPilot documents 0..2; 0 itself makes every running motor's
/// regressor 1 and the fit degenerate).
const EXPO_RANGE: (f64, f64) = (0.05, 2.0);

/// ArduPilot's per-motor form fitted to a model, and what it costs.
#[derive(Debug, Clone, PartialEq)]
pub struct PerMotorFit {
    /// `COMPASS_PMOT_EXP`.
    pub expo: f64,
    /// `COMPASS_PMOTi_{X,Y,Z}` per motor, mG per (V)^expo (minus the fitted coefficient).
    pub compensation_mg: Vec<[f64; 3]>,
    /// RMS over the rows of the full model minus the per-motor form, per axis, µT.
    pub rms_left_ut: [f64; 3],
    /// Worst apparent heading error the per-motor form leaves over the rows, degrees.
    pub worst_heading_deg: f64,
    /// The same with no compensation at all.
    pub uncompensated_heading_deg: f64,
    /// The 95th percentile of the apparent heading error the per-motor form leaves, degrees.
    pub p95_heading_deg: f64,
    /// The same with no compensation at all.
    pub uncompensated_p95_heading_deg: f64,
}

/// The per-motor form fitted at one exponent.
struct AtExponent {
    /// Least-squares coefficients, µT per (V)^e, one column per axis.
    theta: nalgebra::DMatrix<f64>,
    /// What the form leaves of the model at every row, µT.
    left: Vec<Vec3>,
}

impl AtExponent {
    /// Residual sum of squares over rows and axes.
    fn ssr(&self) -> f64 {
        self.left.iter().map(|l| l.norm_squared()).sum()
    }
}

/// Fits the coefficients at exponent `expo`; the regressors `(p_i V)^e` of each row are
/// computed once and serve both the fit and its residuals.
fn solve_at(
    thr: &[Vec<f64>],
    volts: &[f64],
    dist: &[Vec3],
    expo: f64,
) -> Result<AtExponent, SolveError> {
    let n = thr.len();
    let x: Vec<f64> = (0..dist.len())
        .flat_map(|row| {
            thr.iter().map(move |m| {
                let p = m[row] * volts[row];
                if p > 0.0 { p.powf(expo) } else { 0.0 }
            })
        })
        .collect();
    let mut eq = NormalEquations::new(n, 3);
    for (xr, d) in x.chunks_exact(n).zip(dist) {
        eq.add(xr, d.as_slice(), 1.0);
    }
    let theta = eq.solve()?;
    let left = x
        .chunks_exact(n)
        .zip(dist)
        .map(|(xr, d)| d - Vec3::from_fn(|a, _| (0..n).map(|i| theta[(i, a)] * xr[i]).sum()))
        .collect();
    Ok(AtExponent { theta, left })
}

/// Fits ArduPilot's per-motor form to a per-motor model over the rows of `rec` (which needs
/// `bat_v`, and spans where the motors are commanded differently, as in a flight).
pub fn per_motor_fit(
    model: &Model,
    rec: &Recording,
    origin: &str,
) -> Result<PerMotorFit, LogsError> {
    if model.input.kind != InputKind::Motors {
        return Err(LogsError::Export(format!(
            "per-motor parameters need a per-motor model (one fitted on the motor commands); this one's input is {:?}",
            model.input.kind
        )));
    }
    model
        .input
        .check_recording(rec, origin)
        .map_err(|e| LogsError::Export(e.to_string()))?;
    per_motor_over_prediction(
        &model.dist_column(rec),
        Vec3::from(model.reference_ut),
        rec,
        origin,
    )
}

/// ArduPilot's per-motor form fitted to any model's predicted disturbance `dist_ut` at the rows
/// of `rec` (the stand's physics, say); `reference_ut` is the model's motors-off field.
pub fn per_motor_over_prediction(
    dist_ut: &[Vec3],
    reference_ut: Vec3,
    rec: &Recording,
    origin: &str,
) -> Result<PerMotorFit, LogsError> {
    let motors = rec.motor_count();
    if motors > MAX_MOTORS {
        return Err(LogsError::Export(format!(
            "{origin} has {motors} motors; ArduPilot's per-motor compensation covers motors 1 to {MAX_MOTORS}"
        )));
    }
    let volts = rec.bat_v.as_deref().ok_or_else(|| {
        LogsError::Export(format!(
            "{origin}: ArduPilot's per-motor form scales each motor by the battery voltage, but the recording has no `bat_v` column"
        ))
    })?;
    let dist = dist_ut;
    let thr = &rec.thr;
    let refuse = |err: SolveError| match err {
        SolveError::NoData => LogsError::Export(format!("{origin}: no rows to fit")),
        SolveError::Singular { column, .. } => LogsError::Export(format!(
            "{origin}: motor {} was always commanded in step with the others (or never ran), so its own coefficient is not identifiable; per-motor parameters need spans where the motors differ, as in a flight",
            column + 1
        )),
    };
    // An exponent near 0 flattens every running motor's regressor to about 1 and can make the
    // fit singular there alone: such exponents cost infinity rather than ending the search.
    let ssr = |e: f64| {
        solve_at(thr, volts, dist, e)
            .map(|f| f.ssr())
            .unwrap_or(f64::INFINITY)
    };
    // A coarse grid brackets the best exponent, golden section refines it.
    let (expo, _) = magstand_core::bounded_search::minimize(
        magstand_core::bounded_search::Grid {
            lo: EXPO_RANGE.0,
            hi: EXPO_RANGE.1,
            points: 41,
        },
        1e-6,
        100,
        ssr,
    );
    let AtExponent { theta, left } = solve_at(thr, volts, dist, expo).map_err(refuse)?;
    let n = rec.len().max(1) as f64;
    let with_form = heading_errors_deg(reference_ut, left.len(), |k| left[k]);
    let without = heading_errors_deg(reference_ut, dist.len(), |k| dist[k]);
    Ok(PerMotorFit {
        expo,
        compensation_mg: (0..motors)
            .map(|i| std::array::from_fn(|a| -10.0 * theta[(i, a)]))
            .collect(),
        rms_left_ut: std::array::from_fn(|a| {
            (left.iter().map(|l| l[a] * l[a]).sum::<f64>() / n).sqrt()
        }),
        worst_heading_deg: with_form.worst_deg,
        uncompensated_heading_deg: without.worst_deg,
        p95_heading_deg: with_form.p95_deg,
        uncompensated_p95_heading_deg: without.p95_deg,
    })
}

/// The per-motor set as a `.param` file (`NAME,VALUE` lines). ArduPilot applies it to the
/// first compass only.
pub fn per_motor_params(fit: &PerMotorFit) -> String {
    let mut out = format!(
        "# ArduPilot per-motor compass compensation exported by magstand {}: the first compass's\n\
         # field + sum_i COMPASS_PMOTi x (motor_i x battery volts)^COMPASS_PMOT_EXP, in mG\n\
         # (ArduPilot 4.x form; COMPASS_MOTCT is ignored while COMPASS_PMOT_EN is 1).\n\
         COMPASS_PMOT_EN,1\nCOMPASS_PMOT_EXP,{:.3}\n",
        env!("CARGO_PKG_VERSION"),
        fit.expo
    );
    for (i, c) in fit.compensation_mg.iter().enumerate() {
        for (a, axis) in ["X", "Y", "Z"].iter().enumerate() {
            out += &format!("COMPASS_PMOT{}_{axis},{:.4}\n", i + 1, c[a]);
        }
    }
    out
}

/// What the per-motor form leaves, for the terminal.
pub fn describe_per_motor(fit: &PerMotorFit) -> String {
    let bound = if fit.expo > EXPO_RANGE.1 - 1e-3 || fit.expo < EXPO_RANGE.0 + 1e-3 {
        format!(
            "note: the exponent is at the edge of ArduPilot's range ({} to {}); the model is more strongly curved in each motor's command than ArduPilot's form can follow\n",
            EXPO_RANGE.0, EXPO_RANGE.1
        )
    } else {
        String::new()
    };
    bound
        + &format!(
            "ArduPilot per-motor form (exponent {:.3}) leaves {:.3} / {:.3} / {:.3} uT RMS of the full model (x / y / z)\n\
         apparent heading error, worst / 95th percentile: {:.2} / {:.2} deg uncompensated, {:.2} / {:.2} deg with the per-motor form, 0 with the full model\n",
            fit.expo,
            fit.rms_left_ut[0],
            fit.rms_left_ut[1],
            fit.rms_left_ut[2],
            fit.uncompensated_heading_deg,
            fit.uncompensated_p95_heading_deg,
            fit.worst_heading_deg,
            fit.p95_heading_deg
        )
}
