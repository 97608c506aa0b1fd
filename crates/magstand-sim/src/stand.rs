//! The restrained frame as a rapier3d rigid body.
//!
//! The frame is held to the ground by a compliant mount: six springs and dampers (three in
//! translation, three in rotation) pull it back to its rest pose, the stiffness of a
//! weight-and-rubber restraint. Motor thrust
//! acts at the arm ends, propeller drag torques react about the body's z axis, and rotor
//! imbalance adds a force rotating with each rotor. The small attitude changes that result
//! rotate the Earth field in the body frame (the paper's "apparent angular changes"), and the
//! accelerometer and gyro readings come out of the same body.
//!
//! World frame: north-east-down; body frame: forward-right-down. rapier uses glam types; they
//! are converted to nalgebra at this module's boundary and nowhere else.
use nalgebra::{Rotation3, UnitQuaternion};
use rapier3d_f64::math::{Rotation, Vector};
use rapier3d_f64::prelude::*;
use serde::{Deserialize, Serialize};

use crate::error::{Checker, SimError};
use crate::motor::{MAX_MOTORS, MotorParams, MotorState};
use magstand_core::Vec3;

/// Standard gravity, m/s^2.
pub const GRAVITY_MPS2: f64 = 9.80665;

/// Rigid-body parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct StandParams {
    /// Simulate the body with rapier3d; when false the frame is perfectly rigid and still.
    pub enabled: bool,
    /// Heading of the frame's x axis, degrees east of north.
    pub heading_deg: f64,
    /// Mass of the frame, kg.
    pub mass_kg: f64,
    /// Principal moments of inertia about x, y, z, kg m^2.
    pub inertia_kg_m2: [f64; 3],
    /// Natural frequency of the mount for translation and rotation, Hz.
    pub mount_frequency_hz: f64,
    /// Damping ratio of the mount.
    pub mount_damping_ratio: f64,
}

impl Default for StandParams {
    fn default() -> Self {
        Self {
            enabled: true,
            heading_deg: 30.0,
            mass_kg: 1.5,
            inertia_kg_m2: [0.015, 0.015, 0.028],
            mount_frequency_hz: 6.0,
            mount_damping_ratio: 0.2,
        }
    }
}

impl StandParams {
    pub(crate) fn check(&self, c: &Checker, physics_hz: f64) -> Result<(), SimError> {
        c.range("stand.heading_deg", self.heading_deg, -360.0, 360.0)?;
        c.positive("stand.mass_kg", self.mass_kg)?;
        for (k, i) in self.inertia_kg_m2.iter().enumerate() {
            c.positive(&format!("stand.inertia_kg_m2[{k}]"), *i)?;
        }
        // The explicit spring needs several steps per period to stay stable and resolved.
        let max_f = physics_hz / 20.0;
        c.range(
            "stand.mount_frequency_hz",
            self.mount_frequency_hz,
            1e-3,
            max_f,
        )
        .map_err(|_| {
            c.fail(
                "stand.mount_frequency_hz",
                self.mount_frequency_hz,
                &format!("a frequency > 0 and at most physics_hz / 20 ({max_f})"),
            )
        })?;
        c.range(
            "stand.mount_damping_ratio",
            self.mount_damping_ratio,
            0.0,
            10.0,
        )
    }

    /// Rest attitude: body to north-east-down.
    pub fn rest_attitude(&self) -> UnitQuaternion<f64> {
        UnitQuaternion::from_axis_angle(&Vec3::z_axis(), self.heading_deg.to_radians())
    }
}

/// Kinematic state of the frame read back from the body.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BodyState {
    /// Body to world rotation.
    pub attitude: UnitQuaternion<f64>,
    /// Specific force in the body frame (what an accelerometer reads), m/s^2.
    pub specific_force_mps2: Vec3,
    /// Angular rate in the body frame, rad/s.
    pub rate_rps: Vec3,
}

