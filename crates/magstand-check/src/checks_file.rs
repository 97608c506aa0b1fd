//! The check file (`CHECKS.toml`): `[[check]]` entries, read as given ([`CheckFile`]) and
//! checked before anything runs ([`ValidChecks`]): every scenario loaded, every method and
//! figure known, every limit one the method has.
use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use magstand_ident::methods::{self, Method};
use magstand_logs::export::Autopilot;
use magstand_sim::{Scenario, ValidScenario};
use magstand_study::{FIGURE_NAMES, FigureId, StudyConfig, StudyError, StudySetting, ValidStudy};

use crate::CheckError;

/// A statistic over the runs of a check, compared with an upper limit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Statistic {
    /// The worst run.
    Max,
    /// The 95th percentile.
    P95,
    /// The median.
    P50,
    /// The mean.
    Mean,
}

impl Statistic {
    /// Every statistic, with its key in the check file.
    pub const ALL: [(Statistic, &'static str); 4] = [
        (Statistic::Max, "max"),
        (Statistic::P95, "p95"),
        (Statistic::P50, "p50"),
        (Statistic::Mean, "mean"),
    ];

    /// The key in the check file.
    pub fn key(self) -> &'static str {
        Self::ALL
            .iter()
            .find(|(s, _)| *s == self)
            .map(|(_, k)| *k)
            .expect("every statistic has a key")
    }

    /// Its value in a figure's spread.
    pub fn of(self, s: &magstand_study::summary::Stats) -> f64 {
        match self {
            Statistic::Max => s.max,
            Statistic::P95 => s.p95,
            Statistic::P50 => s.p50,
            Statistic::Mean => s.mean,
        }
    }
}

/// One efficiency ratio against the Cramer-Rao bound.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Ratio {
    /// `crlb_ratio`: parameter variance over the bound.
    Crlb,
    /// `mse_crlb_ratio`: parameter mean squared error (bias included) over the bound.
    MseCrlb,
}

impl Ratio {
    /// The key in the check file and in SUMMARY.json.
    pub fn key(self) -> &'static str {
        match self {
            Ratio::Crlb => "crlb_ratio",
            Ratio::MseCrlb => "mse_crlb_ratio",
        }
    }
}

/// One limit of a check.
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum Limit {
    /// A study figure's statistic over the runs is at most `max`.
    Figure {
        /// The figure.
        figure: FigureId,
        /// Which statistic.
        statistic: Statistic,
        /// Upper limit, in the figure's unit.
        max: f64,
    },
    /// An efficiency ratio of the study is at most `max`.
    Ratio {
        /// Which ratio.
        ratio: Ratio,
        /// Upper limit.
        max: f64,
    },
    /// At most `max` runs in which the method failed to fit.
    Failures {
        /// Upper limit.
        max: usize,
    },
    /// The diagnosis of every run's recording names exactly these effects (sorted).
    Verdict {
        /// Expected names; empty for "no significant mismatch".
        names: Vec<String>,
    },
    /// An exported firmware parameter lies in `[lo, hi]` in every run.
    Parameter {
        /// Which autopilot.
        autopilot: Autopilot,
        /// The magnetometer instance the name belongs to.
        instance: usize,
        /// Parameter name, as in the parameter file.
        name: String,
        /// Lower limit.
        lo: f64,
        /// Upper limit.
        hi: f64,
    },
}

impl Limit {
    /// The limit's key, as written in the check file (`rmse_ut.max`, `diagnose.verdict`,
    /// `export.ardupilot.COMPASS_MOT_Z`).
    pub fn key(&self) -> String {
        match self {
            Limit::Figure {
                figure, statistic, ..
            } => format!("{figure}.{}", statistic.key()),
            Limit::Ratio { ratio, .. } => format!("{}.max", ratio.key()),
            Limit::Failures { .. } => "failures.max".into(),
            Limit::Verdict { .. } => "diagnose.verdict".into(),
            Limit::Parameter {
                autopilot, name, ..
            } => format!("export.{}.{name}", autopilot_key(*autopilot)),
        }
    }

