//! Regression: `diagnose` named `unexplained` on axes "-". On a recording whose field follows
//! the commands exactly but for one read of 1e5 µT on x (a sensor's read error, which the
//! diagnosis warns of), the residual failed the whiteness test on x, and the structure was
//! named; but the windows of throttle and time that locate a finding found none significant,
//! so the report said where the structure lay on no axis. The axes of an `unexplained` are now
//! at least those whose whiteness test named it.
mod common;

/// A recording whose field follows the commands exactly but for one read of 1e5 µT on x, and
/// the diagnosis of it: its JSON and the command's run.
fn diagnose_one_spike() -> (serde_json::Value, common::Run) {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("spike.csv");
    let mut text = String::from("t_s,thr_1,thr_2,thr_3,thr_4,mag_x_ut,mag_y_ut,mag_z_ut\n");
    for i in 0..3000 {
        let q = ((i / 300) % 5) as f64 * 0.2;
        let x = if i == 1500 { 1e5 } else { 20.0 + 5.0 * q * q };
        text += &format!(
            "{:.2},{q},{q},{q},{q},{x},{},{}\n",
            i as f64 * 0.02,
            2.0 - q,
            40.0 + q
        );
    }
    std::fs::write(&csv, text).unwrap();
    let (r, d) = common::diagnose(&csv, &dir.path().join("d.json"), &[]);
    assert!(r.ok, "{}", r.stderr);
    assert!(r.stdout.contains("read error"), "{}", r.stdout);
    (d.expect("a diagnosis file"), r)
}

#[test]
fn unexplained_structure_names_the_axes_that_found_it() {
    let (d, r) = diagnose_one_spike();
    assert!(
        d["verdict"]
            .as_array()
            .unwrap()
            .iter()
            .any(|n| n == "unexplained"),
        "{}",
        r.stdout
    );
    for e in d["effects"].as_array().unwrap() {
        let axes = e["located"]["axes"].as_array().unwrap();
        assert!(!axes.is_empty(), "{} located on no axis: {e}", e["name"]);
    }
}

/// Not a regression: beside `unexplained`, the reported sds leave out the bias the structure
/// may put on the parameters, and the diagnosis says so (here of the calibrated constants).
#[test]
fn unexplained_structure_warns_that_the_sds_leave_out_its_bias() {
    let (d, r) = diagnose_one_spike();
    let warned = d["warnings"].as_array().unwrap().iter().any(|w| {
        w.as_str().is_some_and(|w| {
            w.contains("the calibrated constants were fitted beside structure")
                && w.contains("axes x")
        })
    });
    assert!(warned, "{}", r.stdout);
}
