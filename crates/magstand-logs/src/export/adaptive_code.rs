//! The recursive estimation ([`magstand_ident::adaptive`]) as code for a flight controller: a
//! dependency-free C header and a `no_std` Rust module that run the same recursion, row by
//! row, as `magstand compensate --adapt`: the disturbance predicted before the row, then the
//! update of the local linear coefficients with the row's deviation from the motors-off field.
//!
//! The state is fixed-size (the coefficients and their `2m × 2m` scaled covariance), with no
//! allocation; one step costs about `(2m)²` multiply-adds.
use magstand_ident::adaptive::{ValidAdaptConfig, growth, start_variance};
use magstand_ident::{InputKind, Model, Structure};

use super::firmware::list;
use crate::LogsError;

/// What both forms are generated from.
struct Parts {
    method: String,
    kind: InputKind,
    lo: f64,
    hi: f64,
    off_raw: f64,
    edge_lo: f64,
    edge_hi: f64,
    centers: Vec<f64>,
    widths: Vec<f64>,
    /// `[axis][2 i + 0]` slope, `[axis][2 i + 1]` intercept.
    theta0: [Vec<f64>; 3],
    reference_ut: [f64; 3],
    p0: f64,
    grow: f64,
    forgetting: f64,
}

impl Parts {
    fn of(model: &Model, config: &ValidAdaptConfig) -> Result<Self, LogsError> {
        // The recursion's own checks (one input, local linear) with its own reasons.
        magstand_ident::adaptive::Adaptive::new(model, config)
            .map_err(|e| LogsError::Export(e.to_string()))?;
        let Structure::LocalLinear(net) = &model.structure else {
            unreachable!("Adaptive::new refuses other structures")
        };
        let m = net.partition.len();
        let forgetting = config.params().forgetting;
        // An unbounded identified range is written as the widest finite one: C and Rust
        // literals have no infinity.
        let (edge_lo, edge_hi) = model
            .identified
            .as_ref()
            .map_or((-f64::MAX, f64::MAX), |r| (r.lo, r.hi));
        let parts = Parts {
            method: model.method.clone(),
            kind: model.input.kind,
            lo: model.input.lo,
            hi: model.input.hi,
            off_raw: model.input.off_raw,
            edge_lo,
            edge_hi,
            centers: net.partition.centers().to_vec(),
            widths: net.partition.widths().to_vec(),
            theta0: std::array::from_fn(|a| {
                net.coefficients[a]
                    .iter()
                    .flat_map(|c| [c[0], c[1]])
                    .collect()
            }),
            reference_ut: model.reference_ut,
            p0: start_variance(m, forgetting),
            grow: growth(forgetting),
            forgetting,
        };
        let all = [parts.lo, parts.hi, parts.off_raw, parts.p0, parts.grow]
            .into_iter()
            .chain(parts.reference_ut)
            .chain(parts.centers.iter().copied())
            .chain(parts.widths.iter().copied())
            .chain(parts.theta0.iter().flatten().copied());
        if all.clone().any(|v| !v.is_finite()) || parts.hi == parts.lo {
            return Err(LogsError::Export(
                "the model holds a value that is not finite, or an empty input range".into(),
            ));
        }
        Ok(parts)
    }
}

