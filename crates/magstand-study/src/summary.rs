//! SUMMARY.json: per method, the spread of every figure over the runs and the efficiency
//! against the Cramer-Rao bound.
//!
//! A summary is a function of the run outcomes sorted by run and method only, so any thread
//! count, and any split into shards merged afterwards, gives the same file.
use serde::{Deserialize, Serialize};

use crate::crlb::{PARAMS_PER_AXIS, parameter_names};
use crate::run::{BINS, Figures, MethodOutcome};
use crate::study_info::StudyInfo;
use magstand_core::AXES;

/// Spread of one figure over the runs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Stats {
    /// Runs with a value.
    pub n: usize,
    /// Mean.
    pub mean: f64,
    /// Sample standard deviation.
    pub sd: f64,
    /// 5th percentile.
    pub p5: f64,
    /// Median.
    pub p50: f64,
    /// 95th percentile.
    pub p95: f64,
    /// Smallest value.
    pub min: f64,
    /// Largest value (the worst run, for an error).
    pub max: f64,
}

impl Stats {
    /// Stats of the finite values, or `None` when there are none.
    pub fn of(values: impl IntoIterator<Item = f64>) -> Option<Self> {
        let mut v: Vec<f64> = values.into_iter().filter(|x| x.is_finite()).collect();
        if v.is_empty() {
            return None;
        }
        v.sort_by(f64::total_cmp);
        let n = v.len();
        let mean = v.iter().sum::<f64>() / n as f64;
        let sd = if n > 1 {
            (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1) as f64).sqrt()
        } else {
            0.0
        };
        Some(Self {
            n,
            mean,
            sd,
            p5: percentile(&v, 0.05),
            p50: percentile(&v, 0.5),
            p95: percentile(&v, 0.95),
            min: v[0],
            max: v[n - 1],
        })
    }
}

/// Percentile of sorted values, as every figure of magstand takes one
/// ([`magstand_ident::metrics::percentile`]).
pub use magstand_ident::metrics::percentile;

/// The scalar figures of every run and method: the disturbance RMSE against the truth (norm,
/// then per axis, µT), the eq. 20 error (%), and the worst level-mean heading error before and
/// after compensation (degrees). Each has one spelling, [`FigureId::name`], in runs.csv,
/// SUMMARY.json, sweep.csv and check files.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum FigureId {
    /// RMSE of the error vector's norm, µT.
    RmseUt,
    /// RMSE on x, µT.
    RmseXUt,
    /// RMSE on y, µT.
    RmseYUt,
    /// RMSE on z, µT.
    RmseZUt,
    /// RMS eq. 20 error with the motors running, %.
    E20RmsPct,
    /// Worst level-mean heading error before compensation, degrees.
    HeadingBeforeDeg,
    /// Worst level-mean heading error after compensation, degrees.
    HeadingAfterDeg,
}

impl FigureId {
    /// Every figure, in the order files list them.
    pub const ALL: [FigureId; 7] = [
        FigureId::RmseUt,
        FigureId::RmseXUt,
        FigureId::RmseYUt,
        FigureId::RmseZUt,
        FigureId::E20RmsPct,
        FigureId::HeadingBeforeDeg,
        FigureId::HeadingAfterDeg,
    ];

    /// Its name in every file.
    pub const fn name(self) -> &'static str {
        match self {
            FigureId::RmseUt => "rmse_ut",
            FigureId::RmseXUt => "rmse_x_ut",
            FigureId::RmseYUt => "rmse_y_ut",
            FigureId::RmseZUt => "rmse_z_ut",
            FigureId::E20RmsPct => "e20_rms_pct",
            FigureId::HeadingBeforeDeg => "heading_before_deg",
            FigureId::HeadingAfterDeg => "heading_after_deg",
        }
    }

    /// The figure of a name, if it is one.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|f| f.name() == name)
    }

    /// Its value in one run's figures.
    pub fn of(self, f: &Figures) -> f64 {
        match self {
            FigureId::RmseUt => f.rmse_ut,
            FigureId::RmseXUt => f.rmse_axis_ut[0],
            FigureId::RmseYUt => f.rmse_axis_ut[1],
            FigureId::RmseZUt => f.rmse_axis_ut[2],
            FigureId::E20RmsPct => f.e20_rms_pct,
            FigureId::HeadingBeforeDeg => f.heading_before_deg,
            FigureId::HeadingAfterDeg => f.heading_after_deg,
        }
    }
}

impl std::fmt::Display for FigureId {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// The names of [`FigureId::ALL`].
pub const FIGURE_NAMES: [&str; 7] = [
    FigureId::RmseUt.name(),
    FigureId::RmseXUt.name(),
    FigureId::RmseYUt.name(),
    FigureId::RmseZUt.name(),
    FigureId::E20RmsPct.name(),
    FigureId::HeadingBeforeDeg.name(),
    FigureId::HeadingAfterDeg.name(),
];

/// A figure as tables print it: `digits` decimals, or `-` where there is none.
pub fn format_figure(v: Option<f64>, digits: usize) -> String {
    v.map_or("-".into(), |v| format!("{v:.digits$}"))
}

/// A named figure's stats.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Figure {
    /// Column name in runs.csv.
    pub name: String,
    /// Its spread.
    pub stats: Stats,
}

/// One fixed-structure parameter over the runs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ParameterStats {
    /// `axis.parameter`, e.g. `z.a3` (slope of the third local model on z).
    pub name: String,
    /// Mean error (bias), µT per unit.
    pub bias: f64,
    /// Standard deviation of the error over runs.
    pub sd: f64,
    /// Root of the mean CRLB variance: the smallest sd any unbiased estimator can have.
    pub crlb_sd: f64,
}

