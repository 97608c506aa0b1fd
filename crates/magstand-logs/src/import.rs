//! A log becomes a recording: the streams of the format mapping are put onto the
//! magnetometer's time stamps (linear interpolation, quaternions by slerp, states held), on
//! the log's own clock. Gaps and clock resets are found and reported, not papered over: a
//! row is written only where the motor commands bracket it closely, and a reset ends the
//! import at the reset.
use std::fmt::Write as _;
use std::path::Path;

use magstand_core::interpolation::{interpolate, locate};
use magstand_core::recording_csv::format_extra;
use magstand_core::{Quat, Recording};

use crate::LogsError;
use crate::contents::{LogContents, LogFormat};
use crate::streams::{Position, Stream, VehicleStreams};

pub use magstand_core::AUTOPILOT_THROTTLE;

/// What the user chose on the command line; everything is optional.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ImportOptions {
    /// Magnetometer instance (PX4 `sensor_mag` multi-instance; ArduPilot 0 = MAG, 1 = MAG2, ...).
    pub mag: Option<u8>,
    /// Motor count, when the log does not say.
    pub motors: Option<usize>,
    /// PX4 `actuator_outputs` instance to read the motors from (instead of `actuator_motors`).
    pub outputs: Option<u8>,
    /// PWM range of the motor outputs, when the log's parameters do not give it.
    pub pwm_range: Option<(f64, f64)>,
    /// Keep only rows of this kind.
    pub segment: Option<SegmentKind>,
    /// Keep only rows in this time window, s on the log's clock.
    pub window_s: Option<(f64, f64)>,
}

/// What the vehicle was doing at a row.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SegmentKind {
    /// Disarmed, or armed with every motor stopped: the field without motors.
    Off,
    /// Motors spinning while landed (or restrained): what the paper, PX4's strapped
    /// calibration and ArduPilot's compassmot use.
    Ground,
    /// Motors spinning in the air.
    Flight,
    /// Motors spinning, landed state not logged.
    Spinning,
}

impl SegmentKind {
    /// Name in the recording's `segment` column.
    pub fn name(self) -> &'static str {
        match self {
            SegmentKind::Off => "off",
            SegmentKind::Ground => "ground",
            SegmentKind::Flight => "flight",
            SegmentKind::Spinning => "spinning",
        }
    }

    /// Parses a name as written by [`SegmentKind::name`].
    pub fn parse(s: &str) -> Option<Self> {
        [Self::Off, Self::Ground, Self::Flight, Self::Spinning]
            .into_iter()
            .find(|k| k.name() == s)
    }
}

/// A run of rows of one kind.
#[derive(Debug, Clone, PartialEq)]
pub struct Segment {
    /// Its kind.
    pub kind: SegmentKind,
    /// First and last row time, s.
    pub span_s: (f64, f64),
    /// Number of rows.
    pub rows: usize,
    /// Largest overall throttle in it.
    pub max_throttle: f64,
}

/// What an import did, for the terminal and for tests.
#[derive(Debug, Clone, PartialEq)]
pub struct ImportReport {
    /// "ULog" or "DataFlash".
    pub format: &'static str,
    /// The firmware that wrote the log, when it names itself ([`LogContents::firmware`]).
    pub firmware: Option<String>,
    /// How the file broke off, if it did.
    pub damage: Option<String>,
    /// Choices made by the format mapping (instances, PWM ranges).
    pub notes: Vec<String>,
    /// Gaps in the magnetometer stream longer than five typical intervals: (from, to), s.
    pub gaps_s: Vec<(f64, f64)>,
    /// Times where the log's clock went backwards (the import stops at the first).
    pub resets_s: Vec<f64>,
    /// Magnetometer samples not written, with the reason.
    pub dropped: Vec<(String, usize)>,
    /// The runs of each kind.
    pub segments: Vec<Segment>,
    /// Position and date from GPS, for the Earth-field model.
    pub position: Option<Position>,
}

