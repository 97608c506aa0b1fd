//! `magstand import`: a PX4 ULog or ArduPilot DataFlash log as a recording.
use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::Args;

use crate::files;
use magstand_logs::contents::LogFormat;
use magstand_logs::import::{ImportOptions, SegmentKind, import_bytes};

/// Arguments of `magstand import`.
#[derive(Args)]
#[command(allow_negative_numbers = true)]
#[command(group(clap::ArgGroup::new("log").required(true).args(["ulog", "dataflash"])))]
pub struct ImportArgs {
    /// A PX4 ULog file (.ulg).
    #[arg(long)]
    ulog: Option<PathBuf>,
    /// An ArduPilot DataFlash log (.bin).
    #[arg(long)]
    dataflash: Option<PathBuf>,
    /// The recording to write (CSV).
    #[arg(long)]
    out: PathBuf,
    /// Magnetometer instance (PX4 sensor_mag instance; ArduPilot 0 = MAG, 1 = MAG2, ...);
    /// default: the first internal one.
    #[arg(long)]
    mag: Option<u8>,
    /// Number of motors, when the log does not say.
    #[arg(long)]
    motors: Option<usize>,
    /// PX4: read the motors from this actuator_outputs instance instead of actuator_motors.
    #[arg(long)]
    outputs: Option<u8>,
    /// PWM range of the motor outputs as MIN:MAX, when the log's parameters do not give it.
    #[arg(long, value_parser = parse_range)]
    pwm_range: Option<(f64, f64)>,
    /// Keep only rows of one segment kind: off, ground, flight or spinning.
    #[arg(long, value_parser = parse_segment)]
    segment: Option<SegmentKind>,
    /// Keep only rows at or after this time on the log's clock, s.
    #[arg(long)]
    from_s: Option<f64>,
    /// Keep only rows at or before this time on the log's clock, s.
    #[arg(long)]
    to_s: Option<f64>,
}

fn parse_range(s: &str) -> Result<(f64, f64), String> {
    let (a, b) = s
        .split_once(':')
        .ok_or_else(|| format!("{s:?}: expected MIN:MAX, for example 1000:2000"))?;
    let num = |x: &str| {
        x.trim()
            .parse::<f64>()
            .map_err(|_| format!("{x:?} in {s:?} is not a number"))
    };
    Ok((num(a)?, num(b)?))
}

fn parse_segment(s: &str) -> Result<SegmentKind, String> {
    SegmentKind::parse(s).ok_or_else(|| format!("{s:?}: expected off, ground, flight or spinning"))
}

/// Runs `magstand import`.
pub fn run(a: ImportArgs) -> Result<()> {
    let (path, expect_ulog) = match (&a.ulog, &a.dataflash) {
        (Some(p), None) => (p, true),
        (None, Some(p)) => (p, false),
        _ => bail!("give one of --ulog and --dataflash"),
    };
    files::refuse_overwriting_inputs(&[path], &[&a.out])?;
    for (flag, v) in [("--from-s", a.from_s), ("--to-s", a.to_s)] {
        if let Some(v) = v.filter(|v| !v.is_finite()) {
            bail!("{flag} {v}: expected a finite time on the log's clock, s");
        }
    }
    if let (Some(f), Some(t)) = (a.from_s, a.to_s)
        && !(t > f)
    {
        bail!("--from-s {f} --to-s {t}: the window is empty");
    }
    // Read once: the format check and the import share the bytes.
    let bytes = magstand_core::input_file::read(path, magstand_core::input_file::MAX_LOG_BYTES)
        .with_context(|| format!("{}: cannot read", path.display()))?;
    if let Some(found) = LogFormat::detect(&bytes)
        && (found == LogFormat::Ulog) != expect_ulog
    {
        let is_ulog = found == LogFormat::Ulog;
        bail!(
            "{}: this is a {} log; use {}",
            path.display(),
            if is_ulog { "PX4 ULog" } else { "DataFlash" },
            if is_ulog { "--ulog" } else { "--dataflash" }
        );
    }
    let opts = ImportOptions {
        mag: a.mag,
        motors: a.motors,
        outputs: a.outputs,
        pwm_range: a.pwm_range,
        segment: a.segment,
        window_s: match (a.from_s, a.to_s) {
            (None, None) => None,
            (f, t) => Some((f.unwrap_or(f64::NEG_INFINITY), t.unwrap_or(f64::INFINITY))),
        },
    };
    let (rec, report) = import_bytes(&bytes, path, &opts)?;
    drop(bytes);
    files::ensure_parent(&a.out)?;
    magstand_core::recording_csv::write(&rec, &a.out)?;
    eprint!(
        "{}",
        crate::flag_terms::in_flag_terms(&report.summary(&rec), &crate::flag_terms::IMPORT_FLAGS)
    );
    eprintln!("wrote {}", a.out.display());
    Ok(())
}