fn to_glam(v: Vec3) -> Vector {
    Vector::new(v.x, v.y, v.z)
}
fn from_glam(v: Vector) -> Vec3 {
    Vec3::new(v.x, v.y, v.z)
}
fn quat_from_glam(q: &Rotation) -> UnitQuaternion<f64> {
    UnitQuaternion::new_normalize(nalgebra::Quaternion::new(q.w, q.x, q.y, q.z))
}

/// Motor positions in the body frame for an evenly spaced X layout, and spin directions.
pub fn motor_layout(p: &MotorParams) -> Vec<(Vec3, f64)> {
    (0..p.count)
        .map(|m| {
            // First arm front-right (45° for a quad), then around clockwise seen from above.
            let ang = std::f64::consts::PI / p.count as f64
                + std::f64::consts::TAU * m as f64 / p.count as f64;
            let spin = if m % 2 == 0 { 1.0 } else { -1.0 };
            (Vec3::new(ang.cos(), ang.sin(), 0.0) * p.arm_length_m, spin)
        })
        .collect()
}

/// The compliant mount: a spring and damper on each of the six degrees of freedom, pulling the
/// body back to its rest pose.
///
/// Computed here and applied as external forces rather than as rapier joint motors: the body
/// then carries no constraint, rapier's solver has nothing to iterate, and a step costs a
/// fraction of the joint version (same dynamics; see results/BENCHMARKS.md).
#[derive(Debug, Clone, Copy)]
struct Mount {
    /// Translational stiffness, N/m, and damping, N s/m.
    k_lin: f64,
    c_lin: f64,
    /// Rotational stiffness, N m/rad, and damping, N m s/rad, per body axis.
    k_ang: Vec3,
    c_ang: Vec3,
    /// Rest position: the static sag m g / k below the mount point.
    rest_position: Vec3,
}

impl Mount {
    fn new(p: &StandParams) -> Self {
        let w = std::f64::consts::TAU * p.mount_frequency_hz;
        let inertia = Vec3::from(p.inertia_kg_m2);
        Self {
            k_lin: p.mass_kg * w * w,
            c_lin: 2.0 * p.mount_damping_ratio * p.mass_kg * w,
            k_ang: inertia * w * w,
            c_ang: inertia * (2.0 * p.mount_damping_ratio * w),
            rest_position: Vec3::zeros(),
        }
    }

    /// Force (world frame) and torque (body frame) on a body at `position` with `velocity`
    /// (world), rotated by `from_rest` away from its rest attitude and turning at `rate_body`.
    fn reaction(
        &self,
        position: Vec3,
        velocity: Vec3,
        from_rest: &UnitQuaternion<f64>,
        rate_body: Vec3,
    ) -> (Vec3, Vec3) {
        let force = -(position - self.rest_position) * self.k_lin - velocity * self.c_lin;
        let torque = -self.k_ang.component_mul(&from_rest.scaled_axis())
            - self.c_ang.component_mul(&rate_body);
        (force, torque)
    }
}

/// Identifies one stand in a [`StandWorld`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct StandHandle(usize);

/// One frame on its mount, as the world keeps it.
struct StandBody {
    /// `None` for a disabled stand: perfectly rigid and still, no rapier body.
    body: Option<RigidBody>,
    rest: UnitQuaternion<f64>,
    layout: Vec<(Vec3, f64)>,
    mount: Mount,
    /// The body's velocity before the last step (the accelerometer's difference).
    previous_velocity: Vec3,
    /// Force and torque (world frame) set for the next step.
    force: Vector,
    torque: Vector,
    /// The body's effective mass per axis, rapier's (constant: taken once).
    mass: Vector,
}

impl StandBody {
    /// A stand on its mount with `body` (none: disabled, or stepped elsewhere), no force set.
    fn new(p: &StandParams, motors: &MotorParams, body: Option<RigidBody>) -> Self {
        let mass = body
            .as_ref()
            .map_or(Vector::ZERO, |b| b.mass_properties().effective_mass());
        Self {
            body,
            mass,
            rest: p.rest_attitude(),
            layout: motor_layout(motors),
            mount: Mount::new(p),
            previous_velocity: Vec3::zeros(),
            force: Vector::ZERO,
            torque: Vector::ZERO,
        }
    }
}

