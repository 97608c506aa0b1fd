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
///
/// A search whose objective is the one it was last run on (the same other parameters and
/// lead, bit for bit) is not run again: it would find the same optimum, and each of its grid
/// points is a replay of the recording. The newest term was just searched as a candidate
/// beside the others as they are.
pub(crate) fn refine(ctx: &mut Context, terms: &mut [Term], weights: &Weights) {
    let mut searched_at: Vec<Option<Vec<u64>>> = vec![None; terms.len()];
    if let Some(last) = searched_at.last_mut() {
        *last = Some(objective_key(ctx, terms, terms.len() - 1));
    }
    let mut timed_at = None;
    for _ in 0..REFINE_PASSES {
        for k in 0..terms.len() {
            let searches = terms[k].effect.search(ctx);
            let key = objective_key(ctx, terms, k);
            if searches.is_empty() || searched_at[k].as_ref() == Some(&key) {
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
            searched_at[k] = Some(key);
        }
        let key = objective_key(ctx, terms, TIMING);
        if timed_at.as_ref() != Some(&key) {
            ctx.command_lead = calibrate_timing(ctx, terms, weights);
            timed_at = Some(key);
        }
    }
}

/// The index [`objective_key`] takes for the command lead's search.
const TIMING: usize = usize::MAX;

/// What the search of term `skip` (or of the command lead, for [`TIMING`]) holds fixed: the
/// other terms' parameters and, for a term, the command lead, as bits.
fn objective_key(ctx: &Context, terms: &[Term], skip: usize) -> Vec<u64> {
    terms
        .iter()
        .enumerate()
        .filter(|&(k, _)| k != skip)
        .flat_map(|(_, t)| t.theta.iter().map(|v| v.to_bits()))
        .chain((skip != TIMING).then_some(ctx.command_lead.to_bits()))
        .collect()
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
