//! `magstand fit`.
use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::{Args, ValueEnum};

use crate::files;
use crate::simulate_cmd::load_scenario;
use magstand_core::magnetometer_frame::SensorToBody;
use magstand_core::magnetometer_slot::MagnetometerSlot;
use magstand_core::{AXES, recording_csv};
use magstand_ident::{Estimation, Family, FitConfig, FitSetting, InputKind, Model, Structure};

/// Estimation method on the command line.
#[derive(Clone, Copy, ValueEnum)]
pub enum EstimationArg {
    /// One weighted least squares per local model (the paper's).
    Local,
    /// All local models in one least squares.
    Global,
}

/// Model family on the command line.
#[derive(Clone, Copy, ValueEnum)]
pub enum MethodArg {
    /// RBF-blended local linear models (structure flags, or automatic without them).
    LocalLinear,
    /// ArduPilot compassmot's running average through the origin.
    Ardupilot,
    /// PX4's least-squares line (slope only).
    Px4,
    /// A cubic with intercept.
    Cubic,
    /// The stand's electrical physics replayed from the recording's commands and calibrated
    /// (dead zone, spin-up, supply, current law, wiring gains, motors-off field and timing;
    /// the diagnosis's calibration kept as a model). With --scenario, the constants it writes
    /// out are held.
    Physics,
}

/// Input on the command line.
#[derive(Clone, Copy, ValueEnum)]
pub enum InputArg {
    /// Overall throttle (mean motor command).
    Throttle,
    /// Each motor's command.
    Motors,
    /// Supply current `bat_a`.
    Current,
}

/// Weighting on the command line.
#[derive(Clone, Copy, ValueEnum)]
pub enum WeightingArg {
    /// Ordinary least squares (the paper's).
    None,
    /// Inverse of the fitted, input-dependent noise variance.
    InverseVariance,
}

/// Arguments of `magstand fit`.
#[derive(Args)]
#[command(allow_negative_numbers = true)]
pub struct FitArgs {
    /// Recording CSV.
    #[arg(long)]
    recording: PathBuf,
    /// Where to write the model (JSON).
    #[arg(long = "model-out")]
    model_out: PathBuf,
    /// Model family. Default: every family that applies is fitted without the held-out time
    /// blocks and the one with the lowest held-out error is kept, a family with fewer
    /// parameters winning when within one standard error (the table is printed and stored in
    /// the model file). Any structure, input, estimation or weighting flag fits the local
    /// linear family as asked instead.
    #[arg(long, value_enum)]
    method: Option<MethodArg>,
    /// The stand for the physics family (a file, or builtin:NAME): the constants it writes out
    /// are held, the others calibrated. Without it nothing about the stand is assumed.
    #[arg(long)]
    scenario: Option<String>,
    /// Number of local models, evenly spaced on 0..1 (width 2(K-1) unless --width).
    #[arg(long)]
    rbf: Option<usize>,
    /// RBF centres on the normalized input, comma-separated.
    #[arg(long, value_delimiter = ',')]
    centers: Option<Vec<f64>>,
    /// RBF width parameter eps (eq. 13).
    #[arg(long)]
    width: Option<f64>,
    /// Local (the paper's) or global estimation. Default: local with structure flags, global
    /// for the automatic structure.
    #[arg(long, value_enum)]
    estimation: Option<EstimationArg>,
    /// Model input (default: the overall throttle).
    #[arg(long, value_enum)]
    inputs: Option<InputArg>,
    /// Row weighting. Default: none with structure flags (the paper's), inverse-variance for
    /// the automatic structure.
    #[arg(long, value_enum)]
    weighting: Option<WeightingArg>,
    /// Largest number of local models for the automatic structure.
    #[arg(long = "max-models", default_value_t = 10)]
    max_models: usize,
    /// A flight log (needs the attitude columns): take the Earth field out first, fitted from
    /// the log (`fit`) or from the World Magnetic Model (`wmm`, with --lat, --lon, --year), and
    /// estimate the delay of the magnetometer behind the commands.
    #[arg(long, value_enum)]
    earth: Option<EarthArg>,
    /// Latitude for --earth wmm, degrees north.
    #[arg(long)]
    lat: Option<f64>,
    /// Longitude for --earth wmm, degrees east.
    #[arg(long)]
    lon: Option<f64>,
    /// Altitude for --earth wmm, m.
    #[arg(long, default_value_t = 0.0)]
    alt_m: f64,
    /// Date for --earth wmm, decimal year (2025.5 is mid-2025); 1900 to 2030.
    #[arg(long)]
    year: Option<f64>,
    /// Largest delay searched with --earth, s: the samples' age from 0 up to it, the
    /// magnetometer's delay behind the commands either way (negative: commands logged late).
    #[arg(long, default_value_t = 0.5)]
    max_delay_s: f64,
    /// With --earth: rows tilted further than this from level (a flip, a crash) are left out,
    /// degrees; 180 keeps every row.
    #[arg(long, default_value_t = magstand_ident::flight::DEFAULT_MAX_TILT_DEG)]
    max_tilt_deg: f64,
}

