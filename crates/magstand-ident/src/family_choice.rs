//! The choice among model families: each family is fitted without the held-out time blocks
//! and judged on them, and the rule below keeps one. The record of the choice
//! ([`FamilyChoice`]) goes into the model file, so a reader sees what was tried and why the
//! chosen family won.
//!
//! # The rule, and why
//!
//! The loss of a family in a held-out block is the mean over the block's rows of the squared
//! residual summed over the axes. The family with the lowest held-out mean squared error is
//! the *best*. A family with fewer parameters than the best is preferred when its loss is
//! within one standard error of the best's, the standard error being that of the mean paired
//! per-block difference (Breiman's one-standard-error rule, paired since both families are
//! judged on the same blocks). Among the families within that bound the one with the fewest
//! parameters wins, ties going to the lower error.
//!
//! Why a penalty at all: a held-out error is an estimate, and two families whose difference
//! is within its noise have not been told apart by the data; the smaller model then has
//! fewer numbers to be wrong about on a recording it has not seen. Why this one: it is stated
//! in the units of the evidence (held-out blocks), needs no tuning constant, and vanishes as
//! the recording grows, so a family that is really better always wins on enough data.
use std::borrow::Cow;

use serde::{Deserialize, Serialize};

use magstand_core::Vec3;

/// The model families the choice tries, each with one spelling in every file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(try_from = "String", into = "String")]
#[non_exhaustive]
pub enum FamilyId {
    /// Local linear on the overall throttle, automatic structure (`automatic`).
    Throttle,
    /// Local linear on the supply current (`automatic-current`).
    Current,
    /// Local linear on each motor's command (`automatic-motors`).
    Motors,
    /// The stand's physics, calibrated (`physics`).
    Physics,
}

impl FamilyId {
    /// Every family, in the order the choice tries them.
    pub const ALL: [FamilyId; 4] = [
        FamilyId::Throttle,
        FamilyId::Current,
        FamilyId::Motors,
        FamilyId::Physics,
    ];

    /// Its spelling in model files, tables and flags.
    pub fn id(self) -> &'static str {
        match self {
            FamilyId::Throttle => crate::methods::DEFAULT_ID,
            FamilyId::Current => "automatic-current",
            FamilyId::Motors => "automatic-motors",
            FamilyId::Physics => crate::methods::PHYSICS_ID,
        }
    }

    /// The family spelled `id`.
    pub fn from_id(id: &str) -> Option<FamilyId> {
        FamilyId::ALL.into_iter().find(|f| f.id() == id)
    }
}

impl std::fmt::Display for FamilyId {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.pad(self.id())
    }
}

impl From<FamilyId> for String {
    fn from(f: FamilyId) -> String {
        f.id().to_string()
    }
}

impl TryFrom<String> for FamilyId {
    type Error = String;
    fn try_from(id: String) -> Result<Self, String> {
        FamilyId::from_id(&id).ok_or_else(|| {
            let known: Vec<_> = FamilyId::ALL.iter().map(|f| f.id()).collect();
            format!(
                "unknown model family `{id}`: expected one of {}",
                known.join(", ")
            )
        })
    }
}

/// What one family gave on the held-out blocks.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FamilyScore {
    /// The family.
    pub family: FamilyId,
    /// The numbers the family's fit chose (see `Model::parameter_count`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub parameters: Option<usize>,
    /// Held-out RMSE per axis, µT.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub holdout_rmse_ut: Option<[f64; 3]>,
    /// Mean over the held-out blocks of the paired loss difference to the best family, µT²
    /// (0 for the best).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub excess_ut2: Option<f64>,
    /// Standard error of that mean, µT².
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub excess_se_ut2: Option<f64>,
    /// Why the family was not tried or failed, when it was not scored.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub note: Option<String>,
}

/// The record of an automatic choice, stored in the model file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FamilyChoice {
    /// The family kept.
    pub chosen: FamilyId,
    /// Why, in one sentence.
    pub reason: String,
    /// The rule, in one sentence.
    pub rule: String,
    /// Held-out rows every family was judged on.
    pub holdout_rows: usize,
    /// Held-out blocks.
    pub holdout_blocks: usize,
    /// Every family, in the order tried.
    pub families: Vec<FamilyScore>,
}

/// The rule as stored in [`FamilyChoice::rule`].
pub const RULE: &str = "lowest held-out error; a family with fewer parameters is kept instead when its held-out loss is within one standard error (paired over held-out blocks) of the lowest";

