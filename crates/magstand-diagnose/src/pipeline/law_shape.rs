//! The calibrated current law's shape as an uncertainty: a constant fitted beside it (a dead
//! zone) moves with the number of powers of speed the law has, which nobody states, so its
//! uncertainty holds the spread of its optimum over the laws of fewer powers.
use crate::effects::{Context, Param};
use crate::fit::{Design, MAX_SPEED_POWERS, MIN_SPEED_POWERS, Weights, fit};

use super::design::{Term, as_refs, build_with_lead};

/// `p` with half the spread `(lo, hi)` of its optimum over the current laws' shapes
/// ([`law_shape_spread`]) in its sd, and that spread as its basis. At a range limit the
/// chi-square gives no curvature: the spread is then the only uncertainty there is.
pub(crate) fn with_law_shape_spread(ctx: &Context, p: Param, (lo, hi): (f64, f64)) -> Param {
    Param {
        sd: p
            .sd
            .map(|sd| sd.hypot(0.5 * (hi - lo)))
            .or((hi > lo).then_some(0.5 * (hi - lo))),
        ..p
    }
    .resting_on(&format!(
        "the calibrated current law's shape, which is not stated: with laws of {} to {} powers \
         of speed the optimum lies between {lo:.4} and {hi:.4}, and the sd holds half that \
         spread",
        MIN_SPEED_POWERS, ctx.speed_powers
    ))
}

/// The range of the optimum of `terms[k]`'s one linear parameter, on every other point of its
/// search grid with the others held, over the current laws of [`MIN_SPEED_POWERS`]
/// to the context's powers of speed (each a subset of the baseline's columns, and of the
/// terms' columns made from them), with its refined value. None where the law has no fewer
/// powers, or the parameter is not one linear search.
pub(crate) fn law_shape_spread(
    ctx: &Context,
    terms: &[Term],
    k: usize,
    weights: &Weights,
) -> Option<(f64, f64)> {
    use rayon::prelude::*;
    let (min_powers, powers) = (MIN_SPEED_POWERS, ctx.speed_powers);
    let [search] = terms[k].effect.search(ctx).try_into().ok()?;
    if powers <= min_powers || search.log || search.points < 2 {
        return None;
    }
    // Every other point of the search's grid: a spread, not an optimum, is wanted, and each
    // point is a replay of the recording.
    let points = search.points.div_ceil(2).max(2);
    let step = (search.hi - search.lo) / (points - 1) as f64;
    // Each grid point one design, fitted with each law: chi-square by law, by point.
    let profiles: Vec<Vec<f64>> = (0..points)
        .into_par_iter()
        .map(|i| {
            let theta = [search.lo + i as f64 * step];
            let mut refs = as_refs(terms);
            refs[k].1 = &theta;
            let built = build_with_lead(ctx, &refs, ctx.command_lead);
            (min_powers..powers)
                .map(|p| {
                    let design = without_powers_above(&built.design, p);
                    fit(
                        &design,
                        &ctx.rec.mag_ut,
                        Some(&built.fixed),
                        weights,
                        &ctx.split.holdout,
                    )
                    .map_or(f64::INFINITY, |f| f.chi2_fit)
                })
                .collect()
        })
        .collect();
    let refined = *terms[k].theta.first()?;
    (0..powers - min_powers)
        .map(|law| {
            let best =
                (0..points).min_by(|&a, &b| profiles[a][law].total_cmp(&profiles[b][law]))?;
            profiles[best][law]
                .is_finite()
                .then_some(search.lo + best as f64 * step)
        })
        .try_fold((refined, refined), |(lo, hi), v| {
            v.map(|v| (lo.min(v), hi.max(v)))
        })
}

/// `design` without the current law's powers of speed above `powers`, nor the terms' columns
/// made from them.
fn without_powers_above(design: &Design, powers: usize) -> Design {
    let dropped =
        |name: &str| (powers + 1..=MAX_SPEED_POWERS).any(|j| name.contains(&format!("speed^{j}")));
    let mut out = Design::default();
    for (name, column) in design.names.iter().zip(&design.columns) {
        if !dropped(name) {
            out.push(name.clone(), column.clone());
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A law of fewer powers of speed is the baseline's columns up to that power, and the
    /// terms' columns made from those powers only.
    #[test]
    fn a_law_of_fewer_powers_keeps_the_columns_up_to_that_power() {
        let mut d = Design::default();
        for name in [
            "reference",
            "driven",
            "speed^1",
            "speed^3",
            "speed^4",
            "speed^5",
            "voltage_change_x_speed^2",
            "voltage_change_x_speed^5",
        ] {
            d.push(name, vec![0.0; 2]);
        }
        let kept = without_powers_above(&d, 3);
        assert_eq!(
            kept.names,
            [
                "reference",
                "driven",
                "speed^1",
                "speed^3",
                "voltage_change_x_speed^2"
            ],
            "{:?}",
            d.names
        );
        assert_eq!(kept.columns.len(), kept.names.len());
        assert_eq!(without_powers_above(&d, 5).names, d.names);
    }
}
