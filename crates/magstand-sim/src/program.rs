//! Throttle programs: what each motor is commanded over time.
//!
//! Every program compiles to a list of [`Piece`]s, each a linear move of all motor commands
//! from one vector to another over a time span (constant when the two are equal), so that
//! evaluation is one binary search whatever the program.
use rand::{Rng, RngExt};
use serde::{Deserialize, Serialize};

use crate::error::{Checker, SimError};

/// Order of stair or ramp levels.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Direction {
    /// Zero to maximum, as in the paper.
    #[default]
    Up,
    /// Maximum to zero.
    Down,
    /// Up, then down again.
    UpDown,
}

fn d_off() -> f64 {
    5.0
}
fn d_one() -> f64 {
    1.0
}
fn d_repeats() -> u32 {
    1
}

/// The throttle program of a scenario (`[program]`, chosen by `kind`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum ProgramParams {
    /// The paper's stair: all motors together, from zero to `max` in `steps` equal steps.
    Stair {
        /// Motors-off time before each pass and at the end, s (the eq. 9 reference).
        #[serde(default = "d_off")]
        off_s: f64,
        /// Number of non-zero levels.
        steps: u32,
        /// Highest command, 0..1.
        #[serde(default = "d_one")]
        max: f64,
        /// Time at each level, s.
        dwell_s: f64,
        /// Level order.
        #[serde(default)]
        direction: Direction,
        /// Number of passes.
        #[serde(default = "d_repeats")]
        repeats: u32,
    },
    /// A linear ramp of all motors.
    Ramp {
        /// Motors-off time before each pass and at the end, s.
        #[serde(default = "d_off")]
        off_s: f64,
        /// Command at the start of the ramp, 0..1.
        #[serde(default)]
        from: f64,
        /// Command at the end of the ramp, 0..1.
        #[serde(default = "d_one")]
        to: f64,
        /// Duration of one ramp, s.
        duration_s: f64,
        /// Up (from to `to`), down, or up and back.
        #[serde(default)]
        direction: Direction,
        /// Number of passes.
        #[serde(default = "d_repeats")]
        repeats: u32,
    },
    /// One motor at a time (ArduPilot's per-motor calibration): each motor steps through the
    /// levels while the others are off.
    PerMotorSteps {
        /// Motors-off time before each motor and at the end, s.
        #[serde(default = "d_off")]
        off_s: f64,
        /// Number of non-zero levels per motor.
        steps: u32,
        /// Highest command, 0..1.
        #[serde(default = "d_one")]
        max: f64,
        /// Time at each level, s.
        dwell_s: f64,
    },
    /// Random levels and dwell times, for identification richness.
    RandomSteps {
        /// Motors-off time at the start and end, s.
        #[serde(default = "d_off")]
        off_s: f64,
        /// Number of steps.
        count: u32,
        /// Lowest level, 0..1.
        #[serde(default)]
        min: f64,
        /// Highest level, 0..1.
        #[serde(default = "d_one")]
        max: f64,
        /// Shortest dwell, s.
        dwell_min_s: f64,
        /// Longest dwell, s.
        dwell_max_s: f64,
    },
    /// Replays the motor commands of a recording CSV (relative paths are taken from the
    /// scenario file's folder).
    Replay {
        /// Path of the recording.
        file: String,
    },
}

/// Small attitude-like differential commands on top of the program (eq. 4: delta_ang).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DifferentialParams {
    /// Amplitude added to and taken from motor commands, 0..0.5 (0 for none).
    pub amplitude: f64,
    /// Frequency of the pattern, Hz.
    pub frequency_hz: f64,
}

impl Default for DifferentialParams {
    fn default() -> Self {
        Self {
            amplitude: 0.0,
            frequency_hz: 0.5,
        }
    }
}

/// One linear move of all motor commands.
#[derive(Debug, Clone, PartialEq)]
pub struct Piece {
    /// Start time, s.
    pub t0_s: f64,
    /// End time, s.
    pub t1_s: f64,
    /// Commands at the start.
    pub from: Vec<f64>,
    /// Commands at the end.
    pub to: Vec<f64>,
}

