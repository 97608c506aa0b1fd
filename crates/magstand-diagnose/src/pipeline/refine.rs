//! Stage 4, refinement: after a term is accepted, every accepted term's nonlinear parameters
//! and the command timing are refitted together, so the misfit a held parameter leaves is not
//! offered to the next round as a new effect.
use crate::effects::Context;
use crate::fit::Weights;
use crate::optimize::{Search, minimize};

use super::design::{Term, as_refs, chi2_of};

/// Passes of the coordinate search in [`refine`].
const REFINE_PASSES: usize = 2;

/// Refits the nonlinear parameters of all accepted terms and the command lead together, by
/// coordinate search: each term's parameters (over its whole search range) with the others
/// held, then the lead, [`REFINE_PASSES`] times.
pub(crate) fn refine(ctx: &mut Context, terms: &mut [Term], weights: &Weights) {
    for _ in 0..REFINE_PASSES {
        for k in 0..terms.len() {
            let searches = terms[k].effect.search(ctx);
            if searches.is_empty() {
                continue;
            }
            let chi2 = |theta: &[f64]| {
                let mut refs = as_refs(terms);
                refs[k].1 = theta;
                chi2_of(ctx, &refs, ctx.command_lead, weights)
            };
            if let Some(opt) = minimize(&searches, chi2) {
                terms[k].theta = opt.theta;
                terms[k].theta_sd = opt.sd;
            }
        }
        ctx.command_lead = calibrate_timing(ctx, terms, weights);
    }
}

/// The moment within each interval at which logged command changes take effect, searched in
/// 0..1.
pub(crate) fn calibrate_timing(ctx: &Context, terms: &[Term], weights: &Weights) -> f64 {
    let refs = as_refs(terms);
    minimize(
        &[Search {
            name: "command_lead",
            unit: "interval",
            lo: 0.0,
            hi: 1.0,
            log: false,
            points: 5,
        }],
        |t| chi2_of(ctx, &refs, t[0], weights),
    )
    .map_or(0.5, |o| o.theta[0])
}
