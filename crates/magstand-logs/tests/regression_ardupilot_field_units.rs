//! Regression: ArduCopter 3.4-era logs store `CURR` Volt and Curr as floats in volts and
//! amperes (FMT `Qfff`), but the import scaled every `CURR` by 0.01, the Copter 3.3 layout
//! (`h`, hundredths). `bat_a` came out 100x too small and `bat_v` (then below 0.5 V) was
//! silently dropped; the fit could not show it, and the export wrote `COMPASS_MOT2 = -524`
//! mG/A where the truth was about -5.3. Every field magstand reads is now scaled as the log
//! itself declares it: by its FMT type, and its FMTU unit and multiplier when the log has them.
//!
//! Each test writes one flight in several layouts of the same messages, as different firmware
//! versions log them, and checks that the import gives the same physical numbers from all.
use std::path::Path;

use magstand_logs::import::{ImportOptions, import_bytes};
use magstand_logs::log_writer::DataflashBuilder;

mod common;

const ROWS: usize = 120;

/// The flight: 10 Hz, current ramping 1..31 A, a 4S pack sagging under load, and a compass
/// that moves by (-5.3, 4.4, 1.9) mG per ampere on top of a fixed field.
struct Truth {
    t_s: Vec<f64>,
    volt: Vec<f64>,
    amp: Vec<f64>,
    mag_mg: Vec<[f64; 3]>,
    pwm: Vec<f64>,
}

fn truth() -> Truth {
    let t_s: Vec<f64> = (0..ROWS).map(|k| 5.0 + 0.1 * k as f64).collect();
    let amp: Vec<f64> = (0..ROWS)
        .map(|k| 1.0 + 30.0 * k as f64 / ROWS as f64)
        .collect();
    let volt = amp.iter().map(|a| 16.4 - 0.02 * a).collect();
    let mag_mg = amp
        .iter()
        .map(|a| {
            [
                (210.0 - 5.3 * a).round(),
                (-35.0 + 4.4 * a).round(),
                (420.0 + 1.9 * a).round(),
            ]
        })
        .collect();
    let pwm = amp.iter().map(|a| (1150.0 + 25.0 * a).round()).collect();
    Truth {
        t_s,
        volt,
        amp,
        mag_mg,
        pwm,
    }
}

/// How a layout stamps time: `TimeMS` in u32 milliseconds, or `TimeUS` in u64 microseconds.
#[derive(Clone, Copy)]
enum Clock {
    Ms,
    Us,
}

impl Clock {
    fn stamp(self, t_s: f64) -> f64 {
        match self {
            Clock::Ms => (t_s * 1e3).round(),
            Clock::Us => (t_s * 1e6).round(),
        }
    }
    fn format(self) -> (&'static str, &'static str) {
        match self {
            Clock::Ms => ("I", "TimeMS"),
            Clock::Us => ("Q", "TimeUS"),
        }
    }
}

/// One battery layout: message name, format after the time field, labels, and how to write a
/// (volt, amp) pair into its fields.
struct BatteryLayout {
    name: &'static str,
    format: &'static str,
    labels: &'static str,
    row: fn(f64, f64) -> Vec<f64>,
    /// `FMTU` unit and multiplier ids after the time field, when the firmware wrote them.
    units: Option<(&'static str, &'static str)>,
}

fn log_bytes(clock: Clock, battery: &BatteryLayout, declare_units: bool) -> Vec<u8> {
    let t = truth();
    let (tc, tl) = clock.format();
    let mut b = DataflashBuilder::new();
    b.format(
        0x81,
        "MAG",
        &format!("{tc}hhh"),
        &format!("{tl},MagX,MagY,MagZ"),
    )
    .format(
        0x82,
        "RCOU",
        &format!("{tc}HHHH"),
        &format!("{tl},C1,C2,C3,C4"),
    )
    .format(
        0x83,
        battery.name,
        &format!("{tc}{}", battery.format),
        &format!("{tl},{}", battery.labels),
    );
    if declare_units {
        b.unit('s', "s")
            .unit('G', "Gauss")
            .unit('v', "V")
            .unit('A', "A")
            .unit('Y', "us")
            .mult('-', 0.0)
            .mult('0', 1.0)
            .mult('B', 0.01)
            .mult('C', 1e-3)
            .mult('F', 1e-6)
            .units(0x81, "sGGG", "FCCC")
            .units(0x82, "sYYYY", "F----");
        if let Some((u, m)) = battery.units {
            b.units(0x83, &format!("s{u}"), &format!("F{m}"));
        }
    }
    for (name, v) in [
        ("MOT_PWM_MIN", 1100.0),
        ("MOT_PWM_MAX", 1900.0),
        ("COMPASS_EXTERNAL", 0.0),
        ("FRAME_CLASS", 1.0),
    ] {
        b.param(0, name, v);
    }
    for k in 0..ROWS {
        let ts = clock.stamp(t.t_s[k]);
        let m = t.mag_mg[k];
        b.row(0x81, &[ts, m[0], m[1], m[2]]);
        b.row(0x82, &[ts, t.pwm[k], t.pwm[k], t.pwm[k], t.pwm[k]]);
        let fields: Vec<f64> = std::iter::once(ts)
            .chain((battery.row)(t.volt[k], t.amp[k]))
            .collect();
        b.row(0x83, &fields);
    }
    b.into_bytes()
}

