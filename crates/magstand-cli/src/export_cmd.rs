//! `magstand export`: a model as PX4 or ArduPilot parameters, or as a C header.
use std::io::Write;
use std::path::PathBuf;

use anyhow::{Result, bail};
use clap::{Args, ValueEnum};

use crate::files;
use magstand_ident::Model;
use magstand_logs::export::{
    ardupilot_params, c_header, describe, linear_approximation, px4_params,
};

/// What to export to.
#[derive(Clone, Copy, ValueEnum)]
enum Target {
    /// PX4 power compensation (CAL_MAG_COMP_TYP, CAL_MAGn_{X,Y,Z}COMP), QGroundControl format.
    Px4,
    /// ArduPilot compassmot (COMPASS_MOTCT, COMPASS_MOT_{X,Y,Z}), .param format.
    Ardupilot,
    /// The full model as a dependency-free C header.
    C,
}

/// Arguments of `magstand export`.
#[derive(Args)]
pub struct ExportArgs {
    /// Model file written by `magstand fit`.
    #[arg(long)]
    model: PathBuf,
    /// Target.
    #[arg(long = "to", value_enum)]
    target: Target,
    /// Magnetometer instance: PX4's n in CAL_MAGn (from 0), ArduPilot's compass (from 1).
    #[arg(long)]
    instance: Option<usize>,
    /// Output file (default: standard output).
    #[arg(long)]
    out: Option<PathBuf>,
}

/// Runs `magstand export`.
pub fn run(a: ExportArgs) -> Result<()> {
    if let Some(o) = &a.out {
        files::refuse_overwriting_inputs(&[&a.model], &[o])?;
    }
    let model = Model::load(&a.model)?;
    let text = match a.target {
        Target::C => c_header(&model)?,
        Target::Px4 | Target::Ardupilot => {
            let line = linear_approximation(&model)?;
            // What the autopilot's linear form costs goes to stderr, so stdout stays a clean
            // parameter file.
            eprint!("{}", describe(&line));
            match a.target {
                Target::Px4 => px4_params(&line, a.instance.unwrap_or(0)),
                _ => {
                    let i = a.instance.unwrap_or(1);
                    if !(1..=3).contains(&i) {
                        bail!("--instance {i}: ArduPilot compasses are numbered 1 to 3");
                    }
                    ardupilot_params(&line, i)
                }
            }
        }
    };
    match &a.out {
        Some(path) => {
            if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
                files::ensure_dir(dir)?;
            }
            magstand_core::atomic_file::write_bytes(path, text.as_bytes())?;
            eprintln!("wrote {}", path.display());
        }
        None => std::io::stdout().write_all(text.as_bytes())?,
    }
    Ok(())
}