/// Several restrained stands, each a rapier3d rigid body, stepped together.
///
/// Each body keeps rapier's state and mass properties
/// ([`RigidBody::recompute_mass_properties_from_colliders`]; the world inertia turned with the
/// pose by [`RigidBody::set_position`]) and is advanced by the operations rapier's solver
/// applies to a dynamic body that has no contact and no joint, in its order: the force
/// increment, the gyroscopic correction, the linearized rotation, rapier's damping. rapier's
/// physics pipeline itself is not stepped: its broad phase, narrow phase, islands and
/// constraint stages have nothing to do for such a body, yet cost about 1.3 µs per step, more
/// than everything else of a 1 kHz step together (results/BENCHMARKS.md). A test holds every
/// coordinate of a moving body to the pipeline's, bit for bit
/// (`the_bodies_move_as_rapiers_pipeline_moves_them_bit_for_bit`). The stands never interact:
/// each body's state is the same, bit for bit, whatever else is in the world
/// (`simulate_batch`'s tests hold it to that).
pub struct StandWorld {
    stands: Vec<StandBody>,
    dt_s: f64,
}

impl StandWorld {
    /// An empty world stepping `dt_s` seconds at a time.
    pub fn new(dt_s: f64) -> Self {
        Self {
            stands: Vec::new(),
            dt_s,
        }
    }

    /// Adds a stand at rest, its body at the static sag of its mount.
    pub fn add(&mut self, p: &StandParams, motors: &MotorParams) -> StandHandle {
        let body = p.enabled.then(|| stand_body(p));
        self.stands.push(StandBody::new(p, motors, body));
        StandHandle(self.stands.len() - 1)
    }

    /// Sets the motors' forces and torques on stand `h` for the next step (they replace the
    /// previous step's).
    pub fn apply(&mut self, h: StandHandle, motors: &MotorParams, states: &[MotorState]) {
        let stand = &mut self.stands[h.0];
        let Some(b) = stand.body.as_ref() else {
            return;
        };
        let (force, torque) = stand_forces(stand, b, motors, states);
        stand.force = force;
        stand.torque = torque;
    }

    /// Advances every stand by one step.
    pub fn step(&mut self) {
        let dt_s = self.dt_s;
        for stand in &mut self.stands {
            if let Some(b) = stand.body.as_mut() {
                stand.previous_velocity = from_glam(b.linvel());
                integrate(b, stand.force, stand.torque, stand.mass, dt_s);
            }
        }
    }

    /// The state stand `h` reached in the last step.
    pub fn state(&self, h: StandHandle) -> BodyState {
        let dt_s = self.dt_s;
        let stand = &self.stands[h.0];
        let Some(b) = stand.body.as_ref() else {
            return BodyState {
                attitude: stand.rest,
                specific_force_mps2: stand.rest.inverse() * Vec3::new(0.0, 0.0, -GRAVITY_MPS2),
                rate_rps: Vec3::zeros(),
            };
        };
        let attitude = quat_from_glam(b.rotation());
        let velocity = from_glam(b.linvel());
        let accel = (velocity - stand.previous_velocity) / dt_s;
        let gravity = Vec3::new(0.0, 0.0, GRAVITY_MPS2);
        BodyState {
            attitude,
            specific_force_mps2: attitude.inverse() * (accel - gravity),
            rate_rps: attitude.inverse() * from_glam(b.angvel()),
        }
    }

    /// Takes stand `h`'s body out of the world (its run is over); its handle stays valid and
    /// reads the rest state from then on.
    pub fn remove(&mut self, h: StandHandle) {
        self.stands[h.0].body = None;
    }
}

/// A stand's rapier body at rest, at the static sag m g / k of its mount so that the run does
/// not begin with a bounce.
fn stand_body(p: &StandParams) -> RigidBody {
    let w = std::f64::consts::TAU * p.mount_frequency_hz;
    let inertia = to_glam(Vec3::from(p.inertia_kg_m2));
    let mut body = RigidBodyBuilder::dynamic()
        .translation(Vector::new(0.0, 0.0, GRAVITY_MPS2 / (w * w)))
        .rotation(to_glam(p.rest_attitude().scaled_axis()))
        .additional_mass_properties(MassProperties::new(Vector::ZERO, p.mass_kg, inertia))
        .can_sleep(false)
        .build();
    // No colliders: the mass properties are the additional ones alone.
    body.recompute_mass_properties_from_colliders(&ColliderSet::new());
    body
}

