//! Scenario files: every parameter of a simulated test-stand run, in TOML.
//!
//! A scenario is read as an unchecked [`Scenario`] (serde rejects unknown keys and wrong
//! types, naming the key and line), optionally changed by `key=value` overrides, and then
//! checked into a [`ValidScenario`], the only form the simulator accepts. Checking tests every
//! value against its allowed range and names the dotted key of the first one that is not.
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::battery::SupplyParams;
use crate::error::{Checker, SimError};
use crate::hysteresis::HysteresisParams;
use crate::interference::InterferenceParams;
use crate::magnetometer::MagnetometerParams;
use crate::motion::MotionParams;
use crate::motor::MotorParams;
use crate::noise::NoiseParams;
use crate::program::{DifferentialParams, ProgramParams};
use crate::stand::StandParams;
use crate::thermal::ThermalParams;
use crate::variation::StudyParams;
use crate::wiring::WiringParams;
use magstand_core::Vec3;

/// Where the motor-caused disturbance comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum DisturbanceSource {
    /// Currents through the wiring, by Biot-Savart.
    #[default]
    Wiring,
    /// The paper's identified model (Tables I-III) of the overall throttle command, so that a
    /// scenario reproduces the paper's curves exactly.
    PaperTables,
}

/// `[disturbance]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DisturbanceParams {
    /// Source of the disturbance.
    pub source: DisturbanceSource,
    /// Scale applied to the paper-table disturbance (1 reproduces the tables).
    pub scale: f64,
}

impl Default for DisturbanceParams {
    fn default() -> Self {
        Self {
            source: DisturbanceSource::Wiring,
            scale: 1.0,
        }
    }
}

/// `[logging]`: which columns are written and the delay between streams.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct LoggingParams {
    /// Delay of the magnetometer stream against the command stream, s: each row's field was
    /// measured this long before the row's time stamp. Off (0) by default.
    pub mag_delay_s: f64,
    /// Delay of the command stream against the magnetometer stream, s: each row's commands
    /// acted this long before the row's time stamp (a logger that stamps a command when it
    /// is written, after it was sent). Off (0) by default.
    pub command_delay_s: f64,
    /// Write `bat_v` and `bat_a`.
    pub record_power: bool,
    /// Write `temp_c`.
    pub record_temp: bool,
    /// Write the accelerometer and gyro.
    pub record_imu: bool,
    /// Write the ground truth columns.
    pub record_truth: bool,
    /// Write the attitude (`att_q*`).
    pub record_attitude: bool,
}

impl LoggingParams {
    /// How long before its time stamp each row's field was measured, against the time its
    /// commands acted, s: the magnetometer's delay less the commands'. Negative where the
    /// commands are logged later than the field.
    pub fn read_delay_s(&self) -> f64 {
        self.mag_delay_s - self.command_delay_s
    }

    /// Sets the delays so that [`LoggingParams::read_delay_s`] is `delay_s`: a positive one the
    /// magnetometer's, a negative one the commands'.
    pub fn set_read_delay_s(&mut self, delay_s: f64) {
        self.mag_delay_s = delay_s.max(0.0);
        self.command_delay_s = (-delay_s).max(0.0);
    }
}

impl Default for LoggingParams {
    fn default() -> Self {
        Self {
            mag_delay_s: 0.0,
            command_delay_s: 0.0,
            record_power: true,
            record_temp: false,
            record_imu: false,
            record_truth: true,
            record_attitude: false,
        }
    }
}

fn d_physics() -> f64 {
    1000.0
}

