//! Current paths and the field they make at the magnetometer, by the Biot-Savart law.
//!
//! Every conductor is a chain of finite straight segments. For a segment from `A` to `B`
//! carrying current `I`, seen from point `P`, with `a = A - P` and `b = B - P`:
//!
//! `B = (mu0 I / 4 pi) (a x b) (|a| + |b|) / (|a| |b| (|a| |b| + a.b))`
//!
//! The field is linear in each current, so the geometry is reduced once to a gain per current
//! (µT per ampere) and the simulation loop only multiplies and adds.
use serde::{Deserialize, Serialize};

use crate::error::{Checker, SimError};
use magstand_core::Vec3;

/// mu0 / 4 pi in microtesla metre per ampere.
pub const MU0_OVER_4PI_UT_M_PER_A: f64 = 0.1;

/// Which current a conductor carries.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(try_from = "String", into = "String")]
pub enum Carrier {
    /// The whole supply current (battery leads, power distribution board).
    Total,
    /// The current of one motor (ESC leads), 1-based as in the recording's `thr_N`.
    Motor(usize),
}

impl TryFrom<String> for Carrier {
    type Error = String;
    fn try_from(s: String) -> Result<Self, String> {
        if s == "total" {
            return Ok(Carrier::Total);
        }
        s.strip_prefix("motor")
            .and_then(|n| n.parse::<usize>().ok())
            .filter(|&n| n >= 1)
            .map(Carrier::Motor)
            .ok_or_else(|| {
                format!("`{s}` is not a current: expected \"total\" or \"motor1\", \"motor2\", ...")
            })
    }
}

impl From<Carrier> for String {
    fn from(c: Carrier) -> String {
        match c {
            Carrier::Total => "total".into(),
            Carrier::Motor(n) => format!("motor{n}"),
        }
    }
}

/// A straight conductor.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SegmentParams {
    /// The current it carries.
    pub carries: Carrier,
    /// Start point in the body frame (x forward, y right, z down), m. Current flows start to end.
    pub start_m: [f64; 3],
    /// End point, m.
    pub end_m: [f64; 3],
    /// Fraction (and sign) of the carried current: -1 for a return lead.
    #[serde(default = "one")]
    pub scale: f64,
}

/// A circular current loop, discretized as a regular polygon.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LoopParams {
    /// The current it carries.
    pub carries: Carrier,
    /// Centre in the body frame, m.
    pub center_m: [f64; 3],
    /// Normal; the current circulates right-handed about it, so the field at the centre points
    /// along it.
    pub normal: [f64; 3],
    /// Radius, m.
    pub radius_m: f64,
    /// Polygon sides.
    #[serde(default = "default_sides")]
    pub sides: u32,
    /// Fraction (and sign) of the carried current.
    #[serde(default = "one")]
    pub scale: f64,
}

fn one() -> f64 {
    1.0
}
fn default_sides() -> u32 {
    36
}

/// All conductors of the stand.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
///
/// With no `[wiring]` table the default layout for the motor count is used
/// ([`WiringParams::default_for`]); a `[wiring]` table replaces it whole.
#[serde(deny_unknown_fields)]
pub struct WiringParams {
    /// Straight conductors.
    #[serde(default)]
    pub segment: Vec<SegmentParams>,
    /// Circular loops.
    #[serde(rename = "loop", default)]
    pub loops: Vec<LoopParams>,
    /// Per-motor gains added to what the geometry gives, µT per ampere (x, y, z), one entry
    /// per motor or none. This is how a fitted motor asymmetry is switched on when the
    /// geometry that causes it is unknown (the mismatch diagnosis writes it).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub extra_motor_ut_per_a: Vec<[f64; 3]>,
}

/// The arms of the default layout ([`WiringParams::default`]): a quadrotor's.
pub const DEFAULT_ARMS: usize = 4;

impl Default for WiringParams {
    /// A power-distribution loop below and beside the flight controller, and twisted ESC lead
    /// pairs along each of four arms: about 4, 10 and -16 µT at a 60 A full-throttle current.
    fn default() -> Self {
        Self::default_for(DEFAULT_ARMS)
    }
}

