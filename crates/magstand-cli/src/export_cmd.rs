//! `magstand export`: a model as PX4 or ArduPilot parameters, as firmware code (C header or
//! `no_std` Rust module), or as a JSON document for other tools.
use std::io::Write;
use std::path::PathBuf;

use anyhow::{Result, bail};
use clap::{Args, ValueEnum};

use crate::files;
use magstand_core::magnetometer_frame::SensorToBody;
use magstand_core::magnetometer_slot::MagnetometerSlot;
use magstand_core::recording_csv;
use magstand_ident::InputKind;
use magstand_logs::export::json::export_json;
use magstand_logs::export::per_motor::{
    describe_per_motor, per_motor_fit, per_motor_over_prediction, per_motor_params,
};
use magstand_logs::export::{
    Autopilot, LineInput, Span, ardupilot_params, c_adaptive, c_header, describe,
    line_over_prediction, linear_approximation, px4_params, rust_adaptive, rust_module,
};
use magstand_logs::import::AUTOPILOT_THROTTLE;

/// What to export to.
#[derive(Clone, Copy, PartialEq, ValueEnum)]
enum Target {
    /// PX4 power compensation (CAL_MAG_COMP_TYP, CAL_MAGn_{X,Y,Z}COMP), QGroundControl format.
    Px4,
    /// ArduPilot compassmot (COMPASS_MOTCT, COMPASS_MOT_{X,Y,Z}), .param format.
    Ardupilot,
    /// ArduPilot per-motor compensation (COMPASS_PMOT*): needs a per-motor model and
    /// --recording with bat_v.
    ArdupilotPerMotor,
    /// The full model as a dependency-free C header.
    C,
    /// The full model as a no_std Rust module.
    Rust,
    /// A table of the full model and every exported figure, as JSON.
    Json,
    /// The recursive estimation of `compensate --adapt` as a dependency-free C header: the
    /// model's coefficients updated on the flight controller, sample by sample.
    CAdaptive,
    /// The same recursion as a no_std Rust module.
    RustAdaptive,
}

/// The line's input on the command line.
#[derive(Clone, Copy, ValueEnum)]
enum InputArg {
    /// Overall throttle, 0..1.
    Throttle,
    /// Battery current, A.
    Current,
}

/// Arguments of `magstand export`.
#[derive(Args)]
#[command(allow_negative_numbers = true)]
pub struct ExportArgs {
    /// Model file written by `magstand fit`.
    #[arg(long)]
    model: PathBuf,
    /// Target.
    #[arg(long = "to", value_enum)]
    target: Target,
    /// What the autopilot's line multiplies (default: the model's own input). A different one
    /// needs --recording.
    #[arg(long, value_enum)]
    input: Option<InputArg>,
    /// A recording the model applies to: the line is fitted over its rows (the way the vehicle
    /// was flown) rather than evenly over the input range.
    #[arg(long)]
    recording: Option<PathBuf>,
    /// Magnetometer instance: PX4's n in CAL_MAGn (from 0), ArduPilot's compass (from 1).
    #[arg(long)]
    instance: Option<usize>,
    /// Output file (default: standard output).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Forgetting factor of the exported recursion (c-adaptive, rust-adaptive), 0.9 to
    /// 0.999999; as `compensate --forgetting`.
    #[arg(long)]
    forgetting: Option<f64>,
}

/// Writes `text` to --out, or to stdout.
fn emit(a: &ExportArgs, text: &str) -> Result<()> {
    match &a.out {
        Some(path) => {
            files::ensure_parent(path)?;
            magstand_core::atomic_file::write_bytes(path, text.as_bytes())?;
            eprintln!("wrote {}", path.display());
        }
        None => std::io::stdout().write_all(text.as_bytes())?,
    }
    Ok(())
}

