//! ESC and brushless motor with a propeller load.
//!
//! The ESC maps a command in 0..1 to a PWM duty: nothing below the start threshold (the paper's
//! motors started near 37 units of command), then linearly up to full duty. At steady state the
//! applied voltage balances back-EMF and the resistive drop of the current that the propeller's
//! drag torque needs:
//!
//! `V * duty = Ke * w + R * (I0 + kq * w^2 / Kt)`,   `Kt = Ke = 60 / (2 pi Kv)`
//!
//! so current grows with the square of speed, faster than linearly with command, and falls
//! with the supply voltage. The rotor follows its steady-state speed through a first-order lag
//! (spin-up), which makes the current, and the field it causes, lag command steps. Where the
//! current itself is slower still (an ESC that ramps its current, a filtered current, a supply
//! that cannot follow: `current_lag_s`), the current drawn follows the current of the rotor's
//! speed through a first-order lag of its own.
use serde::{Deserialize, Serialize};

use crate::error::{Checker, SimError};

/// Parameters shared by every motor of the stand.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MotorParams {
    /// Number of motors (4 for a quad, 6 for a hexa).
    pub count: usize,
    /// Distance from the frame centre to each motor, m.
    pub arm_length_m: f64,
    /// Command at which the ESC starts driving the motor (dead zone), 0..1.
    pub dead_zone: f64,
    /// Motor velocity constant, rpm per volt.
    pub kv_rpm_per_v: f64,
    /// Winding plus ESC resistance, ohm.
    pub winding_resistance_ohm: f64,
    /// No-load current while spinning, A.
    pub idle_current_a: f64,
    /// Propeller drag-torque coefficient kq: torque = kq * w^2, N m s^2.
    pub torque_coeff_nms2: f64,
    /// Propeller thrust coefficient kf: thrust = kf * w^2, N s^2.
    pub thrust_coeff_ns2: f64,
    /// Spin-up time constant, s.
    pub spinup_tau_s: f64,
    /// Time constant, s, through which the current drawn follows the current of the rotor's
    /// speed (an ESC that ramps its current, a filtered current, a supply that cannot follow);
    /// 0 (the default) for none: the current is that of the speed at once.
    #[serde(skip_serializing_if = "is_zero")]
    pub current_lag_s: f64,
    /// Rotor imbalance (mass times offset), kg m: a force m r w^2 rotating with the rotor.
    pub imbalance_kg_m: f64,
    /// Per-motor scale on the torque coefficient (unequal propellers); empty means all 1.
    pub load_scale: Vec<f64>,
}

impl Default for MotorParams {
    fn default() -> Self {
        Self {
            count: 4,
            arm_length_m: 0.225,
            dead_zone: 0.37,
            kv_rpm_per_v: 920.0,
            winding_resistance_ohm: 0.12,
            idle_current_a: 0.4,
            torque_coeff_nms2: 1.95e-7,
            thrust_coeff_ns2: 1.0e-5,
            spinup_tau_s: 0.06,
            current_lag_s: 0.0,
            imbalance_kg_m: 2.0e-6,
            load_scale: Vec::new(),
        }
    }
}

/// The slowest current lag a scenario may state, s: a lag of minutes is not a current's.
pub const MAX_CURRENT_LAG_S: f64 = 60.0;

/// Whether a value is zero (a setting left at its default is not written out).
fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

/// Most motors a stand may have.
pub const MAX_MOTORS: usize = 16;

impl MotorParams {
    pub(crate) fn check(&self, c: &Checker) -> Result<(), SimError> {
        if !(1..=MAX_MOTORS).contains(&self.count) {
            return Err(c.fail(
                "motors.count",
                self.count,
                &format!("an integer in 1..={MAX_MOTORS}"),
            ));
        }
        c.positive("motors.arm_length_m", self.arm_length_m)?;
        c.range("motors.dead_zone", self.dead_zone, 0.0, 0.95)?;
        c.positive("motors.kv_rpm_per_v", self.kv_rpm_per_v)?;
        c.positive("motors.winding_resistance_ohm", self.winding_resistance_ohm)?;
        c.range("motors.idle_current_a", self.idle_current_a, 0.0, 100.0)?;
        c.positive("motors.torque_coeff_nms2", self.torque_coeff_nms2)?;
        c.range("motors.thrust_coeff_ns2", self.thrust_coeff_ns2, 0.0, 1.0)?;
        c.positive("motors.spinup_tau_s", self.spinup_tau_s)?;
        c.range(
            "motors.current_lag_s",
            self.current_lag_s,
            0.0,
            MAX_CURRENT_LAG_S,
        )?;
        c.range("motors.imbalance_kg_m", self.imbalance_kg_m, 0.0, 1.0)?;
        if !self.load_scale.is_empty() && self.load_scale.len() != self.count {
            return Err(c.fail(
                "motors.load_scale",
                format!("{} values", self.load_scale.len()),
                &format!("one value per motor ({}) or none", self.count),
            ));
        }
        for s in &self.load_scale {
            c.positive("motors.load_scale", *s)?;
        }
        Ok(())
    }