/// A compiled program: commands for every motor at any time.
#[derive(Debug, Clone, PartialEq)]
pub struct Program {
    pieces: Vec<Piece>,
    motors: usize,
    differential: DifferentialParams,
}

/// Longest program a scenario may run, s of simulated time (ten hours): the cost of a
/// simulation grows with it, so it is bounded before anything is allocated.
pub const MAX_PROGRAM_S: f64 = 36_000.0;

impl ProgramParams {
    /// An upper bound of the program's duration, s, from its parameters alone (a replay's
    /// comes from its recording, which is checked when it is read).
    pub fn duration_bound_s(&self, motors: usize) -> f64 {
        match *self {
            // Up and back down (a "both" stair) per pass, each pass after an off time.
            ProgramParams::Stair {
                off_s,
                steps,
                dwell_s,
                repeats,
                ..
            } => f64::from(repeats) * (off_s + 2.0 * f64::from(steps) * dwell_s) + off_s,
            ProgramParams::Ramp {
                off_s,
                duration_s,
                repeats,
                ..
            } => f64::from(repeats) * (off_s + 2.0 * duration_s) + off_s,
            ProgramParams::PerMotorSteps {
                off_s,
                steps,
                dwell_s,
                ..
            } => (motors as f64 + 1.0) * (off_s + 2.0 * f64::from(steps) * dwell_s),
            ProgramParams::RandomSteps {
                off_s,
                count,
                dwell_max_s,
                ..
            } => 2.0 * off_s + f64::from(count) * dwell_max_s,
            ProgramParams::Replay { .. } => 0.0,
        }
    }

    /// Checks each field, then the whole program's length (so a field that is itself wrong,
    /// a NaN dwell, is named as that field).
    pub(crate) fn check(&self, c: &Checker, motors: usize) -> Result<(), SimError> {
        self.check_fields(c)?;
        let bound = self.duration_bound_s(motors);
        if !(bound <= MAX_PROGRAM_S) {
            return Err(c.fail(
                "program",
                format!("up to {bound:.3e} s of simulated time"),
                &format!(
                    "a program of at most {MAX_PROGRAM_S} s (fewer steps or repeats, shorter dwell_s or off_s)"
                ),
            ));
        }
        Ok(())
    }

    fn check_fields(&self, c: &Checker) -> Result<(), SimError> {
        let dur = |k: &str, v: f64| c.range(&format!("program.{k}"), v, 0.0, 1e6);
        let cmd = |k: &str, v: f64| c.range(&format!("program.{k}"), v, 0.0, 1.0);
        let count = |k: &str, v: u32| {
            if (1..=100_000).contains(&v) {
                Ok(())
            } else {
                Err(c.fail(&format!("program.{k}"), v, "an integer in 1..=100000"))
            }
        };
        match *self {
            ProgramParams::Stair {
                off_s,
                steps,
                max,
                dwell_s,
                repeats,
                ..
            } => {
                dur("off_s", off_s)?;
                count("steps", steps)?;
                cmd("max", max)?;
                c.positive("program.dwell_s", dwell_s)?;
                count("repeats", repeats)
            }
            ProgramParams::Ramp {
                off_s,
                from,
                to,
                duration_s,
                repeats,
                ..
            } => {
                dur("off_s", off_s)?;
                cmd("from", from)?;
                cmd("to", to)?;
                c.positive("program.duration_s", duration_s)?;
                count("repeats", repeats)
            }
            ProgramParams::PerMotorSteps {
                off_s,
                steps,
                max,
                dwell_s,
            } => {
                dur("off_s", off_s)?;
                count("steps", steps)?;
                cmd("max", max)?;
                c.positive("program.dwell_s", dwell_s)
            }
            ProgramParams::RandomSteps {
                off_s,
                count: n,
                min,
                max,
                dwell_min_s,
                dwell_max_s,
            } => {
                dur("off_s", off_s)?;
                count("count", n)?;
                cmd("min", min)?;
                cmd("max", max)?;
                if min > max {
                    return Err(c.fail(
                        "program.min",
                        min,
                        &format!("a value not above program.max ({max})"),
                    ));
                }
                c.positive("program.dwell_min_s", dwell_min_s)?;
                c.range("program.dwell_max_s", dwell_max_s, dwell_min_s, 1e6)
            }
            ProgramParams::Replay { ref file } => {
                if file.trim().is_empty() {
                    return Err(c.fail("program.file", "\"\"", "the path of a recording CSV"));
                }
                Ok(())
            }
        }
    }