/// The recursion as a C99 header (`math.h` only): `magstand_adapt_init(&state)` once, then
/// `magstand_adapt_step(&state, raw, mag_ut, dist_ut)` per magnetometer sample.
pub fn c_adaptive(model: &Model, config: &ValidAdaptConfig) -> Result<String, LogsError> {
    let p = Parts::of(model, config)?;
    let m = p.centers.len();
    let theta0 = p
        .theta0
        .iter()
        .map(|t| format!("{{{}}}", list(t.iter().copied())))
        .collect::<Vec<_>>()
        .join(", ");
    let mut h = format!(
        "/* magstand adaptive model (method {}, input {:?}, forgetting {}) exported by magstand {}.\n\
         * The recursive estimation of `magstand compensate --adapt`:\n\
         *   magstand_adapt_state s; magstand_adapt_init(&s);\n\
         *   per sample: magstand_adapt_step(&s, raw, mag_ut, dist_ut);\n\
         * raw is the overall throttle 0..1 (or the supply current in A), mag_ut the reading in uT;\n\
         * dist_ut receives the disturbance predicted before this sample (subtract it from the\n\
         * reading), and the coefficients are then updated with the sample. Run it only on a\n\
         * restrained vehicle, or where the field without motors is known: the update takes the\n\
         * reading less the motors-off field (magstand_reference_ut) as the disturbance.\n\
         * No dependencies but math.h; no allocation. */\n\
         #ifndef MAGSTAND_ADAPT_H\n#define MAGSTAND_ADAPT_H\n#include <math.h>\n\n\
         #define MAGSTAND_ADAPT_MODELS {m}\n#define MAGSTAND_ADAPT_N {n}\n\
         static const double magstand_adapt_lo = {:e}, magstand_adapt_hi = {:e}, magstand_adapt_off_raw = {:e};\n\
         static const double magstand_adapt_edge_lo = {:e}, magstand_adapt_edge_hi = {:e};\n\
         static const double magstand_adapt_p0 = {:e}, magstand_adapt_grow = {:e};\n\
         static const double magstand_reference_ut[3] = {{{}}};\n\
         static const double magstand_adapt_centers[MAGSTAND_ADAPT_MODELS] = {{{}}};\n\
         static const double magstand_adapt_widths[MAGSTAND_ADAPT_MODELS] = {{{}}};\n\
         /* [axis][2 i] slope, [axis][2 i + 1] intercept of local model i */\n\
         static const double magstand_adapt_theta0[3][MAGSTAND_ADAPT_N] = {{{theta0}}};\n\n",
        p.method,
        p.kind,
        p.forgetting,
        env!("CARGO_PKG_VERSION"),
        p.lo,
        p.hi,
        p.off_raw,
        p.edge_lo,
        p.edge_hi,
        p.p0,
        p.grow,
        list(p.reference_ut),
        list(p.centers.iter().copied()),
        list(p.widths.iter().copied()),
        n = 2 * m,
    );
    h += r#"typedef struct {
    double theta[3][MAGSTAND_ADAPT_N];
    double p[MAGSTAND_ADAPT_N][MAGSTAND_ADAPT_N];
} magstand_adapt_state;

static void magstand_adapt_init(magstand_adapt_state *s) {
    int a, r, c;
    for (a = 0; a < 3; a++)
        for (r = 0; r < MAGSTAND_ADAPT_N; r++) s->theta[a][r] = magstand_adapt_theta0[a][r];
    for (r = 0; r < MAGSTAND_ADAPT_N; r++)
        for (c = 0; c < MAGSTAND_ADAPT_N; c++) s->p[r][c] = r == c ? magstand_adapt_p0 : 0.0;
}

static void magstand_adapt_regressors(double u, double z[MAGSTAND_ADAPT_N], double phi[MAGSTAND_ADAPT_MODELS]) {
    double e = u < magstand_adapt_edge_lo ? magstand_adapt_edge_lo : (u > magstand_adapt_edge_hi ? magstand_adapt_edge_hi : u);
    double min_e = INFINITY, sum = 0.0;
    int i;
    for (i = 0; i < MAGSTAND_ADAPT_MODELS; i++) {
        double d = magstand_adapt_widths[i] * (magstand_adapt_centers[i] - e);
        phi[i] = d * d;
        if (phi[i] < min_e) min_e = phi[i];
    }
    for (i = 0; i < MAGSTAND_ADAPT_MODELS; i++) { phi[i] = exp(min_e - phi[i]); sum += phi[i]; }
    for (i = 0; i < MAGSTAND_ADAPT_MODELS; i++) {
        phi[i] /= sum;
        z[2 * i] = phi[i] * u;
        z[2 * i + 1] = phi[i];
    }
}

