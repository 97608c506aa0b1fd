//! The diagnosis in five stages, each a module of its own:
//!
//! 1. [`design`]: the recording's commands replayed through the nominal physics (with any
//!    terms' nonlinear parameters), the regressor columns of the baseline and of each term, and
//!    the weighted fit of such a design with a noise law from its own residuals.
//! 2. [`gain`]: the statistics of a held-out gain (held-out RMSE, per-block improvements, the
//!    combined one-sided test of a candidate's gain) and the white-noise test.
//! 3. [`forward`]: the forward search over the catalog, one accepted term per round; its
//!    candidates' fits (`forward::candidate`), the rules for stated and unstated stand
//!    constants (`forward::stated`), the replication of a name (`forward::replication`) and a
//!    parameter at the edge of its range (`forward::edges`) are modules of their own.
//! 4. [`refine`]: after each acceptance, the accepted terms' nonlinear parameters and the
//!    command timing refitted together.
//! 5. [`assembly`]: the final joint model, the augmented scenario and its simulation, what
//!    remains unexplained, and the diagnosis and model files.
//!
//! A flight log first goes through [`flight`]: the Earth field turned by the logged attitude,
//! the sensor offset and the magnetometer's delay are taken out, and the stand-equivalent
//! recording is diagnosed. [`diagnose`] then checks the recording against the nominal stand,
//! calibrates the baseline and runs the stages in order; [`command_hold`] adds a warning
//! where a stand recording's commands look held over several rows.
use magstand_core::Recording;
use magstand_sim::replay::{Logged, Trace, replay_logged};
use magstand_sim::{Scenario, ValidScenario};

use crate::diagnosis::Diagnosis;
use crate::effects::{Context, catalog};
use crate::fit::Weights;
use crate::locate::Rows;
use crate::observer::{DiagnoseObserver, Silent, Stage};
use crate::{DiagnoseConfig, DiagnoseError, ValidConfig};
use magstand_core::held_out::Split;

pub(crate) mod assembly;
pub(crate) mod command_hold;
pub(crate) mod design;
pub(crate) mod flight;
pub(crate) mod forward;
pub(crate) mod gain;
pub(crate) mod law_shape;
pub(crate) mod refine;

use forward::BaselineFit;

/// Fewest held-out blocks for the paired tests to mean anything.
const MIN_HOLDOUT_BLOCKS: usize = 5;

/// Fewest rows a diagnosis fits on (outside the held-out blocks).
const MIN_FIT_ROWS: usize = 50;

/// Diagnoses `rec` (named `origin` in messages) against the nominal scenario.
pub fn diagnose(
    rec: &Recording,
    origin: &str,
    nominal: &ValidScenario,
    config: &ValidConfig,
) -> Result<Diagnosis, DiagnoseError> {
    diagnose_observed(rec, origin, nominal, config, &Silent)
}

/// [`diagnose`], reporting each [`Stage`] it reaches to `observer` (the
/// diagnosis is the same, bit for bit).
pub fn diagnose_observed(
    rec: &Recording,
    origin: &str,
    nominal: &ValidScenario,
    config: &ValidConfig,
    observer: &dyn DiagnoseObserver,
) -> Result<Diagnosis, DiagnoseError> {
    diagnose_with(rec, origin, nominal, config, false, observer)
}

