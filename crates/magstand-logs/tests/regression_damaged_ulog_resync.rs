//! Regression: a real PX4 1.17 log with one data message whose msg_id had a flipped bit
//! (32812 instead of 44, at byte 942588) and later stretches that do not parse as messages
//! was read only up to the first bad message: 23 of its 95 magnetometer samples, 20 s of an
//! 88 s flight. pyulog skips such a message, and finds its way past unreadable bytes with the
//! synchronisation messages PX4 writes about once a second. The import now does the same and
//! reports what it skipped.

use magstand_logs::import::{ImportOptions, import_bytes, import_file};

mod common;
use common::real_log as log;

#[test]
fn the_bit_flipped_v6xrt_log_reads_to_its_end_as_pyulog_does() {
    let (rec, report) = import_file(
        &log("px4-fmuv6xrt-quad-msgid-bitflip.ulg"),
        &ImportOptions::default(),
    )
    .unwrap();
    let text = report.summary(&rec);
    // pyulog 1.x reads 95 sensor_mag[0] samples, 409.58..503.58 s, none more than 1.05 s apart.
    assert_eq!(rec.len(), 95, "{text}");
    assert!((rec.t_s[0] - 409.58).abs() < 0.01, "{text}");
    assert!((rec.t_s[rec.len() - 1] - 503.58).abs() < 0.01, "{text}");
    let widest = rec.t_s.windows(2).map(|w| w[1] - w[0]).fold(0.0, f64::max);
    assert!(widest < 1.2, "widest gap {widest} s\n{text}");
    let damage = report.damage.as_deref().expect("the damage is reported");
    assert!(
        damage.contains("msg_id 32812") && damage.contains("byte 942588"),
        "{damage}"
    );
}

/// Known damage added to an intact real log: one data message's id corrupted, and a stretch
/// of bytes overwritten with noise. What lies outside them is read as before.
#[test]
fn damage_added_to_an_intact_log_costs_only_the_damaged_stretch() {
    let path = log("px4-cubeorange-octo-x8-fsyr-log123.ulg");
    let clean = std::fs::read(&path).unwrap();
    let (whole, _) = import_bytes(&clean, &path, &ImportOptions::default()).unwrap();

    // Walk the framing to the data messages at about 40 % and 70 % of the file.
    let mut starts = Vec::new();
    let mut i = 16;
    while i + 3 <= clean.len() {
        let size = u16::from_le_bytes([clean[i], clean[i + 1]]) as usize;
        if clean[i + 2] == b'D' {
            starts.push(i);
        }
        i += 3 + size;
    }
    let at = |f: f64| starts[(starts.len() as f64 * f) as usize];
    let mut bad = clean.clone();
    let flip = at(0.4);
    bad[flip + 4] ^= 0x80; // bit 15 of the msg_id
    let noise = at(0.7);
    let mut x = 0x9E37_79B9u32;
    for b in &mut bad[noise..noise + 3000] {
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        *b = (x >> 24) as u8;
    }
    let (rec, report) = import_bytes(&bad, &path, &ImportOptions::default()).unwrap();
    let text = report.summary(&rec);
    assert!(report.damage.is_some(), "{text}");
    // 3 KB of noise and the stretch to the next sync message (about a second of log) cost at
    // most two samples of the 1 Hz magnetometer; nothing after them is lost.
    assert!(
        rec.len() + 2 >= whole.len() && rec.len() <= whole.len(),
        "{} rows of {}\n{text}",
        rec.len(),
        whole.len()
    );
    assert_eq!(rec.t_s.last(), whole.t_s.last(), "{text}");
}