impl WiringParams {
    /// The default layout for `motors` motors: the power-distribution loop of
    /// [`WiringParams::default`], and a twisted ESC lead pair along each of `motors` arms
    /// spaced evenly around the sensor's axis (four of them give the default).
    pub fn default_for(motors: usize) -> Self {
        let n = Vec3::new(0.207, 0.518, -0.829).normalize();
        let c = -0.09 * n;
        let mut segment = Vec::new();
        let spacing = std::f64::consts::TAU / motors.max(1) as f64;
        for m in 0..motors {
            let ang = std::f64::consts::FRAC_PI_4 + m as f64 * spacing;
            let (dir, side) = (
                Vec3::new(ang.cos(), ang.sin(), 0.0),
                Vec3::new(-ang.sin(), ang.cos(), 0.0),
            );
            for (off, scale) in [(0.001, 1.0), (-0.001, -1.0)] {
                let a = Vec3::new(0.0, 0.0, 0.04) + 0.03 * dir + off * side;
                let b = a + 0.17 * dir;
                segment.push(SegmentParams {
                    carries: Carrier::Motor(m + 1),
                    start_m: a.into(),
                    end_m: b.into(),
                    scale,
                });
            }
        }
        WiringParams {
            segment,
            loops: vec![LoopParams {
                carries: Carrier::Total,
                center_m: c.into(),
                normal: n.into(),
                radius_m: 0.02,
                sides: 36,
                scale: 1.0,
            }],
            extra_motor_ut_per_a: Vec::new(),
        }
    }

    /// Whether the conductors are those of the default layout for `motors` motors.
    pub fn is_default_layout_for(&self, motors: usize) -> bool {
        let d = Self::default_for(motors);
        self.segment == d.segment && self.loops == d.loops
    }
}

/// Field at `p` of a straight segment from `a` to `b` carrying 1 A, µT.
///
/// Returns zero when `p` lies on the segment's line (where the field is undefined); scenario
/// checks keep conductors away from the sensor.
pub fn segment_field_per_amp(a: Vec3, b: Vec3, p: Vec3) -> Vec3 {
    let (ra, rb) = (a - p, b - p);
    let (na, nb) = (ra.norm(), rb.norm());
    let cross = ra.cross(&rb);
    let dot = ra.dot(&rb);
    // |a||b| + a.b cancels catastrophically for a long segment seen from its side (a.b < 0);
    // there it equals |a x b|^2 / (|a||b| - a.b), which does not.
    let sum = if dot >= 0.0 {
        na * nb + dot
    } else {
        cross.norm_squared() / (na * nb - dot)
    };
    let denom = na * nb * sum;
    if !(denom > f64::EPSILON * (na * nb).powi(2)) {
        return Vec3::zeros();
    }
    cross * (MU0_OVER_4PI_UT_M_PER_A * (na + nb) / denom)
}

/// Shortest distance from `p` to the segment from `a` to `b`, m.
pub fn distance_to_segment(a: Vec3, b: Vec3, p: Vec3) -> f64 {
    let ab = b - a;
    let t = if ab.norm_squared() > 0.0 {
        ((p - a).dot(&ab) / ab.norm_squared()).clamp(0.0, 1.0)
    } else {
        0.0
    };
    (a + ab * t - p).norm()
}

/// Vertices of a loop polygon, closed (first vertex repeated at the end).
pub fn loop_vertices(center: Vec3, normal: Vec3, radius: f64, sides: u32) -> Vec<Vec3> {
    let n = normal.normalize();
    // Any vector not parallel to n gives an in-plane basis (u, v) with u x v = n.
    let helper = if n.x.abs() < 0.9 {
        Vec3::x()
    } else {
        Vec3::y()
    };
    let u = n.cross(&helper).normalize();
    let v = n.cross(&u);
    (0..=sides)
        .map(|k| {
            let th = std::f64::consts::TAU * k as f64 / sides as f64;
            center + radius * (u * th.cos() + v * th.sin())
        })
        .collect()
}

/// The wiring reduced to gains: field at the sensor per ampere of each current.
#[derive(Debug, Clone, PartialEq)]
pub struct WiringGains {
    /// µT per ampere of the total supply current.
    pub total_ut_per_a: Vec3,
    /// µT per ampere of each motor's current.
    pub motor_ut_per_a: Vec<Vec3>,
}

impl WiringGains {
    /// Field at the sensor, µT.
    pub fn field_ut(&self, total_a: f64, motor_a: &[f64]) -> Vec3 {
        let mut b = self.total_ut_per_a * total_a;
        for (g, i) in self.motor_ut_per_a.iter().zip(motor_a) {
            b += g * *i;
        }
        b
    }
}

impl WiringParams {
    /// Minimum distance allowed between a conductor and the sensor, m.
    pub const MIN_CLEARANCE_M: f64 = 0.002;