static void magstand_adapt_step(magstand_adapt_state *s, double raw, const double mag_ut[3], double dist_ut[3]) {
    double z[MAGSTAND_ADAPT_N], z_off[MAGSTAND_ADAPT_N], phi[MAGSTAND_ADAPT_MODELS];
    double pz[MAGSTAND_ADAPT_N], scale[MAGSTAND_ADAPT_N];
    double u = (raw - magstand_adapt_lo) / (magstand_adapt_hi - magstand_adapt_lo);
    double u_off = (magstand_adapt_off_raw - magstand_adapt_lo) / (magstand_adapt_hi - magstand_adapt_lo);
    double zz = 0.0, sden;
    int a, r, c, finite = 1;
    magstand_adapt_regressors(u_off, z_off, phi);
    magstand_adapt_regressors(u, z, phi);
    for (r = 0; r < MAGSTAND_ADAPT_N; r++) { z[r] -= z_off[r]; zz += z[r] * z[r]; }
    for (a = 0; a < 3; a++) {
        dist_ut[a] = 0.0;
        for (r = 0; r < MAGSTAND_ADAPT_N; r++) dist_ut[a] += z[r] * s->theta[a][r];
        if (!isfinite(mag_ut[a])) finite = 0;
    }
    if (!(zz > 1e-24) || !finite) return;
    for (r = 0; r < MAGSTAND_ADAPT_N; r++) scale[r] = s->p[r][r] >= magstand_adapt_p0 ? 1.0 : magstand_adapt_grow;
    for (r = 0; r < MAGSTAND_ADAPT_N; r++)
        for (c = 0; c < MAGSTAND_ADAPT_N; c++) s->p[r][c] *= scale[r] * scale[c];
    sden = 0.0;
    for (r = 0; r < MAGSTAND_ADAPT_N; r++) {
        pz[r] = 0.0;
        for (c = 0; c < MAGSTAND_ADAPT_N; c++) pz[r] += s->p[r][c] * z[c];
    }
    for (r = 0; r < MAGSTAND_ADAPT_N; r++) sden += z[r] * pz[r];
    sden = 1.0 + sden;
    for (a = 0; a < 3; a++) {
        double e = mag_ut[a] - magstand_reference_ut[a] - dist_ut[a];
        for (r = 0; r < MAGSTAND_ADAPT_N; r++) s->theta[a][r] += pz[r] * e / sden;
    }
    for (r = 0; r < MAGSTAND_ADAPT_N; r++)
        for (c = r; c < MAGSTAND_ADAPT_N; c++) {
            double v = s->p[r][c] - pz[r] * pz[c] / sden;
            s->p[r][c] = v;
            s->p[c][r] = v;
        }
}

#endif /* MAGSTAND_ADAPT_H */
"#;
    Ok(h)
}