impl ImportReport {
    /// A few lines a person reads in ten seconds.
    pub fn summary(&self, rec: &Recording) -> String {
        let mut s = String::new();
        let span = |r: &Recording| match (r.t_s.first(), r.t_s.last()) {
            (Some(a), Some(b)) => format!("{a:.2}..{b:.2} s"),
            _ => "empty".into(),
        };
        let _ = writeln!(
            s,
            "{} log: {} rows, {} motors, {} ({:.1} Hz magnetometer)",
            self.format,
            rec.len(),
            rec.motor_count(),
            span(rec),
            if rec.typical_interval_s() > 0.0 {
                1.0 / rec.typical_interval_s()
            } else {
                0.0
            }
        );
        if let Some(f) = &self.firmware {
            let _ = writeln!(s, "  firmware: {f}");
        }
        if let Some(d) = &self.damage {
            let _ = writeln!(s, "DAMAGED FILE: {d}");
        }
        for n in &self.notes {
            let _ = writeln!(s, "  {n}");
        }
        for (why, n) in &self.dropped {
            let _ = writeln!(s, "  dropped {n} magnetometer samples: {why}");
        }
        for (a, b) in &self.gaps_s {
            let _ = writeln!(
                s,
                "  gap in the magnetometer stream: {a:.3}..{b:.3} s ({:.2} s)",
                b - a
            );
        }
        for t in &self.resets_s {
            let _ = writeln!(
                s,
                "  log clock went backwards at {t:.3} s: rows after it are not imported"
            );
        }
        let _ = writeln!(s, "segments:");
        for g in &self.segments {
            let _ = writeln!(
                s,
                "  {:8} {:9.2}..{:9.2} s  {:6} rows  max throttle {:.2}",
                g.kind.name(),
                g.span_s.0,
                g.span_s.1,
                g.rows,
                g.max_throttle
            );
        }
        if let Some(p) = &self.position {
            let _ = writeln!(
                s,
                "position: {} {}, {:.0} m{}",
                hemisphere_deg(p.lat_deg, 'N', 'S'),
                hemisphere_deg(p.lon_deg, 'E', 'W'),
                p.alt_m,
                p.year.map_or(String::new(), |y| format!(", {y:.2}"))
            );
        }
        s
    }
}

/// A latitude or longitude as its size and hemisphere (`87.70563 W`, not `-87.70563 E`).
fn hemisphere_deg(deg: f64, positive: char, negative: char) -> String {
    let letter = if deg < 0.0 { negative } else { positive };
    format!("{:.5} {letter}", deg.abs())
}

/// Reads a log file of either format (by its first bytes) and imports it.
pub fn import_file(
    path: &Path,
    opts: &ImportOptions,
) -> Result<(Recording, ImportReport), LogsError> {
    let bytes = magstand_core::input_file::read(path, magstand_core::input_file::MAX_LOG_BYTES)
        .map_err(|source| LogsError::Io {
            path: path.to_path_buf(),
            source,
        })?;
    import_bytes(&bytes, path, opts)
}

/// Imports log bytes; the format is recognized by the magic bytes.
pub fn import_bytes(
    bytes: &[u8],
    path: &Path,
    opts: &ImportOptions,
) -> Result<(Recording, ImportReport), LogsError> {
    let log = match LogFormat::detect(bytes) {
        Some(LogFormat::Ulog) => crate::ulog::read_bytes(bytes, path)?,
        Some(LogFormat::DataFlash) => crate::dataflash::read_bytes(bytes, path)?,
        None => {
            return Err(LogsError::Corrupt {
                path: path.to_path_buf(),
                format: "ULog or DataFlash",
                what: "the file starts with neither the ULog magic bytes nor a DataFlash header"
                    .into(),
            });
        }
    };
    import(&log, opts)
}

