//! The straight-line fits that autopilots use today, and a cubic, for comparison.
//!
//! * ArduPilot `compassmot`: per axis, a running average (factor 0.99) of field change over
//!   throttle (or current), through the origin, over samples in time order with the throttle
//!   above zero and, for current, at least 3 A drawn, as the firmware's own loop does. What it
//!   ends with depends on its last hundred or so updates.
//! * PX4 power compensation: a least-squares line per axis; only the slope is kept as
//!   `CAL_MAGn_{X,Y,Z}COMP`.
//! * A cubic with intercept in the normalized input.
use crate::IdentError;
use crate::dataset::{Dataset, InputKind};
use crate::least_squares::NormalEquations;
use crate::local_linear::singular;
use crate::model::Structure;

/// ArduPilot's compassmot updates its running average only while the pilot's throttle is above
/// zero (`control_in / 1000 > 0`: at least 0.001) and, for the current form, while at least
/// 3 A are drawn (`AP_Compass` compassmot, `current >= 3.0f`).
pub const COMPASSMOT_MIN_THROTTLE: f64 = 0.001;
/// See [`COMPASSMOT_MIN_THROTTLE`].
pub const COMPASSMOT_MIN_CURRENT_A: f64 = 3.0;
/// Updates after which compassmot's running average (factor 0.99, starting at zero) holds
/// less than 5 % of its start: 0.99^299 < 0.05. Fewer leave its line biased towards zero.
pub const COMPASSMOT_CONVERGED_UPDATES: usize = 299;

/// Whether compassmot would update its average on row `k` of `data`.
fn compassmot_updates_on(data: &Dataset, k: usize) -> bool {
    let raw = data.spec.lo + data.u[k] * (data.spec.hi - data.spec.lo);
    data.u[k] > 0.0
        && match data.spec.kind {
            InputKind::Current => raw >= COMPASSMOT_MIN_CURRENT_A,
            InputKind::Throttle | InputKind::Motors => raw >= COMPASSMOT_MIN_THROTTLE,
        }
}

/// Rows among `use_row` on which compassmot would update its average.
pub fn compassmot_updates(data: &Dataset, use_row: &dyn Fn(usize) -> bool) -> usize {
    (0..data.len())
        .filter(|&k| use_row(k) && compassmot_updates_on(data, k))
        .count()
}

/// ArduPilot's compassmot: a running average (0.99 old, 0.01 new) of `dmag / u` in time
/// order, over the rows on which the firmware updates it ([`compassmot_updates`]).
pub fn ardupilot(data: &Dataset, use_row: &dyn Fn(usize) -> bool) -> Result<Structure, IdentError> {
    let mut c = [0.0; 3];
    let mut seen = 0usize;
    for k in 0..data.len() {
        if !use_row(k) || !compassmot_updates_on(data, k) {
            continue;
        }
        let u = data.u[k];
        for a in 0..3 {
            c[a] = c[a] * 0.99 + 0.01 * data.y[k][a] / u;
        }
        seen += 1;
    }
    if seen == 0 {
        return Err(IdentError::Singular {
            origin: data.origin.clone(),
            what: "compassmot slope".into(),
            why: match data.spec.kind {
                InputKind::Current => "no rows with the motors running and at least 3 A drawn",
                _ => "no rows with the motors running",
            }
            .into(),
        });
    }
    Ok(Structure::Polynomial {
        coefficients: c.map(|s| vec![0.0, s]),
    })
}

/// Least-squares polynomial of `degree` in the normalized input; `keep_intercept = false`
/// drops the fitted intercept afterwards (PX4 stores only the slope).
pub fn polynomial(
    data: &Dataset,
    degree: usize,
    keep_intercept: bool,
    use_row: &dyn Fn(usize) -> bool,
) -> Result<Structure, IdentError> {
    let p = degree + 1;
    let mut ne = NormalEquations::new(p, 3);
    let mut z = vec![0.0; p];
    for k in 0..data.len() {
        if !use_row(k) {
            continue;
        }
        let u = data.u[k];
        let mut pow = 1.0;
        for zj in z.iter_mut() {
            *zj = pow;
            pow *= u;
        }
        let y = data.y[k];
        ne.add(&z, &[y.x, y.y, y.z], 1.0);
    }
    let th = ne
        .solve()
        .map_err(|e| singular(data, &format!("degree-{degree} polynomial"), e))?;
    let coefficients = [0, 1, 2].map(|a| {
        let mut c: Vec<f64> = (0..p).map(|j| th[(j, a)]).collect();
        if !keep_intercept {
            c[0] = 0.0;
        }
        c
    });
    Ok(Structure::Polynomial { coefficients })
}