/// The recursion as a `no_std` Rust module with no dependencies and no allocation:
/// `State::new()`, then `state.step(raw, mag_ut) -> dist_ut` per magnetometer sample.
pub fn rust_adaptive(model: &Model, config: &ValidAdaptConfig) -> Result<String, LogsError> {
    let p = Parts::of(model, config)?;
    let m = p.centers.len();
    let n = 2 * m;
    let theta0 = p
        .theta0
        .iter()
        .map(|t| format!("[{}]", list(t.iter().copied())))
        .collect::<Vec<_>>()
        .join(", ");
    let mut r = format!(
        "//! magstand adaptive model (method {}, input {:?}, forgetting {}) exported by magstand {}.\n\
         //!\n\
         //! The recursive estimation of `magstand compensate --adapt`: `State::new()` once, then\n\
         //! `state.step(raw, mag_ut)` per sample, with `raw` the overall throttle 0..1 (or the\n\
         //! supply current in A) and `mag_ut` the reading in µT. It returns the disturbance\n\
         //! predicted before this sample (subtract it from the reading) and then updates the\n\
         //! coefficients with the sample, taking the reading less the motors-off field\n\
         //! (`REFERENCE_UT`) as the disturbance: run it on a restrained vehicle, or where that\n\
         //! field is known. `no_std`, no dependencies, no allocation.\n\
         #![allow(clippy::excessive_precision, clippy::unreadable_literal, clippy::needless_range_loop, dead_code)]\n\n\
         const LO: f64 = {:e};\nconst HI: f64 = {:e};\nconst OFF_RAW: f64 = {:e};\n\
         const EDGE_LO: f64 = {:e};\nconst EDGE_HI: f64 = {:e};\n\
         const P0: f64 = {:e};\nconst GROW: f64 = {:e};\n\
         /// The motors-off field the update measures the disturbance from, µT.\n\
         pub const REFERENCE_UT: [f64; 3] = [{}];\n\
         const CENTERS: [f64; {m}] = [{}];\n\
         const WIDTHS: [f64; {m}] = [{}];\n\
         const THETA0: [[f64; {n}]; 3] = [{theta0}];\n\n",
        p.method,
        p.kind,
        p.forgetting,
        env!("CARGO_PKG_VERSION"),
        p.lo,
        p.hi,
        p.off_raw,
        p.edge_lo,
        p.edge_hi,
        p.p0,
        p.grow,
        list(p.reference_ut),
        list(p.centers.iter().copied()),
        list(p.widths.iter().copied()),
    );
    r += super::firmware::EXP_NONPOSITIVE;
    r += &format!(
        r#"
fn regressors(u: f64, z: &mut [f64; {n}]) {{
    let e = if u < EDGE_LO {{ EDGE_LO }} else if u > EDGE_HI {{ EDGE_HI }} else {{ u }};
    let mut phi = [0.0; {m}];
    let mut min_e = f64::INFINITY;
    for i in 0..{m} {{
        let d = WIDTHS[i] * (CENTERS[i] - e);
        phi[i] = d * d;
        if phi[i] < min_e {{
            min_e = phi[i];
        }}
    }}
    let mut sum = 0.0;
    for w in phi.iter_mut() {{
        *w = exp_nonpositive(min_e - *w);
        sum += *w;
    }}
    for i in 0..{m} {{
        phi[i] /= sum;
        z[2 * i] = phi[i] * u;
        z[2 * i + 1] = phi[i];
    }}
}}

/// The coefficients and their scaled covariance.
#[derive(Clone)]
pub struct State {{
    /// `[axis][2 i]` slope and `[axis][2 i + 1]` intercept of local model `i`.
    pub theta: [[f64; {n}]; 3],
    p: [[f64; {n}]; {n}],
}}

impl State {{
    /// The identified model, not yet updated.
    pub fn new() -> Self {{
        let mut p = [[0.0; {n}]; {n}];
        for (r, row) in p.iter_mut().enumerate() {{
            row[r] = P0;
        }}
        State {{ theta: THETA0, p }}
    }}

    /// The disturbance predicted at `raw` before this sample, µT per axis; then the update
    /// with the reading `mag_ut`.
    pub fn step(&mut self, raw: f64, mag_ut: [f64; 3]) -> [f64; 3] {{
        let u = (raw - LO) / (HI - LO);
        let u_off = (OFF_RAW - LO) / (HI - LO);
        let (mut z, mut z_off) = ([0.0; {n}], [0.0; {n}]);
        regressors(u_off, &mut z_off);
        regressors(u, &mut z);
        let mut zz = 0.0;
        for r in 0..{n} {{
            z[r] -= z_off[r];
            zz += z[r] * z[r];
        }}
        let mut dist = [0.0; 3];
        for a in 0..3 {{
            for r in 0..{n} {{
                dist[a] += z[r] * self.theta[a][r];
            }}
        }}
        if !(zz > 1e-24) || !mag_ut.iter().all(|v| v.is_finite()) {{
            return dist;
        }}
        let mut scale = [1.0; {n}];
        for r in 0..{n} {{
            if self.p[r][r] < P0 {{
                scale[r] = GROW;
            }}
        }}
        for r in 0..{n} {{
            for c in 0..{n} {{
                self.p[r][c] *= scale[r] * scale[c];
            }}
        }}
        let mut pz = [0.0; {n}];
        for r in 0..{n} {{
            for c in 0..{n} {{
                pz[r] += self.p[r][c] * z[c];
            }}
        }}
        let mut zpz = 0.0;
        for r in 0..{n} {{
            zpz += z[r] * pz[r];
        }}
        let s = 1.0 + zpz;
        for a in 0..3 {{
            let e = mag_ut[a] - REFERENCE_UT[a] - dist[a];
            for r in 0..{n} {{
                self.theta[a][r] += pz[r] * e / s;
            }}
        }}
        for r in 0..{n} {{
            for c in r..{n} {{
                let v = self.p[r][c] - pz[r] * pz[c] / s;
                self.p[r][c] = v;
                self.p[c][r] = v;
            }}
        }}
        dist
    }}
}}

impl Default for State {{
    fn default() -> Self {{
        Self::new()
    }}
}}
"#
    );
    Ok(r)
}