/// A family to be judged: its id, size, and residuals at the held-out rows, or why it has
/// none.
#[derive(Debug, Clone)]
pub struct Contender<'r> {
    /// The family.
    pub family: FamilyId,
    /// Parameter count.
    pub parameters: usize,
    /// Residual at each held-out row of the recording, in row order, µT, from a fit that did
    /// not see those rows; or why the family was not tried or failed. (Only those rows are
    /// evidence, and a long log's other rows would cost memory for nothing.)
    pub residuals_ut: Result<Cow<'r, [Vec3]>, String>,
}

/// Applies the rule to the contenders on the held-out rows (`holdout`), grouped in time blocks
/// (`block`, one per row). Returns `None` when no contender has residuals.
pub fn choose(
    contenders: &[Contender<'_>],
    holdout: &[bool],
    block: &[u64],
) -> Option<FamilyChoice> {
    // Held-out blocks in order of appearance, and each held-out row's block index among them.
    let mut ids: Vec<u64> = Vec::new();
    let mut row_block: Vec<usize> = Vec::new();
    for (&h, &b) in holdout.iter().zip(block) {
        if !h {
            continue;
        }
        let i = match ids.iter().rposition(|&x| x == b) {
            Some(i) => i,
            None => {
                ids.push(b);
                ids.len() - 1
            }
        };
        row_block.push(i);
    }
    let held_rows = row_block.len();
    // Per family: per-block mean loss, overall MSE and RMSE per axis.
    struct Scored {
        block_loss: Vec<f64>,
        mse: f64,
        rmse: [f64; 3],
    }
    let scored: Vec<Option<Scored>> = contenders
        .iter()
        .map(|c| {
            let r = c.residuals_ut.as_ref().ok()?;
            // Residuals of other rows than these are not this split's evidence.
            if r.len() != held_rows {
                return None;
            }
            let mut sum = vec![0.0; ids.len()];
            let mut count = vec![0usize; ids.len()];
            let mut axes = Vec3::zeros();
            for (v, &b) in r.iter().zip(&row_block) {
                sum[b] += v.norm_squared();
                count[b] += 1;
                axes += v.component_mul(v);
            }
            let n = held_rows.max(1) as f64;
            let mse = axes.sum() / n;
            if !mse.is_finite() {
                return None;
            }
            Some(Scored {
                block_loss: sum
                    .iter()
                    .zip(&count)
                    .map(|(s, c)| s / (*c).max(1) as f64)
                    .collect(),
                mse,
                rmse: [0, 1, 2].map(|a| (axes[a] / n).sqrt()),
            })
        })
        .collect();
    let best = (0..contenders.len())
        .filter(|&i| scored[i].is_some())
        .min_by(|&a, &b| {
            let (x, y) = (scored[a].as_ref(), scored[b].as_ref());
            x.map(|s| s.mse)
                .partial_cmp(&y.map(|s| s.mse))
                .unwrap_or(std::cmp::Ordering::Equal)
        })?;
    let best_loss = &scored[best].as_ref()?.block_loss;
    let paired = |s: &Scored| -> (f64, f64) {
        let d: Vec<f64> = s
            .block_loss
            .iter()
            .zip(best_loss)
            .map(|(a, b)| a - b)
            .collect();
        let n = d.len().max(1) as f64;
        let mean = d.iter().sum::<f64>() / n;
        let var = d.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0).max(1.0);
        (mean, (var / n).sqrt())
    };
    let mut families = Vec::new();
    let mut within: Vec<usize> = Vec::new();
    for (i, c) in contenders.iter().enumerate() {
        let score = match (&scored[i], &c.residuals_ut) {
            (Some(s), _) => {
                let (excess, se) = paired(s);
                if excess <= se {
                    within.push(i);
                }
                FamilyScore {
                    family: c.family,
                    parameters: Some(c.parameters),
                    holdout_rmse_ut: Some(s.rmse),
                    excess_ut2: Some(excess),
                    excess_se_ut2: Some(se),
                    note: None,
                }
            }
            (None, Err(why)) => FamilyScore {
                family: c.family,
                parameters: None,
                holdout_rmse_ut: None,
                excess_ut2: None,
                excess_se_ut2: None,
                note: Some(why.clone()),
            },
            (None, Ok(_)) => FamilyScore {
                family: c.family,
                parameters: Some(c.parameters),
                holdout_rmse_ut: None,
                excess_ut2: None,
                excess_se_ut2: None,
                note: Some("its held-out residuals are not finite".into()),
            },
        };
        families.push(score);
    }
    let chosen = *within.iter().min_by(|&&a, &&b| {
        contenders[a]
            .parameters
            .cmp(&contenders[b].parameters)
            .then(
                scored[a]
                    .as_ref()
                    .map(|s| s.mse)
                    .partial_cmp(&scored[b].as_ref().map(|s| s.mse))
                    .unwrap_or(std::cmp::Ordering::Equal),
            )
    })?;
    let rmse = |i: usize| {
        scored[i].as_ref().map_or(0.0, |s| {
            (s.rmse.iter().map(|x| x * x).sum::<f64>() / 3.0).sqrt()
        })
    };
    let reason = if chosen == best {
        format!(
            "{} has the lowest held-out error ({:.4} µT RMS over the axes) and no family with fewer parameters comes within one standard error of it",
            contenders[best].family,
            rmse(best)
        )
    } else {
        format!(
            "{} ({} parameters, {:.4} µT RMS held out) is within one standard error of the lowest, {} ({} parameters, {:.4} µT), with fewer parameters",
            contenders[chosen].family,
            contenders[chosen].parameters,
            rmse(chosen),
            contenders[best].family,
            contenders[best].parameters,
            rmse(best)
        )
    };
    Some(FamilyChoice {
        chosen: contenders[chosen].family,
        reason,
        rule: RULE.into(),
        holdout_rows: held_rows,
        holdout_blocks: ids.len(),
        families,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn contender(family: FamilyId, parameters: usize, sd: f64, seed: u64) -> Contender<'static> {
        // Deterministic pseudo-noise of the given size.
        let mut x = seed;
        let mut next = || {
            x = x
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((x >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 2.0 * 3f64.sqrt() * sd
        };
        Contender {
            family,
            parameters,
            // The 400 held-out rows of `split`.
            residuals_ut: Ok((0..400)
                .map(|_| Vec3::new(next(), next(), next()))
                .collect::<Vec<_>>()
                .into()),
        }
    }

    fn split() -> (Vec<bool>, Vec<u64>) {
        let block: Vec<u64> = (0..2000).map(|r| r / 40).collect();
        (block.iter().map(|b| b % 5 == 4).collect(), block)
    }

    #[test]
    fn a_clearly_better_family_wins_despite_more_parameters() {
        let (h, b) = split();
        let c = [
            contender(FamilyId::Throttle, 10, 0.5, 1),
            contender(FamilyId::Motors, 40, 0.1, 2),
        ];
        let choice = choose(&c, &h, &b).unwrap();
        assert_eq!(choice.chosen, FamilyId::Motors, "{choice:?}");
        assert_eq!(choice.holdout_blocks, 10);
        let rmse = choice.families[1].holdout_rmse_ut.unwrap();
        assert!((rmse[0] - 0.1).abs() < 0.02, "{rmse:?}");
    }

    #[test]
    fn within_noise_the_smaller_family_wins() {
        let (h, b) = split();
        // The same residuals but for a hair: not told apart by the data.
        let large = contender(FamilyId::Motors, 40, 0.3, 7);
        let mut small = large.clone();
        small.family = FamilyId::Throttle;
        small.parameters = 10;
        if let Ok(r) = &mut small.residuals_ut {
            r.to_mut()[0] *= 1.01;
        }
        let choice = choose(&[large, small], &h, &b).unwrap();
        assert_eq!(choice.chosen, FamilyId::Throttle, "{choice:?}");
        assert!(
            choice.reason.contains("fewer parameters"),
            "{}",
            choice.reason
        );
    }

    #[test]
    fn families_without_residuals_are_recorded_not_chosen() {
        let (h, b) = split();
        let c = [
            Contender {
                family: FamilyId::Current,
                parameters: 0,
                residuals_ut: Err("no bat_a column".into()),
            },
            contender(FamilyId::Throttle, 30, 0.2, 3),
        ];
        let choice = choose(&c, &h, &b).unwrap();
        assert_eq!(choice.chosen, FamilyId::Throttle);
        assert_eq!(choice.families[0].note.as_deref(), Some("no bat_a column"));
        let none = choose(&c[..1], &h, &b);
        assert!(none.is_none(), "{none:?}");
    }

    #[test]
    fn each_family_has_one_spelling_that_reads_back() {
        for f in FamilyId::ALL {
            let text = serde_json::to_string(&f).unwrap();
            assert_eq!(text, format!("\"{}\"", f.id()));
            assert_eq!(serde_json::from_str::<FamilyId>(&text).unwrap(), f);
        }
        let e = serde_json::from_str::<FamilyId>("\"cubic\"").unwrap_err();
        assert!(
            e.to_string().contains("unknown model family `cubic`"),
            "{e}"
        );
    }
}