/// A scenario as read, not yet checked.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scenario {
    /// Short name.
    pub name: String,
    /// What the scenario is for.
    #[serde(default)]
    pub description: String,
    /// Seed used when none is given on the command line.
    #[serde(default)]
    pub seed: u64,
    /// Physics rate, Hz.
    #[serde(default = "d_physics")]
    pub physics_hz: f64,
    /// Throttle program.
    pub program: ProgramParams,
    /// Attitude-like differential commands on top of the program.
    #[serde(default)]
    pub differential: DifferentialParams,
    /// ESCs and motors.
    #[serde(default)]
    pub motors: MotorParams,
    /// Bench supply or battery.
    #[serde(default)]
    pub supply: SupplyParams,
    /// Conductors near the magnetometer.
    #[serde(default)]
    pub wiring: WiringParams,
    /// Source of the disturbance.
    #[serde(default)]
    pub disturbance: DisturbanceParams,
    /// Noise.
    #[serde(default)]
    pub noise: NoiseParams,
    /// Board heating and offset drift.
    #[serde(default)]
    pub thermal: ThermalParams,
    /// Ferromagnetic hysteresis.
    #[serde(default)]
    pub hysteresis: HysteresisParams,
    /// Alternating field from equipment beside the stand.
    #[serde(default)]
    pub interference: InterferenceParams,
    /// The sensor.
    #[serde(default)]
    pub magnetometer: MagnetometerParams,
    /// The rigid body and its mount.
    #[serde(default)]
    pub stand: StandParams,
    /// A gimbal turning the whole stand (a flight's attitude changes).
    #[serde(default)]
    pub motion: MotionParams,
    /// Columns and stream delay.
    #[serde(default)]
    pub logging: LoggingParams,
    /// What a Monte Carlo study changes from run to run.
    #[serde(default)]
    pub study: StudyParams,
    /// The dotted keys the scenario's text wrote out (`motors.dead_zone`, ...): what its author
    /// stated about the stand, as against the defaults filled in for the rest.
    #[serde(skip)]
    stated: StatedKeys,
}

/// The keys a scenario's text wrote out. Not part of its physics: two scenarios with the same
/// values are equal however they were written.
#[derive(Debug, Clone, Default)]
struct StatedKeys(std::collections::BTreeSet<String>);

impl PartialEq for StatedKeys {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

/// A checked scenario, ready to simulate.
#[derive(Debug, Clone, PartialEq)]
pub struct ValidScenario {
    scenario: Scenario,
    origin: String,
    replay: Option<(Vec<f64>, Vec<Vec<f64>>)>,
}

impl ValidScenario {
    /// The checked parameters.
    pub fn params(&self) -> &Scenario {
        &self.scenario
    }

    /// Where the scenario came from.
    pub fn origin(&self) -> &str {
        &self.origin
    }

    /// Replayed commands (times, per-motor commands), for a replay program.
    pub fn replay(&self) -> Option<(&[f64], &[Vec<f64>])> {
        self.replay
            .as_ref()
            .map(|(t, c)| (t.as_slice(), c.as_slice()))
    }

    /// The files this scenario read besides itself: a replay program's recording.
    pub fn input_files(&self) -> Vec<PathBuf> {
        match &self.scenario.program {
            ProgramParams::Replay { file } => vec![PathBuf::from(file)],
            _ => Vec::new(),
        }
    }

    /// The fully resolved scenario as TOML, so a run can be repeated exactly. A replay
    /// program's file is written as the absolute path it was loaded from.
    pub fn to_toml(&self) -> String {
        toml::to_string(&self.scenario).expect("a checked scenario always serializes")
    }

    /// The scenario with `key=value` overrides applied to its fully resolved form (so defaults
    /// and array elements can be overridden too), checked again.
    pub fn with_overrides(&self, overrides: &[String]) -> Result<ValidScenario, SimError> {
        if overrides.is_empty() {
            return Ok(self.clone());
        }
        let mut s = Scenario::from_toml_with_overrides(&self.to_toml(), &self.origin, overrides)?;
        // `to_toml` writes every key out: what is stated is what this scenario stated, and
        // the keys the overrides set.
        s.stated = self.scenario.stated.clone();
        s.stated
            .0
            .extend(overrides.iter().flat_map(|o| override_keys(o)));
        let with = format!("{} (with overrides {})", self.origin, overrides.join(", "));
        s.check(&with, None)
    }

    /// The validation series of a study: this scenario with `[study] validation` applied.
    pub fn validation(&self) -> Result<ValidScenario, SimError> {
        self.with_overrides(&self.scenario.study.validation)
    }