/// Earth-field source on the command line.
#[derive(Clone, Copy, ValueEnum)]
pub enum EarthArg {
    /// Fitted from the flight itself (needs turns).
    Fit,
    /// The reference field at --lat, --lon, --year: the World Magnetic Model from 2020 to
    /// 2030, IGRF-13 from 1900 to 2020.
    #[value(alias = "igrf", alias = "model")]
    Wmm,
}

/// The flight preparation of `--earth`: prints what it found and returns the stand-equivalent
/// recording.
fn take_out_earth_field(
    a: &FitArgs,
    earth: EarthArg,
    rec: &magstand_core::Recording,
    origin: &str,
) -> Result<(
    magstand_core::Recording,
    String,
    Option<magstand_core::Vec3>,
)> {
    use magstand_ident::flight::{EarthField, FlightConfig, FlightInput, prepare_flight};
    let mut model_name = "fitted";
    let field = match earth {
        EarthArg::Fit => EarthField::Fit,
        EarthArg::Wmm => {
            let (Some(lat), Some(lon), Some(year)) = (a.lat, a.lon, a.year) else {
                bail!(
                    "--earth wmm needs --lat, --lon and --year (magstand import prints them when the log has GPS)"
                );
            };
            let at = magstand_logs::earth::earth_field(lat, lon, a.alt_m, year)?;
            model_name = at.model;
            EarthField::Known(at.ned_ut)
        }
    };
    let cfg = FlightConfig {
        earth: field,
        input: match a.inputs {
            Some(InputArg::Current) => FlightInput::Current,
            _ => FlightInput::Throttle,
        },
        max_delay_s: a.max_delay_s,
        max_tilt_deg: a.max_tilt_deg,
    };
    let p = prepare_flight(rec, &cfg, origin)?;
    let e = p.earth_ned_ut;
    let input = match cfg.input {
        FlightInput::Current => "current",
        FlightInput::Throttle => "commands",
    };
    // A negative delay: the input is logged after it acted.
    let input_delay = if p.delay_s < 0.0 {
        format!(
            "{:.3} s ahead of the {input} (the {input} logged late)",
            -p.delay_s
        )
    } else {
        format!("{:.3} s behind the {input}", p.delay_s)
    };
    let summary = format!(
        "Earth field ({}): N {:.2} E {:.2} D {:.2} uT (|e| {:.2} uT, inclination {:.1} deg); magnetometer samples {:.3} s behind the attitude and {}; stacked-fit residual {:.2} uT RMS; attitude: tilt up to {:.0} deg, {:.0} deg of heading covered",
        model_name,
        e.x,
        e.y,
        e.z,
        e.norm(),
        e.z.atan2(e.xy().norm()).to_degrees(),
        p.attitude_delay_s,
        input_delay,
        p.residual_rms_ut,
        p.attitude_span_deg.0,
        p.attitude_span_deg.1
    );
    for w in &p.warnings {
        eprintln!("warning: {}", in_flag_terms(w));
    }
    Ok((p.recording, summary, p.reference_ut))
}