/// The autopilots' forms of a physics model, fitted over a recording's rows: the physics
/// predicts from the recording's commands through the stand's dynamics (spin-up, supply), so
/// it has no form over one input to write as code, and no line without the rows it applies
/// to.
fn export_physics(a: &ExportArgs, model: &magstand_diagnose::AugmentedModel) -> Result<()> {
    if !matches!(
        a.target,
        Target::Px4 | Target::Ardupilot | Target::ArdupilotPerMotor
    ) {
        bail!(
            "{}: a physics model replays the recording's commands through the stand's dynamics (spin-up, supply); it has no form over one input for --to c, rust, json, c-adaptive or rust-adaptive. Export it as px4, ardupilot or ardupilot-per-motor over a recording, or fit a local linear model for code",
            a.model.display()
        );
    }
    let Some(path) = &a.recording else {
        bail!(
            "{}: a physics model predicts from a recording's commands: give --recording R.csv, the rows the line (or the per-motor set) is fitted over",
            a.model.display()
        );
    };
    let rec = recording_csv::read(path)?;
    let origin = path.display().to_string();
    let fitted_on = MagnetometerSlot::agreeing_with(model.magnetometer, &rec, path)?;
    let fitted_on_log = fitted_on.is_some();
    let instance = instance(a, fitted_on)?;
    refuse_per_motor_without_it(a, fitted_on, model.magnetometer_to_body)?;
    let dist = model.dist_column(&rec, &origin)?;
    let reference = model.reference_ut();
    let input = match a.input {
        Some(InputArg::Current) => LineInput::Current,
        _ => LineInput::Throttle,
    };
    warn_of_the_autopilots_throttle(a, fitted_on_log, input, Some(&rec));
    let text = match a.target {
        Target::Px4 | Target::Ardupilot => {
            let line = line_over_prediction(&dist, reference, &rec, &origin, input)?;
            eprint!("{}", describe(&line));
            let frame = compensation_frame(
                a,
                fitted_on,
                (model.magnetometer, model.magnetometer_to_body),
                Some((&rec, path)),
            )?;
            line_params(a, &line, instance, frame)?
        }
        _ => {
            let fit = per_motor_over_prediction(&dist, reference, &rec, &origin)?;
            eprint!("{}", describe_per_motor(&fit));
            per_motor_params(&fit)
        }
    };
    emit(a, &text)
}

/// The settings that name a parameter or a form, checked before any work is done for them
/// (for every kind of model alike).
fn check_settings(a: &ExportArgs) -> Result<()> {
    let adaptive = matches!(a.target, Target::CAdaptive | Target::RustAdaptive);
    if a.forgetting.is_some() && !adaptive {
        bail!("--forgetting sets the recursion of --to c-adaptive or rust-adaptive");
    }
    match (a.target, a.instance) {
        (Target::Px4, Some(i)) if i > 3 => {
            bail!("--instance {i}: PX4 magnetometers are numbered CAL_MAG0 to CAL_MAG3")
        }
        (Target::Ardupilot, Some(i)) if !(1..=3).contains(&i) => {
            bail!("--instance {i}: ArduPilot compasses are numbered 1 to 3")
        }
        (Target::ArdupilotPerMotor, Some(i)) if i != 1 => bail!(
            "ArduPilot applies per-motor compensation to the first compass only; drop --instance or give 1"
        ),
        _ => Ok(()),
    }
}