    /// Back to an unchecked scenario, e.g. to change a parameter and check again.
    pub fn into_inner(self) -> Scenario {
        self.scenario
    }
}

/// The dotted key an override `key=value` sets and the tables above it
/// (`motors.dead_zone=0.3` gives `motors` and `motors.dead_zone`; an index is left out).
fn override_keys(text: &str) -> Vec<String> {
    let key = text.split_once('=').map_or(text, |(k, _)| k).trim();
    let parts: Vec<&str> = key
        .split('.')
        .map(|p| p.split_once('[').map_or(p, |(name, _)| name))
        .collect();
    (1..=parts.len()).map(|n| parts[..n].join(".")).collect()
}

/// Every dotted key of `table`, tables and their members alike (`motors`, `motors.count`).
fn dotted_keys(table: &toml::Table) -> std::collections::BTreeSet<String> {
    fn walk(t: &toml::Table, prefix: &str, out: &mut std::collections::BTreeSet<String>) {
        for (k, v) in t {
            let key = format!("{prefix}{k}");
            if let Some(inner) = v.as_table() {
                walk(inner, &format!("{key}."), out);
            }
            out.insert(key);
        }
    }
    let mut out = std::collections::BTreeSet::new();
    walk(table, "", &mut out);
    out
}

/// The key of a wrong-typed value that the TOML error cannot point at. The program table is
/// read by its `kind`, so a wrong type inside it is reported at the `[program]` header; the
/// key is the one whose removal changes the error. Only tried after a failure.
fn misfit_key(text: &str, error: &toml::de::Error) -> Option<String> {
    if !error.message().starts_with("invalid type") {
        return None;
    }
    let table: toml::Table = text.parse().ok()?;
    for (name, value) in &table {
        let Some(inner) = value.as_table() else {
            continue;
        };
        for key in inner.keys() {
            let mut without = table.clone();
            without.get_mut(name)?.as_table_mut()?.remove(key);
            match without.try_into::<Scenario>() {
                Err(e) if e.message() == error.message() => {}
                _ => return Some(format!("{name}.{key}")),
            }
        }
    }
    None
}

fn parse_error(origin: &str, e: impl std::fmt::Display) -> SimError {
    SimError::Parse {
        origin: origin.to_string(),
        message: e.to_string().trim_end().to_string(),
    }
}

impl Scenario {
    /// The stand modules' tables, in the order their fields are added at the sensor. A new
    /// stand module is registered here, with one line; its check and its module follow.
    pub(crate) fn module_params(&self) -> [&dyn crate::stand_module::ModuleParams; 2] {
        [&self.hysteresis, &self.thermal]
    }

    /// Parses scenario TOML; `origin` names it in errors.
    pub fn from_toml_str(text: &str, origin: &str) -> Result<Self, SimError> {
        let mut s: Scenario = toml::from_str(text).map_err(|e| match misfit_key(text, &e) {
            Some(key) => SimError::Parse {
                origin: origin.to_string(),
                message: format!("key `{key}`: {}", e.message().trim_end()),
            },
            None => parse_error(origin, e),
        })?;
        if let Ok(table) = text.parse::<toml::Table>() {
            s.stated = StatedKeys(dotted_keys(&table));
        }
        Ok(s)
    }

    /// Whether the scenario's text wrote out `key` (a dotted key such as `motors.dead_zone`),
    /// rather than leaving it to its default.
    pub fn states(&self, key: &str) -> bool {
        self.stated.0.contains(key)
    }

    /// The dotted keys the scenario's text wrote out, in order: what [`Scenario::states`]
    /// answers for.
    pub fn stated_keys(&self) -> Vec<String> {
        self.stated.0.iter().cloned().collect()
    }

    /// The same physics with exactly `keys` stated (a scenario read back from a file that
    /// writes every key out, with what its author had stated recorded beside it).
    pub fn with_stated_keys(mut self, keys: impl IntoIterator<Item = String>) -> Self {
        self.stated.0 = keys.into_iter().collect();
        self
    }

