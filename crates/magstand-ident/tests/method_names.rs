//! One spelling per method in every file: the model file's `method` is the name `runs.csv`,
//! the studies and `--methods` use (`global-weighted`, `automatic`), and files written with
//! the old spellings (`global+weighted`, `auto-global+weighted`) still load, under the new
//! ones.
use magstand_ident::method_name;
use magstand_ident::methods::by_id;
use magstand_ident::{Dataset, Fit, InputKind, Model};

fn stair() -> magstand_core::Recording {
    let mut rec = magstand_core::Recording::default();
    for r in 0..3000 {
        let u = ((r / 100) % 10) as f64 / 9.0;
        rec.t_s.push(r as f64 * 0.01);
        let wobble = 0.05 * ((r * 7919) % 13) as f64 / 13.0;
        rec.mag_ut.push(magstand_core::Vec3::new(
            20.0 + 3.0 * u * u + wobble,
            1.0,
            45.0 - 2.0 * u,
        ));
    }
    rec.thr = vec![(0..3000).map(|r| ((r / 100) % 10) as f64 / 9.0).collect()];
    rec.overall_only = true;
    rec
}

/// The catalog method `id` fitted on the stair.
fn fitted(id: &str) -> Model {
    let data = Dataset::from_recording(&stair(), InputKind::Throttle, "stair").unwrap();
    let config = by_id(id).unwrap().config.check().unwrap();
    config.fit(&data).unwrap()
}

#[test]
fn the_model_file_names_a_method_as_the_studies_do() {
    for id in ["global-weighted", "automatic", "global", "px4"] {
        assert_eq!(fitted(id).method, id, "the catalog's {id}");
    }
}

#[test]
fn old_spellings_still_load_under_the_new_ones() {
    let json = serde_json::to_string(&fitted("automatic")).unwrap();
    for (old, new) in [
        ("auto-global+weighted", "automatic"),
        ("global+weighted", "global-weighted"),
        ("auto-local", "automatic-local-unweighted"),
    ] {
        let text = json.replace("\"method\":\"automatic\"", &format!("\"method\":\"{old}\""));
        assert!(text.contains(old), "{text}");
        let back = Model::from_json(&text, "old.json").unwrap();
        assert_eq!(back.method, new);
        assert_eq!(method_name(old), new);
    }
}