    /// The fraction of the way to its target speed a rotor covers in `dt_s`: the exact
    /// discretization of the spin-up lag, stable for any step.
    pub fn spinup_alpha(&self, dt_s: f64) -> f64 {
        crate::lag::lag_factor(dt_s, self.spinup_tau_s)
    }

    /// The lag factors of a step of `dt_s`: the rotor's ([`MotorParams::spinup_alpha`]) and
    /// the current's (1 without a current lag).
    pub fn step_factors(&self, dt_s: f64) -> StepFactors {
        StepFactors {
            spinup: self.spinup_alpha(dt_s),
            current: crate::lag::lag_factor(dt_s, self.current_lag_s),
        }
    }

    /// Torque constant Kt = Ke, N m per A (and V s per rad).
    pub fn torque_constant(&self) -> f64 {
        60.0 / (2.0 * std::f64::consts::PI * self.kv_rpm_per_v)
    }

    /// PWM duty for a command: 0 in the dead zone, then linear to 1 at full command.
    pub fn duty(&self, command: f64) -> f64 {
        if self.drives(command) {
            ((command - self.dead_zone) / (1.0 - self.dead_zone)).min(1.0)
        } else {
            0.0
        }
    }

    /// Whether the ESC drives the motor at `command` (above the dead zone, the one place
    /// that says where it ends): `duty(command) > 0`, without its division. For a dead zone
    /// below 1 (the checked range ends at 0.95) a command above it leaves a positive
    /// difference (IEEE subtraction of two different numbers is never zero) that a divisor of
    /// at most 1 cannot round to zero; a NaN command is driven in both.
    pub fn drives(&self, command: f64) -> bool {
        !(command <= self.dead_zone)
    }

    fn kq(&self, motor: usize) -> f64 {
        self.torque_coeff_nms2 * self.load_scale.get(motor).copied().unwrap_or(1.0)
    }

    /// The constants of motor `motor` that its per-step formulas use.
    pub fn constants(&self, motor: usize) -> MotorConstants {
        let kt = self.torque_constant();
        let kq = self.kq(motor);
        MotorConstants {
            kt,
            kq,
            a: self.winding_resistance_ohm * kq / kt,
        }
    }

    /// Steady-state rotor speed (rad/s) at `duty` and supply `voltage_v`: the positive root of
    /// `(R kq / Kt) w^2 + Ke w + (R I0 - V duty) = 0`.
    pub fn steady_speed(&self, motor: usize, duty: f64, voltage_v: f64) -> f64 {
        self.constants(motor).steady_speed(self, duty, voltage_v)
    }

    /// Current (A) drawn by a motor spinning at `speed` while driven.
    pub fn current(&self, motor: usize, speed: f64, driven: bool) -> f64 {
        self.constants(motor).current(self, speed, driven)
    }

    /// Thrust (N) at `speed`.
    pub fn thrust(&self, speed: f64) -> f64 {
        self.thrust_coeff_ns2 * speed * speed
    }

    /// Propeller drag torque magnitude (N m) at `speed`.
    pub fn drag_torque(&self, motor: usize, speed: f64) -> f64 {
        self.kq(motor) * speed * speed
    }
}

/// One motor's constants, computed once from its parameters: a simulation steps every motor
/// a thousand times a second, and these would otherwise be divided out at each step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotorConstants {
    /// Torque constant Kt = Ke, N m per A.
    kt: f64,
    /// Propeller drag coefficient with the motor's load scale, N m s^2.
    kq: f64,
    /// The quadratic coefficient `R kq / Kt` of the voltage balance.
    a: f64,
}

impl MotorConstants {
    /// Whether `other` holds the same bits: two motors with the same bits and the same
    /// commands step through the same states.
    pub fn same_bits(&self, other: &Self) -> bool {
        [self.kt, self.kq, self.a].map(f64::to_bits)
            == [other.kt, other.kq, other.a].map(f64::to_bits)
    }

