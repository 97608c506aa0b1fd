//! File handling shared by the subcommands: output folders, and the rule that no output may
//! overwrite an input.
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};

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

fn canonical(p: &Path) -> Option<PathBuf> {
    std::fs::canonicalize(p).ok()
}

/// Fails if any output path names the same file as any input path.
pub fn refuse_overwriting_inputs(inputs: &[&Path], outputs: &[&Path]) -> Result<()> {
    for o in outputs {
        let Some(co) = canonical(o) else { continue };
        for i in inputs {
            if canonical(i).as_ref() == Some(&co) {
                bail!(
                    "output {} is the input {}: refusing to overwrite an input",
                    o.display(),
                    i.display()
                );
            }
        }
    }
    Ok(())
}
