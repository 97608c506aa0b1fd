//! Property test of the scenario format: a shipped scenario with one number replaced by a
//! hostile value (1e308, 1e-300, a negative count, 2^63) is either refused naming the key,
//! or it is a stand whose work is within the documented bound and whose simulation writes
//! only finite numbers.
//!
//! This is the class of defect where `program.dwell_s = 1e9` tried to allocate 16 TB and
//! `magnetometer.soft_iron` rows of 1e308 wrote NaN into recording.csv.
use magstand_core::recording_csv;
use magstand_sim::program::MAX_PROGRAM_S;
use magstand_sim::{Scenario, builtin, simulate};
use proptest::prelude::*;

/// Shipped stairs whose effects (paper tables, heating, hysteresis, a battery) are all in
/// play, shortened so that one case simulates in milliseconds.
const BASES: [&str; 4] = ["czyba2015-tables", "thermal", "hysteresis", "battery-sag"];
const SHORT: [&str; 6] = [
    "program.off_s=0.5",
    "program.steps=5",
    "program.dwell_s=0.3",
    "program.repeats=1",
    "program.direction=\"up\"",
    "stand.enabled=false",
];
/// The most physics steps a case may simulate; an accepted scenario above it is only
/// checked against the documented bound.
const STEP_BUDGET: f64 = 50_000.0;

fn base_table(name: &str) -> toml::Table {
    let s = Scenario::from_toml_with_overrides(
        builtin::get(name).unwrap(),
        name,
        &SHORT.map(String::from),
    )
    .unwrap();
    toml::Table::try_from(&s).unwrap()
}

/// Dotted paths of every number in `t`.
fn number_keys(t: &toml::Table, prefix: &str, out: &mut Vec<String>) {
    for (k, v) in t {
        let key = format!("{prefix}{k}");
        match v {
            toml::Value::Integer(_) | toml::Value::Float(_) => out.push(key),
            toml::Value::Table(inner) => number_keys(inner, &format!("{key}."), out),
            toml::Value::Array(a) => {
                for (i, x) in a.iter().enumerate() {
                    match x {
                        toml::Value::Integer(_) | toml::Value::Float(_) => {
                            out.push(format!("{key}[{i}]"))
                        }
                        toml::Value::Array(row) => {
                            for j in 0..row.len() {
                                out.push(format!("{key}[{i}][{j}]"));
                            }
                        }
                        _ => {}
                    }
                }
            }
            _ => {}
        }
    }
}

fn hostile_toml_value() -> impl Strategy<Value = String> {
    prop_oneof![
        magstand_core::file_fuzzing::hostile_f64().prop_map(|x| format!("{x:e}")),
        Just("-1".to_string()),
        Just("0".to_string()),
        Just("9223372036854775807".to_string()),
        Just("100000".to_string()),
        Just("\"abc\"".to_string()),
    ]
}

proptest! {
    #![proptest_config(magstand_core::file_fuzzing::config(128))]

    #[test]
    fn a_crafted_scenario_is_refused_by_key_or_simulates_finite(
        base in 0usize..BASES.len(),
        pick in 0usize..10_000,
        value in hostile_toml_value(),
    ) {
        let name = BASES[base];
        let table = base_table(name);
        let mut keys = Vec::new();
        number_keys(&table, "", &mut keys);
        let key = keys[pick % keys.len()].clone();
        let text = toml::to_string(&table).unwrap();
        let set = format!("{}={value}", key.replace("][", "].["));
        let loaded = Scenario::from_toml_with_overrides(&text, name, std::slice::from_ref(&set))
            .and_then(|s| s.check(name, None));
        let scenario = match loaded {
            Err(e) => {
                let e = e.to_string();
                let top = key.split(['.', '[']).next().unwrap();
                prop_assert!(e.contains(top), "--set {set} refused without naming it: {e}");
                return Ok(());
            }
            Ok(s) => s,
        };
        let p = scenario.params();
        let duration_s = p.program.duration_bound_s(p.motors.count);
        prop_assert!(
            duration_s <= MAX_PROGRAM_S && p.physics_hz <= 100_000.0,
            "--set {set} accepted {duration_s} s at {} Hz", p.physics_hz
        );
        if duration_s * p.physics_hz <= STEP_BUDGET {
            let rec = simulate(&scenario, 1);
            let mut out = Vec::new();
            let written = recording_csv::write_to(&rec, &mut out, std::path::Path::new("r.csv"));
            prop_assert!(written.is_ok(), "--set {set}: {}", written.unwrap_err());
        }
    }
}