/// The flag of each identification setting: the library names settings by its configuration
/// (`max_delay_s`), the command line by its flags.
fn flag(setting: FitSetting) -> Option<&'static str> {
    Some(match setting {
        FitSetting::LocalModels => "--rbf",
        FitSetting::Centers => "--centers",
        FitSetting::Widths => "--width",
        FitSetting::MaxModels => "--max-models",
        FitSetting::Input => "--inputs",
        FitSetting::Earth => "--earth",
        FitSetting::MaxDelayS => "--max-delay-s",
        FitSetting::MaxTiltDeg => "--max-tilt-deg",
        FitSetting::Forgetting => "--forgetting",
        _ => return None,
    })
}

/// An identification message in the command line's terms: each setting it names between
/// backticks becomes its flag.
pub fn in_flag_terms(text: &str) -> String {
    let flags: Vec<(&str, &str)> = FitSetting::ALL
        .iter()
        .filter_map(|&s| Some((s.name(), flag(s)?)))
        .collect();
    crate::flag_terms::in_flag_terms(text, &flags)
}

/// The fit settings the arguments describe.
fn config(a: &FitArgs) -> Result<FitConfig> {
    let structure_flags = a.rbf.is_some() || a.centers.is_some() || a.width.is_some();
    let estimation = a.estimation.map(|e| match e {
        EstimationArg::Local => Estimation::Local,
        EstimationArg::Global => Estimation::Global,
    });
    let mut cfg = match a.method.unwrap_or(MethodArg::LocalLinear) {
        MethodArg::LocalLinear if structure_flags => {
            FitConfig::stated_structure(a.centers.clone(), a.rbf, a.width, estimation)
                .map_err(|e| anyhow::anyhow!(in_flag_terms(&e.to_string())))?
        }
        MethodArg::LocalLinear => FitConfig::automatic_with(a.max_models, estimation),
        MethodArg::Ardupilot => FitConfig::baseline(Family::ArduPilot),
        MethodArg::Px4 => FitConfig::baseline(Family::Px4),
        MethodArg::Cubic => FitConfig::baseline(Family::Cubic),
        MethodArg::Physics => bail!("--method physics is not a local linear fit"),
    };
    if let Some(w) = a.weighting {
        cfg.weighted = matches!(w, WeightingArg::InverseVariance);
    }
    cfg.input = match a.inputs.unwrap_or(InputArg::Throttle) {
        InputArg::Throttle => InputKind::Throttle,
        InputArg::Motors => InputKind::Motors,
        InputArg::Current => InputKind::Current,
    };
    Ok(cfg)
}

/// Prints the short summary of a fitted model.
pub fn print_summary(model: &Model) {
    let terms = match &model.structure {
        Structure::LocalLinear(n) => format!(
            "{} local models, centres [{}]",
            n.partition.len(),
            n.partition
                .centers()
                .iter()
                .map(|c| format!("{c:.3}"))
                .collect::<Vec<_>>()
                .join(", ")
        ),
        Structure::Polynomial { coefficients } => {
            format!("polynomial of degree {}", coefficients[0].len() - 1)
        }
    };
    println!(
        "model: {} on {:?} input, {terms}",
        model.method, model.input.kind
    );
    if let Some(s) = &model.summary {
        println!(
            "{} rows ({} in held-out time blocks)",
            s.rows, s.holdout_rows
        );
        println!(
            "{:>4} {:>9} {:>7} {:>16} {:>13} {:>13}",
            "axis", "rmse_ut", "r2", "holdout_rmse_ut", "sd_off_ut", "sd_full_ut"
        );
        for a in 0..3 {
            let (sd0, sd1) = model
                .sd
                .as_ref()
                .map(|m| (m.sd(0.0)[a], m.sd(1.0)[a]))
                .unwrap_or((f64::NAN, f64::NAN));
            // "-" where there is no figure: no rows held out, no noise model.
            let figure = |v: f64, shown: bool| {
                if shown && v.is_finite() {
                    format!("{v:.3}")
                } else {
                    "-".into()
                }
            };
            println!(
                "{:>4} {:>9.3} {:>7.4} {:>16} {:>13} {:>13}",
                AXES[a],
                s.rmse_ut[a],
                s.r2[a],
                figure(s.holdout_rmse_ut[a], s.holdout_rows > 0),
                figure(sd0, true),
                figure(sd1, true)
            );
        }
    }
}

