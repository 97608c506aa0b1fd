//! Held-out data: the recording cut into time blocks, every few blocks held out.
//!
//! Blocks are short against the recording (1/150 of it) so that both parts cover every
//! throttle level and the whole duration: slow effects (heating, battery) and fast ones
//! (steps) are judged on data the fit never saw. Held-out blocks also serve as roughly
//! independent units for the tests, since residual structure rarely lasts longer than a block.

/// Which rows are held out, and the block of every row.
#[derive(Debug, Clone, PartialEq)]
pub struct Split {
    /// Block index of every row.
    pub block: Vec<usize>,
    /// Whether each row is held out.
    pub holdout: Vec<bool>,
    /// Block length, s.
    pub block_s: f64,
}

impl Split {
    /// Blocks of `block_s` (or 1/150 of the duration, kept in 0.5..10 s); every
    /// `holdout_every`-th block, starting with the last of the first group, is held out.
    pub fn new(t_s: &[f64], block_s: Option<f64>, holdout_every: usize) -> Split {
        let t0 = t_s.first().copied().unwrap_or(0.0);
        let duration = t_s.last().copied().unwrap_or(0.0) - t0;
        let block_s = block_s.unwrap_or((duration / 150.0).clamp(0.5, 10.0));
        let block: Vec<usize> = t_s
            .iter()
            .map(|&t| ((t - t0) / block_s).floor() as usize)
            .collect();
        let holdout = block
            .iter()
            .map(|b| b % holdout_every == holdout_every - 1)
            .collect();
        Split {
            block,
            holdout,
            block_s,
        }
    }

    /// Number of held-out blocks that hold at least one row.
    pub fn holdout_blocks(&self) -> usize {
        let mut seen: Vec<usize> = self
            .block
            .iter()
            .zip(&self.holdout)
            .filter(|(_, h)| **h)
            .map(|(b, _)| *b)
            .collect();
        seen.dedup();
        seen.len()
    }

    /// Number of identification (not held-out) rows.
    pub fn fit_rows(&self) -> usize {
        self.holdout.iter().filter(|h| !**h).count()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_block_in_three_is_held_out() {
        let t: Vec<f64> = (0..3000).map(|k| k as f64 * 0.1).collect();
        let auto = Split::new(&t, None, 3);
        assert!(
            (auto.block_s - 299.9 / 150.0).abs() < 1e-12,
            "{}",
            auto.block_s
        );
        let s = Split::new(&t, Some(2.0), 3);
        assert_eq!(s.holdout_blocks(), 50);
        let held = s.holdout.iter().filter(|h| **h).count();
        assert!((990..=1010).contains(&held), "rows held out: {held}");
        assert!(!s.holdout[0] && s.holdout[40] && !s.holdout[60]);
    }
}