/// The instance whose parameters are written: the magnetometer the model was fitted on
/// (`fitted_on`), which `--instance` may only repeat; where nothing says which that was, the
/// one `--instance` gives, or the first. A compensation written into another sensor's
/// parameters corrects that sensor by a field it does not see: the worst output an export can
/// give. A model fitted on the other firmware's log says nothing of this one's numbering, so
/// `--instance` must say it.
fn instance(a: &ExportArgs, fitted_on: Option<MagnetometerSlot>) -> Result<usize> {
    let (this_firmware, first) = match a.target {
        Target::Px4 => ("PX4", 0),
        _ => ("ArduPilot", 1),
    };
    let own = |slot: MagnetometerSlot| match (a.target, slot) {
        (Target::Px4, MagnetometerSlot::Px4CalMag(n)) => Some(n as usize),
        (Target::Ardupilot | Target::ArdupilotPerMotor, MagnetometerSlot::ArduPilotCompass(n)) => {
            Some(n as usize)
        }
        _ => None,
    };
    let name = |i: usize| match a.target {
        Target::Px4 => format!("CAL_MAG{i}"),
        _ => format!("compass {i}"),
    };
    let chosen = match (fitted_on, a.instance) {
        (Some(slot), given) => match (own(slot), given) {
            (Some(n), Some(i)) if i != n => bail!(
                "--instance {i}: {} was fitted on the magnetometer of {} (`mag_slot` = {slot}); its compensation in {}'s parameters would correct another sensor by a field it does not see. Drop --instance",
                a.model.display(),
                slot.describe(),
                name(i)
            ),
            (Some(n), _) => n,
            (None, Some(i)) => i,
            (None, None) => bail!(
                "{} was fitted on {} (`mag_slot` = {slot}): which of {this_firmware}'s magnetometers that sensor is, the other firmware's log does not say. Give --instance",
                a.model.display(),
                slot.describe(),
            ),
        },
        (None, Some(i)) => i,
        (None, None) => {
            eprintln!(
                "parameters for {}: the model does not say which magnetometer it was fitted on (a recording `magstand import` wrote says it in `mag_slot`); --instance picks another",
                name(first)
            );
            first
        }
    };
    if a.target == Target::ArdupilotPerMotor && chosen != 1 {
        bail!(
            "ArduPilot applies per-motor compensation to the first compass only, and {} was fitted on compass {chosen}",
            a.model.display()
        );
    }
    Ok(chosen)
}

/// The frame the target autopilot adds the compensation in, as the transform to the body
/// frame the model was fitted in ([`Autopilot::compensation_frame`]). The model's own transform
/// (`frame`, its `magnetometer_to_body`) where it names its magnetometer (`slot`), else that of
/// the `recording` the line is fitted over, which then names the magnetometer; it is used where
/// that magnetometer `fitted_on` is the target's. PX4 adds the compensation before its
/// calibration's rotation and scale: a model of a PX4 sensor that does not carry that
/// transform cannot be written in the sensor's frame, and its body-frame coefficients would be
/// wrong in sign or axis on a turned board. A model of an ArduPilot compass exported to PX4
/// takes the PX4 sensor's frame for the body frame, with a warning.
fn compensation_frame(
    a: &ExportArgs,
    fitted_on: Option<MagnetometerSlot>,
    (slot, frame): (Option<MagnetometerSlot>, Option<SensorToBody>),
    recording: Option<(&magstand_core::Recording, &std::path::Path)>,
) -> Result<Option<SensorToBody>> {
    let frame = match (slot, recording) {
        (None, Some((rec, path))) => SensorToBody::of_recording(rec, path)?,
        _ => frame,
    };
    let autopilot = match a.target {
        Target::Px4 => Autopilot::Px4,
        _ => Autopilot::ArduPilot,
    };
    match (autopilot, fitted_on, frame) {
        (Autopilot::Px4, Some(slot @ MagnetometerSlot::Px4CalMag(_)), None) => {
            return Err(px4_frame_unknown(a, slot));
        }
        (Autopilot::Px4, Some(slot @ MagnetometerSlot::ArduPilotCompass(_)), _) => eprintln!(
            "warning: {} was fitted on {slot}, in ArduPilot's body frame; PX4 adds its compensation in the sensor's own frame, taken here to be the body frame (true where CAL_MAGn_ROT and SENS_BOARD_ROT are 0 and the scale is near 1)",
            a.model.display()
        ),
        _ => {}
    }
    Ok(autopilot.compensation_frame(fitted_on, frame))
}

/// The line's parameter file for the target autopilot (`--to px4` or `--to ardupilot`), its
/// coefficients in `frame` ([`compensation_frame`]).
fn line_params(
    a: &ExportArgs,
    line: &magstand_logs::export::LinearFit,
    instance: usize,
    frame: Option<SensorToBody>,
) -> Result<String> {
    Ok(match a.target {
        Target::Px4 => px4_params(line, instance, frame.as_ref())?,
        _ => ardupilot_params(line, instance, frame.as_ref())?,
    })
}

