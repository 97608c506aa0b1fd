//! Power supply: an ideal bench supply, or a lithium-polymer battery whose open-circuit
//! voltage falls with the charge drawn and whose internal resistance makes it sag under load.
use serde::{Deserialize, Serialize};

use crate::error::{Checker, SimError};

/// Open-circuit voltage of one LiPo cell against state of charge (0..1), a typical
/// discharge curve at low rate.
const LIPO_OCV: [(f64, f64); 13] = [
    (0.00, 3.27),
    (0.05, 3.61),
    (0.10, 3.69),
    (0.15, 3.71),
    (0.20, 3.73),
    (0.30, 3.77),
    (0.40, 3.80),
    (0.50, 3.84),
    (0.60, 3.87),
    (0.70, 3.92),
    (0.80, 3.98),
    (0.90, 4.06),
    (1.00, 4.20),
];

/// Open-circuit voltage of one LiPo cell at state of charge `soc` (clamped to 0..1).
pub fn lipo_cell_ocv_v(soc: f64) -> f64 {
    let s = soc.clamp(0.0, 1.0);
    let k = LIPO_OCV
        .iter()
        .position(|&(x, _)| x >= s)
        .unwrap_or(LIPO_OCV.len() - 1)
        .max(1);
    let ((x0, y0), (x1, y1)) = (LIPO_OCV[k - 1], LIPO_OCV[k]);
    y0 + (y1 - y0) * (s - x0) / (x1 - x0)
}

/// Which supply powers the stand.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum SupplyParams {
    /// A laboratory supply: constant voltage behind a small source resistance.
    Bench {
        /// Set voltage, V.
        voltage_v: f64,
        /// Source plus lead resistance, ohm.
        #[serde(default)]
        source_resistance_ohm: f64,
        /// Current of the flight controller and receivers, A (flows through the supply leads).
        #[serde(default = "default_avionics")]
        avionics_current_a: f64,
    },
    /// A LiPo battery.
    Battery {
        /// Cells in series.
        cells: u32,
        /// Capacity, ampere-hours.
        capacity_ah: f64,
        /// Internal plus lead resistance of the whole pack, ohm.
        internal_resistance_ohm: f64,
        /// State of charge at the start, 0..1.
        #[serde(default = "one")]
        initial_charge: f64,
        /// Current of the flight controller and receivers, A.
        #[serde(default = "default_avionics")]
        avionics_current_a: f64,
    },
}

fn one() -> f64 {
    1.0
}
fn default_avionics() -> f64 {
    0.3
}

impl Default for SupplyParams {
    fn default() -> Self {
        SupplyParams::Battery {
            cells: 3,
            capacity_ah: 2.2,
            internal_resistance_ohm: 0.03,
            initial_charge: 1.0,
            avionics_current_a: default_avionics(),
        }
    }
}

impl SupplyParams {
    pub(crate) fn check(&self, c: &Checker) -> Result<(), SimError> {
        match *self {
            SupplyParams::Bench {
                voltage_v,
                source_resistance_ohm,
                avionics_current_a,
            } => {
                c.range("supply.voltage_v", voltage_v, 1.0, 100.0)?;
                c.range(
                    "supply.source_resistance_ohm",
                    source_resistance_ohm,
                    0.0,
                    10.0,
                )?;
                c.range("supply.avionics_current_a", avionics_current_a, 0.0, 50.0)
            }
            SupplyParams::Battery {
                cells,
                capacity_ah,
                internal_resistance_ohm,
                initial_charge,
                avionics_current_a,
            } => {
                if !(1..=14).contains(&cells) {
                    return Err(c.fail("supply.cells", cells, "an integer in 1..=14"));
                }
                c.positive("supply.capacity_ah", capacity_ah)?;
                c.range(
                    "supply.internal_resistance_ohm",
                    internal_resistance_ohm,
                    0.0,
                    10.0,
                )?;
                c.range("supply.initial_charge", initial_charge, 0.0, 1.0)?;
                c.range("supply.avionics_current_a", avionics_current_a, 0.0, 50.0)
            }
        }
    }

