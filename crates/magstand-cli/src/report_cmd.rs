//! `magstand report`: one self-contained HTML page with the figures of a recording, a model
//! and a Monte Carlo study, plus each figure as a standalone SVG.
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use clap::Args;

use crate::files;
use magstand_core::Recording;
use magstand_diagnose::Diagnosis;
use magstand_diagnose::model_choice::DisturbanceModel;
use magstand_report::{ReportInputs, build};
use magstand_study::{StudyResult, Summary};

/// Arguments of `magstand report`.
#[derive(Args)]
#[command(allow_negative_numbers = true)]
pub struct ReportArgs {
    /// Recording to show (for a model: a validation run it was not fitted on).
    #[arg(long)]
    recording: PathBuf,
    /// Model file written by `magstand fit`.
    #[arg(long)]
    model: Option<PathBuf>,
    /// Diagnosis file written by `magstand diagnose --json`.
    #[arg(long)]
    diagnosis: Option<PathBuf>,
    /// Output folder of a `magstand montecarlo` study.
    #[arg(long)]
    montecarlo: Option<PathBuf>,
    /// Output folder: index.html and one SVG per figure.
    #[arg(long)]
    out: PathBuf,
}

/// The header lines every report carries, so the page can be reproduced.
pub fn provenance() -> Vec<(String, String)> {
    vec![
        ("magstand".into(), env!("CARGO_PKG_VERSION").into()),
        (
            "command".into(),
            std::env::args().collect::<Vec<_>>().join(" "),
        ),
    ]
}

/// Writes a report into `out` and returns the page's path. No file it writes may be one of
/// `files_read` or the study folder's files.
#[allow(clippy::too_many_arguments)]
pub fn write_report(
    files_read: &[&Path],
    rec: &Recording,
    recording_name: &str,
    model: Option<&magstand_diagnose::model_choice::DisturbanceModel>,
    diagnosis: Option<&Diagnosis>,
    study_dir: Option<&Path>,
    mut provenance: Vec<(String, String)>,
    out: &Path,
) -> Result<PathBuf> {
    let study = match study_dir {
        Some(d) => {
            let r = StudyResult::read(d).with_context(|| format!("study {}", d.display()))?;
            let s = Summary::new(r.info.clone(), &r.outcomes);
            provenance.push(("Monte Carlo study".into(), d.display().to_string()));
            Some((s, r.outcomes))
        }
        None => None,
    };
    let inputs = ReportInputs {
        recording: rec,
        recording_name: recording_name.into(),
        model: match model {
            Some(DisturbanceModel::LocalLinear(m)) => Some(m),
            _ => None,
        },
        physics: match model {
            Some(DisturbanceModel::Physics(m)) => Some(m),
            _ => None,
        },
        diagnosis,
        study: study.as_ref().map(|(s, o)| (s, o.as_slice())),
        provenance,
    };
    let report = build(&inputs)?;
    let mut read: Vec<PathBuf> = files_read.iter().map(|p| p.to_path_buf()).collect();
    read.extend(study_dir.into_iter().flat_map(StudyResult::files_read));
    let outputs: Vec<PathBuf> = report.file_names().iter().map(|n| out.join(n)).collect();
    files::refuse_overwriting_inputs(&read, &outputs)?;
    files::ensure_dir(out)?;
    Ok(report.write(out)?)
}

/// Runs `magstand report`.
pub fn run(a: ReportArgs) -> Result<()> {
    let mut inputs: Vec<&Path> = vec![&a.recording];
    if let Some(m) = &a.model {
        inputs.push(m);
    }
    if let Some(d) = &a.diagnosis {
        inputs.push(d);
    }
    // Figures of a field in gauss, or of a model applied to it, are as far off as a fit's.
    let rec = files::read_recording(&a.recording)?;
    let model = a.model.as_deref().map(DisturbanceModel::load).transpose()?;
    let diagnosis = a.diagnosis.as_deref().map(Diagnosis::load).transpose()?;
    let mut prov = provenance();
    prov.push(("recording".into(), a.recording.display().to_string()));
    if let (Some(p), Some(m)) = (&a.model, &model) {
        prov.push(("model".into(), format!("{} ({})", p.display(), m.family())));
    }
    let page = write_report(
        &inputs,
        &rec,
        &a.recording.display().to_string(),
        model.as_ref(),
        diagnosis.as_ref(),
        a.montecarlo.as_deref(),
        prov,
        &a.out,
    )?;
    println!("wrote {}", page.display());
    Ok(())
}
