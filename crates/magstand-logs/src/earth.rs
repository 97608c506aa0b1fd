//! The Earth's field at a place and date from the World Magnetic Model (the
//! `world_magnetic_model` crate, WMM2020 and WMM2025, valid 2020 to 2030).
use magstand_core::Vec3;
use world_magnetic_model::GeomagneticField;
use world_magnetic_model::time::Date;
use world_magnetic_model::uom::si::angle::degree;
use world_magnetic_model::uom::si::f32::{Angle, Length};
use world_magnetic_model::uom::si::length::meter;
use world_magnetic_model::uom::si::magnetic_flux_density::nanotesla;

use crate::LogsError;

/// The field in north-east-down, µT, at latitude and longitude (degrees), altitude (m) and
/// date (decimal year).
pub fn wmm_ned_ut(lat_deg: f64, lon_deg: f64, alt_m: f64, year: f64) -> Result<Vec3, LogsError> {
    let bad = |what: String| LogsError::Export(what);
    if !(-90.0..=90.0).contains(&lat_deg) || !(-180.0..=360.0).contains(&lon_deg) {
        return Err(bad(format!(
            "latitude {lat_deg} / longitude {lon_deg}: expected -90..90 and -180..360 degrees"
        )));
    }
    if !year.is_finite() {
        return Err(bad(format!("year {year}: expected a decimal year")));
    }
    let y = year.floor() as i32;
    let day = (((year - year.floor()) * 365.0).floor() as u16 + 1).min(365);
    let date = Date::from_ordinal_date(y, day).map_err(|e| bad(format!("year {year}: {e}")))?;
    let f = GeomagneticField::new(
        Length::new::<meter>(alt_m as f32),
        Angle::new::<degree>(lat_deg as f32),
        Angle::new::<degree>(lon_deg as f32),
        date,
    )
    .map_err(|e| {
        bad(format!(
            "the World Magnetic Model has no field for {lat_deg}, {lon_deg}, {year:.2}: {e}"
        ))
    })?;
    let ut = |b: world_magnetic_model::uom::si::f32::MagneticFluxDensity| {
        b.get::<nanotesla>() as f64 * 1e-3
    };
    Ok(Vec3::new(ut(f.x()), ut(f.y()), ut(f.z())))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn field_near_boulder_in_2025_is_the_published_one() {
        // NOAA's calculator for 40 N, 105 W, sea level, 2025.0: intensity about 52 µT,
        // inclination about 66 degrees down, declination about 7.7 degrees east.
        let e = wmm_ned_ut(40.0, -105.0, 0.0, 2025.0).unwrap();
        let total = e.norm();
        let incl = (e.z / e.xy().norm()).atan().to_degrees();
        assert!((50.0..55.0).contains(&total), "{e:?}");
        assert!((64.0..68.0).contains(&incl), "{incl}");
        let decl = e.y.atan2(e.x).to_degrees();
        assert!((6.5..9.0).contains(&decl), "{decl}");
    }

    #[test]
    fn out_of_range_dates_are_errors() {
        let e = wmm_ned_ut(40.0, -105.0, 0.0, 2015.0)
            .unwrap_err()
            .to_string();
        assert!(e.contains("2015"), "{e}");
        assert!(wmm_ned_ut(95.0, 0.0, 0.0, 2025.0).is_err());
    }
}
