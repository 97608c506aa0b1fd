//! The simulation loop: one physics step at a time, one recording row per magnetometer sample.
use std::collections::VecDeque;

use rand::rngs::Xoshiro256PlusPlus;
use rand::{RngExt, SeedableRng};
use rand_distr::StandardNormal;

use crate::battery::SupplyState;
use crate::motor::{MotorConstants, MotorState, StepFactors};
use crate::program::Program;
use crate::scenario::{DisturbanceSource, Scenario, ValidScenario};
use crate::stand::{BodyState, StandHandle, StandWorld};
use crate::stand_module::{Electrical, StandModule, modules, state_of};
use crate::thermal::TEMP_C;
use crate::wiring::WiringGains;
use magstand_core::rbf::{LocalLinear1d, UT_PER_GAUSS, paper_tables};
use magstand_core::{GroundTruth, ImuColumns, Recording, Vec3};

/// Independent random streams, so that changing one part of a scenario (say, the noise level)
/// does not reshuffle another (the random program).
#[derive(Debug, Clone, Copy)]
enum Stream {
    Program = 1,
    Noise = 2,
    Rotors = 3,
}

/// A generator for one stream of one seed (SplitMix64 mixing of seed and stream).
fn stream_rng(seed: u64, stream: Stream) -> Xoshiro256PlusPlus {
    Xoshiro256PlusPlus::seed_from_u64(magstand_core::seeds::derive(seed, stream as u64))
}

/// Receives progress while a simulation runs; kept apart from the simulator so that a command
/// line can show a bar and a library caller can ignore it.
pub trait Observer {
    /// Called now and then with simulated time done and total, seconds.
    fn progress(&mut self, done_s: f64, total_s: f64);
}

/// An observer that ignores everything.
pub struct Silent;

impl Observer for Silent {
    fn progress(&mut self, _: f64, _: f64) {}
}

/// What the sensor sees at one physics step, before noise.
#[derive(Debug, Clone, Copy)]
struct Snapshot {
    field: Vec3,
    dist: Vec3,
    sd: Vec3,
}

/// Simulates a scenario with `seed`.
pub fn simulate(s: &ValidScenario, seed: u64) -> Recording {
    simulate_observed(s, seed, &mut Silent)
}

/// Simulates a scenario with `seed`, reporting progress to `observer`.
pub fn simulate_observed(s: &ValidScenario, seed: u64, observer: &mut dyn Observer) -> Recording {
    let mut world = StandWorld::new(1.0 / s.params().physics_hz);
    let mut run = Run::new(s, seed, &mut world);
    run_together(std::slice::from_mut(&mut run), &mut world, observer);
    run.rec
}

/// Steps the runs of one world to their ends, reporting the longest one's progress: each run
/// sets its forces and one world step serves them all; a run reads its body only at the steps
/// that record or snapshot it. A run's body leaves the world after its last step.
fn run_together(batch: &mut [Run], world: &mut StandWorld, observer: &mut dyn Observer) {
    world.step();
    let Some(longest) = batch.iter().max_by_key(|r| r.steps) else {
        return;
    };
    let (steps, dt, duration_s) = (longest.steps, longest.dt, longest.duration_s);
    let progress_every = (steps / 200).max(1);
    for k in 0..steps {
        for run in batch.iter_mut().filter(|r| k < r.steps) {
            run.advance(k, world);
        }
        world.step();
        for run in batch.iter().filter(|r| k + 1 == r.steps) {
            // Its run is over: the body would only cost stepping time.
            world.remove(run.handle);
        }
        if k % progress_every == 0 {
            observer.progress(k as f64 * dt, duration_s);
        }
    }
    observer.progress(duration_s, duration_s);
}

