//! Property-test support shared by the crates' file-format tests (feature `file-fuzzing`):
//! the hostile numbers a crafted file carries, and mutation of one number in a JSON document.
//!
//! Every reader of a magstand file format is tested the same way: take a valid file, replace
//! one value with something hostile, and require that the reader either refuses it with an
//! error or yields something whose every derived number is finite.
//!
//! ```
//! use magstand_core::file_fuzzing::{json_number_paths, replace_json_at};
//! let mut v: serde_json::Value = serde_json::from_str(r#"{"a":[1,{"b":2}],"c":"x"}"#).unwrap();
//! let paths = json_number_paths(&v);
//! assert_eq!(paths.len(), 2);
//! replace_json_at(&mut v, &paths[1], serde_json::json!(1e308));
//! assert_eq!(v["a"][1]["b"], 1e308);
//! ```
use proptest::prelude::*;
use serde_json::Value;

/// The property-test settings of every file-format test: `cases` cases from a fixed seed, so
/// the same cases run on every machine and every run (CI never flickers).
pub fn config(cases: u32) -> proptest::test_runner::Config {
    proptest::test_runner::Config {
        cases,
        rng_seed: proptest::test_runner::RngSeed::Fixed(0x6d61_6773),
        ..proptest::test_runner::Config::default()
    }
}

/// The first word of `text` that Rust prints for a non-finite number (`NaN`, `nan`, `inf`),
/// if any. Code such as a C header's `INFINITY` (the start of a minimum search) is not one.
pub fn non_finite_word(text: &str) -> Option<&str> {
    text.split(|c: char| !(c.is_ascii_alphanumeric() || c == '_'))
        .find(|w| matches!(*w, "NaN" | "nan" | "inf"))
}

/// Numbers a crafted file might carry: huge, tiny, negative, zero, integers past 2^53 and
/// ordinary values, but always finite (JSON and CSV readers refuse NaN text themselves).
pub fn hostile_f64() -> impl Strategy<Value = f64> {
    prop_oneof![
        Just(0.0),
        Just(-0.0),
        Just(1e308),
        Just(-1e308),
        Just(1e300),
        Just(1e-300),
        Just(-1e-300),
        Just(f64::MAX),
        Just(f64::MIN_POSITIVE),
        Just(18446744073709551615.0),
        Just(1e12),
        Just(-1.0),
        Just(0.5),
        -1e6..1e6f64,
        -10.0..10.0f64,
        any::<f64>().prop_filter("finite", |x| x.is_finite()),
    ]
}

/// A value to put where a number was: a hostile number, or a value of the wrong type.
pub fn hostile_json_value() -> impl Strategy<Value = Value> {
    prop_oneof![
        8 => hostile_f64().prop_map(|x| serde_json::json!(x)),
        1 => Just(Value::Null),
        1 => Just(serde_json::json!("abc")),
        1 => Just(serde_json::json!([])),
        1 => Just(serde_json::json!(-1)),
        1 => Just(serde_json::json!(u64::MAX)),
    ]
}

/// One step on the way into a JSON document.
#[derive(Debug, Clone, PartialEq)]
pub enum JsonStep {
    /// An object member.
    Key(String),
    /// An array element.
    Index(usize),
}

/// The paths of every number in `v`, in document order.
pub fn json_number_paths(v: &Value) -> Vec<Vec<JsonStep>> {
    fn walk(v: &Value, path: &mut Vec<JsonStep>, out: &mut Vec<Vec<JsonStep>>) {
        match v {
            Value::Number(_) => out.push(path.clone()),
            Value::Array(a) => {
                for (i, x) in a.iter().enumerate() {
                    path.push(JsonStep::Index(i));
                    walk(x, path, out);
                    path.pop();
                }
            }
            Value::Object(o) => {
                for (k, x) in o {
                    path.push(JsonStep::Key(k.clone()));
                    walk(x, path, out);
                    path.pop();
                }
            }
            _ => {}
        }
    }
    let mut out = Vec::new();
    walk(v, &mut Vec::new(), &mut out);
    out
}

/// Replaces the value at `path` (from [`json_number_paths`]) with `new`.
pub fn replace_json_at(v: &mut Value, path: &[JsonStep], new: Value) {
    let mut cur = v;
    for step in path {
        cur = match step {
            JsonStep::Key(k) => &mut cur[k.as_str()],
            JsonStep::Index(i) => &mut cur[*i],
        };
    }
    *cur = new;
}

/// `text` (a JSON document) with the number number `pick % count` replaced by `new`; the
/// document unchanged when it holds no number.
pub fn mutate_json_number(text: &str, pick: usize, new: Value) -> String {
    let mut v: Value = serde_json::from_str(text).expect("the base document is valid JSON");
    let paths = json_number_paths(&v);
    if let Some(path) = paths.get(pick % paths.len().max(1)) {
        replace_json_at(&mut v, path, new);
    }
    v.to_string()
}
