//! Progress bars on stderr (hidden when stderr is not a terminal, so logs and CI stay clean).
use indicatif::{ProgressBar, ProgressStyle};

/// Shows a bar over simulated seconds.
pub struct SimulationBar {
    bar: ProgressBar,
}

impl SimulationBar {
    /// A bar labelled `label`.
    pub fn new(label: &str) -> Self {
        let bar = ProgressBar::new(1000);
        bar.set_style(
            ProgressStyle::with_template("{prefix} [{bar:40}] {percent:>3}% eta {eta}")
                .expect("constant template")
                .progress_chars("=> "),
        );
        bar.set_prefix(label.to_string());
        Self { bar }
    }
}

impl magstand_sim::Observer for SimulationBar {
    fn progress(&mut self, done_s: f64, total_s: f64) {
        if total_s > 0.0 {
            self.bar.set_position((1000.0 * done_s / total_s) as u64);
        }
    }
}

impl Drop for SimulationBar {
    fn drop(&mut self) {
        self.bar.finish_and_clear();
    }
}

/// Shows a bar over Monte Carlo runs, with an ETA. Shared by the worker threads.
pub struct RunsBar {
    bar: ProgressBar,
}

impl RunsBar {
    /// A bar over `total` runs labelled `label`.
    pub fn new(label: &str, total: usize) -> Self {
        let bar = ProgressBar::new(total as u64);
        bar.set_style(
            ProgressStyle::with_template(
                "{prefix} [{bar:40}] {pos}/{len} runs, {elapsed} elapsed, eta {eta}",
            )
            .expect("constant template")
            .progress_chars("=> "),
        );
        bar.set_prefix(label.to_string());
        Self { bar }
    }
}

impl magstand_study::StudyObserver for RunsBar {
    fn run_finished(&self, done: usize, _total: usize) {
        self.bar.set_position(done as u64);
    }
}

impl Drop for RunsBar {
    fn drop(&mut self) {
        self.bar.finish_and_clear();
    }
}
