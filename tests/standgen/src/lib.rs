//! An independent restrained-stand generator: recordings that magstand's simulator did not
//! make, to test magstand's identification and diagnosis on data of unknown origin.
//!
//! Nothing here comes from `magstand-sim` (this crate depends on no magstand crate at all):
//! its own motor law, current law, supply, field and noise, with constants unlike magstand's
//! defaults, its own random numbers, and its own CSV writer following only the recording
//! format documented in magstand's README. What it knows of magstand is that format, and the
//! names of the scenario keys it writes when a stand is *stated* ([`Stand::stated_scenario`]).
//!
//! The laws, chosen to differ from magstand's simulator:
//! - **Motor command to drive**: a dead zone `d`, then `e = ((c - d) / (1 - d))^1`, and no
//!   spin-up unless a [`Effect::CurrentLag`] adds a first-order lag to the current;
//! - **Current**: `I = I_idle + k_a · e^p · (V / V_nominal)` per motor, `p` 1.7 (a fit of a
//!   propeller's power curve, not magstand's motor model);
//! - **Supply**: a bench supply at a fixed voltage, or a battery of `cells` with an open-circuit
//!   voltage falling linearly with the charge drawn and an internal resistance;
//! - **Field**: `d = Σ_i g_i I_i + q (Σ_i I_i)²`, per-motor gain vectors `g_i` and a quadratic
//!   term (a steel part near the sensor), no Biot-Savart geometry;
//! - **Noise**: Gaussian, sd `s0 + s1 (I / I_max)^1.2` per axis, quantised to 0.15 µT;
//! - **Clock**: 75 Hz with ±2 % jitter on each interval.
//!
//! ```
//! use magstand_standgen::{Case, Effect, Stand, generate};
//! let case = Case { stand: Stand::default(), effects: vec![Effect::TimeOffset { delay_s: 0.3 }],
//!                   rows: 2000, seed: 1, log_bat_v: true, log_temp: false };
//! let g = generate(&case);
//! assert_eq!(g.truth_dist_ut.len(), 2000);
//! assert!(g.csv.starts_with("t_s,thr_1,thr_2,thr_3,thr_4,mag_x_ut,mag_y_ut,mag_z_ut,bat_v"));
//! ```
#![warn(missing_docs)]

/// A restrained stand: the constants of its laws.
#[derive(Debug, Clone)]
pub struct Stand {
    /// Motors.
    pub motors: usize,
    /// Commands below this make no current beyond idle (0..1).
    pub dead_zone: f64,
    /// Current of a motor that is on at zero drive, A.
    pub idle_a: f64,
    /// Current of a motor at full drive at the nominal voltage, A (beyond idle).
    pub full_a: f64,
    /// Exponent of the drive-to-current law.
    pub exponent: f64,
    /// Field per ampere of each motor's wires, µT/A (x, y, z), one per motor.
    pub gains_ut_per_a: Vec<[f64; 3]>,
    /// Field per ampere squared of the total current (a steel part), µT/A².
    pub quadratic_ut_per_a2: [f64; 3],
    /// The field without motors, µT (Earth field and sensor offset).
    pub background_ut: [f64; 3],
    /// The supply.
    pub supply: Supply,
    /// Noise sd at zero current and the rise at full current, µT.
    pub noise_ut: (f64, f64),
    /// Sampling rate, Hz.
    pub rate_hz: f64,
    /// Amplitude of the differential (attitude-like) commands added to the program, 0..0.1.
    pub differential: f64,
    /// The battery that replaces the supply under [`Effect::BatterySag`].
    pub battery: Supply,
    /// The overall command's program.
    pub program: Commanded,
}

/// How the overall command moves over a recording.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Commanded {
    /// Random levels held 1.2 to 4.5 s each, one step in six motors-off.
    RandomSteps,
    /// The paper's protocol made periodic: `steps` even levels up to full command and back
    /// down, each held `dwell_s`, then the motors off for `off_s`, over and over.
    Stair {
        /// Levels on the way up (the top one is full command).
        steps: usize,
        /// How long each level is held, s.
        dwell_s: f64,
        /// The motors-off stretch before each cycle, s.
        off_s: f64,
    },
}

/// What feeds the motors.
#[derive(Debug, Clone, Copy)]
pub enum Supply {
    /// A bench supply at a fixed voltage.
    Bench {
        /// Voltage, V.
        voltage_v: f64,
    },
    /// A lithium battery.
    Battery {
        /// Cells in series.
        cells: u32,
        /// Capacity, Ah.
        capacity_ah: f64,
        /// Internal resistance, ohm.
        resistance_ohm: f64,
    },
}

