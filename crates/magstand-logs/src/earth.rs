//! The Earth's field at a place and date: the World Magnetic Model (the
//! `world_magnetic_model` crate, WMM2020 and WMM2025) from 2020 to 2030, and the International
//! Geomagnetic Reference Field (the `igrf` crate, IGRF-13 with its definitive models) from 1900
//! to 2020, so that a log of any year since 1900 has a reference field.
use magstand_core::Vec3;
use world_magnetic_model::GeomagneticField;
use world_magnetic_model::time::Date;
use world_magnetic_model::uom::si::angle::degree;
use world_magnetic_model::uom::si::f32::{Angle, Length};
use world_magnetic_model::uom::si::length::meter;
use world_magnetic_model::uom::si::magnetic_flux_density::nanotesla;

use crate::LogsError;

/// First year the World Magnetic Model covers; earlier dates use IGRF.
pub const WMM_FROM_YEAR: f64 = 2020.0;
/// First year of IGRF-13.
pub const IGRF_FROM_YEAR: f64 = 1900.0;
/// End of the World Magnetic Model's validity.
pub const WMM_UNTIL_YEAR: f64 = 2030.0;

/// The Earth's field at one place and date, and the model that gave it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EarthFieldAt {
    /// North-east-down, µT.
    pub ned_ut: Vec3,
    /// "WMM" or "IGRF-13".
    pub model: &'static str,
}

impl EarthFieldAt {
    /// Inclination below the horizontal, degrees.
    pub fn inclination_deg(&self) -> f64 {
        self.ned_ut.z.atan2(self.ned_ut.xy().norm()).to_degrees()
    }
}

/// The field at latitude and longitude (degrees), altitude (m) and date (decimal year):
/// the WMM from 2020 to 2030, IGRF-13 from 1900 to 2020.
pub fn earth_field(
    lat_deg: f64,
    lon_deg: f64,
    alt_m: f64,
    year: f64,
) -> Result<EarthFieldAt, LogsError> {
    let bad = |what: String| LogsError::EarthModel(what);
    if !(-90.0..=90.0).contains(&lat_deg) || !(-180.0..=360.0).contains(&lon_deg) {
        return Err(bad(format!(
            "latitude {lat_deg} / longitude {lon_deg}: expected -90..90 and -180..360 degrees"
        )));
    }
    if !alt_m.is_finite() || !(-1e4..=1e6).contains(&alt_m) {
        return Err(bad(format!(
            "altitude {alt_m} m: expected -10 000 to 1 000 000 m"
        )));
    }
    if !(IGRF_FROM_YEAR..WMM_UNTIL_YEAR).contains(&year) {
        return Err(bad(format!(
            "year {year}: the Earth-field models cover {IGRF_FROM_YEAR} to {WMM_UNTIL_YEAR} (IGRF-13 before {WMM_FROM_YEAR}, the WMM after)"
        )));
    }
    let y = year.floor() as i32;
    let day = (((year - year.floor()) * 365.0).floor() as u16 + 1).min(365);
    let date = Date::from_ordinal_date(y, day).map_err(|e| bad(format!("year {year}: {e}")))?;
    if year >= WMM_FROM_YEAR {
        wmm(lat_deg, lon_deg, alt_m, year, date)
    } else {
        igrf_field(lat_deg, lon_deg, alt_m, year, date)
    }
}

fn wmm(
    lat_deg: f64,
    lon_deg: f64,
    alt_m: f64,
    year: f64,
    date: Date,
) -> Result<EarthFieldAt, LogsError> {
    let f = GeomagneticField::new(
        Length::new::<meter>(alt_m as f32),
        Angle::new::<degree>(lat_deg as f32),
        Angle::new::<degree>(lon_deg as f32),
        date,
    )
    .map_err(|e| {
        LogsError::EarthModel(format!(
            "the World Magnetic Model has no field for {lat_deg}, {lon_deg}, {year:.2}: {e}"
        ))
    })?;
    let ut = |b: world_magnetic_model::uom::si::f32::MagneticFluxDensity| {
        b.get::<nanotesla>() as f64 * 1e-3
    };
    Ok(EarthFieldAt {
        ned_ut: Vec3::new(ut(f.x()), ut(f.y()), ut(f.z())),
        model: "WMM",
    })
}