/// [`diagnose`], with the replay following the logged supply voltage from the start when
/// `follow_recorded_voltage` and the recording has `bat_v` (the physics model's baseline).
pub(crate) fn diagnose_with(
    rec: &Recording,
    origin: &str,
    nominal: &ValidScenario,
    config: &ValidConfig,
    follow_recorded_voltage: bool,
    observer: &dyn DiagnoseObserver,
) -> Result<Diagnosis, DiagnoseError> {
    let cfg = config.params();
    observer.stage(Stage::Baseline);
    // Of the recording as given: a flight's baseline takes the Earth's field out.
    let doubts = rec.doubts();
    let flight = flight::flight_baseline(rec, origin)?;
    let rec = flight.as_ref().map_or(rec, |f| &f.recording);
    // A supply nobody stated is a constant voltage.
    let benched = with_unstated_supply(nominal)?;
    let nominal = benched.as_ref().unwrap_or(nominal);
    // A motor count nobody stated is the recording's own.
    let counted;
    let nominal = match rec.motor_count() {
        n if n > 1
            && n != nominal.params().motors.count
            && !nominal.params().states("motors.count") =>
        {
            counted = nominal.with_overrides(&[format!("motors.count={n}")])?;
            &counted
        }
        _ => nominal,
    };
    // A dead zone nobody stated that no logged command exceeds starts at none.
    let running = with_running_motors(rec, nominal)?;
    let nominal = running.as_ref().unwrap_or(nominal);
    // In flight the vehicle's motors and battery are not the nominal stand's: where the
    // current is logged, the current-driven physics follows it.
    let follow_recorded_current = flight.is_some() && rec.bat_a.is_some();
    let (scenario, split, nominal_trace) =
        prepare(rec, origin, nominal, cfg, follow_recorded_current)?;
    let mut ctx = Context {
        rec,
        nominal: &scenario,
        split: &split,
        nominal_trace: &nominal_trace,
        rec_origin: origin.to_string(),
        command_lead: 0.5,
        flight: flight.is_some(),
        follow_recorded_voltage: follow_recorded_voltage && rec.bat_v.is_some(),
        follow_recorded_current,
        speed_powers: crate::fit::current_law_powers(&rec.thr),
        // A flight's motors are armed on every row it keeps: the column would repeat the
        // motors-off reference less the driven motors.
        armed_current: flight.is_none() && crate::fit::arming_varies(&rec.thr),
        motor_groups: crate::effects::motor_groups(&rec.thr),
        motor_current_law: None,
        current_law: None,
        replays: Default::default(),
        series_lags: Default::default(),
    };
    let base = calibrate_baseline(&mut ctx, cfg)?;
    let rows = Rows::new(rec, &split.block);
    let effects = catalog();
    let outcome = forward::forward_search(&mut ctx, &effects, &base, &rows, cfg, observer)?;
    observer.stage(Stage::Assembling);
    let mut d = assembly::assemble(&ctx, nominal, &base, outcome, &rows, cfg)?;
    // A flight's commands come from the import, interpolated at the magnetometer's times.
    if flight.is_none()
        && let Some(hold) = command_hold::held_commands(&rec.thr)
    {
        d.warnings.push(command_hold::warning(origin, hold));
    }
    if let Some(f) = flight {
        d.baseline.calibration.extend(f.calibration);
        // The flight's doubts first: they qualify everything after them.
        d.warnings.splice(0..0, f.warnings);
    }
    // After the flight's calibration joins the baseline's: its constants are fitted beside
    // the structure too.
    d.warnings.extend(assembly::unexplained_bias_warning(&d));
    d.warnings.extend(benched.as_ref().map(supply_warning));
    // The model carries the calibration's warnings; the recording's doubts are the
    // recording's, told wherever it is read.
    if let Some(m) = d.model.as_mut() {
        m.calibration_warnings = d.warnings.clone();
    }
    // And the recording's own (its units, its unread columns) before those.
    d.warnings
        .splice(0..0, doubts.into_iter().map(|w| format!("{origin}: {w}")));
    Ok(d)
}

/// What a diagnosis (or a physics fit) says of the constant voltage it replays where the
/// scenario states no `[supply]`: `benched` is that scenario with the constant voltage in its
/// supply's place ([`with_unstated_supply`]).
fn supply_warning(benched: &ValidScenario) -> String {
    format!(
        "{}: no [supply] is stated, so the nominal stand is replayed on a constant {} V supply \
         (not the simulator's default pack): a supply that sags is a finding, battery_sag",
        benched.origin(),
        benched.params().supply.no_load_voltage_v()
    )
}