/// Imports parsed log contents.
pub fn import(
    log: &LogContents,
    opts: &ImportOptions,
) -> Result<(Recording, ImportReport), LogsError> {
    if let Some((lo, hi)) = opts.pwm_range
        && !(lo.is_finite() && hi.is_finite() && hi > lo)
    {
        return Err(LogsError::Unusable {
            path: log.path.clone(),
            what: format!("`pwm_range` = {lo}:{hi}: the maximum must exceed the minimum"),
        });
    }
    if opts.motors == Some(0) {
        return Err(LogsError::Unusable {
            path: log.path.clone(),
            what: "`motors` = 0: a multirotor has at least one motor".into(),
        });
    }
    if let (Some(n), LogFormat::DataFlash) = (opts.outputs, log.format) {
        return Err(LogsError::Unusable {
            path: log.path.clone(),
            what: format!(
                "`outputs` = {n} names a PX4 actuator_outputs instance; a DataFlash log's motors are its RCOU channels (choose them with `motors`, located by SERVOn_FUNCTION)"
            ),
        });
    }
    let streams = match log.format {
        LogFormat::Ulog => crate::px4::streams(log, opts),
        LogFormat::DataFlash => crate::ardupilot::streams(log, opts),
    };
    // On a damaged file, what is missing may be missing because of the damage: say so.
    let mut streams = match (streams, &log.damage) {
        (Ok(s), _) => s,
        (Err(e), Some(d)) => return Err(e.on_damaged_file(d)),
        (Err(e), None) => return Err(e),
    };
    streams.drop_unmeasured_supply(match log.format {
        LogFormat::Ulog => "battery_status",
        LogFormat::DataFlash => "BAT/CURR",
    });
    let mut report = ImportReport {
        format: log.format.name(),
        firmware: log.firmware(),
        damage: log.damage.clone(),
        notes: streams.notes.clone(),
        gaps_s: Vec::new(),
        resets_s: Vec::new(),
        dropped: Vec::new(),
        segments: Vec::new(),
        position: streams.position,
    };
    if let Some(slot) = streams.mag_slot {
        report.notes.push(format!(
            "its compensation parameters: {} (column `{}` = {slot}; `export` writes those)",
            slot.describe(),
            magstand_core::magnetometer_slot::COLUMN
        ));
    }
    let rec = align(log, &streams, opts, &mut report)?;
    Ok((rec, report))
}

/// Median of the positive intervals of a time column.
fn typical_interval(t: &[f64]) -> f64 {
    let mut d: Vec<f64> = t
        .windows(2)
        .map(|w| w[1] - w[0])
        .filter(|d| *d > 0.0)
        .collect();
    if d.is_empty() {
        return f64::INFINITY;
    }
    d.sort_by(f64::total_cmp);
    d[d.len() / 2]
}

/// Index `i` with `t[i] <= x < t[i+1]` and the fraction, when `x` lies inside `t` and the two
/// samples are at most `max_gap` apart.
fn bracket(t: &[f64], x: f64, max_gap: f64) -> Option<(usize, f64)> {
    let i = t.partition_point(|&v| v <= x);
    if i == 0 {
        return None;
    }
    // Exactly on a sample: its own value, whatever gap follows (the last row of a flight
    // before the next one, or of the log).
    if t[i - 1] == x {
        return Some((i - 1, 0.0));
    }
    if i == t.len() {
        return None;
    }
    let (a, b) = (t[i - 1], t[i]);
    (b - a <= max_gap).then(|| (i - 1, (x - a) / (b - a)))
}

fn lerp(a: f64, b: f64, f: f64) -> f64 {
    a + (b - a) * f
}

/// Value of a scalar stream at `x`, interpolated inside and held at its ends.
fn at_scalar(s: &Stream<f64>, x: f64) -> f64 {
    interpolate(&s.values, locate(&s.t_s, x))
}

/// Attitude at `x`: slerp inside, held at the ends.
fn at_quat(s: &Stream<Quat>, x: f64) -> Quat {
    match locate(&s.t_s, x) {
        (k, 0.0) => s.values[k],
        (k, f) => s.values[k]
            .try_slerp(&s.values[k + 1], f, 1e-9)
            .unwrap_or(s.values[k]),
    }
}

/// State at `x`: the last change at or before it, `before` until the first.
fn at_state(s: &Stream<bool>, x: f64, before: bool) -> bool {
    let i = s.t_s.partition_point(|&v| v <= x);
    if i == 0 { before } else { s.values[i - 1] }
}

/// A stream with only strictly increasing times (repeats and out-of-order samples dropped).
fn monotonic<T: Clone>(s: &Stream<T>) -> Stream<T> {
    let mut out = Stream {
        t_s: Vec::new(),
        values: Vec::new(),
    };
    for (t, v) in s.t_s.iter().zip(&s.values) {
        if out.t_s.last().is_none_or(|l| t > l) {
            out.t_s.push(*t);
            out.values.push(v.clone());
        }
    }
    out
}

