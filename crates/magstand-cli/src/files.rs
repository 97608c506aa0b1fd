//! File handling shared by the subcommands: output folders, the rule that no output may
//! overwrite an input, and a recording read with its doubts said.
//!
//! Each command lists its outputs and checks them against its inputs by canonical path before
//! it writes anything ([`refuse_overwriting_inputs`]). Behind that, every write goes through
//! `magstand_core::atomic_file`, which refuses any file this process has read, so an output
//! the list missed still cannot replace an input.
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use magstand_sim::ValidScenario;

/// Creates `dir` (and parents) if needed.
pub fn ensure_dir(dir: &Path) -> Result<()> {
    std::fs::create_dir_all(dir)
        .with_context(|| format!("cannot create output folder {}", dir.display()))
}

/// Creates the folder a file is to be written into, if the path names one.
pub fn ensure_parent(file: &Path) -> Result<()> {
    match file.parent().filter(|d| !d.as_os_str().is_empty()) {
        Some(dir) => ensure_dir(dir),
        None => Ok(()),
    }
}

/// Prints the recording's doubts about its units and columns
/// ([`magstand_core::Recording::doubts`]) as warnings naming `origin`: a model fitted on, or
/// applied to, a field in gauss under `mag_*_ut` is 100 times off, and a `bat_v` logged as
/// `vbat` is not used.
pub fn warn_doubts(rec: &magstand_core::Recording, origin: &str) {
    for doubt in rec.doubts() {
        eprintln!("warning: {origin}: {doubt}");
    }
}

/// Reads the recording at `path` and warns of its doubts ([`warn_doubts`]): what `compensate`
/// and `report` read (`fit` first refuses a stuck sensor, then warns).
pub fn read_recording(path: &Path) -> Result<magstand_core::Recording> {
    let rec = magstand_core::recording_csv::read(path)?;
    warn_doubts(&rec, &path.display().to_string());
    Ok(rec)
}

fn canonical(p: &Path) -> Option<PathBuf> {
    std::fs::canonicalize(p).ok()
}

/// Fails if any output path names the same file as any input path. An output that does not
/// exist yet cannot be an input, so only existing files are compared.
pub fn refuse_overwriting_inputs<I, O>(inputs: &[I], outputs: &[O]) -> Result<()>
where
    I: AsRef<Path>,
    O: AsRef<Path>,
{
    let inputs: Vec<(&Path, PathBuf)> = inputs
        .iter()
        .filter_map(|i| Some((i.as_ref(), canonical(i.as_ref())?)))
        .collect();
    for (k, o) in outputs.iter().enumerate() {
        let o = o.as_ref();
        let absolute = std::path::absolute(o).ok();
        if let Some(other) = outputs[..k]
            .iter()
            .find(|p| std::path::absolute(p.as_ref()).ok() == absolute)
        {
            bail!(
                "output {} is named twice (also as {}): give each output its own path",
                o.display(),
                other.as_ref().display()
            );
        }
        let Some(co) = canonical(o) else { continue };
        if let Some((i, _)) = inputs.iter().find(|(_, ci)| *ci == co) {
            bail!(
                "output {} is the input {}: refusing to overwrite an input (choose another output path)",
                o.display(),
                i.display()
            );
        }
    }
    Ok(())
}

/// The files a scenario `spec` stands for: the scenario file (unless built in) and the
/// recording a replay program reads.
pub fn scenario_inputs(spec: &str, scenario: &ValidScenario) -> Vec<PathBuf> {
    let mut inputs = scenario.input_files();
    if !spec.starts_with("builtin:") {
        inputs.push(PathBuf::from(spec));
    }
    inputs
}