/// Why a model of PX4 sensor `slot` that does not carry its frame cannot give PX4's
/// coefficients.
fn px4_frame_unknown(a: &ExportArgs, slot: MagnetometerSlot) -> anyhow::Error {
    anyhow::anyhow!(
        "{} was fitted on {slot} ({}) but does not say how its readings were taken to the body frame (`magnetometer_to_body`): PX4 adds its compensation before its calibration's rotation and scale, so the coefficients cannot be written in the sensor's frame. Import the log with this version (it writes `mag_to_body`) and fit it again",
        a.model.display(),
        slot.describe()
    )
}

/// Refuses `--to ardupilot-per-motor` for a model of a compass whose firmware has no per-motor
/// compensation: its log has a soft-iron matrix as the frame of its compensation
/// (`magnetometer_to_body` of an ArduPilot compass), which only firmware from before
/// per-motor compensation adds it before.
fn refuse_per_motor_without_it(
    a: &ExportArgs,
    fitted_on: Option<MagnetometerSlot>,
    frame: Option<SensorToBody>,
) -> Result<()> {
    if a.target == Target::ArdupilotPerMotor
        && matches!(fitted_on, Some(MagnetometerSlot::ArduPilotCompass(_)))
        && frame.is_some()
    {
        bail!(
            "{} was fitted on a log whose ArduPilot predates per-motor compensation (COMPASS_PMOT_EN): COMPASS_PMOT* would do nothing on that vehicle. Export --to ardupilot",
            a.model.display()
        );
    }
    Ok(())
}

/// Says, for a throttle line in an autopilot's parameters, which throttle it is fitted
/// against. The autopilot multiplies it by its own throttle: the collective thrust demand,
/// which its thrust curve (ArduPilot's `MOT_THST_EXPO`, PX4's `THR_MDL_FAC`) maps to the motor
/// outputs a log records. Where the recording holds that throttle (`autopilot_throttle`, which
/// `import` writes from ArduPilot's `CTUN`), the line is fitted against it. Otherwise, for a
/// model fitted on an autopilot's log (`from_log`: its magnetometer is named), it is fitted
/// against the motor outputs, and where the curve bends the slopes differ (at ArduPilot's
/// default expo of 0.65, a demand of 0.4 puts the motors at 0.56 of their spin range): a
/// warning. The current, which both measure alike, has no such mapping.
fn warn_of_the_autopilots_throttle(
    a: &ExportArgs,
    from_log: bool,
    input: LineInput,
    recording: Option<&magstand_core::Recording>,
) {
    if input != LineInput::Throttle
        || !matches!(a.target, Target::Px4 | Target::Ardupilot | Target::Json)
    {
        return;
    }
    let own = recording.is_some_and(|r| r.extra_column(AUTOPILOT_THROTTLE).is_some());
    if own {
        eprintln!(
            "the throttle line is fitted against the autopilot's own throttle (`{AUTOPILOT_THROTTLE}`), the thrust demand its compensation multiplies"
        );
    } else if from_log {
        eprintln!(
            "warning: the autopilot multiplies a throttle compensation by its thrust demand, which its thrust curve (ArduPilot's MOT_THST_EXPO, PX4's THR_MDL_FAC) maps to the motor outputs this line is fitted against: where that curve bends, the slope differs between the two. A --recording with `{AUTOPILOT_THROTTLE}` (import writes it from ArduPilot's CTUN) fits it against the autopilot's own; with `bat_a` logged, --input current (COMPASS_MOTCT 2, CAL_MAG_COMP_TYP 2) has no such mapping"
        );
    }
}