    /// The same physics with nothing stated: every constant is a default, a starting point
    /// rather than a claim about the stand (magstand's nominal stand when the user gives none).
    pub fn with_nothing_stated(mut self) -> Self {
        self.stated.0.clear();
        self
    }

    /// Parses scenario TOML and applies `key=value` overrides (dotted keys, TOML values; a value
    /// that is not valid TOML is taken as a string).
    pub fn from_toml_with_overrides(
        text: &str,
        origin: &str,
        overrides: &[String],
    ) -> Result<Self, SimError> {
        if overrides.is_empty() {
            return Self::from_toml_str(text, origin);
        }
        let original: toml::Table = text.parse().map_err(|e| parse_error(origin, e))?;
        // The scenario as written must parse on its own, so that an error found after the
        // overrides is theirs.
        Self::from_toml_str(text, origin)?;
        let merged = |skip: Option<usize>| -> Result<toml::Table, SimError> {
            let mut table = original.clone();
            for (k, o) in overrides.iter().enumerate() {
                if Some(k) != skip {
                    apply_override(&mut table, o)?;
                }
            }
            Ok(table)
        };
        let table = merged(None)?;
        let stated = dotted_keys(&table);
        let error = match table.try_into::<Self>() {
            Ok(mut s) => {
                s.stated = StatedKeys(stated);
                return Ok(s);
            }
            Err(e) => e,
        };
        // Name the `--set` whose removal makes the scenario parse, rather than a line of the
        // merged TOML the user never wrote. (Overrides that only parse together, such as a
        // new `supply.kind` with its keys, are tried as a whole above.)
        for (k, o) in overrides.iter().enumerate() {
            if merged(Some(k))?.try_into::<Self>().is_ok() {
                return Err(SimError::Override {
                    text: o.clone(),
                    message: error.message().trim_end().to_string(),
                });
            }
        }
        Err(parse_error(
            &format!("{origin} (with --set {})", overrides.join(", --set ")),
            error.message(),
        ))
    }

    /// Reads a scenario file, applies overrides and checks it. Relative paths inside (a replay
    /// program's file) are resolved against the file's folder.
    pub fn load(path: &Path, overrides: &[String]) -> Result<ValidScenario, SimError> {
        let text =
            magstand_core::input_file::read_document(path).map_err(|source| SimError::Io {
                path: path.to_path_buf(),
                source,
            })?;
        let origin = path.display().to_string();
        let base = path.parent().map(Path::to_path_buf).unwrap_or_default();
        Self::from_toml_with_overrides(&text, &origin, overrides)?.check(&origin, Some(&base))
    }