fn igrf_field(
    lat_deg: f64,
    lon_deg: f64,
    alt_m: f64,
    year: f64,
    date: Date,
) -> Result<EarthFieldAt, LogsError> {
    // The crate takes whole metres above sea level; below it the field differs by far less
    // than a magnetometer resolves.
    let lon = if lon_deg > 180.0 {
        lon_deg - 360.0
    } else {
        lon_deg
    };
    let f = igrf::declination(lat_deg, lon, alt_m.max(0.0).round() as u32, date).map_err(|e| {
        LogsError::EarthModel(format!(
            "IGRF-13 has no field for {lat_deg}, {lon_deg}, {year:.2}: {e}"
        ))
    })?;
    let v = Vec3::new(f.x, f.y, f.z) * 1e-3;
    if !v.iter().all(|c| c.is_finite()) {
        return Err(LogsError::EarthModel(format!(
            "IGRF-13 gave no finite field for {lat_deg}, {lon_deg}, {year:.2}"
        )));
    }
    Ok(EarthFieldAt {
        ned_ut: v,
        model: "IGRF-13",
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn field_near_boulder_in_2025_is_the_published_one() {
        // NOAA's calculator for 40 N, 105 W, sea level, 2025.0: intensity about 52 µT,
        // inclination about 66 degrees down, declination about 7.7 degrees east.
        let e = earth_field(40.0, -105.0, 0.0, 2025.0).unwrap().ned_ut;
        let total = e.norm();
        let incl = (e.z / e.xy().norm()).atan().to_degrees();
        assert!((50.0..55.0).contains(&total), "{e:?}");
        assert!((64.0..68.0).contains(&incl), "{incl}");
        let decl = e.y.atan2(e.x).to_degrees();
        assert!((6.5..9.0).contains(&decl), "{decl}");
    }

    /// Regression: `--earth wmm` covered 2020 to 2029 only, so a 2015 log failed, and the
    /// error said "cannot export" during `fit`. IGRF now covers the years before 2020.
    #[test]
    fn dates_before_2020_use_igrf_and_meet_the_wmm_at_2020() {
        let old = earth_field(40.0, -105.0, 1600.0, 2015.0).unwrap();
        assert_eq!(old.model, "IGRF-13");
        // Boulder 2015 (NOAA IGRF calculator): about 52.4 µT, inclination 66 degrees, declination
        // 8.5 degrees east.
        assert!((51.0..54.0).contains(&old.ned_ut.norm()), "{old:?}");
        assert!((65.0..67.5).contains(&old.inclination_deg()), "{old:?}");
        let decl = old.ned_ut.y.atan2(old.ned_ut.x).to_degrees();
        assert!((7.5..9.5).contains(&decl), "{decl}");
        // Two models, one field: where they meet they agree to well under a microtesla.
        for (lat, lon) in [
            (40.0, -105.0),
            (-35.36, 149.17),
            (51.5, -0.1),
            (-23.5, -46.6),
        ] {
            let a = earth_field(lat, lon, 0.0, 2019.999).unwrap();
            let b = earth_field(lat, lon, 0.0, 2020.0).unwrap();
            assert_eq!((a.model, b.model), ("IGRF-13", "WMM"));
            assert!(
                (a.ned_ut - b.ned_ut).norm() < 0.5,
                "{lat}, {lon}: IGRF {:?} WMM {:?}",
                a.ned_ut,
                b.ned_ut
            );
        }
    }

    #[test]
    fn out_of_range_inputs_are_errors_naming_them() {
        let e = earth_field(40.0, -105.0, 0.0, 1850.0)
            .unwrap_err()
            .to_string();
        assert!(e.contains("1850") && e.contains("1900"), "{e}");
        assert!(!e.contains("export"), "{e}");
        let e = earth_field(40.0, -105.0, 0.0, 2031.0)
            .unwrap_err()
            .to_string();
        assert!(e.contains("2031") && e.contains("2030"), "{e}");
        assert!(earth_field(95.0, 0.0, 0.0, 2025.0).is_err());
        assert!(earth_field(40.0, 0.0, f64::NAN, 2025.0).is_err());
        assert!(earth_field(40.0, 0.0, 0.0, f64::NAN).is_err());
    }
}