fn align(
    log: &LogContents,
    st: &VehicleStreams,
    opts: &ImportOptions,
    report: &mut ImportReport,
) -> Result<Recording, LogsError> {
    let unusable = |what: String| LogsError::Unusable {
        path: log.path.clone(),
        what,
    };
    if st.mag_ut.is_empty() {
        return Err(unusable(
            "the magnetometer stream has no valid samples".into(),
        ));
    }
    if st.motors.is_empty() {
        return Err(unusable("the motor stream has no samples".into()));
    }
    // The magnetometer's clock: stop at the first reset, drop repeated stamps.
    let mut mag_end = st.mag_ut.len();
    let mut repeats = 0;
    for i in 1..st.mag_ut.len() {
        let (a, b) = (st.mag_ut.t_s[i - 1], st.mag_ut.t_s[i]);
        if b < a {
            report.resets_s.push(a);
            mag_end = i;
            break;
        }
        if b == a {
            repeats += 1;
        }
    }
    if mag_end < st.mag_ut.len() {
        report.dropped.push((
            "after the log clock reset".into(),
            st.mag_ut.len() - mag_end,
        ));
    }
    if repeats > 0 {
        report
            .dropped
            .push(("repeated time stamps".into(), repeats));
    }
    let motors = monotonic(&st.motors);
    let motor_gap = (5.0 * typical_interval(&motors.t_s)).max(0.5);
    let mag_t = &st.mag_ut.t_s[..mag_end];
    let mag_gap = 5.0 * typical_interval(mag_t);
    report.gaps_s = mag_t
        .windows(2)
        .filter(|w| w[1] - w[0] > mag_gap)
        .map(|w| (w[0], w[1]))
        .collect();
    let n_motors = motors.values[0].len();
    let bat_v = st.bat_v.as_ref().map(monotonic).filter(|s| !s.is_empty());
    let bat_a = st.bat_a.as_ref().map(monotonic).filter(|s| !s.is_empty());
    let temp = st
        .mag_temp_c
        .as_ref()
        .map(monotonic)
        .filter(|s| !s.is_empty());
    let att = st
        .attitude
        .as_ref()
        .map(monotonic)
        .filter(|s| !s.is_empty());
    let esc: Vec<Stream<f64>> = st.esc_a.iter().map(monotonic).collect();
    let autopilot_throttle = st
        .autopilot_throttle
        .as_ref()
        .map(monotonic)
        .filter(|s| !s.is_empty());
    let mut autopilot_throttle_col = Vec::new();
    let mut esc_cols: Vec<Vec<String>> = vec![Vec::new(); esc.len()];
    let mut rec = Recording {
        thr: vec![Vec::new(); n_motors],
        bat_v: bat_v.as_ref().map(|_| Vec::new()),
        bat_a: bat_a.as_ref().map(|_| Vec::new()),
        temp_c: temp.as_ref().map(|_| Vec::new()),
        attitude: att.as_ref().map(|_| Vec::new()),
        ..Recording::default()
    };
    let mut armed_col = Vec::new();
    let mut landed_col = Vec::new();
    let mut kinds = Vec::new();
    let (mut no_motors, mut outside_window, mut other_segment) = (0, 0, 0);
    let mut last_t = f64::NEG_INFINITY;
    for i in 0..mag_end {
        let t = st.mag_ut.t_s[i];
        if t <= last_t {
            continue;
        }
        if let Some((a, b)) = opts.window_s
            && !(a..=b).contains(&t)
        {
            outside_window += 1;
            continue;
        }
        let Some((k, f)) = bracket(&motors.t_s, t, motor_gap) else {
            no_motors += 1;
            continue;
        };
        let cmd: Vec<f64> = (0..n_motors)
            .map(|m| {
                let a = motors.values[k][m];
                let b = motors.values.get(k + 1).map_or(a, |v| v[m]);
                lerp(a, b, f).clamp(0.0, 1.0)
            })
            .collect();
        let spinning = cmd.iter().any(|c| *c > 0.02);
        let armed = st
            .armed
            .as_ref()
            .map_or(spinning, |s| at_state(s, t, false));
        let landed = st.landed.as_ref().map(|s| at_state(s, t, true));
        let kind = match (armed && spinning, landed) {
            (false, _) => SegmentKind::Off,
            (true, Some(true)) => SegmentKind::Ground,
            (true, Some(false)) => SegmentKind::Flight,
            (true, None) => SegmentKind::Spinning,
        };
        if opts.segment.is_some_and(|s| s != kind) {
            other_segment += 1;
            continue;
        }
        last_t = t;
        rec.t_s.push(t);
        for (m, c) in cmd.iter().enumerate() {
            rec.thr[m].push(*c);
        }
        rec.mag_ut.push(st.mag_ut.values[i]);
        if let (Some(s), Some(c)) = (&bat_v, rec.bat_v.as_mut()) {
            c.push(at_scalar(s, t));
        }
        if let (Some(s), Some(c)) = (&bat_a, rec.bat_a.as_mut()) {
            c.push(at_scalar(s, t));
        }
        if let (Some(s), Some(c)) = (&temp, rec.temp_c.as_mut()) {
            c.push(at_scalar(s, t));
        }
        if let (Some(s), Some(c)) = (&att, rec.attitude.as_mut()) {
            c.push(at_quat(s, t));
        }
        for (s, col) in esc.iter().zip(esc_cols.iter_mut()) {
            col.push(format_extra(at_scalar(s, t)));
        }
        if let Some(s) = &autopilot_throttle {
            autopilot_throttle_col.push(format_extra(at_scalar(s, t)));
        }
        armed_col.push(if armed { "1" } else { "0" }.to_string());
        landed_col.push(landed.map_or("", |l| if l { "1" } else { "0" }).to_string());
        kinds.push(kind);
    }
    for (why, n) in [
        (
            "no motor commands within a short interval around them".to_string(),
            no_motors,
        ),
        ("outside the `window_s`".to_string(), outside_window),
        (
            "of another segment than the one asked for".to_string(),
            other_segment,
        ),
    ] {
        if n > 0 {
            report.dropped.push((why, n));
        }
    }
    if rec.len() < 2 {
        return Err(unusable(format!(
            "fewer than two magnetometer samples are left to import{}",
            report
                .dropped
                .iter()
                .map(|(w, n)| format!("; {n} dropped {w}"))
                .collect::<String>()
        )));
    }
    report.segments = segments(&rec, &kinds, mag_gap);
    for (i, col) in esc_cols.into_iter().enumerate() {
        rec.extra.push((format!("esc_{}_a", i + 1), col));
    }
    if autopilot_throttle.is_some() {
        rec.extra
            .push((AUTOPILOT_THROTTLE.into(), autopilot_throttle_col));
    }
    rec.extra.push(("armed".into(), armed_col));
    if st.landed.is_some() {
        rec.extra.push(("landed".into(), landed_col));
    }
    rec.extra.push((
        "segment".into(),
        kinds.iter().map(|k| k.name().to_string()).collect(),
    ));
    magstand_core::magnetometer_slot::MagnetometerSlot::write_into(st.mag_slot, &mut rec);
    magstand_core::magnetometer_frame::SensorToBody::write_into(st.mag_to_body, &mut rec);
    rec.check()?;
    Ok(rec)
}

/// Runs of rows of one kind; a gap in the magnetometer stream longer than `gap_s` ends a run
/// (two flights of one log are two segments).
fn segments(rec: &Recording, kinds: &[SegmentKind], gap_s: f64) -> Vec<Segment> {
    let mut out: Vec<Segment> = Vec::new();
    for (r, k) in kinds.iter().enumerate() {
        let thr = rec.overall_throttle(r);
        match out.last_mut() {
            Some(g) if g.kind == *k && rec.t_s[r] - g.span_s.1 <= gap_s => {
                g.span_s.1 = rec.t_s[r];
                g.rows += 1;
                g.max_throttle = g.max_throttle.max(thr);
            }
            _ => out.push(Segment {
                kind: *k,
                span_s: (rec.t_s[r], rec.t_s[r]),
                rows: 1,
                max_throttle: thr,
            }),
        }
    }
    out
}