    /// Checks that the supply can drive `idle_load_a` (the avionics' and every driven motor's
    /// idle current, A) at the start: a source resistance that would take its terminal voltage
    /// to zero or below under that load describes no stand that runs, and the simulated
    /// motors would draw their idle current at a negative voltage (a 12 V bench behind 10 ohm
    /// read -7 V with four motors idling).
    pub(crate) fn check_idle_load(&self, c: &Checker, idle_load_a: f64) -> Result<(), SimError> {
        let (key, resistance_ohm) = match *self {
            SupplyParams::Bench {
                source_resistance_ohm,
                ..
            } => ("supply.source_resistance_ohm", source_resistance_ohm),
            SupplyParams::Battery {
                internal_resistance_ohm,
                ..
            } => ("supply.internal_resistance_ohm", internal_resistance_ohm),
        };
        let open_v = self.no_load_voltage_v();
        let loaded_v = open_v - resistance_ohm * idle_load_a;
        if loaded_v > 0.0 {
            return Ok(());
        }
        Err(c.fail(
            key,
            resistance_ohm,
            &format!(
                "a resistance below {:.4} ohm: the supply's {open_v:.2} V cannot drive the stand's idle load of {idle_load_a:.2} A (supply.avionics_current_a and motors.count x motors.idle_current_a) through it, its terminal voltage would be {loaded_v:.2} V",
                open_v / idle_load_a
            ),
        ))
    }

    /// Terminal voltage at the start, with no load, V.
    pub fn no_load_voltage_v(&self) -> f64 {
        SupplyState::default().voltage_v(self, 0.0)
    }

    /// Current drawn by the avionics, A.
    pub fn avionics_current_a(&self) -> f64 {
        match *self {
            SupplyParams::Bench {
                avionics_current_a, ..
            }
            | SupplyParams::Battery {
                avionics_current_a, ..
            } => avionics_current_a,
        }
    }
}

/// Supply state: charge drawn so far.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SupplyState {
    /// Charge drawn since the start, ampere-hours.
    pub drawn_ah: f64,
}

impl SupplyState {
    /// Terminal voltage while `current_a` flows.
    pub fn voltage_v(&self, p: &SupplyParams, current_a: f64) -> f64 {
        match *p {
            SupplyParams::Bench {
                voltage_v,
                source_resistance_ohm,
                ..
            } => voltage_v - source_resistance_ohm * current_a,
            SupplyParams::Battery {
                cells,
                capacity_ah,
                internal_resistance_ohm,
                initial_charge,
                ..
            } => {
                let soc = initial_charge - self.drawn_ah / capacity_ah;
                cells as f64 * lipo_cell_ocv_v(soc) - internal_resistance_ohm * current_a
            }
        }
    }

    /// Draws `current_a` for `dt_s`.
    pub fn step(&mut self, current_a: f64, dt_s: f64) {
        self.drawn_ah += current_a * dt_s / 3600.0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ocv_matches_its_table_and_interpolates() {
        assert_eq!(lipo_cell_ocv_v(1.0), 4.20);
        assert_eq!(lipo_cell_ocv_v(0.0), 3.27);
        assert!((lipo_cell_ocv_v(0.55) - 3.855).abs() < 1e-12);
        assert_eq!(lipo_cell_ocv_v(-1.0), 3.27);
    }

    #[test]
    fn battery_discharge_follows_charge_drawn_and_sags_under_load() {
        let p = SupplyParams::Battery {
            cells: 3,
            capacity_ah: 2.0,
            internal_resistance_ohm: 0.05,
            initial_charge: 1.0,
            avionics_current_a: 0.0,
        };
        let mut s = SupplyState::default();
        assert!((s.voltage_v(&p, 0.0) - 12.6).abs() < 1e-12);
        assert!((s.voltage_v(&p, 40.0) - (12.6 - 2.0)).abs() < 1e-12);
        // 1 A for one hour from 2 Ah: half charge, 3 x 3.84 V.
        for _ in 0..3600 {
            s.step(1.0, 1.0);
        }
        assert!((s.drawn_ah - 1.0).abs() < 1e-9);
        assert!(
            (s.voltage_v(&p, 0.0) - 11.52).abs() < 1e-9,
            "{}",
            s.voltage_v(&p, 0.0)
        );
    }

    #[test]
    fn bench_supply_is_constant_over_a_run() {
        let p = SupplyParams::Bench {
            voltage_v: 12.0,
            source_resistance_ohm: 0.0,
            avionics_current_a: 0.3,
        };
        let mut s = SupplyState::default();
        s.step(50.0, 3600.0);
        assert_eq!(s.voltage_v(&p, 50.0), 12.0);
    }
}
