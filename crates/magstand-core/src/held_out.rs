//! Held-out data, the one split every fit and test of magstand uses: the recording cut into
//! time blocks, every few blocks held out, a gap in the data (between two flights) a block
//! boundary rather than time.
//!
//! Its users choose the block length and the share:
//! - the identification (`magstand-ident`) holds out every 5th block of 1/50 of the span (at
//!   most 1 s): few, long blocks, since its fits need every throttle level in both parts;
//! - the diagnosis (`magstand-diagnose`) holds out every 3rd block of 1/150 of the duration
//!   (0.5 to 10 s): blocks short against the recording, so that slow effects (heating,
//!   battery) and fast ones (steps) are judged on data the fit never saw, and held-out blocks
//!   serve as roughly independent units for its tests, since residual structure rarely lasts
//!   longer than a block.

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

/// Each row's time with the data's gaps closed to nothing, from the first row, s; `starts`
/// are the rows after a gap ([`crate::rows_after_gaps`]).
fn time_with_data_s(t_s: &[f64], starts: &[usize]) -> Vec<f64> {
    let mut active = Vec::with_capacity(t_s.len());
    let mut closed = 0.0;
    for (r, &t) in t_s.iter().enumerate() {
        if r > 0 && starts.binary_search(&r).is_ok() {
            closed += t - t_s[r - 1];
        }
        active.push(t - t_s[0] - closed);
    }
    active
}

/// The time the recording holds data, s: its span with every gap closed to nothing.
pub fn duration_with_data_s(t_s: &[f64]) -> f64 {
    time_with_data_s(t_s, &crate::rows_after_gaps(t_s))
        .last()
        .copied()
        .unwrap_or(0.0)
}

impl Split {
    /// Blocks of `block_s` (positive) of time with data; every `holdout_every`-th block,
    /// starting with the last of the first group, is held out.
    ///
    /// A gap in the data (a log holding two flights) is a boundary, not a long stretch of
    /// time: a new block starts after each gap, so no block spans one.
    pub fn new(t_s: &[f64], block_s: f64, holdout_every: usize) -> Split {
        let starts = crate::rows_after_gaps(t_s);
        let active = time_with_data_s(t_s, &starts);
        // Blocks are numbered in the order they hold rows: where rows lie further apart than
        // a block (a slow log, or times in milliseconds), numbering by time alone skipped
        // blocks in step with the share, and rows 10 blocks apart held none out.
        let mut block: Vec<usize> = Vec::with_capacity(t_s.len());
        let mut last_time_block = 0;
        for (r, a) in active.iter().enumerate() {
            let b = (a / block_s).floor() as usize;
            // After a gap, a new block even where the closed time stays within the last one.
            let new_block = r > 0 && (b != last_time_block || starts.binary_search(&r).is_ok());
            block.push(match block.last() {
                Some(&prev) if new_block => prev + 1,
                Some(&prev) => prev,
                None => 0,
            });
            last_time_block = b;
        }
        let every = holdout_every.max(1);
        let holdout = block.iter().map(|b| b % every == every - 1).collect();
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
        assert!((duration_with_data_s(&t) - 299.9).abs() < 1e-12);
        let s = Split::new(&t, 2.0, 3);
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
        let duration = duration_with_data_s(&t);
        assert!(
            (duration - (199.9 - 0.1)).abs() < 0.15,
            "{duration} s: the gap counted as time"
        );
        let s = Split::new(&t, duration / 150.0, 3);
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

    #[test]
    fn rows_further_apart_than_a_block_are_held_out_in_turn() {
        // A row every 10 s in blocks of 1 s: one row a block, every fifth held out.
        let t: Vec<f64> = (0..300).map(|k| k as f64 * 10.0).collect();
        let s = Split::new(&t, 1.0, 5);
        assert_eq!(s.holdout_blocks(), 60, "blocks {:?}", &s.block[..12]);
        assert!(s.holdout[4] && !s.holdout[5] && s.holdout[9]);
    }
}
