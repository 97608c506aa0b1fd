//! The magnetometer: Earth field, the sensor's hard and soft iron, range saturation,
//! quantization and output data rate.
use nalgebra::Matrix3;
use serde::{Deserialize, Serialize};

use crate::error::{Checker, SimError};
use magstand_core::Vec3;

/// The Earth field at the stand, either by its elements or as a north-east-down vector.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum EarthField {
    /// Total intensity, inclination (dip, positive down) and declination (east of north).
    Elements {
        /// Total intensity, µT.
        intensity_ut: f64,
        /// Inclination, degrees.
        inclination_deg: f64,
        /// Declination, degrees.
        declination_deg: f64,
    },
    /// The field vector in north-east-down, µT.
    Vector {
        /// North, east, down components, µT.
        ned_ut: [f64; 3],
    },
}

impl EarthField {
    /// North-east-down field vector, µT.
    pub fn ned_ut(&self) -> Vec3 {
        match *self {
            EarthField::Elements {
                intensity_ut,
                inclination_deg,
                declination_deg,
            } => {
                let (i, d) = (inclination_deg.to_radians(), declination_deg.to_radians());
                intensity_ut * Vec3::new(i.cos() * d.cos(), i.cos() * d.sin(), i.sin())
            }
            EarthField::Vector { ned_ut } => ned_ut.into(),
        }
    }
}

/// Magnetometer parameters.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MagnetometerParams {
    /// Sensor position in the body frame, m (conductors are placed in the same frame).
    pub position_m: [f64; 3],
    /// Output data rate, Hz: one recording row per sample.
    pub odr_hz: f64,
    /// The Earth field at the stand (Gliwice, Poland, by default: 50 µT, 67° dip).
    pub earth: EarthField,
    /// Hard-iron offset of the sensor and its board, µT.
    pub hard_iron_ut: [f64; 3],
    /// Soft-iron matrix (rows), applied to every external field.
    pub soft_iron: [[f64; 3]; 3],
    /// Quantization step, µT (0 for none).
    pub quantization_ut: f64,
    /// Measurement range, ± µT per axis; readings saturate there.
    pub range_ut: f64,
}

impl Default for MagnetometerParams {
    fn default() -> Self {
        Self {
            position_m: [0.0; 3],
            odr_hz: 100.0,
            earth: EarthField::Elements {
                intensity_ut: 50.0,
                inclination_deg: 67.0,
                declination_deg: 5.5,
            },
            hard_iron_ut: [0.0; 3],
            soft_iron: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            quantization_ut: 0.092,
            range_ut: 800.0,
        }
    }
}

impl MagnetometerParams {
    pub(crate) fn check(&self, c: &Checker, physics_hz: f64) -> Result<(), SimError> {
        c.within3(
            "magnetometer.position_m",
            self.position_m,
            crate::MAX_DISTANCE_M,
        )?;
        c.range("magnetometer.odr_hz", self.odr_hz, 1e-3, physics_hz)
            .map_err(|_| {
                c.fail(
                    "magnetometer.odr_hz",
                    self.odr_hz,
                    &format!("a rate > 0 and at most physics_hz ({physics_hz})"),
                )
            })?;
        match self.earth {
            EarthField::Elements {
                intensity_ut,
                inclination_deg,
                declination_deg,
            } => {
                c.range("magnetometer.earth.intensity_ut", intensity_ut, 0.0, 1000.0)?;
                c.range(
                    "magnetometer.earth.inclination_deg",
                    inclination_deg,
                    -90.0,
                    90.0,
                )?;
                c.range(
                    "magnetometer.earth.declination_deg",
                    declination_deg,
                    -180.0,
                    180.0,
                )?;
            }
            EarthField::Vector { ned_ut } => {
                c.within3("magnetometer.earth.ned_ut", ned_ut, 1000.0)?
            }
        }
        c.within3(
            "magnetometer.hard_iron_ut",
            self.hard_iron_ut,
            crate::MAX_FIELD_UT,
        )?;
        for (k, row) in self.soft_iron.iter().enumerate() {
            c.within3(&format!("magnetometer.soft_iron[{k}]"), *row, 100.0)?;
        }
        if self.soft_iron_matrix().determinant().abs() < 1e-6 {
            return Err(c.fail(
                "magnetometer.soft_iron",
                format!("{:?}", self.soft_iron),
                "an invertible matrix",
            ));
        }
        c.range(
            "magnetometer.quantization_ut",
            self.quantization_ut,
            0.0,
            100.0,
        )?;
        c.range(
            "magnetometer.range_ut",
            self.range_ut,
            1e-3,
            crate::MAX_FIELD_UT * 10.0,
        )
    }

    /// Soft-iron matrix.
    pub fn soft_iron_matrix(&self) -> Matrix3<f64> {
        let s = &self.soft_iron;
        Matrix3::new(
            s[0][0], s[0][1], s[0][2], s[1][0], s[1][1], s[1][2], s[2][0], s[2][1], s[2][2],
        )
    }

    /// What the converter outputs for a true reading: saturation at the range, then
    /// quantization to the step.
    pub fn digitize(&self, reading_ut: Vec3) -> Vec3 {
        reading_ut.map(|v| {
            let v = v.clamp(-self.range_ut, self.range_ut);
            if self.quantization_ut > 0.0 {
                (v / self.quantization_ut).round() * self.quantization_ut
            } else {
                v
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn elements_give_the_expected_ned_vector() {
        let e = EarthField::Elements {
            intensity_ut: 50.0,
            inclination_deg: 60.0,
            declination_deg: 90.0,
        };
        let v = e.ned_ut();
        assert!(
            v.x.abs() < 1e-12
                && (v.y - 25.0).abs() < 1e-12
                && (v.z - 50.0 * 60f64.to_radians().sin()).abs() < 1e-12,
            "{v}"
        );
        assert!((v.norm() - 50.0).abs() < 1e-12);
    }

    #[test]
    fn digitize_saturates_and_quantizes() {
        let p = MagnetometerParams {
            quantization_ut: 0.5,
            range_ut: 100.0,
            ..Default::default()
        };
        let d = p.digitize(Vec3::new(0.74, -250.0, 0.26));
        assert_eq!(d, Vec3::new(0.5, -100.0, 0.5));
    }
}
