//! Stand modules: the physical parts of the stand beside the motors, the supply and the
//! wiring (board heating, magnetized steel), behind one trait that the simulator
//! ([`crate::simulate`]) and the replay ([`crate::replay`]) both iterate.
//!
//! A module has a state, advances it with the electrical state, adds a field at the sensor,
//! and names the trace column its state is recorded in. A new physical effect is one such
//! file (its parameters, its state and its `impl StandModule`) registered in [`modules`] with
//! one line, plus its diagnosis file in `magstand-diagnose/src/effects/` registered in that
//! crate's catalog. Its parameters still need a field in [`crate::Scenario`] and a line in its
//! check; see the README's worked example.
use magstand_core::Vec3;

use crate::scenario::Scenario;

/// What a module sees of the electrical state at a step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Electrical {
    /// Total supply current, A (motors and avionics).
    pub total_a: f64,
    /// Supply voltage, V.
    pub voltage_v: f64,
}

/// A physical part of the stand with a state and a field at the sensor.
pub trait StandModule: std::fmt::Debug + Send {
    /// The trace column its state is recorded in (`temp_c`, `play_a`).
    fn column(&self) -> &'static str;
    /// The field it adds at the sensor from its state now, µT. A state that follows the
    /// current with no time scale of its own (a play operator) is fed here, once per sample.
    fn field_ut(&mut self, e: Electrical) -> Vec3;
    /// Advances its state over `dt_s` under `e`.
    fn step(&mut self, e: Electrical, dt_s: f64);
    /// Its state, as its trace column records it.
    fn state(&self) -> f64;
    /// Whether its field reaches the sensor from outside (through the sensor's soft iron,
    /// like the wiring's), or arises inside the sensor (an offset drift).
    fn through_soft_iron(&self) -> bool;
}

/// Every module of the stand `s` describes, in the order their fields are added.
pub fn modules(s: &Scenario) -> Vec<Box<dyn StandModule>> {
    vec![
        Box::new(crate::hysteresis::HysteresisModule::new(&s.hysteresis)),
        Box::new(crate::thermal::ThermalModule::new(&s.thermal)),
    ]
}

/// The state of the module recording `column`, if there is one.
pub fn state_of(modules: &[Box<dyn StandModule>], column: &str) -> Option<f64> {
    modules
        .iter()
        .find(|m| m.column() == column)
        .map(|m| m.state())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_module_names_its_own_column() {
        let text = "name = \"t\"\n[program]\nkind = \"stair\"\nsteps = 5\ndwell_s = 2.0\n";
        let s = Scenario::from_toml_str(text, "inline").unwrap();
        let all = modules(&s);
        for (i, m) in all.iter().enumerate() {
            assert!(
                all[..i].iter().all(|o| o.column() != m.column()),
                "two modules record `{}`",
                m.column()
            );
        }
        assert_eq!(
            state_of(&all, crate::thermal::TEMP_C),
            Some(s.thermal.ambient_c)
        );
        assert_eq!(state_of(&all, "nothing"), None);
    }
}