    /// All conductors as (carrier, start, end, scale) segments.
    fn segments(&self) -> Vec<(Carrier, Vec3, Vec3, f64)> {
        let mut out: Vec<_> = self
            .segment
            .iter()
            .map(|s| {
                (
                    s.carries,
                    Vec3::from(s.start_m),
                    Vec3::from(s.end_m),
                    s.scale,
                )
            })
            .collect();
        for l in &self.loops {
            let v = loop_vertices(l.center_m.into(), l.normal.into(), l.radius_m, l.sides);
            out.extend(v.windows(2).map(|w| (l.carries, w[0], w[1], l.scale)));
        }
        out
    }

    pub(crate) fn check(&self, c: &Checker, motors: usize, sensor_m: Vec3) -> Result<(), SimError> {
        let carrier_ok = |key: &str, carrier: Carrier| match carrier {
            Carrier::Motor(n) if n > motors => Err(c.fail(
                key,
                String::from(carrier),
                &format!("\"total\" or motor1..motor{motors}"),
            )),
            _ => Ok(()),
        };
        for (k, s) in self.segment.iter().enumerate() {
            let key = format!("wiring.segment[{k}]");
            carrier_ok(&format!("{key}.carries"), s.carries)?;
            c.within3(&format!("{key}.start_m"), s.start_m, crate::MAX_DISTANCE_M)?;
            c.within3(&format!("{key}.end_m"), s.end_m, crate::MAX_DISTANCE_M)?;
            c.range(&format!("{key}.scale"), s.scale, -100.0, 100.0)?;
            if s.start_m == s.end_m {
                return Err(c.fail(
                    &format!("{key}.end_m"),
                    format!("{:?}", s.end_m),
                    "a point different from start_m",
                ));
            }
            let d = distance_to_segment(s.start_m.into(), s.end_m.into(), sensor_m);
            if d < Self::MIN_CLEARANCE_M {
                return Err(c.fail(
                    &key,
                    format!("{:.4} m from the sensor", d),
                    "a conductor at least 2 mm from the magnetometer",
                ));
            }
        }
        if !self.extra_motor_ut_per_a.is_empty() && self.extra_motor_ut_per_a.len() != motors {
            return Err(c.fail(
                "wiring.extra_motor_ut_per_a",
                format!("{} entries", self.extra_motor_ut_per_a.len()),
                &format!("one [x, y, z] per motor ({motors}) or none"),
            ));
        }
        for (k, g) in self.extra_motor_ut_per_a.iter().enumerate() {
            c.within3(
                &format!("wiring.extra_motor_ut_per_a[{k}]"),
                *g,
                crate::MAX_GAIN_UT_PER_A,
            )?;
        }
        for (k, l) in self.loops.iter().enumerate() {
            let key = format!("wiring.loop[{k}]");
            carrier_ok(&format!("{key}.carries"), l.carries)?;
            c.within3(
                &format!("{key}.center_m"),
                l.center_m,
                crate::MAX_DISTANCE_M,
            )?;
            c.within3(&format!("{key}.normal"), l.normal, 1e3)?;
            if Vec3::from(l.normal).norm() < 1e-9 {
                return Err(c.fail(
                    &format!("{key}.normal"),
                    format!("{:?}", l.normal),
                    "a non-zero vector",
                ));
            }
            c.positive(&format!("{key}.radius_m"), l.radius_m)?;
            if !(3..=10_000).contains(&l.sides) {
                return Err(c.fail(&format!("{key}.sides"), l.sides, "an integer in 3..=10000"));
            }
            c.range(&format!("{key}.scale"), l.scale, -100.0, 100.0)?;
            let v = loop_vertices(l.center_m.into(), l.normal.into(), l.radius_m, l.sides);
            let d = v
                .windows(2)
                .map(|w| distance_to_segment(w[0], w[1], sensor_m))
                .fold(f64::INFINITY, f64::min);
            if d < Self::MIN_CLEARANCE_M {
                return Err(c.fail(
                    &key,
                    format!("{:.4} m from the sensor", d),
                    "a conductor at least 2 mm from the magnetometer",
                ));
            }
        }
        Ok(())
    }

