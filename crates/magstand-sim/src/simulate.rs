//! The simulation loop: one physics step at a time, one recording row per magnetometer sample.
use std::collections::VecDeque;

use rand::rngs::Xoshiro256PlusPlus;
use rand::{RngExt, SeedableRng};
use rand_distr::StandardNormal;

use crate::battery::SupplyState;
use crate::motor::MotorState;
use crate::scenario::{DisturbanceSource, ValidScenario};
use crate::stand::Stand;
use crate::stand_module::{Electrical, modules, state_of};
use crate::thermal::TEMP_C;
use magstand_core::rbf::{UT_PER_GAUSS, paper_tables};
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
    let p = s.params();
    let n_motors = p.motors.count;
    let dt = 1.0 / p.physics_hz;
    let program = p.program.compile(
        n_motors,
        &mut stream_rng(seed, Stream::Program),
        s.replay(),
        &p.differential,
    );
    let duration = program.duration_s();
    let steps = (duration / dt).round() as usize;
    let sample_every = 1.0 / p.magnetometer.odr_hz;
    let delay_steps = (p.logging.mag_delay_s / dt).round() as usize;

    let sensor_pos = Vec3::from(p.magnetometer.position_m);
    let gains = p.wiring.gains(n_motors, sensor_pos);
    let tables = paper_tables();
    let tables_at_zero: Vec<f64> = tables.iter().map(|m| m.eval(0.0)).collect();
    let soft = p.magnetometer.soft_iron_matrix();
    let hard = Vec3::from(p.magnetometer.hard_iron_ut);
    let earth = p.magnetometer.earth.ned_ut();

    let mut rotor_rng = stream_rng(seed, Stream::Rotors);
    let mut motors: Vec<MotorState> = (0..n_motors)
        .map(|_| MotorState {
            angle_rad: std::f64::consts::TAU * rotor_rng.random::<f64>(),
            ..Default::default()
        })
        .collect();
    let mut noise_rng = stream_rng(seed, Stream::Noise);
    let mut supply = SupplyState::default();
    let mut parts = modules(p);
    let mut stand = Stand::new(&p.stand, &p.motors, dt);
    let mut body = stand.step(&p.motors, &motors);
    let mut history: VecDeque<Snapshot> = VecDeque::with_capacity(delay_steps + 1);

    let rows_hint = (duration / sample_every) as usize + 2;
    let mut rec = Recording {
        thr: vec![Vec::with_capacity(rows_hint); n_motors],
        bat_v: p.logging.record_power.then(Vec::new),
        bat_a: p.logging.record_power.then(Vec::new),
        temp_c: p.logging.record_temp.then(Vec::new),
        imu: p.logging.record_imu.then(ImuColumns::default),
        truth: p.logging.record_truth.then(GroundTruth::default),
        attitude: p.logging.record_attitude.then(Vec::new),
        ..Recording::default()
    };
    let mut commands = vec![0.0; n_motors];
    let mut currents = vec![0.0; n_motors];
    let avionics = p.supply.avionics_current_a();
    let mut total_a = avionics;
    let avionics_field = gains.total_ut_per_a * avionics;
    let mut next_sample = 0usize;
    let progress_every = (steps / 200).max(1);

    for k in 0..steps {
        let t = k as f64 * dt;
        program.commands_into(t, &mut commands);
        let throttle = commands.iter().sum::<f64>() / n_motors as f64;
        let voltage = supply.voltage_v(&p.supply, total_a);

        // What the sensor sees now, from the state reached at time t.
        let motor_field = match p.disturbance.source {
            // The avionics current flows with the motors off too: its field is part of m, and
            // only what the motors add is the disturbance (eq. 9).
            DisturbanceSource::Wiring => soft * gains.field_ut(total_a - avionics, &currents),
            DisturbanceSource::PaperTables => {
                // Tables I-III give the deviation in gauss of the commanded overall throttle;
                // eq. 9 makes it zero with the motors off.
                let d = |a: usize| {
                    (tables[a].eval(throttle) - tables_at_zero[a])
                        * UT_PER_GAUSS
                        * p.disturbance.scale
                };
                Vec3::new(d(0), d(1), d(2))
            }
        };
        let electrical = Electrical {
            total_a,
            voltage_v: voltage,
        };
        let mut dist = motor_field;
        for part in parts.iter_mut() {
            let f = part.field_ut(electrical);
            dist += if part.through_soft_iron() {
                soft * f
            } else {
                f
            };
        }
        let attitude = p.motion.rotation(t) * body.attitude;
        let snapshot = Snapshot {
            field: soft
                * (attitude.inverse() * earth + avionics_field + p.interference.field_ut(t))
                + hard,
            dist,
            sd: Vec3::from(p.noise.sd_ut(total_a, throttle)),
        };
        if history.len() > delay_steps {
            history.pop_front();
        }
        history.push_back(snapshot);

        if t + 1e-9 >= next_sample as f64 * sample_every {
            next_sample += 1;
            // The oldest entry is `delay_steps` old (or the first state, early in the run).
            let seen = history[0];
            let noise =
                Vec3::from_fn(|a, _| seen.sd[a] * noise_rng.sample::<f64, _>(StandardNormal));
            rec.t_s.push(t);
            for (m, c) in commands.iter().enumerate() {
                rec.thr[m].push(*c);
            }
            rec.mag_ut
                .push(p.magnetometer.digitize(seen.field + seen.dist + noise));
            if let Some(v) = rec.bat_v.as_mut() {
                v.push(voltage);
            }
            if let Some(a) = rec.bat_a.as_mut() {
                a.push(total_a);
            }
            if let (Some(tc), Some(temp_c)) = (rec.temp_c.as_mut(), state_of(&parts, TEMP_C)) {
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
        for (m, st) in motors.iter_mut().enumerate() {
            st.step(&p.motors, m, commands[m], voltage, dt);
            currents[m] = st.current_a;
        }
        total_a = currents.iter().sum::<f64>() + avionics;
        supply.step(total_a, dt);
        let electrical = Electrical {
            total_a,
            voltage_v: voltage,
        };
        for part in parts.iter_mut() {
            part.step(electrical, dt);
        }
        body = stand.step(&p.motors, &motors);

        if k % progress_every == 0 {
            observer.progress(t, duration);
        }
    }
    observer.progress(duration, duration);
    rec
}