fn assert_reads_the_truth(label: &str, bytes: &[u8]) {
    let (rec, report) = import_bytes(bytes, Path::new(label), &ImportOptions::default())
        .unwrap_or_else(|e| panic!("{label}: {e}"));
    let t = truth();
    let a = rec
        .bat_a
        .as_ref()
        .unwrap_or_else(|| panic!("{label}: no bat_a; {:?}", report.notes));
    let v = rec
        .bat_v
        .as_ref()
        .unwrap_or_else(|| panic!("{label}: no bat_v; {:?}", report.notes));
    assert_eq!(rec.len(), ROWS, "{label}: {}", report.summary(&rec));
    for k in 0..ROWS {
        // Hundredths are the coarsest resolution of any layout; floats are f32.
        assert!(
            (a[k] - t.amp[k]).abs() < 0.006 && (v[k] - t.volt[k]).abs() < 0.006,
            "{label} row {k}: read {} V, {} A, logged {} V, {} A",
            v[k],
            a[k],
            t.volt[k],
            t.amp[k]
        );
        let want = [
            t.mag_mg[k][0] * 0.1,
            t.mag_mg[k][1] * 0.1,
            t.mag_mg[k][2] * 0.1,
        ];
        for (axis, w) in want.iter().enumerate() {
            assert!(
                (rec.mag_ut[k][axis] - w).abs() < 1e-9,
                "{label} row {k} axis {axis}: read {} µT, logged {w} µT",
                rec.mag_ut[k][axis]
            );
        }
    }
}

fn copter33_curr() -> BatteryLayout {
    // Copter 3.3: TimeMS,Throttle,Volt,Curr,Vcc,CurrTot,Volt2 as IhhhHfh, volts and amperes in
    // hundredths.
    BatteryLayout {
        name: "CURR",
        format: "hhhHfh",
        labels: "Throttle,Volt,Curr,Vcc,CurrTot,Volt2",
        row: |v, a| {
            vec![
                500.0,
                (v * 100.0).round(),
                (a * 100.0).round(),
                5000.0,
                0.0,
                0.0,
            ]
        },
        units: None,
    }
}

fn copter34_curr() -> BatteryLayout {
    // Copter 3.4: CURR as Qfff..., volts and amperes in floats.
    BatteryLayout {
        name: "CURR",
        format: "fff",
        labels: "Volt,Curr,CurrTot",
        row: |v, a| vec![v, a, 0.0],
        units: None,
    }
}

#[test]
fn curr_in_hundredths_and_in_floats_read_the_same_amperes_and_volts() {
    assert_reads_the_truth(
        "copter33.bin",
        &log_bytes(Clock::Ms, &copter33_curr(), false),
    );
    assert_reads_the_truth(
        "copter34.bin",
        &log_bytes(Clock::Us, &copter34_curr(), false),
    );
}

#[test]
fn bat_scaled_by_its_declared_multiplier() {
    // Current firmware: floats declared in V and A without a multiplier.
    let floats = BatteryLayout {
        name: "BAT",
        format: "Bfff",
        labels: "Inst,Volt,Curr,CurrTot",
        row: |v, a| vec![0.0, v, a, 0.0],
        units: Some(("-vA-", "-00-")),
    };
    assert_reads_the_truth("bat-floats.bin", &log_bytes(Clock::Us, &floats, true));
    // The same message stored as integer hundredths, declared so by its FMTU multiplier B.
    let integers = BatteryLayout {
        name: "BAT",
        format: "BHH",
        labels: "Inst,Volt,Curr",
        row: |v, a| vec![0.0, (v * 100.0).round(), (a * 100.0).round()],
        units: Some(("-vA", "-BB")),
    };
    assert_reads_the_truth("bat-centi.bin", &log_bytes(Clock::Us, &integers, true));
}

#[test]
fn a_current_field_declared_in_another_unit_is_refused() {
    let wrong = BatteryLayout {
        name: "BAT",
        format: "Bff",
        labels: "Inst,Volt,Curr",
        row: |v, a| vec![0.0, v, a],
        units: Some(("-vv", "-00")),
    };
    let e = import_bytes(
        &log_bytes(Clock::Us, &wrong, true),
        Path::new("bat-volts.bin"),
        &ImportOptions::default(),
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("bat-volts.bin") && e.contains("BAT.Curr") && e.contains("'V'"),
        "{e}"
    );
}

/// The real Copter 4.6.2 fixture declares BAT in V and A (floats) and MAG in gauss with
/// multiplier 1e-3 (int16 milligauss): the import must read its FMTU and find exactly that.
#[test]
fn the_copter_462_log_declares_the_units_the_import_assumes() {
    let path = common::real_log("ardupilot-copter462-pixhawk4-first80k.bin");
    let bytes = std::fs::read(&path).unwrap();
    let log = magstand_logs::dataflash::read_bytes(&bytes, &path).unwrap();
    let mag = &log.field_units["MAG"]["MagX"];
    assert_eq!(
        (mag.type_char, mag.unit.as_deref(), mag.mult),
        ('h', Some("Gauss"), Some(0.0010000000474974513)),
        "{mag:?}"
    );
    let curr = &log.field_units["BAT"]["Curr"];
    assert_eq!(
        (curr.type_char, curr.unit.as_deref(), curr.mult),
        ('f', Some("A"), Some(1.0)),
        "{curr:?}"
    );
    let (rec, report) = import_bytes(
        &bytes,
        &path,
        &ImportOptions {
            motors: Some(4),
            ..ImportOptions::default()
        },
    )
    .unwrap();
    // Disarmed on the bench: a 4S pack at 14-17 V, a few tens of milliamperes.
    let v = rec.bat_v.as_ref().expect("bat_v");
    let a = rec.bat_a.as_ref().expect("bat_a");
    assert!(
        v.iter().all(|v| (13.0..17.5).contains(v)) && a.iter().all(|a| a.abs() < 1.0),
        "{v:?} {a:?} {}",
        report.summary(&rec)
    );
    let n = rec.mag_ut[0].norm();
    assert!((15.0..80.0).contains(&n), "{n} µT");
}