    /// The bound for people: `<= 0.05`, `= [thermal_drift]`, `in [40, 260]`.
    pub fn bound(&self) -> String {
        match self {
            Limit::Figure { max, .. } | Limit::Ratio { max, .. } => format!("<= {max}"),
            Limit::Failures { max } => format!("<= {max}"),
            Limit::Verdict { names } => format!("= [{}]", names.join(", ")),
            Limit::Parameter { lo, hi, .. } => format!("in [{lo}, {hi}]"),
        }
    }

    /// Whether the limit is on the Monte Carlo study's figures (rather than on each run's
    /// diagnosis or export).
    pub fn needs_study(&self) -> bool {
        matches!(
            self,
            Limit::Figure { .. } | Limit::Ratio { .. } | Limit::Failures { .. }
        )
    }
}

fn autopilot_key(a: Autopilot) -> &'static str {
    match a {
        Autopilot::Px4 => "px4",
        Autopilot::ArduPilot => "ardupilot",
    }
}

/// Figure names accepted beside [`FIGURE_NAMES`]: `heading_deg` is the heading error that
/// remains after compensation.
const FIGURE_ALIASES: [(&str, FigureId); 1] = [("heading_deg", FigureId::HeadingAfterDeg)];

/// The method a check names when it gives none: what `magstand fit` does with no options
/// (the choice among families, `chosen`), or for an entry with export limits the local linear
/// family that choice always tries (`automatic`).
pub const DEFAULT_METHOD: &str = "default";

/// Keys of an entry that are settings rather than limits.
const SETTINGS: [&str; 6] = ["name", "scenario", "method", "runs", "seed", "set"];

/// A check file as written, not yet checked.
#[derive(Debug, Clone)]
pub struct CheckFile {
    origin: String,
    base_dir: PathBuf,
    entries: Vec<toml::Table>,
}

impl CheckFile {
    /// Reads a check file; scenario files it names are found relative to its folder.
    pub fn load(path: &Path) -> Result<CheckFile, CheckError> {
        let text =
            magstand_core::input_file::read_document(path).map_err(|source| CheckError::Io {
                path: path.to_path_buf(),
                source,
            })?;
        let base = path.parent().map(Path::to_path_buf).unwrap_or_default();
        Self::from_toml_str(&text, &path.display().to_string(), &base)
    }

    /// Parses check-file text named `origin`; relative scenario paths resolve against
    /// `base_dir`.
    pub fn from_toml_str(
        text: &str,
        origin: &str,
        base_dir: &Path,
    ) -> Result<CheckFile, CheckError> {
        let file_error = |message: String| CheckError::File {
            origin: origin.into(),
            message,
        };
        let table: toml::Table = toml::from_str(text).map_err(|e| file_error(e.to_string()))?;
        if let Some(key) = table.keys().find(|k| *k != "check") {
            return Err(file_error(format!(
                "unknown top-level key `{key}`: expected only [[check]] entries"
            )));
        }
        let Some(checks) = table.get("check") else {
            return Err(file_error(
                "no [[check]] entry: expected at least one".into(),
            ));
        };
        let Some(array) = checks.as_array() else {
            return Err(file_error(
                "`check` must be an array of tables: write each entry as [[check]]".into(),
            ));
        };
        let entries = array
            .iter()
            .enumerate()
            .map(|(i, v)| {
                v.as_table().cloned().ok_or_else(|| {
                    file_error(format!("check {}: expected a table ([[check]])", i + 1))
                })
            })
            .collect::<Result<Vec<_>, _>>()?;
        if entries.is_empty() {
            return Err(file_error(
                "no [[check]] entry: expected at least one".into(),
            ));
        }
        Ok(CheckFile {
            origin: origin.into(),
            base_dir: base_dir.to_path_buf(),
            entries,
        })
    }

    /// Checks every entry: an error names the first entry and key that cannot run.
    pub fn check(self) -> Result<ValidChecks, CheckError> {
        let mut checks: Vec<ValidCheck> = Vec::new();
        for (i, entry) in self.entries.iter().enumerate() {
            let check = Entry {
                file: &self,
                index: i + 1,
                name: entry
                    .get("name")
                    .and_then(|v| v.as_str())
                    .unwrap_or("")
                    .to_string(),
                table: entry,
            }
            .check()?;
            if checks.iter().any(|c| c.name == check.name) {
                return Err(CheckError::Entry {
                    origin: self.origin.clone(),
                    index: i + 1,
                    name: check.name,
                    key: "name".into(),
                    message: "another check has this name: expected names unique in the file (they name the JUnit test cases)".into(),
                });
            }
            checks.push(check);
        }
        Ok(ValidChecks {
            origin: self.origin,
            checks,
        })
    }
}