    /// Reduces the geometry to gains at the sensor position `sensor_m`.
    pub fn gains(&self, motors: usize, sensor_m: Vec3) -> WiringGains {
        let mut g = WiringGains {
            total_ut_per_a: Vec3::zeros(),
            motor_ut_per_a: vec![Vec3::zeros(); motors],
        };
        for (carrier, a, b, scale) in self.segments() {
            let f = segment_field_per_amp(a, b, sensor_m) * scale;
            match carrier {
                Carrier::Total => g.total_ut_per_a += f,
                Carrier::Motor(n) => {
                    if let Some(m) = g.motor_ut_per_a.get_mut(n - 1) {
                        *m += f;
                    }
                }
            }
        }
        for (m, extra) in g.motor_ut_per_a.iter_mut().zip(&self.extra_motor_ut_per_a) {
            *m += Vec3::from(*extra);
        }
        g
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn long_segment_matches_the_infinite_wire() {
        // mu0 I / (2 pi d) = 0.2 uT m/A * I / d.
        let d = 0.05;
        let f = segment_field_per_amp(
            Vec3::new(-1e4, 0.0, -d),
            Vec3::new(1e4, 0.0, -d),
            Vec3::zeros(),
        );
        let expected = 0.2 / d;
        assert!(
            (f.norm() - expected).abs() < 1e-6 * expected,
            "{f} vs {expected}"
        );
        // Current along +x below the point (z = -d, with z down means above): right-hand rule.
        assert!(f.y.abs() > 0.99 * f.norm(), "{f}");
    }

    #[test]
    fn finite_segment_matches_the_closed_form() {
        // Perpendicular bisector at distance d of a segment of half-length L:
        // B = mu0 I / (4 pi d) * 2 L / sqrt(L^2 + d^2).
        let (l, d) = (0.03, 0.02);
        let f = segment_field_per_amp(Vec3::new(-l, d, 0.0), Vec3::new(l, d, 0.0), Vec3::zeros());
        let expected = 0.1 / d * 2.0 * l / (l * l + d * d).sqrt();
        assert!(
            (f.norm() - expected).abs() < 1e-12 * expected.max(1.0),
            "{} vs {expected}",
            f.norm()
        );
        // Current +x at y = +d: at the origin (on -y side) B = x cross (-y) = -z.
        assert!(f.z < 0.0, "{f}");
    }

    #[test]
    fn circular_loop_matches_the_on_axis_formula() {
        // B = mu0 I R^2 / (2 (R^2 + z^2)^(3/2)) along the normal.
        let (r, z) = (0.02, 0.05);
        let w = WiringParams {
            segment: vec![],
            loops: vec![LoopParams {
                carries: Carrier::Total,
                center_m: [0.0, 0.0, -z],
                normal: [0.0, 0.0, 1.0],
                radius_m: r,
                sides: 2000,
                scale: 1.0,
            }],
            extra_motor_ut_per_a: Vec::new(),
        };
        let g = w.gains(1, Vec3::zeros()).total_ut_per_a;
        let mu0 = 4.0 * std::f64::consts::PI * MU0_OVER_4PI_UT_M_PER_A;
        let expected = mu0 * r * r / (2.0 * (r * r + z * z).powf(1.5));
        assert!(
            (g.z - expected).abs() < 1e-5 * expected,
            "{} vs {expected}",
            g.z
        );
        assert!(g.x.abs() < 1e-9 && g.y.abs() < 1e-9, "{g}");
    }

    #[test]
    fn twisted_pair_nearly_cancels() {
        let one = segment_field_per_amp(
            Vec3::new(0.0, 0.05, 0.0),
            Vec3::new(0.2, 0.05, 0.0),
            Vec3::zeros(),
        );
        let back = segment_field_per_amp(
            Vec3::new(0.0, 0.051, 0.0),
            Vec3::new(0.2, 0.051, 0.0),
            Vec3::zeros(),
        );
        let pair = one - back;
        assert!(pair.norm() < 0.05 * one.norm(), "{pair} vs {one}");
    }

    #[test]
    fn default_layout_is_sized_like_the_paper() {
        let g = WiringParams::default().gains(4, Vec3::zeros());
        let b = g.field_ut(60.0, &[15.0; 4]);
        assert!((b.norm() - 19.0).abs() < 3.0, "{b}");
        assert!(b.x > 0.0 && b.y > 0.0 && b.z < 0.0, "{b}");
    }

    #[test]
    fn carrier_names_round_trip_and_bad_names_are_refused() {
        assert_eq!(
            Carrier::try_from("motor3".to_string()),
            Ok(Carrier::Motor(3))
        );
        assert_eq!(String::from(Carrier::Total), "total");
        assert!(Carrier::try_from("motor0".to_string()).is_err());
        assert!(Carrier::try_from("battery".to_string()).is_err());
    }
}