    /// Loads and checks the scenario a command line names: `builtin:NAME` for a shipped
    /// scenario ([`crate::builtin`]), anything else a file (whose relative references resolve
    /// against its folder).
    pub fn load_spec(spec: &str, overrides: &[String]) -> Result<ValidScenario, SimError> {
        let Some(name) = spec.strip_prefix("builtin:") else {
            return Self::load(Path::new(spec), overrides);
        };
        let text = crate::builtin::get(name).ok_or_else(|| SimError::Parse {
            origin: spec.into(),
            message: format!(
                "no shipped scenario `{name}`; shipped: {}",
                crate::builtin::ALL
                    .iter()
                    .map(|(n, _)| *n)
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        })?;
        Self::from_toml_with_overrides(text, spec, overrides)?.check(spec, None)
    }

    /// Checks every value and loads what the scenario refers to.
    pub fn check(
        mut self,
        origin: &str,
        base_dir: Option<&Path>,
    ) -> Result<ValidScenario, SimError> {
        let c = Checker { origin, table: "" };
        c.range("physics_hz", self.physics_hz, 10.0, 100_000.0)?;
        self.program.check(&c, self.motors.count)?;
        c.range(
            "differential.amplitude",
            self.differential.amplitude,
            0.0,
            0.5,
        )?;
        c.range(
            "differential.frequency_hz",
            self.differential.frequency_hz,
            0.0,
            self.physics_hz / 4.0,
        )?;
        self.motors.check(&c)?;
        self.supply.check(&c)?;
        self.supply.check_idle_load(
            &c,
            self.supply.avionics_current_a()
                + self.motors.count as f64 * self.motors.idle_current_a,
        )?;
        self.magnetometer.check(&c, self.physics_hz)?;
        // A stand whose wiring nobody wrote out has the default layout for its own motor
        // count: the default's four arms would leave a hexacopter's fifth and sixth motors
        // without leads, and their field, differing from the others', would be taken as the
        // stand's (a motor asymmetry of the nominal physics that no stand has).
        if !self.states("wiring")
            && self.motors.count != crate::wiring::DEFAULT_ARMS
            && self
                .wiring
                .is_default_layout_for(crate::wiring::DEFAULT_ARMS)
        {
            let extra = std::mem::take(&mut self.wiring.extra_motor_ut_per_a);
            self.wiring = WiringParams::default_for(self.motors.count);
            self.wiring.extra_motor_ut_per_a = extra;
        }
        self.wiring.check(
            &c,
            self.motors.count,
            Vec3::from(self.magnetometer.position_m),
        )?;
        c.range("disturbance.scale", self.disturbance.scale, -100.0, 100.0)?;
        self.noise.check(&c)?;
        for module in self.module_params() {
            module.check(&c.in_table(module.table()))?;
        }
        self.interference.check(&c)?;
        self.stand.check(&c, self.physics_hz)?;
        self.motion.check(&c)?;
        c.range("logging.mag_delay_s", self.logging.mag_delay_s, 0.0, 10.0)?;
        c.range(
            "logging.command_delay_s",
            self.logging.command_delay_s,
            0.0,
            10.0,
        )?;
        self.study.check(&c)?;
        let replay = match &mut self.program {
            ProgramParams::Replay { file } => {
                let mut path = PathBuf::from(&*file);
                if path.is_relative()
                    && let Some(b) = base_dir
                {
                    path = b.join(path);
                }
                let rec = magstand_core::recording_csv::read(&path)?;
                let n = rec.motor_count();
                if n != 1 && n != self.motors.count {
                    return Err(c.fail(
                        "program.file",
                        format!("{} ({n} motor columns)", path.display()),
                        &format!("a recording with a single thr column or {} motor columns (motors.count)", self.motors.count),
                    ));
                }
                *file = std::path::absolute(&path)
                    .unwrap_or(path)
                    .display()
                    .to_string();
                Some((rec.t_s, rec.thr))
            }
            _ => None,
        };
        Ok(ValidScenario {
            scenario: self,
            origin: origin.to_string(),
            replay,
        })
    }
}

/// Sets `a.b.c = value` in a TOML table.
fn apply_override(table: &mut toml::Table, text: &str) -> Result<(), SimError> {
    let fail = |message: &str| SimError::Override {
        text: text.to_string(),
        message: message.to_string(),
    };
    let (key, raw) = text
        .split_once('=')
        .ok_or_else(|| fail("expected key=value"))?;
    let parts: Vec<&str> = key.trim().split('.').collect();
    if parts.iter().any(|p| p.is_empty()) {
        return Err(fail("the key is empty or has an empty part"));
    }
    let value = match format!("v = {}", raw.trim()).parse::<toml::Table>() {
        Ok(mut t) => t.remove("v").expect("just parsed"),
        Err(_) => toml::Value::String(raw.trim().to_string()),
    };
    let mut cur = table;
    let (last, index) = split_index(parts[parts.len() - 1]).map_err(|m| fail(&m))?;
    for p in &parts[..parts.len() - 1] {
        let entry = cur
            .entry(p.to_string())
            .or_insert_with(|| toml::Value::Table(toml::Table::new()));
        cur = entry
            .as_table_mut()
            .ok_or_else(|| fail(&format!("`{p}` is not a table")))?;
    }
    match index {
        None => {
            cur.insert(last.to_string(), value);
        }
        Some(i) => {
            let array = cur
                .get_mut(last)
                .and_then(toml::Value::as_array_mut)
                .ok_or_else(|| fail(&format!("`{last}` is not an array here")))?;
            let len = array.len();
            let slot = array.get_mut(i).ok_or_else(|| {
                fail(&format!(
                    "index {i} is outside `{last}`, which has {len} elements"
                ))
            })?;
            *slot = value;
        }
    }
    Ok(())
}

/// `name[i]` into `("name", Some(i))`, `name` into `("name", None)`.
fn split_index(part: &str) -> Result<(&str, Option<usize>), String> {
    match part.split_once('[') {
        None => Ok((part, None)),
        Some((name, rest)) => {
            let i = rest
                .strip_suffix(']')
                .and_then(|i| i.trim().parse().ok())
                .ok_or_else(|| format!("`{part}`: expected `name[index]`"))?;
            Ok((name, Some(i)))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MINIMAL: &str = "name = \"t\"\n[program]\nkind = \"stair\"\nsteps = 5\ndwell_s = 2.0\n";

    fn check(text: &str, overrides: &[&str]) -> Result<ValidScenario, SimError> {
        let o: Vec<String> = overrides.iter().map(|s| s.to_string()).collect();
        Scenario::from_toml_with_overrides(text, "s.toml", &o)?.check("s.toml", None)
    }

    #[test]
    fn minimal_scenario_gets_defaults_and_round_trips() {
        let v = check(MINIMAL, &[]).unwrap();
        assert_eq!(v.params().motors.count, 4);
        let again = Scenario::from_toml_str(&v.to_toml(), "resolved").unwrap();
        assert_eq!(&again, v.params());
    }

    #[test]
    fn unknown_key_is_named() {
        let e = check(&format!("{MINIMAL}[supply]\nkind = \"battery\"\ncells = 3\ncapacty_ah = 2\ninternal_resistance_ohm = 0.01\n"), &[]).unwrap_err().to_string();
        assert!(e.contains("capacty_ah"), "{e}");
    }

    #[test]
    fn wrong_type_is_named() {
        let e = check(&format!("{MINIMAL}[motors]\ncount = \"four\"\n"), &[])
            .unwrap_err()
            .to_string();
        assert!(e.contains("count"), "{e}");
    }

    /// Regression: the default wiring had leads along four arms whatever the motor count, so
    /// a hexacopter's motors 5 and 6 carried no field and motors 1 to 4 one of -0.048 µT/A
    /// on z. A diagnosis of a six-motor stand with alike wiring took that difference for the
    /// stand's, and named `motor_asymmetry` (or `unexplained`) on every effect-free control
    /// of the independent generator's hexacopter. The default layout now has one lead pair
    /// per motor, and a motor count set by an override (as a diagnosis sets the recording's)
    /// takes it too; a `[wiring]` table written out stays as written.
    #[test]
    fn a_stand_with_no_wiring_written_has_leads_for_each_of_its_motors() {
        let text = "name = \"x\"\n[program]\nkind = \"stair\"\nsteps = 4\ndwell_s = 1.0\n";
        let gains = |v: &ValidScenario| {
            let p = v.params();
            p.wiring
                .gains(p.motors.count, Vec3::from(p.magnetometer.position_m))
                .motor_ut_per_a
        };
        let quad = check(text, &[]).unwrap();
        assert_eq!(quad.params().wiring, WiringParams::default());
        for motors in [6, 8] {
            for v in [
                check(&format!("{text}[motors]\ncount = {motors}\n"), &[]).unwrap(),
                quad.with_overrides(&[format!("motors.count={motors}")])
                    .unwrap(),
            ] {
                let g = gains(&v);
                assert_eq!(g.len(), motors);
                for (m, gm) in g.iter().enumerate() {
                    assert!(
                        (gm - g[0]).norm() < 1e-9 && g[0].norm() > 0.01,
                        "{motors} motors: motor {} {gm:?} against motor 1 {:?}",
                        m + 1,
                        g[0]
                    );
                }
            }
        }
        // Written out, a layout is the user's, whatever the motor count.
        let written = format!(
            "{text}[motors]\ncount = 6\n[[wiring.segment]]\ncarries = \"motor1\"\nstart_m = [0.05, 0.0, 0.0]\nend_m = [0.2, 0.0, 0.0]\n"
        );
        let v = check(&written, &[]).unwrap();
        assert_eq!(v.params().wiring.segment.len(), 1);
    }

    #[test]
    fn the_keys_written_out_are_stated_and_the_defaults_are_not() {
        let text = "name = \"x\"\n[program]\nkind = \"stair\"\nsteps = 4\ndwell_s = 1.0\n[motors]\ndead_zone = 0.2\n";
        let s = Scenario::from_toml_str(text, "x").unwrap();
        assert!(s.states("motors.dead_zone") && s.states("motors") && s.states("program.steps"));
        assert!(!s.states("motors.spinup_tau_s") && !s.states("supply"));
        let o = Scenario::from_toml_with_overrides(text, "x", &["motors.spinup_tau_s=0.1".into()])
            .unwrap();
        assert!(o.states("motors.spinup_tau_s") && o.states("motors.dead_zone"));
        assert!(!s.with_nothing_stated().states("motors.dead_zone"));
        // A checked scenario changed by overrides states what it stated and what they set,
        // not every key its resolved TOML writes out.
        let v = Scenario::from_toml_str(text, "x")
            .unwrap()
            .check("x", None)
            .unwrap()
            .with_overrides(&["magnetometer.soft_iron[0]=[1.0,0.0,0.0]".into()])
            .unwrap();
        let p = v.params();
        assert!(p.states("motors.dead_zone") && p.states("magnetometer.soft_iron"));
        assert!(!p.states("motors.spinup_tau_s") && !p.states("supply.kind"));
    }

    /// Regression: a wrong type inside `[program]` was reported at the `[program]` header
    /// line, without the key, because the program is read by its `kind`.
    #[test]
    fn a_wrong_type_inside_the_program_names_the_key() {
        let text = "name = \"x\"\n[program]\nkind = \"stair\"\nsteps = 4\ndwell_s = \"abc\"\n";
        let e = Scenario::from_toml_str(text, "bad.toml")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("bad.toml") && e.contains("`program.dwell_s`") && e.contains("expected f64"),
            "{e}"
        );
    }

    #[test]
    fn out_of_range_values_name_key_and_range() {
        let cases = [
            ("supply.capacity_ah=-1", "supply.capacity_ah"),
            ("program.max=1.5", "program.max"),
            ("magnetometer.odr_hz=0", "magnetometer.odr_hz"),
            ("physics_hz=0", "physics_hz"),
            ("motors.dead_zone=1.2", "motors.dead_zone"),
            ("motors.current_lag_s=-0.1", "motors.current_lag_s"),
            ("motors.current_lag_s=nan", "motors.current_lag_s"),
        ];
        for (o, key) in cases {
            let e = check(
                MINIMAL,
                &[
                    "supply.kind=\"battery\"",
                    "supply.cells=3",
                    "supply.capacity_ah=2",
                    "supply.internal_resistance_ohm=0.01",
                    o,
                ],
            )
            .unwrap_err()
            .to_string();
            assert!(e.contains(key) && e.contains("expected"), "{o}: {e}");
        }
    }

    #[test]
    fn overrides_change_nested_values_and_reject_nonsense() {
        let v = check(MINIMAL, &["motors.dead_zone=0.3", "program.steps=7"]).unwrap();
        assert_eq!(v.params().motors.dead_zone, 0.3);
        assert!(check(MINIMAL, &["no_equals_sign"]).is_err());
        assert!(check(MINIMAL, &["name.x=1"]).is_err());
    }

    #[test]
    fn a_conductor_through_the_sensor_is_refused() {
        let text = format!(
            "{MINIMAL}[[wiring.segment]]\ncarries = \"total\"\nstart_m = [-0.1, 0.0, 0.0]\nend_m = [0.1, 0.0, 0.0]\n"
        );
        let e = check(&text, &[]).unwrap_err().to_string();
        assert!(e.contains("wiring.segment[0]") && e.contains("2 mm"), "{e}");
    }

    #[test]
    fn carrier_beyond_the_motor_count_is_refused() {
        let text = format!(
            "{MINIMAL}[[wiring.segment]]\ncarries = \"motor5\"\nstart_m = [-0.1, 0.1, 0.0]\nend_m = [0.1, 0.1, 0.0]\n"
        );
        let e = check(&text, &[]).unwrap_err().to_string();
        assert!(e.contains("wiring.segment[0].carries"), "{e}");
    }

    #[test]
    fn overrides_reach_defaults_and_array_elements_of_the_resolved_scenario() {
        let v = check(MINIMAL, &[]).unwrap();
        let moved = v
            .with_overrides(&["magnetometer.position_m[1]=0.02".into()])
            .unwrap();
        assert_eq!(moved.params().magnetometer.position_m, [0.0, 0.02, 0.0]);
        let e = v
            .with_overrides(&["magnetometer.position_m[3]=0.02".into()])
            .unwrap_err()
            .to_string();
        assert!(e.contains("index 3") && e.contains("3 elements"), "{e}");
        let e = v
            .with_overrides(&["motors.kv_rpm_per_v[0]=1.0".into()])
            .unwrap_err()
            .to_string();
        assert!(e.contains("not an array"), "{e}");
    }

    #[test]
    fn study_draws_follow_their_distributions_and_are_checked() {
        use rand::SeedableRng;
        let text = format!(
            "{MINIMAL}[study]\nvalidation = ['program.direction=\"down\"']\n\
             [[study.vary]]\nkey = \"motors.kv_rpm_per_v\"\nnormal = [900.0, 10.0]\n\
             [[study.vary]]\nkey = \"noise.sensor_sd_ut\"\nuniform = [0.1, 0.2]\n"
        );
        let v = check(&text, &[]).unwrap();
        assert_eq!(
            v.validation().unwrap().params().program,
            check(MINIMAL, &["program.direction=\"down\""])
                .unwrap()
                .params()
                .program
        );
        let mut rng = rand::rngs::Xoshiro256PlusPlus::seed_from_u64(5);
        let draws: Vec<(f64, f64)> = (0..2000)
            .map(|_| {
                let d = v.with_overrides(&v.params().study.draw(&mut rng)).unwrap();
                (
                    d.params().motors.kv_rpm_per_v,
                    d.params().noise.sensor_sd_ut,
                )
            })
            .collect();
        let n = draws.len() as f64;
        let mean_kv = draws.iter().map(|d| d.0).sum::<f64>() / n;
        let sd_kv = (draws.iter().map(|d| (d.0 - mean_kv).powi(2)).sum::<f64>() / n).sqrt();
        assert!((mean_kv - 900.0).abs() < 1.0, "mean {mean_kv}");
        assert!((sd_kv - 10.0).abs() < 0.6, "sd {sd_kv}");
        assert!(draws.iter().all(|d| (0.1..0.2).contains(&d.1)));

        let bad = format!(
            "{MINIMAL}[[study.vary]]\nkey = \"motors.kv_rpm_per_v\"\nnormal = [900.0, 10.0]\nuniform = [1.0, 2.0]\n"
        );
        let e = check(&bad, &[]).unwrap_err().to_string();
        assert!(
            e.contains("study.vary[0]") && e.contains("exactly one"),
            "{e}"
        );
        let bad = format!(
            "{MINIMAL}[[study.vary]]\nkey = \"noise.sensor_sd_ut\"\nuniform = [0.3, 0.2]\n"
        );
        let e = check(&bad, &[]).unwrap_err().to_string();
        assert!(e.contains("study.vary[0].uniform[1]"), "{e}");
        // A draw outside the parameter's range is refused by the parameter's own check.
        let neg = format!(
            "{MINIMAL}[[study.vary]]\nkey = \"noise.sensor_sd_ut\"\nuniform = [-2.0, -1.0]\n"
        );
        let v = check(&neg, &[]).unwrap();
        let e = v
            .with_overrides(&v.params().study.draw(&mut rng))
            .unwrap_err()
            .to_string();
        assert!(e.contains("noise.sensor_sd_ut"), "{e}");
    }
}