    /// See [`MotorParams::steady_speed`].
    pub fn steady_speed(&self, p: &MotorParams, duty: f64, voltage_v: f64) -> f64 {
        let drive = voltage_v.max(0.0) * duty - p.winding_resistance_ohm * p.idle_current_a;
        if duty <= 0.0 || drive <= 0.0 {
            return 0.0;
        }
        // Stable form of (-b + sqrt(b^2 + 4 a drive)) / 2a for small a.
        2.0 * drive / (self.kt + (self.kt * self.kt + 4.0 * self.a * drive).sqrt())
    }

    /// See [`MotorParams::current`].
    pub fn current(&self, p: &MotorParams, speed: f64, driven: bool) -> f64 {
        if !driven {
            return 0.0;
        }
        p.idle_current_a + self.kq * speed * speed / self.kt
    }
}

/// `angle % TAU`, the same bits, without the remainder's loop where one turn is taken off
/// (every step of a rotor below one turn per step): for `TAU <= angle < 2 TAU` the subtraction
/// is exact (Sterbenz), as the remainder is.
fn wrap_angle(angle: f64) -> f64 {
    use std::f64::consts::TAU;
    if (0.0..TAU).contains(&angle) {
        angle
    } else if (TAU..2.0 * TAU).contains(&angle) {
        angle - TAU
    } else {
        angle % TAU
    }
}

/// Sine and cosine of a rotor angle in `[0, 2 pi)` (as [`wrap_angle`] keeps it), within about
/// one unit in the last place: fdlibm's kernels (`__kernel_sin`, `__kernel_cos`) on the angle
/// less its nearest multiple of pi/2 (Cody and Waite's two-part pi/2, exact for these
/// multiples). The quadrant is applied without a branch: a rotor turns about a radian per step,
/// so the quadrant changes at random and a branch on it would be mispredicted half the time.
/// Four rotors take this every physics step; the C library's `sincos` was a tenth of a study's
/// time.
pub(crate) fn rotor_sin_cos(angle: f64) -> (f64, f64) {
    // fdlibm's constants, by their bits as its source gives them.
    const PIO2_HI: f64 = f64::from_bits(0x3FF9_21FB_5440_0000);
    const PIO2_LO: f64 = f64::from_bits(0x3DD0_B461_1A62_6331);
    const S1: f64 = f64::from_bits(0xBFC5_5555_5555_5549);
    const S2: f64 = f64::from_bits(0x3F81_1111_1110_F8A6);
    const S3: f64 = f64::from_bits(0xBF2A_01A0_19C1_61D5);
    const S4: f64 = f64::from_bits(0x3EC7_1DE3_57B1_FE7D);
    const S5: f64 = f64::from_bits(0xBE5A_E5E6_8A2B_9CEB);
    const S6: f64 = f64::from_bits(0x3DE5_D93A_5ACF_D57C);
    const C1: f64 = f64::from_bits(0x3FA5_5555_5555_554C);
    const C2: f64 = f64::from_bits(0xBF56_C16C_16C1_5177);
    const C3: f64 = f64::from_bits(0x3EFA_01A0_19CB_1590);
    const C4: f64 = f64::from_bits(0xBE92_7E4F_809C_52AD);
    const C5: f64 = f64::from_bits(0x3E21_EE9E_BDB4_B1C4);
    const C6: f64 = f64::from_bits(0xBDA8_FAE9_BE88_38D4);
    // The nearest integer by the 1.5 * 2^52 shift (round half to even; `round` is a library
    // call without SSE4.1).
    const SHIFT: f64 = 6_755_399_441_055_744.0;
    let shifted = angle * std::f64::consts::FRAC_2_PI + SHIFT;
    let n = shifted - SHIFT;
    let r = (angle - n * PIO2_HI) - n * PIO2_LO;
    let z = r * r;
    let sin_r = r + r * z * (S1 + z * (S2 + z * (S3 + z * (S4 + z * (S5 + z * S6)))));
    let half_z = 0.5 * z;
    let w = 1.0 - half_z;
    let cos_r = w
        + (((1.0 - w) - half_z)
            + z * z * (C1 + z * (C2 + z * (C3 + z * (C4 + z * (C5 + z * C6))))));
    // The quadrant is n's low bits, the mantissa's of the shifted sum (two's complement for a
    // negative n): odd quadrants swap sine and cosine, quadrants 2 and 3
    // flip both signs (a turn by pi); done on the bits, without a branch.
    let quadrant = shifted.to_bits();
    let odd = 0u64.wrapping_sub(quadrant & 1);
    let flip = (quadrant & 2) << 62;
    let neg_sin_r = (-sin_r).to_bits();
    let sin = (sin_r.to_bits() & !odd) | (cos_r.to_bits() & odd);
    let cos = (cos_r.to_bits() & !odd) | (neg_sin_r & odd);
    (f64::from_bits(sin ^ flip), f64::from_bits(cos ^ flip))
}