/// Prints the PX4 and ArduPilot figures beside the model's, on the same rows.
fn print_compatibility(model: &Model, rec: &magstand_core::Recording, origin: &str) -> Result<()> {
    let c = magstand_ident::compatibility::compatibility(model, rec, origin)?;
    println!(
        "beside the autopilots' lines on the same rows (PX4 keeps its line's slope only; interference as ArduPilot's compassmot: field change at the top of the recorded range, % of 530 mG{}):",
        if c.on_autopilot_throttle {
            "; the lines on the autopilot's own throttle, `autopilot_throttle`"
        } else {
            ""
        }
    );
    println!(
        "{:>12} {:>23} {:>26} {:>13}",
        "", "r2 x / y / z", "holdout_rmse_ut x / y / z", "interference"
    );
    for (name, f) in [
        ("magstand", Some(&c.model)),
        ("PX4 line", Some(&c.px4)),
        ("compassmot", c.ardupilot.as_ref()),
    ] {
        let Some(f) = f else {
            println!("{name:>12} {:>75}", "withheld (below)");
            continue;
        };
        println!(
            "{name:>12} {:>7.4} {:>7.4} {:>7.4} {:>8.3} {:>8.3} {:>8.3} {:>13}",
            f.r2[0],
            f.r2[1],
            f.r2[2],
            f.holdout_rmse_ut[0],
            f.holdout_rmse_ut[1],
            f.holdout_rmse_ut[2],
            f.interference_pct
                .map_or("withheld".to_string(), |p| format!("{p:.0} %"))
        );
    }
    for w in &c.withheld {
        println!("withheld: {w}");
    }
    println!(
        "(ArduPilot's guidance on interference: below 30 % fine, 30-60 % a grey zone, above 60 % unacceptable)"
    );
    Ok(())
}

/// What the arguments ask for.
enum Plan {
    /// One local linear (or autopilot, or cubic) fit as configured.
    Local(magstand_ident::ValidFitConfig),
    /// The stand's physics.
    Physics,
    /// Every family that applies, one kept.
    Choose,
}

/// The plan the arguments describe: the automatic choice unless a family or any structure,
/// input, estimation or weighting flag is given.
fn plan(a: &FitArgs) -> Result<Plan> {
    let local_flags = a.rbf.is_some()
        || a.centers.is_some()
        || a.width.is_some()
        || a.inputs.is_some()
        || a.estimation.is_some()
        || a.weighting.is_some()
        || a.max_models != 10;
    match a.method {
        None if !local_flags => Ok(Plan::Choose),
        Some(MethodArg::Physics) if local_flags => bail!(
            "--method physics takes none of --rbf, --centers, --width, --inputs, --estimation, --weighting, --max-models: its structure is the stand's physics"
        ),
        Some(MethodArg::Physics) => Ok(Plan::Physics),
        _ if a.scenario.is_some() => bail!(
            "--scenario describes the stand for --method physics (or the automatic choice); a local linear fit does not use it"
        ),
        _ => Ok(Plan::Local(config(a)?.check()?)),
    }
}

/// The warnings of the calibration a physics model came from, on stderr.
fn print_calibration_warnings(m: &magstand_diagnose::AugmentedModel) {
    for w in &m.calibration_warnings {
        eprintln!("warning: {w}");
    }
}