/// `nominal` with the supply of the stand assumed when no scenario is given (a constant
/// voltage, [`crate::DEFAULT_NOMINAL`]) where it states no `[supply]`; None where it states
/// one or already has that supply. The simulator's default supply, which a scenario without
/// that table otherwise brings, is a 3-cell pack of 2.2 Ah: replayed as the nominal physics,
/// a stand's run empties it, and the motors slow in the model where nothing says they do (on
/// the independent generator's octocopter, a bench at 50 Hz, a scenario stating only the
/// dead zone named `battery_sag` and `unexplained`). A pack's sag is a finding, not an
/// assumption.
fn with_unstated_supply(nominal: &ValidScenario) -> Result<Option<ValidScenario>, DiagnoseError> {
    let constant = crate::unstated_nominal()?.params().supply.clone();
    let params = nominal.params();
    if params.states("supply") || params.supply == constant {
        return Ok(None);
    }
    let mut scenario = params.clone();
    scenario.supply = constant;
    Ok(Some(scenario.check(nominal.origin(), None)?))
}

/// `nominal` with its dead zone at 0 where no scenario states it and no logged command
/// exceeds it: none otherwise. An unstated dead zone is a starting point that the baseline
/// calibrates (over its whole search range), not a claim about the stand; left above every
/// command, the nominal motors would never run and the recording would be refused for a
/// constant nobody claimed (the simulator's default of 0.37 refused a stand run at up to
/// 0.36). A recording whose commands are all 0 is still refused, by name, in `prepare`.
fn with_running_motors(
    rec: &Recording,
    nominal: &ValidScenario,
) -> Result<Option<ValidScenario>, DiagnoseError> {
    let params = nominal.params();
    let largest = largest_command(rec);
    if params.states("motors.dead_zone") || largest > params.motors.dead_zone || largest <= 0.0 {
        return Ok(None);
    }
    let mut scenario = params.clone();
    scenario.motors.dead_zone = 0.0;
    Ok(Some(scenario.check(nominal.origin(), None)?))
}

/// The largest motor command `rec` logs, 0 where none is above 0.
fn largest_command(rec: &Recording) -> f64 {
    rec.thr.iter().flatten().fold(0.0, |a: f64, &c| a.max(c))
}

/// The diagnosis's held-out split: blocks of `block_s`, or of 1/150 of the time with data
/// (kept in 0.5..10 s), every `holdout_every`th held out.
pub(crate) fn held_out_split(t_s: &[f64], block_s: Option<f64>, holdout_every: usize) -> Split {
    let block_s = block_s.unwrap_or_else(|| {
        (magstand_core::held_out::duration_with_data_s(t_s) / 150.0).clamp(0.5, 10.0)
    });
    Split::new(t_s, block_s, holdout_every)
}

/// Checks that the recording fits the nominal stand and is long enough to hold out, and
/// returns the nominal physics for it, its split and its nominal replay.
fn prepare(
    rec: &Recording,
    origin: &str,
    nominal: &ValidScenario,
    cfg: &DiagnoseConfig,
    follow_recorded_current: bool,
) -> Result<(Scenario, Split, Trace), DiagnoseError> {
    let bad = |message: String| DiagnoseError::Recording {
        origin: origin.into(),
        message,
    };
    let motors = nominal.params().motors.count;
    let n_cols = rec.motor_count();
    if n_cols != motors && n_cols != 1 {
        return Err(bad(format!(
            "{n_cols} motor command columns, but the scenario {} has motors.count = {motors}: \
             expected {motors} thr_N columns (or one thr column for all motors)",
            nominal.origin()
        )));
    }
    // A stuck or disconnected sensor (an axis that reads the same in every row, often zero)
    // gives a residual with no noise at all, which any effect "explains": refuse it by name.
    if let Some(why) = rec.unresponsive_magnetometer() {
        return Err(bad(why));
    }
    let split = held_out_split(&rec.t_s, cfg.block_s, cfg.holdout_every);
    if split.holdout_blocks() < MIN_HOLDOUT_BLOCKS || split.fit_rows() < MIN_FIT_ROWS {
        // Shorter blocks give more of them, not more rows to fit: a third of the rows stays
        // held out whatever their length.
        let remedy = if split.fit_rows() < MIN_FIT_ROWS {
            format!(
                "a longer recording: with one block in {} held out, {MIN_FIT_ROWS} rows to fit \
                 take about {} rows",
                cfg.holdout_every,
                MIN_FIT_ROWS * cfg.holdout_every / (cfg.holdout_every - 1)
            )
        } else {
            "a longer recording, or a shorter `block_s`".to_string()
        };
        return Err(bad(format!(
            "{} rows in {} held-out blocks of {:.2} s: expected at least {MIN_FIT_ROWS} rows to \
             fit and {} held-out blocks ({remedy})",
            rec.len(),
            split.holdout_blocks(),
            split.block_s,
            MIN_HOLDOUT_BLOCKS
        )));
    }
    let mut scenario = nominal.params().clone();
    // The program is the recording's; the nominal stand's own logging delay is physics.
    scenario.study = Default::default();
    let logged = Logged::of(rec, false, follow_recorded_current);
    let nominal_trace = replay_logged(&scenario, &rec.t_s, &rec.thr, logged, 0.5);
    let avionics = scenario.supply.avionics_current_a();
    let max_motor_a = nominal_trace
        .total_a
        .iter()
        .map(|a| a - avionics)
        .fold(0.0, f64::max);
    if max_motor_a <= 0.0 {
        let largest = largest_command(rec);
        let dead_zone = scenario.motors.dead_zone;
        let why = if largest <= 0.0 {
            "every motor command is 0".to_string()
        } else if largest <= dead_zone && nominal.params().states("motors.dead_zone") {
            format!(
                "the largest motor command, {largest:.4}, is within the dead zone {dead_zone} that \
                 {} states (`motors.dead_zone`)",
                nominal.origin()
            )
        } else {
            format!("no motor draws current under the nominal physics (dead zone {dead_zone})")
        };
        return Err(bad(format!(
            "the motors never run: {why}; expected commands that drive the motors"
        )));
    }
    Ok((scenario, split, nominal_trace))
}

