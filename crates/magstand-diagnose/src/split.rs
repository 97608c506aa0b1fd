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
    ///
    /// A gap in the data (a log holding two flights) is a boundary, not a long stretch of
    /// time: the duration counts only the time with data, and a new block starts after each
    /// gap, so no block spans one.
    pub fn new(t_s: &[f64], block_s: Option<f64>, holdout_every: usize) -> Split {
        let starts = magstand_core::rows_after_gaps(t_s);
        // Time with data: every gap closed to nothing.
        let mut active = Vec::with_capacity(t_s.len());
        let mut closed = 0.0;
        for (r, &t) in t_s.iter().enumerate() {
            if r > 0 && starts.binary_search(&r).is_ok() {
                closed += t - t_s[r - 1];
            }
            active.push(t - t_s[0] - closed);
        }
        let duration = active.last().copied().unwrap_or(0.0);
        let block_s = block_s.unwrap_or((duration / 150.0).clamp(0.5, 10.0));
        let mut block: Vec<usize> = Vec::with_capacity(t_s.len());
        let mut offset = 0;
        for (r, a) in active.iter().enumerate() {
            let b = (a / block_s).floor() as usize + offset;
            if r > 0 && starts.binary_search(&r).is_ok() && b <= block[r - 1] {
                offset += block[r - 1] + 1 - b;
            }
            block.push((a / block_s).floor() as usize + offset);
        }
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

    #[test]
    fn a_gap_is_a_block_boundary_and_not_time() {
        // Two 100 s flights at 10 Hz, ten minutes apart.
        let mut t: Vec<f64> = (0..1000).map(|k| k as f64 * 0.1).collect();
        t.extend((0..1000).map(|k| 700.0 + k as f64 * 0.1));
        let s = Split::new(&t, None, 3);
        assert!(
            (s.block_s - (199.9 - 0.1) / 150.0).abs() < 0.01,
            "block {} s: the gap counted as time",
            s.block_s
        );
        assert!(
            s.block[1000] > s.block[999],
            "blocks {} and {} span the gap",
            s.block[999],
            s.block[1000]
        );
        let blocks = s
            .block
            .iter()
            .collect::<std::collections::BTreeSet<_>>()
            .len();
        assert!((149..=152).contains(&blocks), "{blocks} blocks");
    }
}