/// Simulates several scenarios, each with its own seed, their stands stepped together in one
/// [`StandWorld`] (a study's identification and validation series of a run).
///
/// Each recording is the same, byte for byte, as [`simulate`] gives for that scenario and seed
/// alone: the stands never interact, and every random stream belongs to one run. Scenarios with
/// different physics rates go to separate worlds.
pub fn simulate_batch(runs: &[(&ValidScenario, u64)]) -> Vec<Recording> {
    let mut out: Vec<Option<Recording>> = vec![None; runs.len()];
    let mut rates: Vec<u64> = runs
        .iter()
        .map(|(s, _)| s.params().physics_hz.to_bits())
        .collect();
    rates.sort_unstable();
    rates.dedup();
    for rate in rates {
        let members: Vec<usize> = (0..runs.len())
            .filter(|&i| runs[i].0.params().physics_hz.to_bits() == rate)
            .collect();
        let mut world = StandWorld::new(1.0 / f64::from_bits(rate));
        let mut batch: Vec<Run> = members
            .iter()
            .map(|&i| Run::new(runs[i].0, runs[i].1, &mut world))
            .collect();
        run_together(&mut batch, &mut world, &mut Silent);
        for (run, &i) in batch.into_iter().zip(&members) {
            out[i] = Some(run.rec);
        }
    }
    out.into_iter().flatten().collect()
}

/// One stand's simulation in progress: everything but its rigid body, which a [`StandWorld`]
/// holds and steps.
struct Run<'a> {
    p: &'a Scenario,
    program: Program,
    dt: f64,
    duration_s: f64,
    steps: usize,
    /// Whether step k records a sample (the magnetometer's data rate on the physics grid).
    sample_at: Vec<bool>,
    delay_steps: usize,
    gains: WiringGains,
    tables: [LocalLinear1d; 3],
    tables_at_zero: Vec<f64>,
    soft: nalgebra::Matrix3<f64>,
    hard: Vec3,
    earth: Vec3,
    motors: Vec<MotorState>,
    noise_rng: Xoshiro256PlusPlus,
    supply: SupplyState,
    parts: Vec<Box<dyn StandModule>>,
    handle: StandHandle,
    /// The snapshots samples will still read, with their step.
    history: VecDeque<(usize, Snapshot)>,
    rec: Recording,
    commands: Vec<f64>,
    /// The commands a sample logs where they are logged late (`logging.command_delay_s`):
    /// the program's at the sample's time less the delay, and the piece they lie in.
    logged_commands: Option<(Vec<f64>, usize)>,
    currents: Vec<f64>,
    avionics_a: f64,
    total_a: f64,
    avionics_field: Vec3,
    /// Each module's field at the sensor at the current step.
    module_fields: Vec<Vec3>,
    /// Whether the alternating interference field is on.
    interference_on: bool,
    /// Each motor's constants.
    motor_constants: Vec<MotorConstants>,
    /// The program's piece at the last step.
    program_cursor: usize,
    /// The motors' lag factors per step.
    step_factors: StepFactors,
}

