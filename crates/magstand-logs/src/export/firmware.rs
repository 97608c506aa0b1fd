//! The full model as code for one's own firmware: a dependency-free C header and a `no_std`
//! Rust module, both generated from the same parts, both evaluating the disturbance and the
//! noise sd at a raw input exactly as [`Model::dist_at_input`] and the model's sd do.
//!
//! Only one-input local linear models are written (per-motor models take every motor's
//! command; polynomials are what the autopilots' own parameters already hold).
use magstand_ident::{InputKind, Model, Structure};

use crate::LogsError;

/// What both firmware forms are generated from.
struct Parts {
    method: String,
    kind: InputKind,
    lo: f64,
    hi: f64,
    off_raw: f64,
    centers: Vec<f64>,
    widths: Vec<f64>,
    /// `[axis][model][slope, intercept]` over the normalized input.
    coef: [Vec<Vec<f64>>; 3],
    knots: Vec<f64>,
    /// `[axis][knot]`, µT.
    sd_ut: [Vec<f64>; 3],
}

impl Parts {
    /// The parts of a one-input local linear model; other models are refused with the reason.
    fn of(model: &Model) -> Result<Self, LogsError> {
        if model.input.kind == InputKind::Motors {
            return Err(LogsError::Export(
                "a per-motor model takes every motor's command; the firmware export takes one input (fit it on the throttle or the current)".into(),
            ));
        }
        let Structure::LocalLinear(net) = &model.structure else {
            return Err(LogsError::Export(format!(
                "the firmware export writes local linear models; `{}` is a polynomial (export it as PX4 or ArduPilot parameters)",
                model.method
            )));
        };
        let (knots, sd_ut) = match &model.sd {
            Some(s) => (s.knots.clone(), s.sd_ut.clone()),
            None => (vec![0.0, 1.0], std::array::from_fn(|_| vec![0.0; 2])),
        };
        let parts = Self {
            method: model.method.clone(),
            kind: model.input.kind,
            lo: model.input.lo,
            hi: model.input.hi,
            off_raw: model.input.off_raw,
            centers: net.partition.centers().to_vec(),
            widths: net.partition.widths().to_vec(),
            coef: net.coefficients.clone(),
            knots,
            sd_ut,
        };
        let all = [parts.lo, parts.hi, parts.off_raw]
            .into_iter()
            .chain(parts.centers.iter().copied())
            .chain(parts.widths.iter().copied())
            .chain(parts.coef.iter().flatten().flatten().copied())
            .chain(parts.knots.iter().copied())
            .chain(parts.sd_ut.iter().flatten().copied());
        if all.clone().any(|v| !v.is_finite()) || parts.hi == parts.lo {
            return Err(LogsError::Export(
                "the model holds a value that is not finite, or an empty input range".into(),
            ));
        }
        Ok(parts)
    }

    fn models(&self) -> usize {
        self.centers.len()
    }

    /// `coef` as a nested initializer, `[axis][model][slope, intercept]`, with `open` and
    /// `close` as the brackets (`{}` in C, `[]` in Rust).
    fn coefficient_table(&self, open: &str, close: &str) -> String {
        self.coef
            .iter()
            .map(|axis| {
                let models = nested(axis.iter().map(|c| c.iter().copied()), open, close);
                format!("{open}{models}{close}")
            })
            .collect::<Vec<_>>()
            .join(", ")
    }
}