/// The mount's and the motors' force and torque on a stand's body, world frame.
fn stand_forces(
    stand: &StandBody,
    b: &RigidBody,
    motors: &MotorParams,
    states: &[MotorState],
) -> (Vector, Vector) {
    let q = quat_from_glam(b.rotation());
    let origin = from_glam(b.translation());
    let (mount_force, mount_torque) = stand.mount.reaction(
        origin,
        from_glam(b.linvel()),
        &(stand.rest.inverse() * q),
        q.inverse() * from_glam(b.angvel()),
    );
    // The rotors' forces and torques summed in the body frame and turned into the world
    // once: a force f at arm r adds r x f about the centre of mass (the body's origin).
    let (mut force_body, mut torque_body) = (Vec3::zeros(), mount_torque);
    // Every rotor's sine and cosine in one loop of its own, which the compiler vectorizes.
    debug_assert!(states.len() <= MAX_MOTORS, "{} motors", states.len());
    let mut turn = [(0.0, 0.0); MAX_MOTORS];
    for (t, s) in turn.iter_mut().zip(states) {
        *t = crate::motor::rotor_sin_cos(s.angle_rad);
    }
    for (m, (((arm, spin), s), &(sin, cos))) in
        stand.layout.iter().zip(states).zip(&turn).enumerate()
    {
        let w = s.speed_rad_s;
        // Thrust pushes up (body -z); the rotor's imbalance force turns with it.
        let imbalance = motors.imbalance_kg_m * w * w * Vec3::new(cos, sin, 0.0);
        let force = Vec3::new(0.0, 0.0, -motors.thrust(w)) + imbalance;
        force_body += force;
        // Drag on a rotor spinning +spin about body z reacts on the frame with -spin.
        torque_body += arm.cross(&force) + Vec3::new(0.0, 0.0, -spin * motors.drag_torque(m, w));
    }
    (
        to_glam(mount_force + q * force_body),
        to_glam(q * torque_body),
    )
}

/// One step of a body of effective mass `mass` under `force` and `torque` (world frame) and
/// gravity, as rapier's solver steps a dynamic body that has no contact and no joint, in the
/// same operations and order (so the same bits): the velocity increment of the forces, the
/// gyroscopic correction at the step's starting attitude, then the pose by the linearized
/// rotation of the new velocities. The bounds rapier puts on speed (a quarter turn per step)
/// are far above a stand's motion and left out.
fn integrate(b: &mut RigidBody, force: Vector, torque: Vector, mass: Vector, dt_s: f64) {
    let mprops = b.mass_properties();
    let mut forces = RigidBodyForces {
        user_force: force,
        user_torque: torque,
        ..Default::default()
    };
    forces.compute_effective_force_and_torque(Vector::new(0.0, 0.0, GRAVITY_MPS2), mass);
    let local = &mprops.local_mprops;
    let mut linvel = b.linvel() + forces.force * mprops.effective_inv_mass * dt_s;
    let mut angvel = b.angvel() + mprops.effective_world_inv_inertia * forces.torque * dt_s;
    let mut rotation = *b.rotation();
    angvel = gyroscopic_corrected(
        angvel,
        rotation * local.principal_inertia_local_frame,
        local.principal_inertia(),
        local.inv_principal_inertia,
        dt_s,
    );
    let half_turn = angvel * (dt_s * 0.5);
    rotation =
        (Rotation::from_xyzw(half_turn.x, half_turn.y, half_turn.z, 1.0) * rotation).normalize();
    let translation = b.translation() + linvel * dt_s;
    // rapier's (zero) damping, applied as it does.
    linvel *= 1.0 / (1.0 + dt_s * b.linear_damping());
    angvel *= 1.0 / (1.0 + dt_s * b.angular_damping());
    b.set_vels(RigidBodyVelocity { linvel, angvel }, false);
    b.set_position(Pose::from_parts(translation, rotation), false);
}