impl<'a> Run<'a> {
    /// Prepares the run and puts its stand into `world`, with the forces of its first step.
    fn new(s: &'a ValidScenario, seed: u64, world: &mut StandWorld) -> Self {
        let p = s.params();
        let n_motors = p.motors.count;
        let dt = 1.0 / p.physics_hz;
        let program = p.program.compile(
            n_motors,
            &mut stream_rng(seed, Stream::Program),
            s.replay(),
            &p.differential,
        );
        let duration_s = program.duration_s();
        let sample_every = 1.0 / p.magnetometer.odr_hz;
        let sensor_pos = Vec3::from(p.magnetometer.position_m);
        let gains = p.wiring.gains(n_motors, sensor_pos);
        let tables = paper_tables();
        let tables_at_zero: Vec<f64> = tables.iter().map(|m| m.eval(0.0)).collect();
        let mut rotor_rng = stream_rng(seed, Stream::Rotors);
        let motors: Vec<MotorState> = (0..n_motors)
            .map(|_| MotorState {
                angle_rad: std::f64::consts::TAU * rotor_rng.random::<f64>(),
                ..Default::default()
            })
            .collect();
        let handle = world.add(&p.stand, &p.motors);
        world.apply(handle, &p.motors, &motors);
        let delay_steps = (p.logging.mag_delay_s / dt).round() as usize;
        let rows_hint = (duration_s / sample_every) as usize + 2;
        let steps = (duration_s / dt).round() as usize;
        let mut sample_at = vec![false; steps];
        let mut next_sample = 0usize;
        for (k, at) in sample_at.iter_mut().enumerate() {
            if k as f64 * dt + 1e-9 >= next_sample as f64 * sample_every {
                next_sample += 1;
                *at = true;
            }
        }
        let rec = Recording {
            thr: vec![Vec::with_capacity(rows_hint); n_motors],
            bat_v: p.logging.record_power.then(Vec::new),
            bat_a: p.logging.record_power.then(Vec::new),
            temp_c: p.logging.record_temp.then(Vec::new),
            imu: p.logging.record_imu.then(ImuColumns::default),
            truth: p.logging.record_truth.then(GroundTruth::default),
            attitude: p.logging.record_attitude.then(Vec::new),
            ..Recording::default()
        };
        let avionics_a = p.supply.avionics_current_a();
        let parts = modules(p);
        Self {
            p,
            program,
            dt,
            duration_s,
            steps,
            sample_at,
            delay_steps,
            avionics_field: gains.total_ut_per_a * avionics_a,
            gains,
            tables,
            tables_at_zero,
            soft: p.magnetometer.soft_iron_matrix(),
            hard: Vec3::from(p.magnetometer.hard_iron_ut),
            earth: p.magnetometer.earth.ned_ut(),
            motors,
            noise_rng: stream_rng(seed, Stream::Noise),
            supply: SupplyState::default(),
            module_fields: vec![Vec3::zeros(); parts.len()],
            parts,
            handle,
            history: VecDeque::with_capacity(delay_steps + 1),
            rec,
            commands: vec![0.0; n_motors],
            logged_commands: (p.logging.command_delay_s > 0.0).then(|| (vec![0.0; n_motors], 0)),
            currents: vec![0.0; n_motors],
            avionics_a,
            total_a: avionics_a,
            interference_on: p.interference.amplitude_ut.iter().any(|a| *a != 0.0),
            step_factors: p.motors.step_factors(dt),
            program_cursor: 0,
            motor_constants: (0..n_motors).map(|m| p.motors.constants(m)).collect(),
        }
    }