/// A cell's open-circuit voltage, empty, V: this generator's cells are straight in the charge.
const CELL_EMPTY_V: f64 = 3.55;

/// A cell's open-circuit voltage from empty to full, V.
const CELL_SPAN_V: f64 = 0.65;

impl Supply {
    /// A battery's open-circuit fall per cell per ampere-hour drawn until it is empty, V/Ah
    /// (None for a bench supply).
    pub fn cell_fall_v_per_ah(&self) -> Option<f64> {
        match *self {
            Supply::Bench { .. } => None,
            Supply::Battery { capacity_ah, .. } => Some(CELL_SPAN_V / capacity_ah),
        }
    }

    fn nominal_v(&self) -> f64 {
        match *self {
            Supply::Bench { voltage_v } => voltage_v,
            Supply::Battery { cells, .. } => 3.85 * cells as f64,
        }
    }
}

impl Default for Stand {
    /// A hexacopter-sized quad on a 5 V-per-cell-free bench: every constant is unlike
    /// magstand's defaults (dead zone 0.12 against 0.37, 75 Hz against 100 Hz, a 16.8 V bench).
    fn default() -> Self {
        Stand {
            motors: 4,
            dead_zone: 0.12,
            idle_a: 0.7,
            full_a: 16.0,
            exponent: 1.7,
            // Alike for every motor: the field of this stand depends on the total current
            // only, so a control has no motor asymmetry by any definition.
            gains_ut_per_a: vec![[0.55, -0.25, 0.90]; 4],
            quadratic_ut_per_a2: [0.0009, -0.0006, 0.0012],
            background_ut: [18.0, -4.5, 44.0],
            supply: Supply::Bench { voltage_v: 16.8 },
            noise_ut: (0.08, 0.35),
            rate_hz: 75.0,
            differential: 0.03,
            battery: Supply::Battery {
                cells: 4,
                capacity_ah: 1.3,
                resistance_ohm: 0.045,
            },
            program: Commanded::RandomSteps,
        }
    }
}

impl Stand {
    /// A second stand, unlike both magstand's defaults and [`Stand::default`]: a hexacopter
    /// on a 6S bench at 50 Hz, a low dead zone, a steeper current law, other wiring and
    /// noise. No threshold or rule of magstand's diagnosis was developed against it: the
    /// independent suite's held-out stand (`STAND=held-out`).
    pub fn held_out() -> Self {
        Stand {
            motors: 6,
            dead_zone: 0.06,
            idle_a: 0.4,
            full_a: 11.0,
            exponent: 2.3,
            gains_ut_per_a: vec![[-0.35, 0.60, 0.50]; 6],
            quadratic_ut_per_a2: [-0.0004, 0.0007, 0.0005],
            background_ut: [-12.0, 21.0, 38.0],
            supply: Supply::Bench { voltage_v: 25.2 },
            noise_ut: (0.12, 0.20),
            rate_hz: 50.0,
            differential: 0.04,
            battery: Supply::Battery {
                cells: 6,
                capacity_ah: 4.0,
                resistance_ohm: 0.03,
            },
            program: Commanded::RandomSteps,
        }
    }

    /// A third stand, added in the thirty-second session after the diagnosis had been
    /// developed on the other two, and run as it was first written: an octocopter on a 6S
    /// bench at 120 Hz, with a dead zone, current law, wiring, noise and pack unlike both
    /// (`STAND=octocopter`).
    pub fn octocopter() -> Self {
        Stand {
            motors: 8,
            dead_zone: 0.10,
            idle_a: 0.6,
            full_a: 8.0,
            exponent: 1.5,
            gains_ut_per_a: vec![[0.28, 0.40, -0.62]; 8],
            quadratic_ut_per_a2: [0.0004, -0.0002, 0.0006],
            background_ut: [24.0, 2.5, -41.0],
            supply: Supply::Bench { voltage_v: 22.2 },
            noise_ut: (0.06, 0.45),
            rate_hz: 120.0,
            differential: 0.05,
            battery: Supply::Battery {
                cells: 6,
                capacity_ah: 3.0,
                resistance_ohm: 0.05,
            },
            program: Commanded::RandomSteps,
        }
    }
}

