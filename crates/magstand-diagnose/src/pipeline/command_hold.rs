//! Commands logged at a fraction of the magnetometer's rate and held between its rows: each
//! command change shows zero to `k - 1` rows after it acted, a lateness that varies from change
//! to change. No catalog effect is that lateness; beside a slow lag it has been named
//! `hysteresis` and `unexplained` (the independent generator's default stand and hexacopter,
//! commands held over three rows: 6 of 34 recordings). The diagnosis says so in its warnings,
//! so that such names are read with it.

/// Fewest command changes before their rows' spacing says anything: by chance, `n` changes
/// fall on rows a whole `k` apart with probability `k^-(n-1)`.
const MIN_CHANGES: usize = 20;

/// Longest hold looked for, rows: a longer common spacing is a program stepped on a clock
/// (a stair of fixed dwell), not a logger's rate.
const MAX_HOLD_ROWS: usize = 10;

/// Fewest different spacings between changes: a program stepped on a clock (a stair of one
/// dwell, logged at a rate that divides it) changes on rows a whole number apart as well,
/// every change on time; a logger's hold catches changes made at any moment, a whole number
/// of its rows apart but irregularly so. (A program of irregular dwells on a clock, whole
/// tenths of a second at 50 Hz, cannot be told from a hold by the commands alone: the warning
/// names both.)
const MIN_SPACINGS: usize = 3;

/// Where every change of the logged commands (any motor's) falls on rows a whole number of
/// rows apart, 2 to [`MAX_HOLD_ROWS`], with at least [`MIN_CHANGES`] changes at
/// [`MIN_SPACINGS`] different spacings or more: that whole number (the greatest common divisor
/// of the rows between changes) and the number of changes.
pub(crate) fn held_commands(thr: &[Vec<f64>]) -> Option<(usize, usize)> {
    let rows = thr.first().map_or(0, Vec::len);
    let changes: Vec<usize> = (1..rows)
        .filter(|&r| thr.iter().any(|c| c[r] != c[r - 1]))
        .collect();
    if changes.len() < MIN_CHANGES {
        return None;
    }
    let gcd = |mut a: usize, mut b: usize| {
        while b != 0 {
            (a, b) = (b, a % b);
        }
        a
    };
    let mut gaps: Vec<usize> = changes.windows(2).map(|w| w[1] - w[0]).collect();
    let spacing = gaps.iter().fold(0, |g, &d| gcd(g, d));
    gaps.sort_unstable();
    gaps.dedup();
    ((2..=MAX_HOLD_ROWS).contains(&spacing) && gaps.len() >= MIN_SPACINGS)
        .then_some((spacing, changes.len()))
}

/// The diagnosis's warning for commands held over `k` rows with `changes` changes.
pub(crate) fn warning(origin: &str, (k, changes): (usize, usize)) -> String {
    format!(
        "{origin}: every change of the commands ({changes} of them) falls a whole multiple of {k} rows after the one before: either they are logged at 1/{k} of the magnetometer's rate and held between, and each change shows 0 to {} rows after it acted, so a `time_offset`, `current_lag`, `hysteresis` or `unexplained` named here may be that lateness rather than physics (log the commands at the magnetometer's rate, or with their own time stamps), or the program steps on a clock of 1/{k} of that rate, and nothing is amiss",
        k - 1
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Commands of two motors stepping at the rows `steps` (each a new level), `rows` long.
    fn stepping(rows: usize, steps: &[usize]) -> Vec<Vec<f64>> {
        let level = |r: usize| steps.iter().filter(|&&s| s <= r).count() as f64 * 0.01;
        vec![
            (0..rows).map(level).collect(),
            (0..rows).map(|r| 0.5 * level(r)).collect(),
        ]
    }

    #[test]
    fn changes_on_every_third_row_are_a_hold_and_a_free_program_is_not() {
        // Irregular dwells (7, 11, 4, ... intervals of 3 rows): every change on rows 3 apart.
        let dwells = [7, 11, 4, 9, 5, 13, 6, 8, 10, 3];
        let mut at = 2;
        let held: Vec<usize> = (0..30)
            .map(|i| {
                at += 3 * dwells[i % dwells.len()];
                at
            })
            .collect();
        let rows = at + 10;
        assert_eq!(held_commands(&stepping(rows, &held)), Some((3, 30)));
        // The same changes one row later on every fifth: no common spacing.
        let free: Vec<usize> = held
            .iter()
            .enumerate()
            .map(|(i, &r)| r + usize::from(i % 5 == 0))
            .collect();
        assert_eq!(held_commands(&stepping(rows, &free)), None);
        // Too few changes to say, and stairs stepped on a clock: every 200 rows (100 Hz, 2 s),
        // and every 10 rows (a stand logging at 10 Hz, 1 s dwell), every change on time.
        assert_eq!(held_commands(&stepping(rows, &held[..10])), None);
        for dwell in [200, 10] {
            let stair: Vec<usize> = (1..40).map(|i| dwell * i).collect();
            assert_eq!(
                held_commands(&stepping(41 * dwell, &stair)),
                None,
                "{dwell}"
            );
        }
    }
}
