//! Procedure sweeps: one whole study per value of one setting of the identification series
//! (say `program.dwell_s=2,5,10`), with the same seeds for every value, and the accuracy
//! tabulated against the value in `sweep.csv`, to choose a calibration procedure.
use magstand_sim::ValidScenario;

use crate::summary::{FigureId, Summary, format_figure};
use crate::{StudyConfig, StudyError, StudySetting, ValidStudy};

/// The sweep's table, written beside one folder per value.
pub const SWEEP_FILE: &str = "sweep.csv";

/// A checked sweep: every value's study checked before any runs, so a typo in the last value
/// fails at once.
#[derive(Debug, Clone)]
pub struct ValidSweep {
    /// The swept key.
    pub key: String,
    /// The values, in the order given.
    pub values: Vec<String>,
    /// One checked study per value.
    pub studies: Vec<ValidStudy>,
    /// The folder of each value: `KEY=VALUE` with every character outside letters, digits and
    /// `.+-_=` replaced by `_`, so that a value can never name a path elsewhere.
    pub folders: Vec<String>,
}

fn invalid(value: &str, expected: String) -> StudyError {
    StudyError::InvalidSetting {
        setting: StudySetting::Sweep,
        value: value.into(),
        expected,
    }
}

impl ValidSweep {
    /// Parses `key=v1,v2,...` and checks one study per value: `config` with the
    /// identification overrides `ident_overrides` and `key=value` after them.
    pub fn new(
        text: &str,
        scenario: &ValidScenario,
        config: impl Fn(Vec<String>) -> StudyConfig,
        ident_overrides: &[String],
    ) -> Result<Self, StudyError> {
        let (key, values) = text
            .split_once('=')
            .filter(|(k, v)| !k.trim().is_empty() && !v.trim().is_empty())
            .ok_or_else(|| invalid(text, "key=v1,v2,... (e.g. program.dwell_s=2,5,10)".into()))?;
        let key = key.trim().to_string();
        let values: Vec<String> = values.split(',').map(|v| v.trim().to_string()).collect();
        let mut studies = Vec::with_capacity(values.len());
        for v in &values {
            let mut ident = ident_overrides.to_vec();
            ident.push(format!("{key}={v}"));
            studies.push(config(ident).check(scenario).map_err(|e| match e {
                StudyError::InvalidSetting { .. } => e,
                e => invalid(
                    &format!("{key}={v}"),
                    format!("a value the scenario takes: {e}"),
                ),
            })?);
        }
        let safe = |text: &str| -> String {
            text.chars()
                .map(|c| match c {
                    c if c.is_ascii_alphanumeric() || "+-_=.".contains(c) => c,
                    _ => '_',
                })
                .collect()
        };
        let mut folders: Vec<String> = Vec::new();
        for v in &values {
            let folder = format!("{}={}", safe(&key), safe(v));
            if let Some(k) = folders.iter().position(|f| *f == folder) {
                return Err(invalid(
                    text,
                    format!(
                        "distinct values: `{}` and `{v}` would share the folder {folder}",
                        values[k]
                    ),
                ));
            }
            folders.push(folder);
        }
        Ok(ValidSweep {
            key,
            values,
            studies,
            folders,
        })
    }
}

/// The sweep's rows, one per value and method: value, method, median and 95th percentile of
/// the disturbance RMSE (µT), median worst heading error after compensation (degrees), and the
/// efficiency against the Cramer-Rao bound, formatted as `sweep.csv` writes them.
pub fn sweep_rows(table: &[(String, Summary)]) -> Vec<[String; 6]> {
    let mut rows = Vec::new();
    for (v, s) in table {
        for m in &s.methods {
            let r = m.figure(FigureId::RmseUt);
            rows.push([
                v.clone(),
                m.method.clone(),
                format_figure(r.map(|r| r.p50), 4),
                format_figure(r.map(|r| r.p95), 4),
                format_figure(m.figure(FigureId::HeadingAfterDeg).map(|h| h.p50), 3),
                format_figure(m.crlb_ratio, 3),
            ]);
        }
    }
    rows
}

/// The text of `sweep.csv` for the swept `key`.
pub fn sweep_csv(key: &str, table: &[(String, Summary)]) -> String {
    let mut out =
        format!("{key},method,rmse_ut_p50,rmse_ut_p95,heading_after_deg_p50,crlb_ratio\n");
    for r in sweep_rows(table) {
        out += &(r.join(",") + "\n");
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scenario() -> ValidScenario {
        let text = magstand_sim::builtin::get("czyba2015-stair").unwrap();
        magstand_sim::Scenario::from_toml_str(text, "s")
            .and_then(|s| s.check("s", None))
            .unwrap()
    }

    #[test]
    fn a_sweep_checks_every_value_and_names_the_bad_one() {
        let s = scenario();
        let config = |ident| StudyConfig {
            identification_overrides: ident,
            ..StudyConfig::new(4, 1)
        };
        let ok = ValidSweep::new("program.dwell_s=2, 5", &s, config, &[]).unwrap();
        assert_eq!(ok.values, ["2", "5"]);
        assert_eq!(ok.folders, ["program.dwell_s=2", "program.dwell_s=5"]);
        for text in ["program.dwell_s", "=2,5", "program.dwell_s=2,-1"] {
            let e = ValidSweep::new(text, &s, config, &[])
                .unwrap_err()
                .to_string();
            assert!(e.contains("sweep"), "{text}: {e}");
        }
        let e = ValidSweep::new("program.dwell_s=2,-1", &s, config, &[])
            .unwrap_err()
            .to_string();
        assert!(e.contains("program.dwell_s=-1"), "{e}");
        let e = ValidSweep::new("description=a/b,a_b", &s, config, &[])
            .unwrap_err()
            .to_string();
        assert!(e.contains("share the folder"), "{e}");
    }
}