impl Stand {
    /// The stand as a magstand scenario states it: the constants magstand's scenario has keys
    /// for (motor count, dead zone, no spin-up lag to speak of, supply, sampling rate). The
    /// current law, the wiring and the noise have no such keys: they stay unknown. This stand's
    /// current follows each command at once; a scenario must state some spin-up, so it states
    /// 1 ms, a tenth of a sample interval and more (5 ms, a third of one at 75 Hz, left 7 % of
    /// each step for the first sample after it, which the diagnosis rightly rejected).
    pub fn stated_scenario(&self, stated_dead_zone: f64) -> String {
        let supply = match self.supply {
            Supply::Bench { voltage_v } => {
                format!("[supply]\nkind = \"bench\"\nvoltage_v = {voltage_v}\n")
            }
            Supply::Battery {
                cells,
                capacity_ah,
                resistance_ohm,
            } => format!(
                "[supply]\nkind = \"battery\"\ncells = {cells}\ncapacity_ah = {capacity_ah}\ninternal_resistance_ohm = {resistance_ohm}\n"
            ),
        };
        format!(
            "name = \"independent stand (stated)\"\n[program]\nkind = \"random_steps\"\ncount = 10\ndwell_min_s = 1.0\ndwell_max_s = 2.0\n[motors]\ncount = {}\ndead_zone = {stated_dead_zone}\nspinup_tau_s = 0.001\n{supply}[magnetometer]\nodr_hz = {}\n",
            self.motors, self.rate_hz
        )
    }
}

/// A physical effect added to the stand, or its absence.
#[derive(Debug, Clone, PartialEq)]
pub enum Effect {
    /// The board heats with the current: a first-order temperature, and an offset per degree.
    ThermalDrift {
        /// Time constant, s.
        tau_s: f64,
        /// Temperature rise per ampere at equilibrium, °C/A.
        rise_c_per_a: f64,
        /// Offset per degree, µT/°C.
        ut_per_c: [f64; 3],
    },
    /// A play operator on the total current (magnetised steel that remembers).
    Hysteresis {
        /// Half-width of the play, A.
        play_a: f64,
        /// Field per ampere of the played current, µT/A.
        gain_ut_per_a: [f64; 3],
    },
    /// The magnetometer stream is late by this much against the commands.
    TimeOffset {
        /// Delay, s: negative where the commands are the stream logged late.
        delay_s: f64,
    },
    /// The current follows the command with a first-order lag (slow ESCs or heavy props).
    CurrentLag {
        /// Time constant, s.
        tau_s: f64,
    },
    /// One motor's wires carry a field larger than the others' by a factor.
    MotorAsymmetry {
        /// The motor (0-based).
        motor: usize,
        /// Factor on its gain vector.
        scale: f64,
    },
    /// A battery instead of the bench (its sag shows in `bat_v`, if logged).
    BatterySag,
    /// The real dead zone differs from the stand's (the stated one stays the stand's).
    DeadZone {
        /// The real dead zone.
        actual: f64,
    },
    /// Outside magstand's catalog: a slow periodic field (a neighbour's machine).
    PeriodicInterference {
        /// Amplitude, µT.
        amplitude_ut: [f64; 3],
        /// Period, s.
        period_s: f64,
    },
}

impl Effect {
    /// The name magstand's diagnosis should give, if the effect is in its catalog.
    pub fn catalog_name(&self) -> Option<&'static str> {
        Some(match self {
            Effect::ThermalDrift { .. } => "thermal_drift",
            Effect::Hysteresis { .. } => "hysteresis",
            Effect::TimeOffset { .. } => "time_offset",
            Effect::CurrentLag { .. } => "current_lag",
            Effect::MotorAsymmetry { .. } => "motor_asymmetry",
            Effect::BatterySag => "battery_sag",
            Effect::DeadZone { .. } => "dead_zone",
            Effect::PeriodicInterference { .. } => return None,
        })
    }
}

/// One recording to make.
#[derive(Debug, Clone)]
pub struct Case {
    /// The stand.
    pub stand: Stand,
    /// Effects added.
    pub effects: Vec<Effect>,
    /// Rows.
    pub rows: usize,
    /// Seed of the program and the noise.
    pub seed: u64,
    /// Whether `bat_v` and `bat_a` are logged.
    pub log_bat_v: bool,
    /// Whether `temp_c` is logged.
    pub log_temp: bool,
}