/// One entry being checked.
struct Entry<'a> {
    file: &'a CheckFile,
    index: usize,
    name: String,
    table: &'a toml::Table,
}

impl Entry<'_> {
    fn error(&self, key: &str, message: impl Into<String>) -> CheckError {
        CheckError::Entry {
            origin: self.file.origin.clone(),
            index: self.index,
            name: self.name.clone(),
            key: key.into(),
            message: message.into(),
        }
    }

    fn string(&self, key: &str) -> Result<Option<String>, CheckError> {
        match self.table.get(key) {
            None => Ok(None),
            Some(toml::Value::String(s)) => Ok(Some(s.clone())),
            Some(v) => Err(self.error(key, format!("expected a string, found {}", v.type_str()))),
        }
    }

    fn integer(&self, key: &str, lo: i64, hi: i64) -> Result<Option<i64>, CheckError> {
        match self.table.get(key) {
            None => Ok(None),
            Some(toml::Value::Integer(n)) if (lo..=hi).contains(n) => Ok(Some(*n)),
            Some(v) => Err(self.error(
                key,
                format!("{v} is not allowed: expected a whole number in {lo}..={hi}"),
            )),
        }
    }

    /// A scenario named in the entry, relative to the check file's folder unless builtin or
    /// absolute.
    /// Also returns the files it read: the scenario file (not a shipped one) and the recording
    /// a replay program reads.
    fn scenario(
        &self,
        key: &str,
        spec: &str,
        set: &[String],
    ) -> Result<(ValidScenario, Vec<PathBuf>), CheckError> {
        let builtin = spec.starts_with("builtin:");
        let spec = if builtin || Path::new(spec).is_absolute() {
            spec.to_string()
        } else {
            self.file.base_dir.join(spec).display().to_string()
        };
        let scenario =
            Scenario::load_spec(&spec, set).map_err(|e| self.error(key, e.to_string()))?;
        let mut read: Vec<PathBuf> = (!builtin)
            .then(|| PathBuf::from(&spec))
            .into_iter()
            .collect();
        read.extend(scenario.input_files());
        Ok((scenario, read))
    }

    fn check(self) -> Result<ValidCheck, CheckError> {
        let name = self
            .string("name")?
            .filter(|n| !n.trim().is_empty())
            .ok_or_else(|| self.error("name", "missing: expected a name for the check"))?;
        let spec = self.string("scenario")?.ok_or_else(|| {
            self.error(
                "scenario",
                "missing: expected a scenario file or builtin:NAME",
            )
        })?;
        let set = match self.table.get("set") {
            None => Vec::new(),
            Some(toml::Value::Array(a)) => a
                .iter()
                .map(|v| v.as_str().map(str::to_string))
                .collect::<Option<Vec<_>>>()
                .ok_or_else(|| self.error("set", "expected an array of \"key=value\" strings"))?,
            Some(v) => {
                return Err(self.error(
                    "set",
                    format!(
                        "expected an array of \"key=value\" strings, found {}",
                        v.type_str()
                    ),
                ));
            }
        };
        let (scenario, mut inputs) = self.scenario("scenario", &spec, &set)?;
        let runs = self.integer("runs", 2, 100_000)?.ok_or_else(|| {
            self.error(
                "runs",
                "missing: expected the number of runs (at least 2, for a spread)",
            )
        })? as usize;
        let seed = self
            .integer("seed", 0, i64::MAX)?
            .map_or(scenario.params().seed, |s| s as u64);
        let method_id = self
            .string("method")?
            .unwrap_or_else(|| DEFAULT_METHOD.to_string());
        // What `fit` does with no options is the choice among families; firmware parameters
        // come from a local linear model, so an entry that checks them exports the local
        // linear family the choice always tries (a physics model has no export yet).
        let exports = self.table.contains_key("export");
        let id = if method_id == DEFAULT_METHOD && exports {
            methods::DEFAULT_ID.to_string()
        } else if method_id == DEFAULT_METHOD {
            methods::CHOSEN_ID.to_string()
        } else {
            method_id.clone()
        };
        let study = StudyConfig {
            methods: vec![id.clone()],
            ..StudyConfig::new(runs, seed)
        }
        .check(&scenario)
        .map_err(|e| match e {
            StudyError::InvalidSetting {
                setting: StudySetting::Methods,
                expected,
                ..
            } => self.error(
                "method",
                format!("`{method_id}` is not allowed: expected {expected}, or {DEFAULT_METHOD}"),
            ),
            e => self.error("scenario", e.to_string()),
        })?;
        let method = methods::by_id(&id).expect("the study checked the method id");
        let mut limits = Vec::new();
        let mut nominal = None;
        for (key, value) in self.table {
            if SETTINGS.contains(&key.as_str()) {
                continue;
            }
            match key.as_str() {
                "diagnose" => {
                    let (verdict, n, read) = self.diagnose(value, &scenario)?;
                    limits.push(verdict);
                    nominal = Some(n);
                    inputs.extend(read);
                }
                "export" if !matches!(method.fitter, methods::Fitter::Config(_)) => {
                    return Err(self.error(
                        key,
                        format!(
                            "the method `{}` has no firmware parameters to check here: export limits need a single-configuration method ({})",
                            method.id,
                            methods::catalog()
                                .iter()
                                .map(|m| m.id)
                                .collect::<Vec<_>>()
                                .join(", ")
                        ),
                    ));
                }
                "export" => limits.extend(self.export(value)?),
                _ => limits.extend(self.figure(key, value, &method)?),
            }
        }
        if limits.is_empty() {
            return Err(self.error(
                "name",
                "no limits: expected at least one, e.g. rmse_ut.max = 0.05",
            ));
        }
        // A fit that fails in any run fails a study check unless the file allows it.
        if limits.iter().any(Limit::needs_study)
            && !limits.iter().any(|l| matches!(l, Limit::Failures { .. }))
        {
            limits.push(Limit::Failures { max: 0 });
        }
        Ok(ValidCheck {
            name,
            scenario_spec: spec,
            method_id,
            method,
            study,
            limits,
            nominal,
            inputs,
        })
    }

    /// A figure's table of statistics: `rmse_ut.max = 0.05`, `crlb_ratio.max = 1.2`,
    /// `failures.max = 0`.
    fn figure(
        &self,
        key: &str,
        value: &toml::Value,
        method: &Method,
    ) -> Result<Vec<Limit>, CheckError> {
        let known = || {
            let mut names: Vec<&str> = FIGURE_NAMES.to_vec();
            names.extend(FIGURE_ALIASES.iter().map(|(a, _)| *a));
            names.extend([
                "crlb_ratio",
                "mse_crlb_ratio",
                "failures",
                "diagnose",
                "export",
            ]);
            names.join(", ")
        };
        let figure = FigureId::from_name(key).or_else(|| {
            FIGURE_ALIASES
                .iter()
                .find(|(a, _)| *a == key)
                .map(|(_, f)| *f)
        });
        let ratio = match key {
            "crlb_ratio" => Some(Ratio::Crlb),
            "mse_crlb_ratio" => Some(Ratio::MseCrlb),
            _ => None,
        };
        if figure.is_none() && ratio.is_none() && key != "failures" {
            return Err(self.error(
                key,
                format!(
                    "unknown figure or setting; expected a setting ({}) or a figure: {}",
                    SETTINGS.join(", "),
                    known()
                ),
            ));
        }
        let Some(stats) = value.as_table() else {
            return Err(self.error(
                key,
                format!("expected a table of limits, e.g. {key}.max = 1.0"),
            ));
        };
        if ratio.is_some() && !method.fixed_structure {
            return Err(self.error(
                key,
                format!(
                    "the method `{}` has no Cramer-Rao ratio: only the paper's fixed 3-RBF structure has one (methods {})",
                    method.id,
                    methods::catalog()
                        .iter()
                        .filter(|m| m.fixed_structure)
                        .map(|m| m.id)
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            ));
        }
        let mut limits = Vec::new();
        for (stat, v) in stats {
            let full = format!("{key}.{stat}");
            let number = match v {
                toml::Value::Float(x) => *x,
                toml::Value::Integer(n) => *n as f64,
                v => {
                    return Err(
                        self.error(&full, format!("expected a number, found {}", v.type_str()))
                    );
                }
            };
            if !(number.is_finite() && number >= 0.0) {
                return Err(self.error(
                    &full,
                    format!("{number} is not allowed: expected a finite number >= 0"),
                ));
            }
            if let Some(figure) = figure {
                let statistic = Statistic::ALL
                    .iter()
                    .find(|(_, k)| *k == stat)
                    .map(|(s, _)| *s)
                    .ok_or_else(|| {
                        self.error(
                            &full,
                            format!(
                                "unknown statistic; expected one of {} (each an upper limit over the runs)",
                                Statistic::ALL.map(|(_, k)| k).join(", ")
                            ),
                        )
                    })?;
                limits.push(Limit::Figure {
                    figure,
                    statistic,
                    max: number,
                });
                continue;
            }
            if stat != "max" {
                return Err(self.error(
                    &full,
                    format!("unknown statistic; {key} is one number per study: expected {key}.max"),
                ));
            }
            limits.push(match ratio {
                Some(ratio) => Limit::Ratio { ratio, max: number },
                None if number.fract() == 0.0 => Limit::Failures {
                    max: number as usize,
                },
                None => {
                    return Err(self.error(
                        &full,
                        format!("{number} is not allowed: expected a whole number of runs"),
                    ));
                }
            });
        }
        Ok(limits)
    }

    /// `diagnose.verdict = [...]` and the optional `diagnose.nominal`.
    fn diagnose(
        &self,
        value: &toml::Value,
        scenario: &ValidScenario,
    ) -> Result<(Limit, ValidScenario, Vec<PathBuf>), CheckError> {
        let Some(table) = value.as_table() else {
            return Err(self.error(
                "diagnose",
                "expected a table, e.g. diagnose.verdict = [\"thermal_drift\"]",
            ));
        };
        if let Some(k) = table.keys().find(|k| *k != "verdict" && *k != "nominal") {
            return Err(self.error(
                &format!("diagnose.{k}"),
                "unknown key: expected diagnose.verdict and, optionally, diagnose.nominal",
            ));
        }
        let known: BTreeSet<&str> = magstand_diagnose::effects::names()
            .into_iter()
            .chain([magstand_diagnose::UNEXPLAINED])
            .collect();
        let names = table
            .get("verdict")
            .ok_or_else(|| {
                self.error(
                    "diagnose.verdict",
                    "missing: expected the names the diagnosis must give, e.g. [\"thermal_drift\"], or [] for none",
                )
            })?
            .as_array()
            .and_then(|a| {
                a.iter()
                    .map(|v| v.as_str().map(str::to_string))
                    .collect::<Option<BTreeSet<String>>>()
            })
            .ok_or_else(|| self.error("diagnose.verdict", "expected an array of effect names"))?;
        if let Some(bad) = names.iter().find(|n| !known.contains(n.as_str())) {
            return Err(self.error(
                "diagnose.verdict",
                format!(
                    "unknown effect `{bad}`: expected names from {}",
                    known.into_iter().collect::<Vec<_>>().join(", ")
                ),
            ));
        }
        let (nominal, read) = match table.get("nominal") {
            None => (
                magstand_diagnose::unstated_nominal()
                    .map_err(|e| self.error("diagnose.nominal", e.to_string()))?,
                Vec::new(),
            ),
            Some(toml::Value::String(spec)) => self.scenario("diagnose.nominal", spec, &[])?,
            Some(v) => {
                return Err(self.error(
                    "diagnose.nominal",
                    format!(
                        "expected a scenario file or builtin:NAME, found {}",
                        v.type_str()
                    ),
                ));
            }
        };
        let (motors, nominal_motors) = (
            scenario.params().motors.count,
            nominal.params().motors.count,
        );
        if motors != nominal_motors {
            return Err(self.error(
                "diagnose.nominal",
                format!(
                    "the nominal stand has {nominal_motors} motors, the scenario {motors}: expected the same stand"
                ),
            ));
        }
        Ok((
            Limit::Verdict {
                names: names.into_iter().collect(),
            },
            nominal,
            read,
        ))
    }

    /// `export.ardupilot.NAME = [lo, hi]` and `export.px4.NAME = [lo, hi]`.
    fn export(&self, value: &toml::Value) -> Result<Vec<Limit>, CheckError> {
        let Some(table) = value.as_table() else {
            return Err(self.error(
                "export",
                "expected a table, e.g. export.ardupilot.COMPASS_MOT_Z = [40, 260]",
            ));
        };
        let mut limits = Vec::new();
        for (target, params) in table {
            let autopilot = match target.as_str() {
                "ardupilot" => Autopilot::ArduPilot,
                "px4" => Autopilot::Px4,
                _ => {
                    return Err(self.error(
                        &format!("export.{target}"),
                        "unknown autopilot: expected ardupilot or px4",
                    ));
                }
            };
            let Some(params) = params.as_table() else {
                return Err(self.error(
                    &format!("export.{target}"),
                    "expected a table of parameter ranges, e.g. COMPASS_MOT_Z = [40, 260]",
                ));
            };
            for (name, range) in params {
                let key = format!("export.{target}.{name}");
                let instance = autopilot
                    .instances()
                    .find(|&i| autopilot.parameter_names(i).contains(name))
                    .ok_or_else(|| {
                        let first = *autopilot.instances().start();
                        self.error(
                            &key,
                            format!(
                                "unknown parameter: expected one of {} (or another instance's)",
                                autopilot.parameter_names(first).join(", ")
                            ),
                        )
                    })?;
                let bounds: Option<Vec<f64>> = range.as_array().and_then(|a| {
                    a.iter()
                        .map(|v| v.as_float().or_else(|| v.as_integer().map(|n| n as f64)))
                        .collect()
                });
                let (lo, hi) = match bounds.as_deref() {
                    Some(&[lo, hi]) if lo.is_finite() && hi.is_finite() && lo <= hi => (lo, hi),
                    _ => {
                        return Err(self.error(
                            &key,
                            format!("{range} is not allowed: expected [lo, hi], two finite numbers with lo <= hi"),
                        ));
                    }
                };
                limits.push(Limit::Parameter {
                    autopilot,
                    instance,
                    name: name.clone(),
                    lo,
                    hi,
                });
            }
        }
        Ok(limits)
    }
}