/// The fractions of the way a motor covers in one step: its rotor toward its target speed, and
/// its current toward the current of that speed (1 without a current lag). Exact
/// discretizations of the two first-order lags, stable for any step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepFactors {
    /// The spin-up's factor, [`MotorParams::spinup_alpha`].
    pub spinup: f64,
    /// The current lag's factor.
    pub current: f64,
}

impl StepFactors {
    /// The factors of no step (a part of an interval of no length).
    pub const NONE: StepFactors = StepFactors {
        spinup: 0.0,
        current: 0.0,
    };
}

/// State of one motor: rotor speed and rotor angle (for the imbalance force).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct MotorState {
    /// Rotor speed, rad/s.
    pub speed_rad_s: f64,
    /// Rotor angle, rad.
    pub angle_rad: f64,
    /// Current drawn, A.
    pub current_a: f64,
}

impl MotorState {
    /// Advances one motor by `dt_s` under `command` at supply `voltage_v`.
    pub fn step(&mut self, p: &MotorParams, motor: usize, command: f64, voltage_v: f64, dt_s: f64) {
        self.step_with(
            p,
            &p.constants(motor),
            command,
            voltage_v,
            dt_s,
            p.step_factors(dt_s),
        );
    }

    /// As [`MotorState::step`], with the motor's constants and the lag factors of the step
    /// computed once by the caller (an exponential and a few divisions per motor and step are
    /// a noticeable part of a simulation's cost).
    pub fn step_with(
        &mut self,
        p: &MotorParams,
        c: &MotorConstants,
        command: f64,
        voltage_v: f64,
        dt_s: f64,
        factors: StepFactors,
    ) {
        self.step_electrical_with(p, c, command, voltage_v, factors);
        self.angle_rad = wrap_angle(self.angle_rad + self.speed_rad_s * dt_s);
    }

    /// Advances speed and current only (not the rotor angle, which only the rigid body
    /// needs), with the lag factors [`MotorParams::step_factors`] of the step: the replay of
    /// a recording steps every motor by the same interval.
    pub fn step_electrical(
        &mut self,
        p: &MotorParams,
        motor: usize,
        command: f64,
        voltage_v: f64,
        factors: StepFactors,
    ) {
        self.step_electrical_with(p, &p.constants(motor), command, voltage_v, factors);
    }

    /// As [`MotorState::step_electrical`], with the motor's constants computed once by the
    /// caller.
    pub fn step_electrical_with(
        &mut self,
        p: &MotorParams,
        c: &MotorConstants,
        command: f64,
        voltage_v: f64,
        factors: StepFactors,
    ) {
        let duty = p.duty(command);
        self.step_toward(
            p,
            c,
            c.steady_speed(p, duty, voltage_v),
            duty > 0.0,
            factors,
        );
    }

    /// Advances the speed alone toward `target_rad_s`: [`MotorState::step_toward`] for a part
    /// of a step after which another part follows at once, where the motor's current has no
    /// lag (its current is then the current of the speed at the end, and the current computed
    /// here would be overwritten unread).
    pub fn step_speed_toward(&mut self, target_rad_s: f64, factors: StepFactors) {
        self.speed_rad_s += (target_rad_s - self.speed_rad_s) * factors.spinup;
    }

    /// Advances speed and current toward a steady speed `target_rad_s` already worked out for
    /// the command (`driven` while the ESC drives the motor), with lag factors `factors`: what
    /// [`MotorState::step_electrical_with`] does once it has the target, for a caller that
    /// keeps the target while the command and the voltage hold. A current lag follows the
    /// current of the speed at the step's end, held over the step.
    pub fn step_toward(
        &mut self,
        p: &MotorParams,
        c: &MotorConstants,
        target_rad_s: f64,
        driven: bool,
        factors: StepFactors,
    ) {
        self.step_speed_toward(target_rad_s, factors);
        self.follow_current(p, c, driven, factors);
    }