    /// Step `k`: records a sample when one is due, advances the electrical part under the
    /// commands of time `k dt`, and sets the motors' forces on the body for the world's step.
    fn advance(&mut self, k: usize, world: &mut StandWorld) {
        let p = self.p;
        let n_motors = self.commands.len();
        let t = k as f64 * self.dt;
        self.program
            .commands_from(t, &mut self.program_cursor, &mut self.commands);
        let throttle = self.commands.iter().sum::<f64>() / n_motors as f64;
        let voltage = self.supply.voltage_v(&p.supply, self.total_a);
        let soft = self.soft;
        let electrical = Electrical {
            total_a: self.total_a,
            voltage_v: voltage,
        };
        // A module's field is taken at every step, read or not: a play operator's state
        // follows every current it is fed.
        for (part, field) in self.parts.iter_mut().zip(self.module_fields.iter_mut()) {
            let f = part.field_ut(electrical);
            *field = if part.through_soft_iron() {
                soft * f
            } else {
                f
            };
        }
        let is_sample = self.sample_at[k];
        // What the sensor sees now, from the state reached at time t: needed only at the
        // steps a sample will read (`mag_delay_s` earlier than the sample, or the first).
        let needed = k == 0 || self.sample_at.get(k + self.delay_steps) == Some(&true);
        // The body's state after the last step, read only where a snapshot or a sample uses it.
        let body: Option<BodyState> = (needed || is_sample).then(|| world.state(self.handle));
        let attitude = body.map(|b| {
            if p.motion.is_on() {
                p.motion.rotation(t) * b.attitude
            } else {
                b.attitude
            }
        });
        if let Some(attitude) = attitude.filter(|_| needed) {
            let motor_field = match p.disturbance.source {
                // The avionics current flows with the motors off too: its field is part of
                // m, and only what the motors add is the disturbance (eq. 9).
                DisturbanceSource::Wiring => {
                    soft * self
                        .gains
                        .field_ut(self.total_a - self.avionics_a, &self.currents)
                }
                DisturbanceSource::PaperTables => {
                    // Tables I-III give the deviation in gauss of the commanded overall
                    // throttle; eq. 9 makes it zero with the motors off.
                    let d = |a: usize| {
                        (self.tables[a].eval(throttle) - self.tables_at_zero[a])
                            * UT_PER_GAUSS
                            * p.disturbance.scale
                    };
                    Vec3::new(d(0), d(1), d(2))
                }
            };
            let mut outside = attitude.inverse() * self.earth + self.avionics_field;
            if self.interference_on {
                outside += p.interference.field_ut(t);
            }
            let mut dist = motor_field;
            for f in &self.module_fields {
                dist += f;
            }
            let snapshot = Snapshot {
                field: soft * outside + self.hard,
                dist,
                sd: Vec3::from(p.noise.sd_ut(self.total_a, throttle)),
            };
            self.history.push_back((k, snapshot));
        }

        if let (true, Some(body), Some(attitude)) = (is_sample, body, attitude) {
            // The state of `delay_steps` ago (or the first state, early in the run).
            let target = k.saturating_sub(self.delay_steps);
            while self.history.front().is_some_and(|(j, _)| *j < target) {
                self.history.pop_front();
            }
            let seen = self.history[0].1;
            let noise_rng = &mut self.noise_rng;
            let noise =
                Vec3::from_fn(|a, _| seen.sd[a] * noise_rng.sample::<f64, _>(StandardNormal));
            let rec = &mut self.rec;
            rec.t_s.push(t);
            let logged = match self.logged_commands.as_mut() {
                Some((logged, cursor)) => {
                    let at = t - p.logging.command_delay_s;
                    self.program.commands_from(at, cursor, logged);
                    logged
                }
                None => &self.commands,
            };
            for (m, c) in logged.iter().enumerate() {
                rec.thr[m].push(*c);
            }
            rec.mag_ut
                .push(p.magnetometer.digitize(seen.field + seen.dist + noise));
            if let Some(v) = rec.bat_v.as_mut() {
                v.push(voltage);
            }
            if let Some(a) = rec.bat_a.as_mut() {
                a.push(self.total_a);
            }
            if let (Some(tc), Some(temp_c)) = (rec.temp_c.as_mut(), state_of(&self.parts, TEMP_C)) {
                tc.push(temp_c);
            }
            if let Some(imu) = rec.imu.as_mut() {
                imu.acc_mps2.push(body.specific_force_mps2);
                imu.gyr_rps.push(body.rate_rps);
            }
            if let Some(q) = rec.attitude.as_mut() {
                // The attitude stream is logged with the commands, not with the delayed field.
                q.push(attitude);
            }
            if let Some(g) = rec.truth.as_mut() {
                g.field_ut.push(seen.field);
                g.dist_ut.push(seen.dist);
                g.sd_ut.push(seen.sd);
            }
        }

        // Advance everything by one step under the commands of time t.
        for (m, st) in self.motors.iter_mut().enumerate() {
            st.step_with(
                &p.motors,
                &self.motor_constants[m],
                self.commands[m],
                voltage,
                self.dt,
                self.step_factors,
            );
            self.currents[m] = st.current_a;
        }
        self.total_a = self.currents.iter().sum::<f64>() + self.avionics_a;
        self.supply.step(self.total_a, self.dt);
        let electrical = Electrical {
            total_a: self.total_a,
            voltage_v: voltage,
        };
        for part in self.parts.iter_mut() {
            part.step(electrical, self.dt);
        }
        world.apply(self.handle, &p.motors, &self.motors);
    }
}