/// One checked entry, ready to run.
#[derive(Debug, Clone)]
pub struct ValidCheck {
    /// Its name.
    pub name: String,
    /// The scenario as the file names it.
    pub scenario_spec: String,
    /// The method as the file names it (`default` included).
    pub method_id: String,
    /// The method fitted.
    pub method: Method,
    /// The study whose runs the check measures.
    pub study: ValidStudy,
    /// The limits, in the file's order (a `failures.max = 0` added to a study check that
    /// states none).
    pub limits: Vec<Limit>,
    /// The nominal stand the diagnosis compares with, when the check has a verdict.
    pub nominal: Option<ValidScenario>,
    /// The files the check reads: its scenario and nominal files (not shipped ones) and the
    /// recordings they replay.
    pub inputs: Vec<PathBuf>,
}

impl ValidCheck {
    /// Runs of the check.
    pub fn runs(&self) -> usize {
        self.study.config().runs
    }

    /// Its seed.
    pub fn seed(&self) -> u64 {
        self.study.config().seed
    }
}

/// A checked check file.
#[derive(Debug, Clone)]
pub struct ValidChecks {
    /// The file.
    pub origin: String,
    /// Its entries.
    pub checks: Vec<ValidCheck>,
}

impl ValidChecks {
    /// Every file the checks read beside the check file (scenarios, nominal stands and the
    /// recordings they replay), for a caller that must not write over them.
    pub fn input_files(&self) -> Vec<PathBuf> {
        self.checks
            .iter()
            .flat_map(|c| c.inputs.iter().cloned())
            .collect()
    }
}