    /// Advances the speed alone along a target that moves in a straight line from `from_rad_s`
    /// to `to_rad_s` over the step (a logged voltage between two rows), `ramp` being the
    /// step's [`ramp_factor`](crate::lag::ramp_factor): the exact step of the spin-up for such a
    /// target, where [`MotorState::step_speed_toward`] holds one.
    pub fn step_speed_along(
        &mut self,
        from_rad_s: f64,
        to_rad_s: f64,
        factors: StepFactors,
        ramp: f64,
    ) {
        self.speed_rad_s += (from_rad_s - self.speed_rad_s) * factors.spinup;
        self.speed_rad_s += (to_rad_s - from_rad_s) * ramp;
    }

    /// [`MotorState::step_toward`] along a moving target ([`MotorState::step_speed_along`]).
    #[allow(clippy::too_many_arguments)]
    pub fn step_along(
        &mut self,
        p: &MotorParams,
        c: &MotorConstants,
        from_rad_s: f64,
        to_rad_s: f64,
        driven: bool,
        factors: StepFactors,
        ramp: f64,
    ) {
        self.step_speed_along(from_rad_s, to_rad_s, factors, ramp);
        self.follow_current(p, c, driven, factors);
    }

    /// Advances the current toward the current of the speed reached (`driven` while the ESC
    /// drives the motor), held over the step.
    fn follow_current(
        &mut self,
        p: &MotorParams,
        c: &MotorConstants,
        driven: bool,
        factors: StepFactors,
    ) {
        let of_speed_a = c.current(p, self.speed_rad_s, driven);
        // Without a lag, the current of the speed itself (the same bits as before the lag
        // existed, which `x + (y - x) * 1` is not always).
        self.current_a = if p.current_lag_s > 0.0 {
            self.current_a + (of_speed_a - self.current_a) * factors.current
        } else {
            of_speed_a
        };
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Distance in units in the last place between `a` and the correctly rounded `b`, counted
    /// at `b`'s magnitude (or at 2^-53 near zero, where a rotor angle's sine is absolute).
    fn ulps(a: f64, b: f64) -> f64 {
        (a - b).abs() / (b.abs().max(1.0) * f64::EPSILON / 2.0)
    }

    #[test]
    fn a_rotors_sine_and_cosine_are_the_library_ones_within_two_ulps() {
        use std::f64::consts::{FRAC_PI_2, TAU};
        let mut angles: Vec<f64> = (0..200_000).map(|i| TAU * i as f64 / 200_000.0).collect();
        // The quadrant edges and their neighbours, where the reduction cancels most.
        for k in 0..4 {
            let edge = k as f64 * FRAC_PI_2;
            for x in [
                edge,
                edge.next_up(),
                edge.next_down(),
                edge + 1e-9,
                edge - 1e-9,
            ] {
                angles.push(x);
            }
        }
        angles.extend([TAU.next_down(), 1e-300, 0.0, -0.7, -3.0, 7.0]);
        let mut worst = (0.0f64, 0.0);
        for &x in &angles {
            let (s, c) = rotor_sin_cos(x);
            let (s_ref, c_ref) = x.sin_cos();
            let e = ulps(s, s_ref).max(ulps(c, c_ref));
            if e > worst.0 {
                worst = (e, x);
            }
        }
        assert!(
            worst.0 <= 2.0,
            "{} ulps off the library's sin_cos at angle {}",
            worst.0,
            worst.1
        );
    }

    #[test]
    fn a_wrapped_angle_has_the_remainders_bits() {
        use std::f64::consts::TAU;
        let mut x = 0.37_f64;
        for k in 0..100_000 {
            // Angles below a turn, between one and two, beyond, negative, and the edges.
            let a = match k % 5 {
                0 => x * TAU,
                1 => TAU + x * TAU,
                2 => 40.0 * x * TAU,
                3 => -x * TAU,
                _ => [0.0, TAU, 2.0 * TAU, -0.0, f64::MIN_POSITIVE][k / 5 % 5],
            };
            assert_eq!(wrap_angle(a).to_bits(), (a % TAU).to_bits(), "angle {a}");
            x = (x * 3.9 * (1.0 - x)).clamp(1e-6, 1.0 - 1e-6);
        }
    }

    /// A current lag: the current drawn follows the current of the rotor's speed through
    /// `1 - e^(-t / tau)` after a step (the rotor itself near its speed within a few
    /// milliseconds); without one, the current is that of the speed at every step.
    #[test]
    fn a_lagged_current_follows_the_current_of_the_speed_as_a_first_order_lag() {
        let p = MotorParams {
            spinup_tau_s: 0.001,
            current_lag_s: 0.25,
            ..MotorParams::default()
        };
        let (dt, mut s) = (1e-4, MotorState::default());
        let steady = p.current(0, p.steady_speed(0, p.duty(0.8), 12.0), true);
        for k in 1..=10_000 {
            s.step(&p, 0, 0.8, 12.0, dt);
            let t = k as f64 * dt;
            if k % 2500 == 0 {
                let want = steady * (1.0 - (-t / p.current_lag_s).exp());
                // The rotor's own millisecond and the step's hold: well under 1 %.
                assert!(
                    (s.current_a - want).abs() < 0.005 * steady,
                    "t = {t} s: {} A, the lag gives {want} A of {steady} A",
                    s.current_a
                );
            }
        }
        let (d, mut plain) = (MotorParams::default(), MotorState::default());
        plain.step(&d, 0, 0.8, 12.0, dt);
        let of_speed = d.current(0, plain.speed_rad_s, true);
        assert_eq!(plain.current_a.to_bits(), of_speed.to_bits());
    }

    /// `drives` is `duty > 0` over the checked dead zones, at and around each, and for
    /// commands of every size (a replay reads it for every motor at every row).
    #[test]
    fn drives_is_a_positive_duty_without_its_division() {
        let commands = [
            0.0,
            -0.0,
            1e-320,
            5e-324,
            1e-300,
            0.1,
            0.5,
            0.999,
            1.0,
            1.5,
            -0.2,
            1e300,
            f64::NAN,
        ];
        for dead_zone in [0.0, 1e-12, 0.06, 0.12, 0.37, 0.6, 0.95] {
            let p = MotorParams {
                dead_zone,
                ..MotorParams::default()
            };
            let near = [
                dead_zone,
                f64::from_bits(dead_zone.to_bits() + 1),
                f64::from_bits(dead_zone.to_bits().saturating_sub(1)),
            ];
            for command in commands.into_iter().chain(near) {
                assert_eq!(
                    p.drives(command),
                    p.duty(command) > 0.0,
                    "dead zone {dead_zone:e}, command {command:e}: duty {}",
                    p.duty(command)
                );
            }
        }
    }

    #[test]
    fn dead_zone_gives_no_speed_and_no_current() {
        let p = MotorParams::default();
        let mut s = MotorState::default();
        for _ in 0..1000 {
            s.step(&p, 0, 0.36, 12.0, 1e-3);
        }
        assert_eq!((s.speed_rad_s, s.current_a), (0.0, 0.0));
    }

    #[test]
    fn steady_speed_solves_the_voltage_balance() {
        let p = MotorParams::default();
        for duty in [0.1, 0.5, 1.0] {
            let w = p.steady_speed(0, duty, 11.1);
            let kt = p.torque_constant();
            let lhs = 11.1 * duty;
            let rhs = kt * w + p.winding_resistance_ohm * p.current(0, w, true);
            assert!((lhs - rhs).abs() < 1e-9, "duty {duty}: {lhs} vs {rhs}");
        }
    }

    #[test]
    fn current_is_convex_in_command_and_falls_with_voltage() {
        let p = MotorParams::default();
        let i = |c: f64, v: f64| p.current(0, p.steady_speed(0, p.duty(c), v), true);
        let (lo, mid, hi) = (i(0.5, 11.1), i(0.75, 11.1), i(1.0, 11.1));
        assert!(mid < 0.5 * (lo + hi), "convex: {lo} {mid} {hi}");
        assert!(i(1.0, 10.0) < i(1.0, 12.0));
    }

    #[test]
    fn spin_up_follows_a_first_order_lag() {
        let p = MotorParams::default();
        let mut s = MotorState::default();
        let target = p.steady_speed(0, p.duty(0.8), 12.0);
        let dt = 1e-4;
        let steps = (p.spinup_tau_s / dt).round() as usize;
        for _ in 0..steps {
            s.step(&p, 0, 0.8, 12.0, dt);
        }
        let frac = s.speed_rad_s / target;
        let expected = 1.0 - (-1.0f64).exp();
        assert!(
            (frac - expected).abs() < 1e-3,
            "after one tau: {frac} vs {expected}"
        );
    }
}
