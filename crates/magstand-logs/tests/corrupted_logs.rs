//! Corrupted and truncated logs never panic the importers: whatever the bytes, the result is a
//! recording or an error that names the file. Also the two named bad inputs: a log without a
//! magnetometer and one without PWM limits.
use std::path::Path;

use magstand_core::Recording;
use magstand_logs::import::{ImportOptions, import_bytes};
use magstand_logs::log_writer::{LogWriteOptions, dataflash_bytes, ulog_bytes};
use proptest::prelude::*;

fn small_run() -> Recording {
    let text = "t_s,thr_1,thr_2,thr_3,thr_4,mag_x_ut,mag_y_ut,mag_z_ut,bat_v,bat_a\n";
    let rows: String = (0..40)
        .map(|i| {
            let c = (i as f64 / 40.0).min(1.0);
            format!(
                "{},{c},{c},{c},{c},{},{},-40,12,{}\n",
                i as f64 * 0.1,
                20.0 + c,
                3.0 - c,
                10.0 * c
            )
        })
        .collect();
    magstand_core::recording_csv::read_str(&(text.to_string() + &rows), "mem").unwrap()
}

fn replace(bytes: &[u8], from: &[u8], to: &[u8]) -> Vec<u8> {
    let mut out = bytes.to_vec();
    let mut i = 0;
    while i + from.len() <= out.len() {
        if &out[i..i + from.len()] == from {
            out[i..i + from.len()].copy_from_slice(to);
        }
        i += 1;
    }
    out
}

#[test]
fn a_log_without_magnetometer_or_pwm_limits_says_so() {
    let rec = small_run();
    let opts = LogWriteOptions::default();
    let ulog = replace(&ulog_bytes(&rec, &opts), b"sensor_mag", b"sensor_xyz");
    let e = import_bytes(&ulog, Path::new("nomag.ulg"), &ImportOptions::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("nomag.ulg") && e.contains("magnetometer"), "{e}");
    let df = replace(&dataflash_bytes(&rec, &opts), b"MAG\0", b"MAX\0");
    let e = import_bytes(&df, Path::new("nomag.bin"), &ImportOptions::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("nomag.bin") && e.contains("MAG"), "{e}");
    let df = replace(&dataflash_bytes(&rec, &opts), b"MOT_PWM_M", b"MOT_XXX_M");
    let e = import_bytes(&df, Path::new("nopwm.bin"), &ImportOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("nopwm.bin") && e.contains("PWM limits") && e.contains("`pwm_range`"),
        "{e}"
    );
    let ulog = replace(
        &ulog_bytes(&rec, &opts),
        b"actuator_motors",
        b"actuator_xxxxxx",
    );
    let e = import_bytes(&ulog, Path::new("nomotors.ulg"), &ImportOptions::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("nomotors.ulg") && e.contains("motor"), "{e}");
}

fn check(bytes: &[u8], name: &str) {
    match import_bytes(bytes, Path::new(name), &ImportOptions::default()) {
        Ok((rec, _)) => rec.check().unwrap(),
        Err(e) => assert!(e.to_string().contains(name), "{e}"),
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 96, ..ProptestConfig::default() })]

    #[test]
    fn truncated_logs_never_panic(cut in 0usize..4000, df in any::<bool>()) {
        let rec = small_run();
        let bytes = if df { dataflash_bytes(&rec, &LogWriteOptions::default()) } else { ulog_bytes(&rec, &LogWriteOptions::default()) };
        let cut = cut.min(bytes.len());
        check(&bytes[..cut], "cut.log");
    }

    #[test]
    fn flipped_bytes_never_panic(
        flips in proptest::collection::vec((0usize..6000, any::<u8>()), 1..12),
        df in any::<bool>(),
    ) {
        let rec = small_run();
        let mut bytes = if df { dataflash_bytes(&rec, &LogWriteOptions::default()) } else { ulog_bytes(&rec, &LogWriteOptions::default()) };
        for (i, b) in flips {
            let n = bytes.len();
            bytes[i % n] = b;
        }
        check(&bytes, "flipped.log");
    }
}