/// Numbers in a form both C and Rust read back to the same double (shortest round trip).
pub(crate) fn list(values: impl IntoIterator<Item = f64>) -> String {
    values
        .into_iter()
        .map(|v| format!("{v:e}"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// `{...}` (C) or `[...]` (Rust) around each inner list, joined.
fn nested<'a, I: IntoIterator<Item = f64>>(
    rows: impl IntoIterator<Item = I>,
    open: &'a str,
    close: &'a str,
) -> String {
    rows.into_iter()
        .map(|r| format!("{open}{}{close}", list(r)))
        .collect::<Vec<_>>()
        .join(", ")
}

/// The full model as a dependency-free C header (C99, `math.h` only): the disturbance and the
/// noise sd at a raw input, per axis, in µT. Per-motor models and polynomials are refused.
pub fn c_header(model: &Model) -> Result<String, LogsError> {
    let p = Parts::of(model)?;
    let m = p.models();
    let coef = p.coefficient_table("{", "}");
    let mut h = format!(
        "/* magstand model (method {}, input {:?}) exported by magstand {}.\n\
         * magstand_dist(raw, out) writes the predicted disturbance in uT per axis (x, y, z) at a raw\n\
         * input (overall throttle 0..1, or supply current in A); subtract it from the reading.\n\
         * magstand_sd(raw, out) writes the predicted noise standard deviation in uT.\n\
         * No dependencies but math.h; no allocation; reentrant. */\n\
         #ifndef MAGSTAND_MODEL_H\n#define MAGSTAND_MODEL_H\n#include <math.h>\n\n",
        p.method,
        p.kind,
        env!("CARGO_PKG_VERSION")
    );
    h += &format!(
        "#define MAGSTAND_MODELS {m}\n#define MAGSTAND_KNOTS {}\n\
         static const double magstand_lo = {:e}, magstand_hi = {:e}, magstand_off_raw = {:e};\n\
         static const double magstand_centers[MAGSTAND_MODELS] = {{{}}};\n\
         static const double magstand_widths[MAGSTAND_MODELS] = {{{}}};\n\
         /* [axis][model][slope, intercept] over the normalized input */\n\
         static const double magstand_coef[3][MAGSTAND_MODELS][2] = {{{coef}}};\n\
         static const double magstand_knots[MAGSTAND_KNOTS] = {{{}}};\n\
         static const double magstand_sd_ut[3][MAGSTAND_KNOTS] = {{{}}};\n\n",
        p.knots.len(),
        p.lo,
        p.hi,
        p.off_raw,
        list(p.centers.iter().copied()),
        list(p.widths.iter().copied()),
        list(p.knots.iter().copied()),
        nested(p.sd_ut.iter().map(|v| v.iter().copied()), "{", "}"),
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

/// `e^x` for `x <= 0` in `core` (which has no `exp`), as generated modules carry it.
pub(crate) const EXP_NONPOSITIVE: &str = r#"/// e^x for x <= 0 (0 below the smallest normal result).
fn exp_nonpositive(x: f64) -> f64 {
    const LN2_HI: f64 = 6.93147180369123816490e-01;
    const LN2_LO: f64 = 1.90821492927058770002e-10;
    if x < -708.0 {
        return 0.0;
    }
    // k = round(x / ln 2), so that |r| <= ln(2) / 2.
    let k = (x * core::f64::consts::LOG2_E - 0.5) as i64;
    let r = (x - k as f64 * LN2_HI) - k as f64 * LN2_LO;
    let (mut term, mut sum) = (1.0, 1.0);
    let mut i = 1;
    while i < 20 {
        term *= r / i as f64;
        sum += term;
        i += 1;
    }
    sum * f64::from_bits(((k + 1023) as u64) << 52)
}

"#;

/// The full model as a `no_std` Rust module with no dependencies and no allocation:
/// `dist_ut(raw) -> [f64; 3]` and `sd_ut(raw) -> [f64; 3]`. `core` has no `exp`, so the
/// module carries its own for the non-positive arguments the blending needs (Cody-Waite range
/// reduction and a Taylor series; relative error about 1e-15). Per-motor models and
/// polynomials are refused.
pub fn rust_module(model: &Model) -> Result<String, LogsError> {
    let p = Parts::of(model)?;
    let m = p.models();
    let k = p.knots.len();
    let coef = p.coefficient_table("[", "]");
    let mut r = format!(
        "//! magstand model (method {}, input {:?}) exported by magstand {}.\n\
         //!\n\
         //! `dist_ut(raw)` is the predicted disturbance in µT per axis (x, y, z) at a raw input\n\
         //! (overall throttle 0..1, or supply current in A); subtract it from the reading.\n\
         //! `sd_ut(raw)` is the predicted noise standard deviation in µT.\n\
         //! `no_std`, no dependencies, no allocation.\n\
         #![allow(clippy::excessive_precision, clippy::unreadable_literal, dead_code)]\n\n\
         /// Raw input mapped to 0 of the normalized input.\n\
         pub const LO: f64 = {:e};\n\
         /// Raw input mapped to 1 of the normalized input.\n\
         pub const HI: f64 = {:e};\n\
         /// Raw input with the motors off.\n\
         pub const OFF_RAW: f64 = {:e};\n\
         const CENTERS: [f64; {m}] = [{}];\n\
         const WIDTHS: [f64; {m}] = [{}];\n\
         /// `[axis][model][slope, intercept]` over the normalized input.\n\
         const COEF: [[[f64; 2]; {m}]; 3] = [{coef}];\n\
         const KNOTS: [f64; {k}] = [{}];\n\
         const SD_UT: [[f64; {k}]; 3] = [{}];\n\n",
        p.method,
        p.kind,
        env!("CARGO_PKG_VERSION"),
        p.lo,
        p.hi,
        p.off_raw,
        list(p.centers.iter().copied()),
        list(p.widths.iter().copied()),
        list(p.knots.iter().copied()),
        nested(p.sd_ut.iter().map(|v| v.iter().copied()), "[", "]"),
    );
    r += EXP_NONPOSITIVE;
    r += r#"fn output(raw: f64) -> [f64; 3] {
    let u = (raw - LO) / (HI - LO);
    let mut w = [0.0; CENTERS.len()];
    let mut min_e = f64::INFINITY;
    for i in 0..w.len() {
        let d = WIDTHS[i] * (CENTERS[i] - u);
        w[i] = d * d;
        if w[i] < min_e {
            min_e = w[i];
        }
    }
    let mut sum = 0.0;
    for wi in w.iter_mut() {
        *wi = exp_nonpositive(min_e - *wi);
        sum += *wi;
    }
    let mut out = [0.0; 3];
    for (a, o) in out.iter_mut().enumerate() {
        for i in 0..w.len() {
            *o += w[i] / sum * (COEF[a][i][0] * u + COEF[a][i][1]);
        }
    }
    out
}

/// Predicted disturbance at a raw input, µT per axis; zero with the motors off.
pub fn dist_ut(raw: f64) -> [f64; 3] {
    let (on, off) = (output(raw), output(OFF_RAW));
    [on[0] - off[0], on[1] - off[1], on[2] - off[2]]
}

/// Predicted noise standard deviation at a raw input, µT per axis.
pub fn sd_ut(raw: f64) -> [f64; 3] {
    let u = (raw - LO) / (HI - LO);
    let last = KNOTS.len() - 1;
    let pick = |k: usize| [SD_UT[0][k], SD_UT[1][k], SD_UT[2][k]];
    if u <= KNOTS[0] {
        return pick(0);
    }
    if u >= KNOTS[last] {
        return pick(last);
    }
    let mut k = 1;
    while KNOTS[k] <= u {
        k += 1;
    }
    let f = (u - KNOTS[k - 1]) / (KNOTS[k] - KNOTS[k - 1]);
    let (lo, hi) = (pick(k - 1), pick(k));
    [
        (1.0 - f) * lo[0] + f * hi[0],
        (1.0 - f) * lo[1] + f * hi[1],
        (1.0 - f) * lo[2] + f * hi[2],
    ]
}
"#;
    Ok(r)
}