    /// Compiles the program for `motors` motors. `rng` draws random steps; `replay` supplies
    /// the commands of a replayed recording as (times, per-motor commands).
    pub fn compile(
        &self,
        motors: usize,
        rng: &mut impl Rng,
        replay: Option<(&[f64], &[Vec<f64>])>,
        differential: &DifferentialParams,
    ) -> Program {
        let mut b = Builder {
            t: 0.0,
            pieces: Vec::new(),
            motors,
        };
        match *self {
            ProgramParams::Stair {
                off_s,
                steps,
                max,
                dwell_s,
                direction,
                repeats,
            } => {
                let levels = ordered(
                    (1..=steps).map(|k| max * k as f64 / steps as f64).collect(),
                    direction,
                );
                for _ in 0..repeats {
                    b.hold_all(0.0, off_s);
                    for l in &levels {
                        b.hold_all(*l, dwell_s);
                    }
                }
                b.hold_all(0.0, off_s);
            }
            ProgramParams::Ramp {
                off_s,
                from,
                to,
                duration_s,
                direction,
                repeats,
            } => {
                for _ in 0..repeats {
                    b.hold_all(0.0, off_s);
                    match direction {
                        Direction::Up => b.ramp_all(from, to, duration_s),
                        Direction::Down => b.ramp_all(to, from, duration_s),
                        Direction::UpDown => {
                            b.ramp_all(from, to, duration_s);
                            b.ramp_all(to, from, duration_s);
                        }
                    }
                }
                b.hold_all(0.0, off_s);
            }
            ProgramParams::PerMotorSteps {
                off_s,
                steps,
                max,
                dwell_s,
            } => {
                for m in 0..motors {
                    b.hold_all(0.0, off_s);
                    for k in 1..=steps {
                        let mut v = vec![0.0; motors];
                        v[m] = max * k as f64 / steps as f64;
                        b.hold(v, dwell_s);
                    }
                }
                b.hold_all(0.0, off_s);
            }
            ProgramParams::RandomSteps {
                off_s,
                count,
                min,
                max,
                dwell_min_s,
                dwell_max_s,
            } => {
                b.hold_all(0.0, off_s);
                for _ in 0..count {
                    let level = min + (max - min) * rng.random::<f64>();
                    let dwell = dwell_min_s + (dwell_max_s - dwell_min_s) * rng.random::<f64>();
                    b.hold_all(level, dwell);
                }
                b.hold_all(0.0, off_s);
            }
            ProgramParams::Replay { .. } => {
                let (t, thr) =
                    replay.expect("replay commands are loaded when the scenario is checked");
                let n = t.len();
                // Zero-order hold: each command lasts until the next sample; the last one for
                // one mean interval.
                let tail = if n > 1 {
                    (t[n - 1] - t[0]) / (n - 1) as f64
                } else {
                    1.0
                };
                for r in 0..n {
                    let t1 = if r + 1 < n { t[r + 1] } else { t[r] + tail };
                    let v: Vec<f64> = (0..motors).map(|m| thr[m.min(thr.len() - 1)][r]).collect();
                    b.pieces.push(Piece {
                        t0_s: t[r],
                        t1_s: t1,
                        from: v.clone(),
                        to: v,
                    });
                }
                b.t = t[n - 1] + tail;
            }
        }
        Program {
            pieces: b.pieces,
            motors,
            differential: differential.clone(),
        }
    }
}

fn ordered(up: Vec<f64>, direction: Direction) -> Vec<f64> {
    match direction {
        Direction::Up => up,
        Direction::Down => up.into_iter().rev().collect(),
        Direction::UpDown => {
            let mut v = up.clone();
            v.extend(up.into_iter().rev().skip(1));
            v
        }
    }
}

struct Builder {
    t: f64,
    pieces: Vec<Piece>,
    motors: usize,
}

