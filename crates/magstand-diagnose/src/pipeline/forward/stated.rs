//! Stand constants stated and unstated: a fitted constant is a finding only where the data
//! reject the statement; one nobody stated is a calibration.
use super::*;

/// How far, in standard uncertainties, a fitted stand constant must lie from the stated value
/// for the data to reject the statement.
pub(super) const REJECT_STATED_SD: f64 = 3.0;

/// A candidate that re-fits a stand constant the scenario states (a dead zone, a spin-up
/// time) stands only where the data reject the stated value: its fit must lie more than
/// [`REJECT_STATED_SD`] standard uncertainties from it, and the recording must be able to
/// tell the two apart by more than the calibrated current law
/// ([`Effect::inseparable_from_stated`]). Otherwise it is kept in the record, untestable,
/// with why. (A constant the scenario leaves out is tested by its held-out gain
/// and, when accepted, reported as calibration: see [`calibrates`].)
///
/// The uncertainty of a constant that trades off against the calibrated current law's shape
/// (a dead zone) holds half the spread of its optimum over the laws of fewer powers of speed
/// ([`law_shape_spread`](crate::pipeline::law_shape::law_shape_spread)), as its report does: the law's
/// shape is calibrated whatever the scenario states. The spread is profiled (16 replays) only
/// where the curvature alone would reject the statement.
///
/// Returns the refit's held-out gain where it is kept within the statement: a term that
/// gains no more must also stand beside the constant so refitted.
pub(super) fn refuse_within_stated(
    c: &mut Candidate,
    effect: &dyn Effect,
    ctx: &Context,
    terms: &[Term],
    weights: &Weights,
) -> Option<f64> {
    let (key, stated) = stated_constant(effect, ctx)?;
    // An effect that re-fits a stand constant searches that constant alone (asserted for the
    // whole catalog by `every_effect_searches_its_declared_parameters`).
    let (theta, sd, fitted) = c.fitted.as_ref()?;
    let mut shown = sd
        .first()
        .copied()
        .flatten()
        .map(|sd| sd * fitted.sd_factor);
    let rejects_by =
        |sd: Option<f64>| sd.is_some_and(|sd| (theta[0] - stated).abs() > REJECT_STATED_SD * sd);
    if rejects_by(shown) && effect.trades_off_with_the_law_shape() {
        let mut with = terms.to_vec();
        with.push(Term {
            effect,
            theta: theta.clone(),
            theta_sd: sd.clone(),
        });
        let spread = crate::pipeline::law_shape::law_shape_spread(
            ctx,
            &with,
            terms.len(),
            weights,
            crate::pipeline::law_shape::Laws::AlsoWithoutLinearPower,
        );
        if let (Some(sd), Some((lo, hi))) = (shown, spread) {
            shown = Some(sd.hypot(0.5 * (hi - lo)));
        }
    }
    let rejects = rejects_by(shown)
        || !effect.trades_off_with_the_law_shape()
            && rejects_by_chi2(effect, ctx, terms, weights, stated, fitted);
    let fitted = crate::diagnosis::value_with_sd(theta[0], shown);
    let why_not = if !rejects {
        format!(
            "fitted {key} = {fitted} is within {REJECT_STATED_SD} sd of the stated {stated} (or its uncertainty is unknown): the data do not reject the statement"
        )
    } else if let Some(why) = effect.inseparable_from_stated(ctx, stated, theta[0]) {
        format!(
            "fitted {key} = {fitted} differs from the stated {stated}, but {why}: the data do not reject the statement"
        )
    } else {
        return None;
    };
    c.result.note = Some(why_not);
    c.result.p_value = None;
    c.result.improvement
}

/// Whether the chi-square rejects the statement `stated` of `effect`'s constant against its
/// `fitted` refit (the others as they are): the fit at the stated value lies more than
/// [`REJECT_STATED_SD`] squared above the refit's, in units of the residuals' variance factor
/// (a likelihood-ratio test, the square of the sd test where the chi-square is a parabola).
///
/// The sd test alone reads the chi-square's curvature at the refit, which says nothing where
/// it is not a parabola out to the statement: a spin-up refitted near its fastest, 1 ms, at
/// 50 Hz, where a millisecond more or less changes nothing the data see, had an sd of 0.70 s
/// (or none at the bound), and statements of 0.05 and 0.3 s that the data reject by far
/// (held-out error 1.4 and 3.6 µT against 0.2 µT refitted) were kept, the misfit named
/// `unexplained`. Not for a constant that trades off with the current law's shape (a dead
/// zone): at a fixed law the chi-square rejects what the law's calibrated shape would take up,
/// which its sd holds as the spread over those shapes.
fn rejects_by_chi2(
    effect: &dyn Effect,
    ctx: &Context,
    terms: &[Term],
    weights: &Weights,
    stated: f64,
    fitted: &crate::fit::Fitted,
) -> bool {
    let mut refs = as_refs(terms);
    let at_statement = [stated];
    refs.push((effect, &at_statement));
    let Some(chi2_stated) = chi2_of(ctx, &refs, ctx.command_lead, weights) else {
        return false;
    };
    let variance = fitted.sd_factor * fitted.sd_factor;
    (chi2_stated - fitted.chi2_fit) / variance > REJECT_STATED_SD * REJECT_STATED_SD
}

/// Whether an accepted `effect` with parameters `theta` is the calibration of a stand constant
/// the scenario leaves out (a dead zone, a spin-up time nobody stated) rather than a finding:
/// such a term stays in the model but is reported under `baseline.calibration`, not named.
/// The effect's own [`Effect::beyond_calibration`] names the exception (a lag slower than any
/// spin-up).
pub(crate) fn calibrates(effect: &dyn Effect, ctx: &Context, theta: &[f64]) -> bool {
    is_unstated_constant(effect, ctx) && effect.beyond_calibration(theta).is_none()
}

/// The stand constant `effect` fits and its value, where the scenario states it.
pub(super) fn stated_constant(effect: &dyn Effect, ctx: &Context) -> Option<(&'static str, f64)> {
    effect
        .stand_constant(ctx)
        .filter(|(key, _)| ctx.nominal.states(key))
}

/// Whether `effect` fits a stand constant the scenario leaves out (a dead zone, a spin-up
/// time): a candidate of the calibration rounds that open the search.
pub(super) fn is_unstated_constant(effect: &dyn Effect, ctx: &Context) -> bool {
    effect
        .stand_constant(ctx)
        .is_some_and(|(key, _)| !ctx.nominal.states(key))
}