/// Everything known about one method.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MethodSummary {
    /// Method id.
    pub method: String,
    /// Label for tables.
    pub label: String,
    /// Runs in which the method gave a model.
    pub runs: usize,
    /// Runs in which it failed.
    pub failures: usize,
    /// The first failure's message, if any.
    pub first_failure: Option<String>,
    /// Stats of each scalar figure.
    pub figures: Vec<Figure>,
    /// Stats of the error norm's RMSE per throttle bin (index i: throttle i/10 to (i+1)/10).
    pub bins: Vec<Option<Stats>>,
    /// Per parameter, for the fixed structure.
    pub parameters: Vec<ParameterStats>,
    /// Efficiency: trace of the empirical parameter covariance over the trace of the CRLB
    /// (1 is the limit for an unbiased estimator).
    pub crlb_ratio: Option<f64>,
    /// The same with the mean squared error (bias included) in the numerator.
    pub mse_crlb_ratio: Option<f64>,
}

impl MethodSummary {
    /// Stats of a figure.
    pub fn figure(&self, id: FigureId) -> Option<&Stats> {
        self.figures
            .iter()
            .find(|f| f.name == id.name())
            .map(|f| &f.stats)
    }
}

/// The whole summary.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Summary {
    /// What was run.
    pub study: StudyInfo,
    /// Per method, in table order.
    pub methods: Vec<MethodSummary>,
}

impl Summary {
    /// Summarizes outcomes (any order; sorted here by run, then method order).
    pub fn new(study: StudyInfo, outcomes: &[MethodOutcome]) -> Self {
        let methods = study
            .methods
            .iter()
            .map(|id| {
                let mut rows: Vec<&MethodOutcome> =
                    outcomes.iter().filter(|o| &o.method == id).collect();
                rows.sort_by_key(|o| o.run);
                summarize(id, &rows)
            })
            .collect();
        Summary { study, methods }
    }

    /// The summary as pretty JSON.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("summaries serialize")
    }

    /// A method's summary by id.
    pub fn method(&self, id: &str) -> Option<&MethodSummary> {
        self.methods.iter().find(|m| m.method == id)
    }
}

fn summarize(id: &str, rows: &[&MethodOutcome]) -> MethodSummary {
    let ok: Vec<&Figures> = rows.iter().filter_map(|o| o.figures.as_ref()).collect();
    let figures = FigureId::ALL
        .iter()
        .filter_map(|id| {
            Stats::of(ok.iter().map(|x| id.of(x))).map(|stats| Figure {
                name: id.name().into(),
                stats,
            })
        })
        .collect();
    let bins = (0..BINS)
        .map(|b| Stats::of(ok.iter().map(|f| f.bin_rmse_ut[b])))
        .collect();

    // Parameter errors and bounds: only runs that have both.
    let with: Vec<(&PerAxis, &PerAxis)> = ok
        .iter()
        .filter_map(|f| Some((f.param_error.as_ref()?, f.crlb_diag.as_ref()?)))
        .collect();
    let mut parameters = Vec::new();
    let (mut var_sum, mut mse_sum, mut crlb_sum) = (0.0, 0.0, 0.0);
    if with.len() >= 2 {
        let n = with.len() as f64;
        for (a, axis) in AXES.iter().enumerate() {
            for (p, pname) in parameter_names().iter().enumerate().take(PARAMS_PER_AXIS) {
                let errs: Vec<f64> = with.iter().map(|(e, _)| e[a][p]).collect();
                let bias = errs.iter().sum::<f64>() / n;
                let var = errs.iter().map(|e| (e - bias).powi(2)).sum::<f64>() / (n - 1.0);
                let mse = errs.iter().map(|e| e * e).sum::<f64>() / n;
                let crlb = with.iter().map(|(_, c)| c[a][p]).sum::<f64>() / n;
                var_sum += var;
                mse_sum += mse;
                crlb_sum += crlb;
                parameters.push(ParameterStats {
                    name: format!("{axis}.{pname}"),
                    bias,
                    sd: var.sqrt(),
                    crlb_sd: crlb.sqrt(),
                });
            }
        }
    }
    let ratio = |x: f64| (crlb_sum > 0.0 && !parameters.is_empty()).then(|| x / crlb_sum);
    MethodSummary {
        method: id.into(),
        label: magstand_ident::methods::by_id(id)
            .map(|m| m.label.to_string())
            .unwrap_or_else(|| id.to_string()),
        runs: ok.len(),
        failures: rows.len() - ok.len(),
        first_failure: rows.iter().find_map(|o| o.error.clone()),
        figures,
        bins,
        crlb_ratio: ratio(var_sum),
        mse_crlb_ratio: ratio(mse_sum),
        parameters,
    }
}

/// One vector of parameters per axis (x, y, z).
type PerAxis = [Vec<f64>; 3];

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percentiles_interpolate_between_order_statistics() {
        let v: Vec<f64> = (1..=11).map(f64::from).collect();
        assert_eq!(percentile(&v, 0.5), 6.0);
        assert_eq!(percentile(&v, 0.05), 1.5);
        assert_eq!(percentile(&v, 0.95), 10.5);
        let s = Stats::of([3.0, f64::NAN, 1.0, 2.0]).unwrap();
        assert_eq!((s.n, s.mean, s.sd, s.p50), (3, 2.0, 1.0, 2.0));
        assert!(Stats::of([f64::NAN]).is_none());
    }
}