impl Builder {
    fn hold(&mut self, v: Vec<f64>, dt: f64) {
        if dt > 0.0 {
            self.pieces.push(Piece {
                t0_s: self.t,
                t1_s: self.t + dt,
                from: v.clone(),
                to: v,
            });
            self.t += dt;
        }
    }
    fn hold_all(&mut self, level: f64, dt: f64) {
        self.hold(vec![level; self.motors], dt);
    }
    fn ramp_all(&mut self, from: f64, to: f64, dt: f64) {
        self.pieces.push(Piece {
            t0_s: self.t,
            t1_s: self.t + dt,
            from: vec![from; self.motors],
            to: vec![to; self.motors],
        });
        self.t += dt;
    }
}

impl Program {
    /// Total duration, s.
    pub fn duration_s(&self) -> f64 {
        self.pieces.last().map(|p| p.t1_s).unwrap_or(0.0)
    }

    /// The compiled pieces.
    pub fn pieces(&self) -> &[Piece] {
        &self.pieces
    }

    /// Writes each motor's command at time `t_s` into `out` (length = motors).
    pub fn commands_into(&self, t_s: f64, out: &mut [f64]) {
        let k = self
            .pieces
            .partition_point(|p| p.t1_s <= t_s)
            .min(self.pieces.len().saturating_sub(1));
        self.piece_commands_into(k, t_s, out);
    }

    /// As [`Program::commands_into`] for times that never go back: `cursor` keeps the piece
    /// of the last call, so a step costs a comparison instead of a search.
    pub fn commands_from(&self, t_s: f64, cursor: &mut usize, out: &mut [f64]) {
        let last = self.pieces.len().saturating_sub(1);
        while *cursor < last && self.pieces[*cursor].t1_s <= t_s {
            *cursor += 1;
        }
        self.piece_commands_into(*cursor, t_s, out);
    }