/// rapier's gyroscopic correction of a body's angular velocity: the explicit term of Euler's
/// equations, its angular momentum's length kept.
fn gyroscopic_corrected(
    angvel: Vector,
    principal_axes: Rotation,
    principal_inertia: Vector,
    inv_principal_inertia: Vector,
    dt_s: f64,
) -> Vector {
    let w = principal_axes.inverse() * angvel;
    let momentum = principal_inertia * w;
    let total = momentum + -w.cross(momentum) * dt_s;
    let total_sq = total.length_squared();
    if total_sq == 0.0 {
        return angvel;
    }
    let capped = total * (momentum.length_squared() / total_sq).sqrt();
    principal_axes * (inv_principal_inertia * capped)
}

/// The frame on its mount: a world of one stand.
pub struct Stand {
    world: StandWorld,
    handle: StandHandle,
}

impl Stand {
    /// Builds the body and its mount.
    pub fn new(p: &StandParams, motors: &MotorParams, dt_s: f64) -> Self {
        let mut world = StandWorld::new(dt_s);
        let handle = world.add(p, motors);
        Self { world, handle }
    }

    /// Applies the motors' forces and torques for one step and advances the body.
    pub fn step(&mut self, motors: &MotorParams, states: &[MotorState]) -> BodyState {
        self.world.apply(self.handle, motors, states);
        self.world.step();
        self.world.state(self.handle)
    }

    /// Rotation of the body away from its rest attitude, radians.
    pub fn tilt_from_rest(&self, state: &BodyState) -> f64 {
        (self.world.stands[self.handle.0].rest.inverse() * state.attitude).angle()
    }
}