/// Calibrates the command timing and the baseline, and tests its held-out residual for white
/// noise.
fn calibrate_baseline(
    ctx: &mut Context,
    cfg: &DiagnoseConfig,
) -> Result<BaselineFit, DiagnoseError> {
    ctx.command_lead = refine::calibrate_timing(ctx, &[], &Weights(vec![[1.0; 3]; ctx.rec.len()]));
    let model = design::fit_model(ctx, &[], None)?;
    let z = gain::standardized(&model.fitted.residuals(&ctx.rec.mag_ut), &model.weights);
    let white = gain::whiteness(&z, ctx.split);
    Ok(BaselineFit {
        structured: white.iter().any(|&p| p < assembly::white_threshold(cfg)),
        white,
        lead: ctx.command_lead,
        model,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scenario(text: &str) -> ValidScenario {
        let text =
            format!("name = \"s\"\n[program]\nkind = \"stair\"\nsteps = 4\ndwell_s = 5.0\n{text}");
        magstand_sim::Scenario::from_toml_str(&text, "s")
            .and_then(|s| s.check("s", None))
            .unwrap_or_else(|e| panic!("{e}\n{text}"))
    }

    #[test]
    fn a_supply_nobody_stated_is_the_unstated_stands_constant_voltage() {
        let constant = crate::unstated_nominal().unwrap().params().supply.clone();
        let given = scenario("[motors]\ndead_zone = 0.1\n");
        let replayed = with_unstated_supply(&given)
            .unwrap()
            .expect("the default pack replaced");
        assert_eq!(replayed.params().supply, constant);
        // Nothing more is stated than the scenario stated, and nothing else changed.
        assert_eq!(
            replayed.params().stated_keys(),
            given.params().stated_keys()
        );
        assert_eq!(replayed.params().motors, given.params().motors);
        // A stated supply, of any kind, is the one replayed.
        for stated in [
            "[supply]\nkind = \"battery\"\ncells = 6\ncapacity_ah = 3.0\ninternal_resistance_ohm = 0.05\n",
            "[supply]\nkind = \"bench\"\nvoltage_v = 22.2\n",
        ] {
            let s = scenario(stated);
            assert!(with_unstated_supply(&s).unwrap().is_none(), "{stated}");
        }
        // No scenario: already that supply.
        let unstated = crate::unstated_nominal().unwrap();
        assert!(with_unstated_supply(&unstated).unwrap().is_none());
        // Said of the replaced supply (and only there: the warning is made from it).
        let said = supply_warning(&replayed);
        assert!(
            said.starts_with("s: no [supply] is stated") && said.contains("12 V"),
            "{said}"
        );
    }
}