/// Prints the physics model's summary: what was calibrated and its held-out error.
fn print_physics(p: &magstand_diagnose::model_choice::PhysicsFit) {
    let d = &p.diagnosis;
    println!(
        "model: physics (the stand's electrical physics replayed from the recording's commands; nominal stand: {})",
        d.scenario
    );
    let calibrated: Vec<String> = d
        .baseline
        .calibration
        .iter()
        // The stand's constants and the timing; the wiring coefficients are in the file.
        .filter(|c| c.name.contains('.') || c.name == "command_lead")
        .map(|c| {
            format!(
                "{} = {} {}",
                c.name,
                magstand_diagnose::diagnosis::value_with_sd(c.value, c.sd),
                c.unit
            )
        })
        .collect();
    if !calibrated.is_empty() {
        println!("calibrated: {}", calibrated.join(", "));
    }
    let named: Vec<&str> = d.verdict.iter().map(String::as_str).collect();
    if !named.is_empty() {
        println!(
            "effects the data demanded (see `magstand diagnose`): {}",
            named.join(", ")
        );
    }
    // The calibrated model's, with every accepted term: a calibration is a term too, and the
    // last named effect's figure would leave out the terms after it.
    let after = d.simulation.holdout_rmse_after_ut;
    println!(
        "{} rows ({} in held-out time blocks); held-out RMSE x {:.3} y {:.3} z {:.3} uT",
        d.settings.rows[0] + d.settings.rows[1],
        d.settings.rows[1],
        after[0],
        after[1],
        after[2]
    );
}

/// Prints the table of an automatic choice.
pub fn print_choice(c: &magstand_ident::family_choice::FamilyChoice) {
    println!(
        "model families, judged on {} held-out rows in {} time blocks:",
        c.holdout_rows, c.holdout_blocks
    );
    println!(
        "  {:<18} {:>6} {:>27} {:>24}",
        "family", "params", "holdout_rmse_ut x / y / z", "excess over best (uT^2)"
    );
    for f in &c.families {
        let mark = if f.family == c.chosen {
            "  <- chosen"
        } else {
            ""
        };
        match (f.holdout_rmse_ut, f.parameters) {
            (Some(r), Some(p)) => println!(
                "  {:<18} {:>6} {:>8.4} {:>8.4} {:>8.4} {:>24}{mark}",
                f.family,
                p,
                r[0],
                r[1],
                r[2],
                format!(
                    "{:.2e} +- {:.1e}",
                    f.excess_ut2.unwrap_or(0.0),
                    f.excess_se_ut2.unwrap_or(0.0)
                )
            ),
            _ => println!(
                "  {:<18} {:>6} {}",
                f.family,
                "-",
                f.note.as_deref().unwrap_or("not scored")
            ),
        }
    }
    println!("rule: {}", c.rule);
    println!("chosen: {}: {}", c.chosen, c.reason);
}

