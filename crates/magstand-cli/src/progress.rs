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

/// Shows what a running diagnosis is doing: its stage, the round and how many of its
/// candidates are fitted, with the time elapsed. Shared by the worker threads.
pub struct DiagnosisSpinner {
    bar: ProgressBar,
    /// The current round: its title and its candidates' names.
    round: std::sync::Mutex<(String, String)>,
}

impl DiagnosisSpinner {
    /// A spinner labelled `label` (the recording's name).
    pub fn new(label: &str) -> Self {
        let bar = ProgressBar::new_spinner();
        bar.set_style(
            ProgressStyle::with_template("{prefix} {spinner} {elapsed} {wide_msg}")
                .expect("constant template"),
        );
        bar.set_prefix(label.to_string());
        bar.enable_steady_tick(std::time::Duration::from_millis(120));
        Self {
            bar,
            round: std::sync::Mutex::new((String::new(), String::new())),
        }
    }
}

impl magstand_diagnose::DiagnoseObserver for DiagnosisSpinner {
    fn stage(&self, stage: magstand_diagnose::Stage) {
        use magstand_diagnose::Stage;
        // A poisoned lock only means a worker panicked; the text is still whole.
        let mut round = self.round.lock().unwrap_or_else(|e| e.into_inner());
        // The counts first and the names last, where a narrow terminal cuts the line.
        let fitted = |(title, names): &(String, String), done: usize, of: usize| {
            format!("{title}: {done} of {of} candidates fitted ({names})")
        };
        let message = match stage {
            Stage::Baseline => "calibrating the baseline".to_string(),
            Stage::Round {
                number,
                calibration,
                candidates,
            } => {
                let kind = if calibration { " (calibration)" } else { "" };
                *round = (format!("round {number}{kind}"), candidates.join(", "));
                fitted(&round, 0, candidates.len())
            }
            Stage::CandidateFitted { done, of, .. } => fitted(&round, done, of),
            Stage::Refining { candidate } => {
                format!("{}: every term refitted with {candidate}", round.0)
            }
            Stage::Assembling => "assembling the final model".to_string(),
            // A stage this command does not know yet: keep the line as it is.
            _ => return,
        };
        self.bar.set_message(message);
    }
}

impl Drop for DiagnosisSpinner {
    fn drop(&mut self) {
        self.bar.finish_and_clear();
    }
}
