//! The straight-line fits that autopilots use today, and a cubic, for comparison.
//!
//! * ArduPilot `compassmot`: per axis, a running average (factor 0.99) of field change over
//!   throttle (or current), through the origin, over samples in time order with the motors
//!   running. What it ends with depends on the last second or so of data.
//! * PX4 power compensation: a least-squares line per axis; only the slope is kept as
//!   `CAL_MAGn_{X,Y,Z}COMP`.
//! * A cubic with intercept in the normalized input.
use crate::IdentError;
use crate::dataset::Dataset;
use crate::least_squares::NormalEquations;
use crate::local_linear::singular;
use crate::model::Structure;

/// ArduPilot-style running average of `dmag / u` over rows with `u > 0` in time order.
pub fn ardupilot(data: &Dataset, use_row: &dyn Fn(usize) -> bool) -> Result<Structure, IdentError> {
    let mut c = [0.0; 3];
    let mut seen = 0usize;
    for k in 0..data.len() {
        let u = data.u[k];
        if !use_row(k) || u <= 0.0 {
            continue;
        }
        for a in 0..3 {
            c[a] = c[a] * 0.99 + 0.01 * data.y[k][a] / u;
        }
        seen += 1;
    }
    if seen == 0 {
        return Err(IdentError::Singular {
            origin: data.origin.clone(),
            what: "compassmot slope".into(),
            why: "no rows with the motors running".into(),
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