/// Runs `magstand fit`.
pub fn run(a: FitArgs) -> Result<()> {
    let plan = plan(&a)?;
    let nominal = match (&plan, &a.scenario) {
        (Plan::Local(_), _) => None,
        (_, Some(s)) => Some(load_scenario(s, &[])?),
        (_, None) => Some(magstand_diagnose::unstated_nominal()?),
    };
    let mut inputs = vec![a.recording.clone()];
    if let (Some(s), Some(n)) = (&a.scenario, &nominal) {
        inputs.extend(files::scenario_inputs(s, n));
    }
    files::refuse_overwriting_inputs(&inputs, &[&a.model_out])?;
    let mut rec = recording_csv::read(&a.recording)?;
    let origin = a.recording.display().to_string();
    // A stuck sensor fits any model with no error at all: a model of nothing, and firmware
    // parameters of zero that look like a result. (Fewer rows than a fit takes are refused
    // by the fit, with their count.)
    if let Some(why) = rec
        .unresponsive_magnetometer()
        .filter(|_| rec.len() >= magstand_ident::MIN_ROWS)
    {
        bail!("{origin}: {why}");
    }
    files::warn_doubts(&rec, &origin);
    let slot = MagnetometerSlot::of_recording(&rec, &a.recording)?;
    let to_body = SensorToBody::of_recording(&rec, &a.recording)?;
    // Printed after the model is written: a reader that closes stdout early must not cost it.
    let mut earth_summary = None;
    let mut flight_reference = None;
    if let Some(earth) = a.earth {
        let (taken_out, summary, reference) = take_out_earth_field(&a, earth, &rec, &origin)?;
        flight_reference = reference;
        rec = taken_out;
        earth_summary = Some(summary);
    }
    files::ensure_parent(&a.model_out)?;
    let save_err = || format!("writing {}", a.model_out.display());
    let mut choice_to_print = None;
    let model = match (plan, nominal) {
        (Plan::Local(cfg), _) => cfg.fit_recording_or(&rec, &origin, flight_reference)?,
        (Plan::Physics, Some(nominal)) => {
            let split = magstand_diagnose::model_choice::identification_split(&rec).check()?;
            let mut p =
                magstand_diagnose::model_choice::fit_physics(&rec, &origin, &nominal, &split)?;
            p.model.magnetometer = slot;
            p.model.magnetometer_to_body = to_body;
            p.model.save(&a.model_out).with_context(save_err)?;
            if let Some(s) = earth_summary {
                println!("{s}");
            }
            print_physics(&p);
            // The calibration's own warnings (a supply nobody stated, a flight's preparation);
            // the recording's doubts were printed when it was read.
            print_calibration_warnings(&p.model);
            println!("wrote {}", a.model_out.display());
            return Ok(());
        }
        (_, nominal) => {
            let nominal = match nominal {
                Some(n) => n,
                None => magstand_diagnose::unstated_nominal()?,
            };
            let (chosen, choice) = magstand_diagnose::model_choice::choose_model(
                &rec,
                &origin,
                &nominal,
                flight_reference,
            )?;
            match chosen {
                magstand_diagnose::model_choice::DisturbanceModel::Physics(m) => {
                    let m = magstand_diagnose::AugmentedModel {
                        magnetometer: slot,
                        magnetometer_to_body: to_body,
                        ..*m
                    };
                    m.save(&a.model_out).with_context(save_err)?;
                    if let Some(s) = earth_summary {
                        println!("{s}");
                    }
                    print_choice(&choice);
                    print_calibration_warnings(&m);
                    println!("wrote {}", a.model_out.display());
                    return Ok(());
                }
                magstand_diagnose::model_choice::DisturbanceModel::LocalLinear(m) => {
                    choice_to_print = Some(choice);
                    *m
                }
            }
        }
    };
    let model = Model {
        magnetometer: slot,
        magnetometer_to_body: to_body,
        ..model
    };
    model.save(&a.model_out).with_context(save_err)?;
    if let Some(s) = earth_summary {
        println!("{s}");
    }
    if let Some(c) = &choice_to_print {
        print_choice(c);
    }
    print_summary(&model);
    print_compatibility(&model, &rec, &origin)?;
    println!("wrote {}", a.model_out.display());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Parser)]
    struct Wrapper {
        #[command(flatten)]
        fit: FitArgs,
    }

    /// `magstand check`'s `method = "default"` and the studies' `automatic` stand for what
    /// `fit` does with no options: the two must not drift apart.
    #[test]
    fn library_setting_names_become_flags() {
        assert_eq!(
            in_flag_terms(
                "invalid setting `max_delay_s` = 12: raise `max_delay_s`, or give `earth`"
            ),
            "invalid setting `--max-delay-s` = 12: raise `--max-delay-s`, or give `--earth`"
        );
        // Every setting the command line has a flag for is translated.
        for s in FitSetting::ALL {
            let text = in_flag_terms(&format!("`{}`", s.name()));
            assert!(flag(s).is_none() || text.contains("--"), "{s}: {text}");
        }
    }

    #[test]
    fn the_default_fit_is_the_choice_and_flags_fit_as_asked() {
        let parse = |extra: &[&str]| {
            let mut args = vec!["fit", "--recording", "r.csv", "--model-out", "m.json"];
            args.extend(extra);
            Wrapper::try_parse_from(args).unwrap().fit
        };
        // `magstand check`'s `method = "default"` stands for this choice.
        assert!(matches!(plan(&parse(&[])).unwrap(), Plan::Choose));
        assert!(matches!(
            plan(&parse(&["--method", "physics"])).unwrap(),
            Plan::Physics
        ));
        // A flag of the local linear family is a statement: that family, as asked.
        let Plan::Local(cfg) = plan(&parse(&["--inputs", "throttle"])).unwrap() else {
            panic!("--inputs must fit the local linear family");
        };
        let automatic =
            magstand_ident::methods::by_id(magstand_ident::methods::DEFAULT_ID).unwrap();
        assert_eq!(cfg.config(), &automatic.config);
        assert!(plan(&parse(&["--method", "physics", "--rbf", "3"])).is_err());
    }
}
