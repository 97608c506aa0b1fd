//! The exact step of a first-order lag, shared by the motors' spin-up and the board's heating.

/// The fraction of the way to its target a first-order lag of time constant `tau_s` covers in
/// `dt_s`: `1 - exp(-dt_s / tau_s)`, exact for a target held over the step and stable for any
/// step.
pub fn lag_factor(dt_s: f64, tau_s: f64) -> f64 {
    1.0 - (-dt_s / tau_s).exp()
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
}
