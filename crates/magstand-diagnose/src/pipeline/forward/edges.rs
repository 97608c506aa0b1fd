//! A finding's parameter at the edge of its search range: a reason the data do not
//! determine it, and the limit that edge stands for.
use super::*;

/// Where a finding's parameter `theta` lies at the edge of its search range, that parameter
/// and its range, as a reason the data do not determine it, or where the effect says so of a
/// place inside the range ([`Effect::undetermined_at`]: a delay within an interval of zero);
/// None otherwise, and for a calibration (a stand constant is reported, not named, and its
/// range is the physical one). Checked at acceptance and again on the refined parameters.
pub(super) fn at_edge(ctx: &Context, effect: &dyn Effect, theta: &[f64]) -> Option<String> {
    if calibrates(effect, ctx, theta) {
        return None;
    }
    search_at_bound(ctx, effect, theta)
        .filter(|_| at_a_stated_limit(ctx, effect, theta).is_none())
        .map(|(search, v, _)| {
            format!(
                "its {} = {v:.4} lies at the edge of its search range [{}, {}], so the data do not determine it",
                search.name, search.lo, search.hi
            )
        })
        // Inside the range, where the effect itself cannot be told from the baseline.
        .or_else(|| effect.undetermined_at(ctx, theta))
}

/// Where `effect`'s parameters `theta` lie at the lower end of a range that is a limit the data
/// determine ([`Effect::lower_edge_is_a_limit`]) against a stand constant the scenario
/// states: that search and what the limit means (the finding is that the statement is too
/// high). Only there: the same lag with nothing stated is a calibration, and behind a
/// flight's measured current a lag at its fastest is no lag at all.
pub(crate) fn at_a_stated_limit(
    ctx: &Context,
    effect: &dyn Effect,
    theta: &[f64],
) -> Option<(crate::optimize::Search, &'static str)> {
    stated_constant(effect, ctx)?;
    let (search, _, lower) = search_at_bound(ctx, effect, theta)?;
    let meaning = effect
        .lower_edge_is_a_limit(search.name)
        .filter(|_| lower)?;
    Some((search, meaning))
}

/// The first of `effect`'s searched parameters `theta` at the edge of its range ([`at_edge`]):
/// its search, its value and whether the edge is the lower one. None for a calibration, whose
/// value at an edge is reported as a limit ([`search_at_bound`]) rather than refused.
pub(super) fn edge_of(
    ctx: &Context,
    effect: &dyn Effect,
    theta: &[f64],
) -> Option<(crate::optimize::Search, f64, bool)> {
    if calibrates(effect, ctx, theta) {
        return None;
    }
    search_at_bound(ctx, effect, theta)
}

/// The first of `effect`'s searched parameters `theta` that lies at the edge of its search
/// range ([`Search::at_bound`](crate::optimize::Search::at_bound)): its search, its value and
/// whether the edge is the lower one.
pub(crate) fn search_at_bound(
    ctx: &Context,
    effect: &dyn Effect,
    theta: &[f64],
) -> Option<(crate::optimize::Search, f64, bool)> {
    effect
        .search(ctx)
        .into_iter()
        .zip(theta)
        .find(|(search, v)| search.at_bound(**v))
        .map(|(search, v)| {
            let lower = (v - search.lo).abs() <= (search.hi - v).abs();
            (search, *v, lower)
        })
}

/// The form a fit of `effect` at the edge of a parameter's range stands for
/// ([`Effect::edge_limit`]).
pub(super) fn edge_limit(
    ctx: &Context,
    effect: &dyn Effect,
    theta: &[f64],
) -> Option<&'static dyn Effect> {
    let (search, _, lower) = edge_of(ctx, effect, theta)?;
    effect.edge_limit(search.name, lower)
}

/// Whether an accepted term's refined parameters lie at an edge ([`refined_to_edge`]): what
/// a refinement asks of its newest term after each search of it.
pub(super) fn refused_at_edge(ctx: &Context, term: &Term) -> bool {
    refined_to_edge(ctx, term).is_some()
}

/// [`at_edge`] of an accepted term's refined parameters.
pub(super) fn refined_to_edge(ctx: &Context, term: &Term) -> Option<String> {
    at_edge(ctx, term.effect, &term.theta)
        .map(|why| format!("refitted beside the other terms, {why}"))
}
