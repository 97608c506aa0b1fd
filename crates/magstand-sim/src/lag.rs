//! The exact step of a first-order lag, shared by the motors' spin-up and the board's heating.

/// The fraction of the way to its target a first-order lag of time constant `tau_s` covers in
/// `dt_s`: `1 - exp(-dt_s / tau_s)`, exact for a target held over the step and stable for any
/// step.
pub fn lag_factor(dt_s: f64, tau_s: f64) -> f64 {
    1.0 - (-dt_s / tau_s).exp()
}

/// The share of a target's change over a step of `dt_s` that a first-order lag of time
/// constant `tau_s` has followed by the step's end, where the target moves along a straight
/// line over the step (a first-order hold) and `alpha` is the step's [`lag_factor`]:
/// `1 - (tau_s / dt_s) * alpha`. The state at the step's end is then
/// `x + (from - x) * alpha + (to - from) * ramp`, exact for the straight line. Without a lag
/// the state is the target, and the share 1. A measured input read at its samples (a logged
/// voltage) moves between them along such a line.
pub fn ramp_factor(alpha: f64, dt_s: f64, tau_s: f64) -> f64 {
    if tau_s > 0.0 && dt_s > 0.0 {
        1.0 - tau_s / dt_s * alpha
    } else {
        1.0
    }
}

/// [`lag_factor`] for one time constant, kept for the step length last asked: a simulation
/// steps by one length throughout, a replay by the few lengths of its sample intervals, and
/// the exponential is most of a small step's cost. The same bits as computing it each time.
#[derive(Debug, Clone, Copy)]
pub struct LagFactor {
    tau_s: f64,
    last: (u64, f64),
}

impl LagFactor {
    /// The factor of a lag with time constant `tau_s`.
    pub fn new(tau_s: f64) -> Self {
        Self {
            tau_s,
            last: (f64::NAN.to_bits(), 0.0),
        }
    }

    /// The factor for a step of `dt_s`.
    pub fn of(&mut self, dt_s: f64) -> f64 {
        if self.last.0 != dt_s.to_bits() {
            self.last = (dt_s.to_bits(), lag_factor(dt_s, self.tau_s));
        }
        self.last.1
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_kept_factor_is_the_computed_one_bit_for_bit() {
        let mut kept = LagFactor::new(0.06);
        for dt in [1e-3, 1e-3, 6.7e-3, 1e-3, 0.0, 2.5] {
            assert_eq!(
                kept.of(dt).to_bits(),
                lag_factor(dt, 0.06).to_bits(),
                "step {dt}"
            );
        }
        assert_eq!(lag_factor(1.0, 1.0), 1.0 - (-1.0f64).exp());
    }

    /// The step with a straight-line target against the lag's closed form: for a target
    /// `from + (to - from) t / dt`, `x(t) = u(t) - k tau + (x0 - from + k tau) exp(-t / tau)`
    /// with `k = (to - from) / dt`.
    #[test]
    fn a_straight_line_target_is_followed_exactly() {
        for (tau, dt) in [(0.05f64, 0.01f64), (0.5, 0.0133), (2.0, 1e-4), (1e-3, 0.02)] {
            let (x0, from, to) = (3.0, 10.0, 7.5);
            let k = (to - from) / dt;
            let exact = to - k * tau + (x0 - from + k * tau) * (-dt / tau).exp();
            let alpha = lag_factor(dt, tau);
            let stepped = x0 + (from - x0) * alpha + (to - from) * ramp_factor(alpha, dt, tau);
            assert!(
                (stepped - exact).abs() < 1e-9,
                "tau {tau}, dt {dt}: stepped {stepped}, exact {exact}"
            );
        }
        // Without a lag the state is the target at the step's end.
        assert_eq!(ramp_factor(lag_factor(0.01, 0.0), 0.01, 0.0), 1.0);
    }
}