/// A generated recording and its truth.
#[derive(Debug, Clone)]
pub struct Generated {
    /// The recording, as magstand's documented CSV format.
    pub csv: String,
    /// The true motor disturbance at each row (everything the motors cause, effects
    /// included), µT.
    pub truth_dist_ut: Vec<[f64; 3]>,
    /// Sample times, s.
    pub t_s: Vec<f64>,
}

/// splitmix64 and Box-Muller: this crate's own random numbers.
struct Random(u64);

impl Random {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
    fn uniform(&mut self) -> f64 {
        ((self.next() >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }
    fn normal(&mut self) -> f64 {
        let (u, v) = (self.uniform(), self.uniform());
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }
}

/// Random steps of the overall command with motors-off stretches, plus small differential
/// commands that change sign every few seconds; returns the per-motor commands at `t`.
struct Program {
    /// (start time s, level) of each step.
    steps: Vec<(f64, f64)>,
    /// (start time s, pattern index) of each differential stretch.
    patterns: Vec<(f64, usize)>,
    differential: f64,
}

impl Program {
    fn new(kind: Commanded, duration_s: f64, differential: f64, rng: &mut Random) -> Self {
        let steps = match kind {
            Commanded::RandomSteps => Self::random_steps(duration_s, rng),
            Commanded::Stair {
                steps,
                dwell_s,
                off_s,
            } => Self::stair(duration_s, steps.max(1), dwell_s, off_s),
        };
        let mut patterns = Vec::new();
        let mut t = 0.0;
        while t < duration_s {
            patterns.push((t, (rng.next() % 4) as usize));
            t += 2.0 + 4.0 * rng.uniform();
        }
        Program {
            steps,
            patterns,
            differential,
        }
    }

    /// Up-and-down stairs of `n` levels held `dwell_s` each, after `off_s` with the motors
    /// off, repeated to the end (which is motors-off).
    fn stair(duration_s: f64, n: usize, dwell_s: f64, off_s: f64) -> Vec<(f64, f64)> {
        let mut steps = vec![(0.0, 0.0)];
        let mut t = off_s;
        let levels: Vec<f64> = (1..=n)
            .chain((1..n).rev())
            .map(|k| k as f64 / n as f64)
            .collect();
        'cycles: loop {
            for &level in &levels {
                if t + dwell_s > duration_s {
                    break 'cycles;
                }
                steps.push((t, level));
                t += dwell_s;
            }
            steps.push((t, 0.0));
            t += off_s;
        }
        steps.push((t.min(duration_s), 0.0));
        steps
    }

    /// Random levels held 1.2 to 4.5 s, one step in six motors-off.
    fn random_steps(duration_s: f64, rng: &mut Random) -> Vec<(f64, f64)> {
        let mut steps = vec![(0.0, 0.0)];
        let mut t = 4.0;
        while t < duration_s - 4.0 {
            // One step in six is motors-off, so the reference is seen throughout.
            let level = if rng.uniform() < 1.0 / 6.0 {
                0.0
            } else {
                0.15 + 0.85 * rng.uniform()
            };
            steps.push((t, level));
            t += 1.2 + 3.3 * rng.uniform();
        }
        steps.push((t, 0.0));
        steps
    }

    fn commands(&self, t: f64, motors: usize) -> Vec<f64> {
        let at = |v: &[(f64, f64)]| v.iter().rev().find(|(s, _)| *s <= t).map_or(0.0, |x| x.1);
        let level = at(&self.steps);
        let pattern = self
            .patterns
            .iter()
            .rev()
            .find(|(s, _)| *s <= t)
            .map_or(0, |x| x.1);
        (0..motors)
            .map(|i| {
                if level == 0.0 {
                    return 0.0;
                }
                // Roll, pitch, yaw-like sign patterns, as an attitude controller would add.
                let sign = match pattern {
                    0 => 0.0,
                    1 => [1.0, -1.0][i % 2],
                    2 => [1.0, 1.0, -1.0, -1.0][i % 4],
                    _ => [1.0, -1.0, -1.0, 1.0][i % 4],
                };
                (level + sign * self.differential).clamp(0.0, 1.0)
            })
            .collect()
    }
}

/// Makes the recording of `case`.
pub fn generate(case: &Case) -> Generated {
    let s = &case.stand;
    let mut rng = Random(case.seed ^ 0x05ee_d0f5_7a9d);
    // Jittered sample times first, so the program spans them.
    let mut t_s = Vec::with_capacity(case.rows);
    let mut t = 0.0;
    for _ in 0..case.rows {
        t_s.push(t);
        t += (1.0 + 0.04 * (rng.uniform() - 0.5)) / s.rate_hz;
    }
    let duration_s = t;
    let program = Program::new(s.program, duration_s, s.differential, &mut rng);

    let find = |f: fn(&Effect) -> bool| case.effects.iter().find(|e| f(e)).cloned();
    let dead_zone = match find(|e| matches!(e, Effect::DeadZone { .. })) {
        Some(Effect::DeadZone { actual }) => actual,
        _ => s.dead_zone,
    };
    let lag_tau = match find(|e| matches!(e, Effect::CurrentLag { .. })) {
        Some(Effect::CurrentLag { tau_s }) => tau_s,
        _ => 0.0,
    };
    let delay_s = match find(|e| matches!(e, Effect::TimeOffset { .. })) {
        Some(Effect::TimeOffset { delay_s }) => delay_s,
        _ => 0.0,
    };
    let supply = if case.effects.contains(&Effect::BatterySag) {
        s.battery
    } else {
        s.supply
    };
    let mut gains = s.gains_ut_per_a.clone();
    if let Some(Effect::MotorAsymmetry { motor, scale }) =
        find(|e| matches!(e, Effect::MotorAsymmetry { .. }))
    {
        gains[motor] = gains[motor].map(|g| g * scale);
    }
    let max_total_a = s.motors as f64 * (s.idle_a + s.full_a);

    // The physics on a fine grid (1 kHz), sampled at the jittered times; the magnetometer
    // sees the field `delay_s` earlier than its time stamp says.
    let dt = 1e-3;
    let steps = (duration_s / dt).ceil() as usize + 2;
    let mut currents = vec![0.0; s.motors];
    let mut charge_ah = 0.0;
    let mut temp_c = 25.0;
    let mut played_a: f64 = 0.0;
    let mut fine_field = Vec::with_capacity(steps);
    let mut fine_supply = Vec::with_capacity(steps);
    let mut fine_temp = Vec::with_capacity(steps);
    let mut fine_cmd = Vec::with_capacity(steps);
    let mut volts = supply.nominal_v();
    for k in 0..steps {
        let tk = k as f64 * dt;
        let cmd = program.commands(tk, s.motors);
        let total: f64 = currents.iter().sum();
        volts = match supply {
            Supply::Bench { voltage_v } => voltage_v,
            Supply::Battery {
                cells,
                capacity_ah,
                resistance_ohm,
            } => {
                let soc = (1.0 - charge_ah / capacity_ah).max(0.0);
                cells as f64 * (CELL_EMPTY_V + CELL_SPAN_V * soc) - resistance_ohm * total
            }
        };
        for (i, c) in cmd.iter().enumerate() {
            let target = if *c <= 0.0 {
                0.0
            } else {
                let e = ((c - dead_zone) / (1.0 - dead_zone)).max(0.0);
                s.idle_a + s.full_a * e.powf(s.exponent) * (volts / supply.nominal_v())
            };
            currents[i] = if lag_tau > 0.0 {
                currents[i] + (target - currents[i]) * (dt / lag_tau).min(1.0)
            } else {
                target
            };
        }
        let total: f64 = currents.iter().sum();
        charge_ah += total * dt / 3600.0;
        let mut field = [0.0; 3];
        for (i, g) in gains.iter().enumerate() {
            for a in 0..3 {
                field[a] += g[a] * currents[i];
            }
        }
        for a in 0..3 {
            field[a] += s.quadratic_ut_per_a2[a] * total * total;
        }
        for e in &case.effects {
            match *e {
                Effect::ThermalDrift {
                    tau_s,
                    rise_c_per_a,
                    ut_per_c,
                } => {
                    let target = 25.0 + rise_c_per_a * total;
                    temp_c += (target - temp_c) * dt / tau_s;
                    for a in 0..3 {
                        field[a] += ut_per_c[a] * (temp_c - 25.0);
                    }
                }
                Effect::Hysteresis {
                    play_a,
                    gain_ut_per_a,
                } => {
                    played_a = played_a.clamp(total - play_a, total + play_a);
                    for a in 0..3 {
                        field[a] += gain_ut_per_a[a] * played_a;
                    }
                }
                Effect::PeriodicInterference {
                    amplitude_ut,
                    period_s,
                } => {
                    let w = (std::f64::consts::TAU * tk / period_s).sin();
                    for a in 0..3 {
                        field[a] += amplitude_ut[a] * w;
                    }
                }
                _ => {}
            }
        }
        fine_field.push(field);
        fine_supply.push((volts, total));
        fine_temp.push(temp_c);
        fine_cmd.push(cmd);
    }
    let _ = volts;

    let fine = |t: f64| ((t / dt).round().max(0.0) as usize).min(steps - 1);
    let mut header: Vec<String> = vec!["t_s".into()];
    header.extend((1..=s.motors).map(|i| format!("thr_{i}")));
    header.extend(["mag_x_ut", "mag_y_ut", "mag_z_ut"].map(String::from));
    if case.log_bat_v {
        header.extend(["bat_v", "bat_a"].map(String::from));
    }
    if case.log_temp {
        header.push("temp_c".into());
    }
    let mut csv = header.join(",") + "\n";
    let mut truth = Vec::with_capacity(case.rows);
    for &t in &t_s {
        let now = fine(t);
        let seen = fine(t - delay_s);
        let field = fine_field[seen];
        let (volts, total) = fine_supply[now];
        let sd = s.noise_ut.0 + s.noise_ut.1 * (fine_supply[seen].1 / max_total_a).powf(1.2);
        let mut row = vec![format!("{t:.6}")];
        row.extend(fine_cmd[now].iter().map(|c| format!("{c:.4}")));
        for a in 0..3 {
            let m = s.background_ut[a] + field[a] + sd * rng.normal();
            row.push(format!("{:.2}", (m / 0.15).round() * 0.15));
        }
        if case.log_bat_v {
            row.push(format!("{volts:.3}"));
            row.push(format!("{total:.3}"));
        }
        if case.log_temp {
            row.push(format!("{:.2}", fine_temp[now]));
        }
        csv += &(row.join(",") + "\n");
        truth.push(field);
    }
    Generated {
        csv,
        truth_dist_ut: truth,
        t_s,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The stair: motors off for `off_s`, then each level up to full command and back down,
    /// `dwell_s` each, then off again, over and over; no step starts past the end, and the
    /// recording ends with the motors off.
    #[test]
    fn a_stair_goes_up_to_full_command_and_back_after_its_off_time() {
        let steps = Program::stair(100.0, 4, 5.0, 8.0);
        let cycle: Vec<f64> = steps.iter().skip(1).take(8).map(|s| s.1).collect();
        assert_eq!(
            cycle,
            [0.25, 0.5, 0.75, 1.0, 0.75, 0.5, 0.25, 0.0],
            "{steps:?}"
        );
        assert_eq!(steps[0], (0.0, 0.0), "{steps:?}");
        assert_eq!(steps[1].0, 8.0, "{steps:?}");
        for w in steps[1..9].windows(2) {
            assert!((w[1].0 - w[0].0 - 5.0).abs() < 1e-12, "{steps:?}");
        }
        // The second cycle starts after the off time.
        assert_eq!(steps[9], (51.0, 0.25), "{steps:?}");
        assert!(steps.iter().all(|s| s.0 <= 100.0), "{steps:?}");
        assert_eq!(steps.last().map(|s| s.1), Some(0.0), "{steps:?}");
    }

    /// A stair's recording commands the stand at its levels only (the differential commands
    /// leave the mean over the motors where no motor is clipped at full command), and the
    /// stands drive random steps unless a stair is asked for.
    #[test]
    fn a_stair_recording_holds_its_levels() {
        assert_eq!(Stand::default().program, Commanded::RandomSteps);
        let stand = Stand {
            program: Commanded::Stair {
                steps: 8,
                dwell_s: 6.0,
                off_s: 8.0,
            },
            ..Stand::default()
        };
        let mut rng = Random(7);
        let program = Program::new(stand.program, 300.0, stand.differential, &mut rng);
        let mut levels: Vec<i64> = (0..3000)
            .map(|k| {
                let cmd = program.commands(k as f64 * 0.1, stand.motors);
                (cmd.iter().sum::<f64>() / cmd.len() as f64 * 1000.0).round() as i64
            })
            .collect();
        levels.sort_unstable();
        levels.dedup();
        // At full command half the motors' differential is clipped: their mean is lower by
        // half of it there.
        let clipped_top = ((1.0 - stand.differential / 2.0) * 1000.0).round() as i64;
        assert_eq!(
            levels,
            [0, 125, 250, 375, 500, 625, 750, 875, clipped_top, 1000],
            "differential {}",
            stand.differential
        );
    }
}
