//! `magstand demo`: the embedded paper-like scenario end to end.
use std::path::PathBuf;

use anyhow::Result;
use clap::Args;

use crate::progress::SimulationBar;
use crate::simulate_cmd::load_scenario;
use magstand_core::recording_csv;

/// Arguments of `magstand demo`.
#[derive(Args)]
pub struct DemoArgs {
    /// Folder for the demo's files.
    #[arg(long, default_value = "magstand-demo")]
    out: PathBuf,
    /// Random seed.
    #[arg(long, default_value_t = 3)]
    seed: u64,
}

/// Runs the demo.
pub fn run(a: DemoArgs) -> Result<()> {
    let scenario = load_scenario("builtin:czyba2015-stair", &[])?;
    crate::files::ensure_dir(&a.out)?;
    let rec =
        magstand_sim::simulate_observed(&scenario, a.seed, &mut SimulationBar::new("simulate"));
    let path = a.out.join("recording.csv");
    recording_csv::write(&rec, &path)?;
    let truth = rec
        .truth
        .as_ref()
        .expect("the demo scenario records ground truth");
    println!(
        "Simulated {} ({} samples) -> {}",
        scenario.params().name,
        rec.len(),
        path.display()
    );
    println!(
        "{:>8} {:>10} {:>10} {:>10} {:>10} {:>8}",
        "throttle", "dist_x_ut", "dist_y_ut", "dist_z_ut", "|dist|_ut", "sd_ut"
    );
    for level in [0.0, 0.2, 0.4, 0.6, 0.8, 1.0] {
        let rows: Vec<usize> = (0..rec.len())
            .filter(|&r| (rec.overall_throttle(r) - level).abs() < 1e-9)
            .collect();
        if rows.is_empty() {
            continue;
        }
        let n = rows.len() as f64;
        let mean = rows
            .iter()
            .map(|&r| truth.dist_ut[r])
            .sum::<magstand_core::Vec3>()
            / n;
        let sd = rows.iter().map(|&r| truth.sd_ut[r].x).sum::<f64>() / n;
        println!(
            "{level:>8.2} {:>10.2} {:>10.2} {:>10.2} {:>10.2} {sd:>8.2}",
            mean.x,
            mean.y,
            mean.z,
            mean.norm()
        );
    }
    Ok(())
}
