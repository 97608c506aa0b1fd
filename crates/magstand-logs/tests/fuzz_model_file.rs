//! Property test of the model file format (`magstand fit --model-out`): a valid model with
//! one number replaced by a hostile value (1e308, 1e-300, 2^64, a negative count, a string)
//! is either refused at load, or everything derived from it is finite: the compensated
//! recording (written through the recording CSV writer, which refuses non-finite cells),
//! the autopilot lines and their parameter files, and the C header.
//!
//! This is the class of defect where a model of `width 1e300` compensated to all-NaN columns
//! and a coefficient of 1e308 exported `CAL_MAG0_XCOMP -inf`.
use magstand_core::file_fuzzing::{hostile_json_value, mutate_json_number};
use magstand_core::recording_csv;
use magstand_ident::{Dataset, Fit, FitConfig, InputKind, Model};
use magstand_logs::export::{
    LineInput, Span, ardupilot_params, c_header, linear_approximation, px4_params,
};
use proptest::prelude::*;

fn small_stair() -> magstand_core::Recording {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../tests/data/bad-inputs/small-stair.csv");
    recording_csv::read(&path).unwrap()
}

/// A fitted model (automatic structure) as the JSON `save` writes.
fn model_text(rec: &magstand_core::Recording) -> String {
    let data = Dataset::from_recording(rec, InputKind::Throttle, "small-stair").unwrap();
    let model = FitConfig::automatic().check().unwrap().fit(&data).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("model.json");
    model.save(&path).unwrap();
    std::fs::read_to_string(path).unwrap()
}

/// Fails on the words Rust prints for non-finite numbers (`NaN`, `inf`); the C header's own
/// `INFINITY` (the start of a minimum search) is code, not a value.
fn finite_text(what: &str, text: &str) {
    let bad = magstand_core::file_fuzzing::non_finite_word(text);
    assert!(bad.is_none(), "{what} holds {bad:?}:\n{text}");
}

proptest! {
    #![proptest_config(magstand_core::file_fuzzing::config(128))]

    #[test]
    fn a_crafted_model_is_refused_or_gives_finite_outputs(
        pick in 0usize..10_000,
        value in hostile_json_value(),
    ) {
        thread_local! {
            static BASE: (magstand_core::Recording, String) = {
                let rec = small_stair();
                let text = model_text(&rec);
                (rec, text)
            };
        }
        BASE.with(|(rec, text)| {
            let crafted = mutate_json_number(text, pick, value.clone());
            let Ok(model) = Model::from_json(&crafted, "crafted.json") else {
                return;
            };
            let out = model
                .compensate(rec, "small-stair.csv")
                .unwrap_or_else(|e| panic!("a loaded model must compensate ({value}): {e}"));
            let dist = model.dist_column(rec);
            let sd: Vec<_> = (0..rec.len()).map(|r| model.sd_at(rec, r)).collect();
            for (r, (m, (d, s))) in out.mag_ut.iter().zip(dist.iter().zip(&sd)).enumerate() {
                assert!(
                    m.iter().chain(d.iter()).chain(s.iter()).all(|x| x.is_finite()),
                    "{value} at number {pick}: row {r} compensated {m:?}, disturbance {d:?}, sd {s:?}"
                );
            }
            // A finite but huge result is refused by the writer by name, never written.
            let mut csv = Vec::new();
            if let Err(e) = recording_csv::write_to(&out, &mut csv, std::path::Path::new("out.csv")) {
                let e = e.to_string();
                assert!(e.contains("out.csv") && e.contains("magnitude at most"), "{e}");
            }
            if let Ok(line) = linear_approximation(&model, LineInput::Throttle, Span::ModelRange) {
                // A frame the model file names is a valid one (its reader checks it).
                if let Ok(text) = px4_params(&line, 0, model.magnetometer_to_body.as_ref()) {
                    finite_text("PX4 parameters", &text);
                }
                if let Ok(text) = ardupilot_params(&line, 0, model.magnetometer_to_body.as_ref()) {
                    finite_text("ArduPilot parameters", &text);
                }
            }
            if let Ok(h) = c_header(&model) {
                finite_text("the C header", &h);
            }
        });
    }
}