    fn piece_commands_into(&self, k: usize, t_s: f64, out: &mut [f64]) {
        let Some(p) = self.pieces.get(k) else {
            out.fill(0.0);
            return;
        };
        let span = p.t1_s - p.t0_s;
        let f = if span > 0.0 {
            ((t_s - p.t0_s) / span).clamp(0.0, 1.0)
        } else {
            0.0
        };
        for (m, o) in out.iter_mut().enumerate() {
            *o = p.from[m] + (p.to[m] - p.from[m]) * f;
        }
        let d = &self.differential;
        if d.amplitude > 0.0 && self.motors > 1 {
            let phase = std::f64::consts::TAU * d.frequency_hz * t_s;
            for (m, o) in out.iter_mut().enumerate() {
                if *o > 0.0 {
                    // Evenly spaced phases sum to zero: the overall throttle is unchanged.
                    let arm = std::f64::consts::TAU * m as f64 / self.motors as f64;
                    *o = (*o + d.amplitude * (phase + arm).sin()).clamp(0.0, 1.0);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    fn compile(p: &ProgramParams, motors: usize) -> Program {
        let mut rng = rand::rngs::Xoshiro256PlusPlus::seed_from_u64(1);
        p.compile(motors, &mut rng, None, &DifferentialParams::default())
    }

    fn at(p: &Program, t: f64) -> Vec<f64> {
        let mut v = vec![0.0; p.motors];
        p.commands_into(t, &mut v);
        v
    }

    #[test]
    fn a_cursor_gives_the_same_commands_as_the_search() {
        let p = compile(
            &ProgramParams::Stair {
                off_s: 0.5,
                steps: 6,
                max: 0.9,
                dwell_s: 0.25,
                direction: Direction::Up,
                repeats: 2,
            },
            4,
        );
        let (mut cursor, mut v) = (0, vec![0.0; 4]);
        for k in 0..=(p.duration_s() * 1000.0) as usize + 10 {
            let t = k as f64 * 1e-3;
            p.commands_from(t, &mut cursor, &mut v);
            assert_eq!(v, at(&p, t), "t = {t}");
        }
    }

    #[test]
    fn stair_goes_from_zero_to_max_in_equal_steps() {
        let p = compile(
            &ProgramParams::Stair {
                off_s: 2.0,
                steps: 4,
                max: 1.0,
                dwell_s: 1.0,
                direction: Direction::Up,
                repeats: 1,
            },
            4,
        );
        assert_eq!(p.duration_s(), 2.0 + 4.0 + 2.0);
        assert_eq!(at(&p, 1.0), vec![0.0; 4]);
        assert_eq!(at(&p, 2.5), vec![0.25; 4]);
        assert_eq!(at(&p, 5.5), vec![1.0; 4]);
        assert_eq!(at(&p, 7.0), vec![0.0; 4]);
    }

    #[test]
    fn up_down_stair_visits_the_top_once() {
        let p = compile(
            &ProgramParams::Stair {
                off_s: 0.0,
                steps: 3,
                max: 0.9,
                dwell_s: 1.0,
                direction: Direction::UpDown,
                repeats: 1,
            },
            1,
        );
        let levels: Vec<f64> = (0..5).map(|k| at(&p, k as f64 + 0.5)[0]).collect();
        let expected = [0.3, 0.6, 0.9, 0.6, 0.3];
        for (l, e) in levels.iter().zip(expected) {
            assert!((l - e).abs() < 1e-12, "{levels:?}");
        }
    }

    #[test]
    fn ramp_interpolates_linearly() {
        let p = compile(
            &ProgramParams::Ramp {
                off_s: 1.0,
                from: 0.2,
                to: 1.0,
                duration_s: 4.0,
                direction: Direction::Up,
                repeats: 1,
            },
            2,
        );
        assert!((at(&p, 3.0)[1] - 0.6).abs() < 1e-12);
    }

    #[test]
    fn per_motor_steps_drive_one_motor_at_a_time() {
        let p = compile(
            &ProgramParams::PerMotorSteps {
                off_s: 1.0,
                steps: 2,
                max: 0.8,
                dwell_s: 1.0,
            },
            4,
        );
        assert_eq!(at(&p, 1.5), vec![0.4, 0.0, 0.0, 0.0]);
        assert_eq!(at(&p, 5.5), vec![0.0, 0.8, 0.0, 0.0]);
        assert_eq!(p.duration_s(), 4.0 * 3.0 + 1.0);
    }

    #[test]
    fn random_steps_stay_in_bounds_and_depend_on_the_seed() {
        let params = ProgramParams::RandomSteps {
            off_s: 1.0,
            count: 50,
            min: 0.4,
            max: 0.9,
            dwell_min_s: 0.5,
            dwell_max_s: 2.0,
        };
        let p = compile(&params, 1);
        for piece in &p.pieces()[1..51] {
            assert!((0.4..=0.9).contains(&piece.from[0]), "{piece:?}");
            assert!(
                (0.5..=2.0).contains(&(piece.t1_s - piece.t0_s)),
                "{piece:?}"
            );
        }
        let mut other = rand::rngs::Xoshiro256PlusPlus::seed_from_u64(2);
        assert_ne!(
            p,
            params.compile(1, &mut other, None, &DifferentialParams::default())
        );
    }

    #[test]
    fn differential_commands_keep_the_overall_throttle() {
        let mut rng = rand::rngs::Xoshiro256PlusPlus::seed_from_u64(1);
        let d = DifferentialParams {
            amplitude: 0.03,
            frequency_hz: 1.3,
        };
        let p = ProgramParams::Stair {
            off_s: 0.0,
            steps: 1,
            max: 0.6,
            dwell_s: 10.0,
            direction: Direction::Up,
            repeats: 1,
        }
        .compile(4, &mut rng, None, &d);
        for k in 0..50 {
            let v = at(&p, 0.17 * k as f64);
            let mean = v.iter().sum::<f64>() / 4.0;
            assert!((mean - 0.6).abs() < 1e-12, "{v:?}");
        }
        assert!(at(&p, 0.2).iter().any(|&c| (c - 0.6).abs() > 0.01));
    }

    #[test]
    fn replay_holds_each_sample_until_the_next() {
        let t = [0.0, 1.0, 2.0];
        let thr = vec![vec![0.0, 0.5, 0.7]];
        let mut rng = rand::rngs::Xoshiro256PlusPlus::seed_from_u64(1);
        let p = ProgramParams::Replay { file: "x".into() }.compile(
            4,
            &mut rng,
            Some((&t, &thr)),
            &DifferentialParams::default(),
        );
        assert_eq!(at(&p, 1.5), vec![0.5; 4]);
        assert_eq!(p.duration_s(), 3.0);
    }
}