/// Roll, pitch, yaw (radians) of a body-to-NED attitude.
pub fn euler_rpy(q: &UnitQuaternion<f64>) -> (f64, f64, f64) {
    let r: Rotation3<f64> = q.to_rotation_matrix();
    r.euler_angles()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(
        p: &StandParams,
        motors: &MotorParams,
        states: &[MotorState],
        seconds: f64,
    ) -> (Stand, BodyState) {
        let dt = 1e-3;
        let mut s = Stand::new(p, motors, dt);
        let mut last = s.step(motors, states);
        for _ in 1..(seconds / dt) as usize {
            last = s.step(motors, states);
        }
        (s, last)
    }

    #[test]
    fn at_rest_the_accelerometer_reads_minus_g_on_z() {
        let p = StandParams {
            heading_deg: 0.0,
            ..Default::default()
        };
        let m = MotorParams::default();
        let (_, st) = run(&p, &m, &[MotorState::default(); 4], 3.0);
        assert!(
            (st.specific_force_mps2.z + GRAVITY_MPS2).abs() < 1e-3,
            "{}",
            st.specific_force_mps2
        );
        assert!(st.rate_rps.norm() < 1e-6, "{}", st.rate_rps);
    }

    #[test]
    fn differential_thrust_tilts_the_frame_by_torque_over_stiffness() {
        let p = StandParams {
            heading_deg: 0.0,
            mount_damping_ratio: 1.0,
            ..Default::default()
        };
        let m = MotorParams {
            imbalance_kg_m: 0.0,
            ..Default::default()
        };
        // Right-side motors (1 front-right, 2 rear-right) faster: roll left (negative about x).
        let speed = |w: f64| MotorState {
            speed_rad_s: w,
            angle_rad: 0.0,
            current_a: 0.0,
        };
        let states = [speed(600.0), speed(600.0), speed(500.0), speed(500.0)];
        let (_, st) = run(&p, &m, &states, 4.0);
        let (roll, _, _) = euler_rpy(&st.attitude);
        let layout = motor_layout(&m);
        // tau_x = sum(y_i * (-T_i)) for force (0,0,-T) at (x_i, y_i, 0).
        let tau_x: f64 = layout
            .iter()
            .zip(&states)
            .map(|((arm, _), s)| arm.y * -m.thrust(s.speed_rad_s))
            .sum();
        let k = p.inertia_kg_m2[0] * (std::f64::consts::TAU * p.mount_frequency_hz).powi(2);
        let expected = tau_x / k;
        assert!(roll < 0.0, "roll {roll}");
        assert!(
            (roll - expected).abs() < 0.05 * expected.abs(),
            "roll {roll} vs tau/k {expected}"
        );
    }

    /// A body's pose and velocities, every coordinate.
    fn coordinates(b: &RigidBody) -> [f64; 13] {
        let (q, x, v, w) = (b.rotation(), b.translation(), b.linvel(), b.angvel());
        [
            q.x, q.y, q.z, q.w, x.x, x.y, x.z, v.x, v.y, v.z, w.x, w.y, w.z,
        ]
    }

    /// The same stand stepped by rapier's full physics pipeline, its forces set as
    /// `StandWorld` sets them: each step's coordinates of the body.
    fn pipeline_trajectory(
        p: &StandParams,
        motors: &MotorParams,
        states: &[MotorState],
        steps: usize,
        dt_s: f64,
    ) -> Vec<[f64; 13]> {
        let mut world = PhysicsWorld::new();
        world.gravity = Vector::new(0.0, 0.0, GRAVITY_MPS2);
        world.integration_parameters.dt = dt_s;
        // One substep: the stands were stepped so before (the recordings did not change).
        world.integration_parameters.num_solver_iterations = 1;
        let handle = world.insert_body(stand_body(p));
        let stand = StandBody::new(p, motors, None);
        (0..steps)
            .map(|_| {
                let b = &mut world.bodies[handle];
                let (force, torque) = stand_forces(&stand, b, motors, states);
                b.reset_forces(false);
                b.reset_torques(false);
                b.add_force(force, false);
                b.add_torque(torque, false);
                world.step();
                coordinates(&world.bodies[handle])
            })
            .collect()
    }

    #[test]
    fn the_bodies_move_as_rapiers_pipeline_moves_them_bit_for_bit() {
        let p = StandParams {
            heading_deg: 20.0,
            mount_damping_ratio: 0.05,
            ..Default::default()
        };
        let m = MotorParams::default();
        // Unequal speeds and rotor angles: a tilt, a yaw torque and turning imbalance forces,
        // a motion large enough for the gyroscopic term to matter.
        let states: Vec<MotorState> = [900.0, 700.0, 820.0, 640.0]
            .iter()
            .enumerate()
            .map(|(i, &w)| MotorState {
                speed_rad_s: w,
                angle_rad: 0.7 * i as f64,
                current_a: 0.0,
            })
            .collect();
        let dt_s = 1e-3;
        let reference = pipeline_trajectory(&p, &m, &states, 3000, dt_s);
        let mut world = StandWorld::new(dt_s);
        let h = world.add(&p, &m);
        let mut largest_tilt = 0.0f64;
        for (k, expected) in reference.iter().enumerate() {
            world.apply(h, &m, &states);
            world.step();
            let b = world.stands[h.0]
                .body
                .as_ref()
                .expect("an enabled stand has a body");
            let got = coordinates(b);
            assert!(
                got.iter()
                    .zip(expected)
                    .all(|(a, b)| a.to_bits() == b.to_bits()),
                "step {k}: {got:?} against the pipeline's {expected:?}"
            );
            largest_tilt = largest_tilt
                .max((p.rest_attitude().inverse() * quat_from_glam(b.rotation())).angle());
        }
        assert!(
            largest_tilt > 0.01,
            "the test must move the body: tilt {largest_tilt} rad"
        );
    }

    #[test]
    fn a_disabled_stand_stays_at_rest_attitude() {
        let p = StandParams {
            enabled: false,
            heading_deg: 90.0,
            ..Default::default()
        };
        let m = MotorParams::default();
        let (_, st) = run(
            &p,
            &m,
            &[MotorState {
                speed_rad_s: 900.0,
                ..Default::default()
            }; 4],
            0.1,
        );
        assert!((st.attitude.angle() - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
    }
}