/// Runs `magstand export`.
pub fn run(a: ExportArgs) -> Result<()> {
    check_settings(&a)?;
    if let Some(o) = &a.out {
        let mut inputs = vec![a.model.as_path()];
        inputs.extend(a.recording.as_deref());
        files::refuse_overwriting_inputs(&inputs, &[o])?;
    }
    let model = match magstand_diagnose::model_choice::DisturbanceModel::load(&a.model)? {
        magstand_diagnose::model_choice::DisturbanceModel::LocalLinear(m) => *m,
        magstand_diagnose::model_choice::DisturbanceModel::Physics(m) => {
            return export_physics(&a, &m);
        }
    };
    let recording = a.recording.as_ref().map(recording_csv::read).transpose()?;
    let origin = a
        .recording
        .as_ref()
        .map(|p| p.display().to_string())
        .unwrap_or_default();
    let fitted_on = match (&recording, &a.recording) {
        (Some(rec), Some(path)) => MagnetometerSlot::agreeing_with(model.magnetometer, rec, path)?,
        _ => model.magnetometer,
    };
    // Resolved before any line is fitted: a refusal costs nothing.
    let instance = match a.target {
        Target::Px4 | Target::Ardupilot | Target::ArdupilotPerMotor => instance(&a, fitted_on)?,
        _ => 0,
    };
    refuse_per_motor_without_it(&a, fitted_on, model.magnetometer_to_body)?;
    let span = match &recording {
        Some(r) => Span::Rows {
            recording: r,
            origin: &origin,
        },
        None => Span::ModelRange,
    };
    let input = match a.input {
        Some(InputArg::Throttle) => LineInput::Throttle,
        Some(InputArg::Current) => LineInput::Current,
        None => LineInput::of(&model),
    };
    warn_of_the_autopilots_throttle(&a, fitted_on.is_some(), input, recording.as_ref());
    let adapt_config = magstand_ident::adaptive::AdaptConfig {
        forgetting: a
            .forgetting
            .unwrap_or(magstand_ident::adaptive::AdaptConfig::default().forgetting),
    }
    .check()
    .map_err(|e| anyhow::anyhow!(crate::fit_cmd::in_flag_terms(&e.to_string())))?;
    if a.input.is_some()
        && matches!(
            a.target,
            Target::C | Target::Rust | Target::CAdaptive | Target::RustAdaptive
        )
    {
        bail!(
            "--input chooses the autopilot line's input; the firmware exports take the model's own input ({:?})",
            model.input.kind
        );
    }
    // What the autopilot forms cost goes to stderr, so stdout stays a clean file.
    let text = match a.target {
        Target::C => c_header(&model)?,
        Target::Rust => rust_module(&model)?,
        Target::CAdaptive => c_adaptive(&model, &adapt_config)?,
        Target::RustAdaptive => rust_adaptive(&model, &adapt_config)?,
        Target::Px4 | Target::Ardupilot => {
            let frame = compensation_frame(
                &a,
                fitted_on,
                (model.magnetometer, model.magnetometer_to_body),
                recording.as_ref().zip(a.recording.as_deref()),
            )?;
            let line = linear_approximation(&model, input, span)?;
            eprint!("{}", describe(&line));
            line_params(&a, &line, instance, frame)?
        }
        Target::ArdupilotPerMotor => {
            let Some(rec) = &recording else {
                bail!(
                    "--to ardupilot-per-motor fits each motor's coefficient over a recording: give --recording R.csv (with bat_v and spans where the motors differ)"
                );
            };
            let fit = per_motor_fit(&model, rec, &origin)?;
            eprint!("{}", describe_per_motor(&fit));
            per_motor_params(&fit)
        }
        Target::Json => {
            // The document's PX4 coefficients need the frame `--to px4` needs.
            if let (Some(slot @ MagnetometerSlot::Px4CalMag(_)), None) =
                (model.magnetometer, model.magnetometer_to_body)
            {
                return Err(px4_frame_unknown(&a, slot));
            }
            let line = linear_approximation(&model, input, span)?;
            eprint!("{}", describe(&line));
            let per_motor = match &recording {
                Some(rec) if model.input.kind == InputKind::Motors && rec.bat_v.is_some() => {
                    Some(per_motor_fit(&model, rec, &origin)?)
                }
                _ => None,
            };
            export_json(&model, &line, per_motor.as_ref())?
        }
    };
    emit(&a, &text)
}
