//! Stand modules: the physical parts of the stand beside the motors, the supply and the
//! wiring (board heating, magnetized steel), behind one trait that the simulator
//! ([`crate::simulate`]) and the replay ([`crate::replay`]) both iterate.
//!
//! A module has a state, advances it with the electrical state, adds a field at the sensor,
//! and names the trace column its state is recorded in. Its parameters, a scenario table, say
//! how they are checked and build the module (`ModuleParams`). A new physical effect is one
//! such file (its parameters, its state, `impl ModuleParams` and `impl StandModule`), its table
//! as a field of [`crate::Scenario`], and one line in `Scenario::module_params`, which both the
//! scenario's check and [`modules`] iterate; plus its diagnosis file in
//! `magstand-diagnose/src/effects/` registered in that crate's catalog. See the README's worked
//! example.
use magstand_core::Vec3;

use crate::error::{Checker, SimError};
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
    /// A copy in the same state (a replay reads a late magnetometer from copies stepped on
    /// between rows).
    fn boxed_clone(&self) -> Box<dyn StandModule>;
}

impl Clone for Box<dyn StandModule> {
    fn clone(&self) -> Self {
        self.boxed_clone()
    }
}

/// A stand module's scenario table: its keys checked, and the module built from them.
pub(crate) trait ModuleParams: std::fmt::Debug {
    /// The scenario table's name (`thermal`), the prefix of every key its check names.
    fn table(&self) -> &'static str;
    /// Checks every value against its allowed range, naming the key of the first that is not;
    /// `c` writes the table's name before each key.
    fn check(&self, c: &Checker) -> Result<(), SimError>;
    /// The module in its starting state.
    fn build(&self) -> Box<dyn StandModule>;
    /// Whether the module adds a field at the sensor (it is switched on); one that does not
    /// still has a state (a board heats whether or not its sensor drifts with it).
    fn adds_field(&self) -> bool;
}

/// Every module of the stand `s` describes, in the order their fields are added.
pub fn modules(s: &Scenario) -> Vec<Box<dyn StandModule>> {
    s.module_params().iter().map(|p| p.build()).collect()
}

/// The modules of the stand `s` that add a field at the sensor, in the order their fields are
/// added: what shapes the field, where a switched-off module's state is not wanted.
pub fn field_modules(s: &Scenario) -> Vec<Box<dyn StandModule>> {
    s.module_params()
        .iter()
        .filter(|p| p.adds_field())
        .map(|p| p.build())
        .collect()
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

    #[test]
    fn a_module_table_is_checked_through_its_registration() {
        let text = "name = \"t\"\n[program]\nkind = \"stair\"\nsteps = 5\ndwell_s = 2.0\n\
                    [hysteresis]\nplay_a = -1.0\n";
        let e = Scenario::from_toml_str(text, "inline")
            .unwrap()
            .check("inline", None)
            .unwrap_err()
            .to_string();
        assert!(e.contains("hysteresis.play_a"), "{e}");
        let s = Scenario::from_toml_str(text.replace("-1.0", "1.0").as_str(), "inline").unwrap();
        let tables: Vec<_> = s.module_params().iter().map(|p| p.table()).collect();
        assert_eq!(tables, ["hysteresis", "thermal"]);
        assert_eq!(modules(&s).len(), tables.len());
    }
}
