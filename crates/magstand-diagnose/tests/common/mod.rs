//! Scenario and diagnosis set-up shared by the integration tests.
#![allow(dead_code)] // each test file uses part of it
use magstand_core::Recording;
use magstand_diagnose::{DiagnoseConfig, Diagnosis, diagnose};
use magstand_sim::{Scenario, ValidScenario, builtin};

/// The shipped bench-supply stair as the nominal stand, and the same stand run up and down
/// twice with `overrides` as the stand the recording comes from.
pub fn bench_supply_stair(overrides: &[&str]) -> (ValidScenario, ValidScenario) {
    let text = builtin::get("bench-supply-stair").unwrap();
    let nominal = Scenario::from_toml_str(text, "nominal")
        .unwrap()
        .check("nominal", None)
        .unwrap();
    let mut o = vec![
        "program.direction=\"up_down\"".to_string(),
        "program.repeats=2".into(),
    ];
    o.extend(overrides.iter().map(|s| s.to_string()));
    let real = Scenario::from_toml_with_overrides(text, "real", &o)
        .unwrap()
        .check("real", None)
        .unwrap();
    (nominal, real)
}

/// Diagnoses `rec` (named `origin`) against `nominal` with the default settings.
pub fn diagnose_default(rec: &Recording, origin: &str, nominal: &ValidScenario) -> Diagnosis {
    diagnose(
        rec,
        origin,
        nominal,
        &DiagnoseConfig::default().check().unwrap(),
    )
    .unwrap()
}

/// Standard normal draws from a fixed xorshift stream (Box-Muller): a test that writes its
/// own recording owns its noise too.
pub struct Normal(pub u64);

impl Normal {
    fn uniform(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        ((self.0 >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }

    /// The next draw.
    pub fn draw(&mut self) -> f64 {
        let (u, v) = (self.uniform(), self.uniform());
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }
}
