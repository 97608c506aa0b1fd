//! The recording CSV format: magstand's public file contract.
//!
//! One header row, then one row per magnetometer sample. Columns, in the order magstand writes
//! them (readers accept any order):
//!
//! | column | unit | required |
//! |---|---|---|
//! | `t_s` | s, strictly increasing | yes |
//! | `thr_1` .. `thr_N` (or a single `thr`, the overall throttle) | command 0..1 | yes |
//! | `mag_x_ut`, `mag_y_ut`, `mag_z_ut` | µT, body frame (x forward, y right, z down) | yes |
//! | `bat_v`, `bat_a` | V, A | no |
//! | `temp_c` | °C | no |
//! | `acc_{x,y,z}_mps2`, `gyr_{x,y,z}_rps` | m/s², rad/s (each group all three or none) | no |
//! | `att_qw`, `att_qx`, `att_qy`, `att_qz` | unit quaternion, body to north-east-down (all four or none) | no |
//! | `true_field_{x,y,z}_ut`, `true_dist_{x,y,z}_ut`, `true_sd_{x,y,z}_ut` | µT (simulations; all nine or none) | no |
//!
//! Every number must be finite and within its column's limit ([`magnitude_limit`]: 1e9 s for
//! `t_s`, 1e5 µT for fields, 1e4 V, 1e5 A, far beyond any real sensor), on reading and on
//! writing; motor commands are numbered from 1 without gaps. Any other column is carried
//! through verbatim. Numbers are written with fixed precision so
//! that the same recording always gives the same bytes.
use std::collections::HashMap;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};

use rayon::prelude::*;

use crate::atomic_file;
use crate::recording::{GroundTruth, ImuColumns, Recording};
use crate::{AXES, CoreError, Quat, Vec3};

/// Reads a recording from a CSV file.
///
/// The file is read whole and its rows parsed on every core by a reader for the plain form
/// magstand and most tools write (no quoted cells); anything else, and every error, goes
/// through the general CSV reader, whose messages name the row, the column and the cell.
pub fn read(path: impl AsRef<Path>) -> Result<Recording, CoreError> {
    let path = path.as_ref();
    let bytes = crate::input_file::read(path, crate::input_file::MAX_RECORDING_BYTES)
        .map_err(|e| CoreError::io(path, e))?;
    read_bytes(&bytes, path)
}

/// Reads a recording from CSV text; `origin` names it in error messages.
pub fn read_str(text: &str, origin: impl AsRef<Path>) -> Result<Recording, CoreError> {
    read_bytes(text.as_bytes(), origin.as_ref())
}

fn read_bytes(bytes: &[u8], path: &Path) -> Result<Recording, CoreError> {
    refuse_binary(bytes, path)?;
    match crate::fast_csv::read(bytes, path) {
        Some(rec) => Ok(rec),
        None => read_general(bytes, path),
    }
}

/// A flight log or another binary file where a recording was expected, said as such rather
/// than as the CSV parser's complaint about UTF-8 at byte 0. A flight log is named by its
/// magic bytes ([`crate::input_file::ULOG_MAGIC`], [`crate::input_file::DATAFLASH_MAGIC`]),
/// anything else by a NUL byte near its start, which no CSV text holds.
fn refuse_binary(bytes: &[u8], path: &Path) -> Result<(), CoreError> {
    let log = |what: &str, flag: &str| CoreError::NotText {
        path: path.to_path_buf(),
        what: what.into(),
        hint: format!(
            "; `magstand import {flag} {} --out R.csv` makes one from it",
            path.display()
        ),
    };
    if bytes.starts_with(crate::input_file::ULOG_MAGIC) {
        return Err(log("a PX4 ULog log", "--ulog"));
    }
    if bytes.starts_with(crate::input_file::DATAFLASH_MAGIC) {
        return Err(log("an ArduPilot DataFlash log", "--dataflash"));
    }
    if bytes.iter().take(4096).any(|&b| b == 0) {
        return Err(CoreError::NotText {
            path: path.to_path_buf(),
            what: "a binary file (it holds NUL bytes)".into(),
            hint: String::new(),
        });
    }
    Ok(())
}

/// The general reader alone (any CSV the `csv` crate reads, with messages that name the row,
/// the column and the cell).
pub(crate) fn read_general(bytes: &[u8], path: &Path) -> Result<Recording, CoreError> {
    read_from(bytes, path)
}

/// Column lookup over one header, with the file name for its errors.
struct Header<'a> {
    path: &'a Path,
    names: &'a [String],
    index: HashMap<String, usize>,
    used: Vec<bool>,
}

impl Header<'_> {
    fn find(&mut self, name: &str) -> Option<usize> {
        let i = *self.index.get(name)?;
        self.used[i] = true;
        Some(i)
    }

    fn require(&mut self, name: &str, expected: &str) -> Result<usize, CoreError> {
        self.find(name).ok_or_else(|| self.missing(name, expected))
    }

    /// The error for a column `name` the header lacks, with what the header looks like where
    /// that explains it.
    fn missing(&self, name: &str, expected: &str) -> CoreError {
        CoreError::MissingColumn {
            path: self.path.to_path_buf(),
            column: name.to_string(),
            expected: format!("{expected}{}", header_hint(self.names, name)),
        }
    }

    /// A group of three axis columns `{prefix}{x,y,z}{suffix}`: all present, or none.
    fn triple(&mut self, prefix: &str, suffix: &str) -> Result<Option<[usize; 3]>, CoreError> {
        let names = AXES.map(|a| format!("{prefix}{a}{suffix}"));
        let found = names.clone().map(|n| self.index.contains_key(&n));
        if found.iter().all(|f| !f) {
            return Ok(None);
        }
        let mut out = [0; 3];
        for (k, n) in names.iter().enumerate() {
            out[k] = self.require(n, "the x, y and z columns of a group come together")?;
        }
        Ok(Some(out))
    }
}

/// Why a header may lack column `name` though the file holds it: another delimiter, a line
/// before the header, names in another case. Empty where none of those is seen.
fn header_hint(names: &[String], name: &str) -> String {
    let first = names.first().map(String::as_str).unwrap_or("");
    if first.starts_with('#') {
        return format!(
            "; line 1 is `{}`: the first line must be the header (t_s, thr_1.., mag_x_ut, ...), \
             and comment lines are not read",
            shown(first)
        );
    }
    if names.len() == 1 {
        for (delimiter, said) in [(';', "`;`"), ('\t', "tabs"), (' ', "spaces")] {
            if first.contains(delimiter) {
                return format!(
                    "; the header is one column, `{}`: its names are separated by {said}, and a \
                     recording's by commas",
                    shown(first)
                );
            }
        }
    }
    if let Some(other) = names.iter().find(|n| n.eq_ignore_ascii_case(name)) {
        return format!("; the header has `{other}`: column names are lower case");
    }
    String::new()
}

/// The largest magnitude a cell of `column` may have. Far beyond any real sensor (a
/// magnetometer saturates below 0.01 T), these bounds keep arithmetic on the values finite:
/// squares and sums of 1e308 overflow.
pub fn magnitude_limit(column: &str) -> f64 {
    match column {
        "t_s" => 1e9,                                                // 31 years
        c if c.starts_with("mag_") || c.starts_with("true_") => 1e5, // 0.1 T in µT
        "bat_v" => 1e4,
        "bat_a" => 1e5,
        "temp_c" => 1e4,
        c if c.starts_with("acc_") => 1e5,
        c if c.starts_with("gyr_") => 1e4,
        _ => 1e9,
    }
}

/// A cell as an error message shows it: cut to 40 characters.
pub fn shown(cell: &str) -> String {
    let mut it = cell.chars();
    let head: String = it.by_ref().take(40).collect();
    if it.next().is_some() {
        format!("{head}... ({} bytes)", cell.len())
    } else {
        head
    }
}

fn parse_cell(path: &Path, row: usize, column: &str, cell: &str) -> Result<f64, CoreError> {
    let limit = magnitude_limit(column);
    let bad = || CoreError::BadCell {
        path: path.to_path_buf(),
        row,
        column: column.to_string(),
        found: shown(cell),
        expected: match column {
            // A logger's wall-clock stamps (Unix time, 1.7e9 s in 2025) are the likeliest
            // times past the limit: say what the column holds and how to get there.
            "t_s" => format!(
                "a finite number of magnitude at most {limit:e}: seconds from the recording's \
                 start or the logger's boot (for Unix time stamps, subtract the first row's)"
            ),
            // An optional column measured on some rows only (a battery monitor slower than
            // the magnetometer): say how to make it whole.
            "bat_v" | "bat_a" | "temp_c" if cell.trim().is_empty() => format!(
                "a finite number of magnitude at most {limit:e} on every row: an optional \
                 column holds a value wherever it is given; where `{column}` was not measured \
                 on some rows, fill them (e.g. from the rows beside them, as `magstand import` \
                 does) or leave the column out"
            ),
            _ => format!("a finite number of magnitude at most {limit:e}"),
        },
    };
    let v: f64 = cell.trim().parse().map_err(|_| bad())?;
    if crate::within(v, limit) {
        Ok(v)
    } else {
        Err(bad())
    }
}

/// Where each part of a recording sits in a file's columns.
pub(crate) struct Layout {
    pub names: Vec<String>,
    pub t_col: usize,
    pub thr_cols: Vec<usize>,
    pub thr_names: Vec<String>,
    pub overall_only: bool,
    pub mag_cols: [usize; 3],
    pub bat_v: Option<usize>,
    pub bat_a: Option<usize>,
    pub temp_c: Option<usize>,
    pub acc: Option<[usize; 3]>,
    pub gyr: Option<[usize; 3]>,
    pub att: Option<[usize; 4]>,
    pub truth: Option<[[usize; 3]; 3]>,
    pub extra_cols: Vec<usize>,
}

impl Layout {
    /// An empty recording with this layout's columns.
    pub fn empty_recording(&self) -> Recording {
        Recording {
            thr: vec![Vec::new(); self.thr_cols.len()],
            overall_only: self.overall_only,
            bat_v: self.bat_v.map(|_| Vec::new()),
            bat_a: self.bat_a.map(|_| Vec::new()),
            temp_c: self.temp_c.map(|_| Vec::new()),
            imu: (self.acc.is_some() || self.gyr.is_some()).then(ImuColumns::default),
            attitude: self.att.map(|_| Vec::new()),
            truth: self.truth.map(|_| GroundTruth::default()),
            extra: self
                .extra_cols
                .iter()
                .map(|&i| (self.names[i].clone(), Vec::new()))
                .collect(),
            ..Recording::default()
        }
    }
}

/// The columns [`layout`] reads, by name or (ending in `_`) by prefix: any other column is
/// carried as extra ([`Recording::unread_column_doubts`] says where one looks meant to be
/// read). Kept beside the reader, whose names it lists.
pub(crate) const READ_COLUMNS: [&str; 14] = [
    "t_s", "thr", "thr_", "mag_", "bat_v", "bat_a", "temp_c", "acc_", "gyr_", "att_qw", "att_qx",
    "att_qy", "att_qz", "true_",
];

/// The layout of a header's column names.
pub(crate) fn layout(names: Vec<String>, path: &Path) -> Result<Layout, CoreError> {
    if names.iter().all(|n| n.is_empty()) {
        return Err(CoreError::Csv {
            path: path.to_path_buf(),
            row: 0,
            message:
                "the file is empty; expected a header line (t_s, thr_1.., mag_x_ut, ...) and rows"
                    .into(),
        });
    }
    let mut index = HashMap::new();
    for (i, n) in names.iter().enumerate() {
        if index.insert(n.clone(), i).is_some() {
            return Err(CoreError::DuplicateColumn {
                path: path.to_path_buf(),
                column: n.clone(),
            });
        }
    }
    let mut h = Header {
        path,
        names: &names,
        used: vec![false; names.len()],
        index,
    };
    let t_col = h.require("t_s", "time in seconds")?;
    let thr_cols: Vec<usize> = if h.index.contains_key("thr_1") {
        let mut v = Vec::new();
        while let Some(i) = h.find(&format!("thr_{}", v.len() + 1)) {
            v.push(i);
        }
        v
    } else {
        vec![h.require(
            "thr",
            "motor commands thr_1..thr_N or the overall throttle thr, 0..1",
        )?]
    };
    // Motor commands are numbered from 1 without gaps: thr_1, thr_3 would otherwise read as
    // one motor and the rest as extra columns.
    if let Some(stray) = names.iter().find(|n| {
        n.strip_prefix("thr_")
            .and_then(|k| k.parse::<usize>().ok())
            .is_some_and(|k| k == 0 || k > thr_cols.len())
    }) {
        return Err(CoreError::MissingColumn {
            path: path.to_path_buf(),
            column: format!("thr_{}", thr_cols.len() + 1),
            expected: format!(
                "motor commands are numbered thr_1..thr_N without gaps, and `{stray}` is there"
            ),
        });
    }
    let overall_only = !h.index.contains_key("thr_1");
    let mag_cols = h
        .triple("mag_", "_ut")?
        .ok_or_else(|| h.missing("mag_x_ut", "magnetometer x, y, z in microtesla"))?;
    let bat_v = h.find("bat_v");
    let bat_a = h.find("bat_a");
    let temp_c = h.find("temp_c");
    let acc = h.triple("acc_", "_mps2")?;
    let gyr = h.triple("gyr_", "_rps")?;
    let att = {
        let names = ["att_qw", "att_qx", "att_qy", "att_qz"];
        if names.iter().any(|n| h.index.contains_key(*n)) {
            let mut c = [0; 4];
            for (k, n) in names.iter().enumerate() {
                c[k] = h.require(
                    n,
                    "an attitude comes as all four of att_qw, att_qx, att_qy, att_qz",
                )?;
            }
            Some(c)
        } else {
            None
        }
    };
    let tf = h.triple("true_field_", "_ut")?;
    let td = h.triple("true_dist_", "_ut")?;
    let ts = h.triple("true_sd_", "_ut")?;
    let truth = match (tf, td, ts) {
        (None, None, None) => None,
        (Some(f), Some(d), Some(s)) => Some([f, d, s]),
        _ => {
            let missing = [
                ("true_field_x_ut", tf),
                ("true_dist_x_ut", td),
                ("true_sd_x_ut", ts),
            ]
            .into_iter()
            .find(|(_, c)| c.is_none())
            .map(|(n, _)| n)
            .unwrap_or("true_field_x_ut");
            return Err(CoreError::MissingColumn {
                path: path.to_path_buf(),
                column: missing.into(),
                expected: "ground truth comes as all of true_field, true_dist and true_sd".into(),
            });
        }
    };
    let extra_cols: Vec<usize> = (0..names.len()).filter(|&i| !h.used[i]).collect();

    let thr_names: Vec<String> = if overall_only {
        vec!["thr".into()]
    } else {
        (1..=thr_cols.len()).map(|i| format!("thr_{i}")).collect()
    };
    Ok(Layout {
        names,
        t_col,
        thr_cols,
        thr_names,
        overall_only,
        mag_cols,
        bat_v,
        bat_a,
        temp_c,
        acc,
        gyr,
        att,
        truth,
        extra_cols,
    })
}

fn read_from(reader: impl Read, path: &Path) -> Result<Recording, CoreError> {
    let mut csv = csv::ReaderBuilder::new()
        .has_headers(true)
        .from_reader(reader);
    let csv_err = |row: usize, e: csv::Error| CoreError::Csv {
        path: path.to_path_buf(),
        row,
        message: e.to_string(),
    };
    let names: Vec<String> = csv
        .headers()
        .map_err(|e| csv_err(0, e))?
        .iter()
        .map(|s| s.trim().to_string())
        .collect();
    let lay = layout(names, path)?;
    let mut rec = lay.empty_recording();
    let Layout {
        names,
        t_col,
        thr_cols,
        thr_names,
        overall_only: _,
        mag_cols,
        bat_v,
        bat_a,
        temp_c,
        acc,
        gyr,
        att,
        truth,
        extra_cols,
    } = lay;
    let mut record = csv::StringRecord::new();
    let mut row = 0usize;
    loop {
        match csv.read_record(&mut record) {
            Ok(false) => break,
            Ok(true) => {}
            Err(e) => return Err(csv_err(row + 1, e)),
        }
        row += 1;
        let num = |i: usize| parse_cell(path, row, &names[i], &record[i]);
        let vec3 = |c: [usize; 3]| -> Result<Vec3, CoreError> {
            Ok(Vec3::new(num(c[0])?, num(c[1])?, num(c[2])?))
        };
        let t = num(t_col)?;
        if let Some(&prev) = rec.t_s.last()
            && t <= prev
        {
            return Err(CoreError::TimeNotIncreasing {
                path: path.to_path_buf(),
                row,
                t_s: t,
                previous_s: prev,
            });
        }
        rec.t_s.push(t);
        for (k, &c) in thr_cols.iter().enumerate() {
            let v = num(c)?;
            if !(0.0..=1.0).contains(&v) {
                return Err(CoreError::BadCell {
                    path: path.to_path_buf(),
                    row,
                    column: thr_names[k].clone(),
                    found: shown(&record[c]),
                    expected: "a motor command in 0..1".into(),
                });
            }
            rec.thr[k].push(v);
        }
        rec.mag_ut.push(vec3(mag_cols)?);
        for (col, dst) in [
            (bat_v, &mut rec.bat_v),
            (bat_a, &mut rec.bat_a),
            (temp_c, &mut rec.temp_c),
        ] {
            if let (Some(c), Some(d)) = (col, dst.as_mut()) {
                d.push(num(c)?);
            }
        }
        // A supply voltage cannot be negative: a replay below 0 V would run the motors
        // backwards. (A sensor that did not measure has no column; 0 V is a dead supply.)
        if let (Some(c), Some(v)) = (bat_v, rec.bat_v.as_ref().and_then(|v| v.last()))
            && *v < 0.0
        {
            return Err(CoreError::BadCell {
                path: path.to_path_buf(),
                row,
                column: "bat_v".into(),
                found: shown(&record[c]),
                expected: "a supply voltage of 0 V or more (leave the column out where the voltage was not measured)".into(),
            });
        }
        if let Some(imu) = rec.imu.as_mut() {
            // A missing group is stored as zeros only when its partner exists; `check` keeps lengths equal.
            imu.acc_mps2.push(match acc {
                Some(c) => vec3(c)?,
                None => Vec3::zeros(),
            });
            imu.gyr_rps.push(match gyr {
                Some(c) => vec3(c)?,
                None => Vec3::zeros(),
            });
        }
        if let (Some(c), Some(q)) = (att, rec.attitude.as_mut()) {
            let v = nalgebra::Vector4::new(num(c[1])?, num(c[2])?, num(c[3])?, num(c[0])?);
            // Logged quaternions are normalized to float precision; anything far from unit
            // length is not an attitude.
            if (v.norm() - 1.0).abs() > 1e-3 {
                return Err(CoreError::BadCell {
                    path: path.to_path_buf(),
                    row,
                    column: "att_qw".into(),
                    found: format!("a quaternion of norm {:.6}", v.norm()),
                    expected: "a unit quaternion (norm 1)".into(),
                });
            }
            q.push(Quat::from_quaternion(nalgebra::Quaternion::from(v)));
        }
        if let (Some([f, d, s]), Some(g)) = (truth, rec.truth.as_mut()) {
            g.field_ut.push(vec3(f)?);
            g.dist_ut.push(vec3(d)?);
            g.sd_ut.push(vec3(s)?);
        }
        for (k, &c) in extra_cols.iter().enumerate() {
            rec.extra[k].1.push(record[c].to_string());
        }
    }
    if row == 0 {
        return Err(CoreError::TooFewRows {
            path: path.to_path_buf(),
            rows: 0,
            needed: 1,
            why: "(a recording needs at least one sample)".into(),
        });
    }
    Ok(rec)
}

/// Header names of a recording, in the order [`write()`] puts them.
pub fn header(rec: &Recording) -> Vec<String> {
    let mut h = vec!["t_s".to_string()];
    if rec.overall_only && rec.thr.len() == 1 {
        h.push("thr".into());
    } else {
        h.extend((1..=rec.thr.len()).map(|i| format!("thr_{i}")));
    }
    h.extend(AXES.map(|a| format!("mag_{a}_ut")));
    for (name, present) in [
        ("bat_v", rec.bat_v.is_some()),
        ("bat_a", rec.bat_a.is_some()),
        ("temp_c", rec.temp_c.is_some()),
    ] {
        if present {
            h.push(name.into());
        }
    }
    if rec.imu.is_some() {
        h.extend(AXES.map(|a| format!("acc_{a}_mps2")));
        h.extend(AXES.map(|a| format!("gyr_{a}_rps")));
    }
    if rec.attitude.is_some() {
        h.extend(["att_qw", "att_qx", "att_qy", "att_qz"].map(String::from));
    }
    if rec.truth.is_some() {
        for group in ["true_field", "true_dist", "true_sd"] {
            h.extend(AXES.map(|a| format!("{group}_{a}_ut")));
        }
    }
    h.extend(rec.extra.iter().map(|(n, _)| n.clone()));
    h
}

/// Rows formatted by one worker at a time when writing.
const WRITE_CHUNK_ROWS: usize = 4096;

/// Writes a recording as CSV to any writer.
///
/// The rows are formatted in chunks on every core, a few chunks per core at a time, and
/// written in order: the text is the same as one row after the other, and memory stays at a
/// few chunks whatever the recording's length.
pub fn write_to(rec: &Recording, mut out: impl Write, origin: &Path) -> Result<(), CoreError> {
    rec.check()?;
    let names = header(rec);
    // What is written must read back: every number finite and within its column's limit.
    let limits: Vec<f64> = names.iter().map(|n| magnitude_limit(n)).collect();
    let exact_time = needs_exact_time(&rec.t_s);
    let row_text = RowText {
        rec,
        names: &names,
        limits: &limits,
        exact_time,
        origin,
    };
    let mut head = csv::WriterBuilder::new().from_writer(Vec::new());
    head.write_record(&names).map_err(|e| csv_io(origin, e))?;
    out.write_all(&written(head, origin)?)
        .map_err(|e| CoreError::io(origin, e))?;
    let batch_rows = WRITE_CHUNK_ROWS * 4 * rayon::current_num_threads().max(1);
    let mut start = 0;
    while start < rec.len() {
        let end = (start + batch_rows).min(rec.len());
        let chunks: Vec<std::ops::Range<usize>> = (start..end)
            .step_by(WRITE_CHUNK_ROWS)
            .map(|a| a..(a + WRITE_CHUNK_ROWS).min(end))
            .collect();
        let texts: Vec<Result<Vec<u8>, CoreError>> = chunks
            .into_par_iter()
            .map(|rows| row_text.format(rows))
            .collect();
        // The first bad cell in row order is the error, as a row-by-row writer would find it.
        for text in texts {
            out.write_all(&text?)
                .map_err(|e| CoreError::io(origin, e))?;
        }
        start = end;
    }
    out.flush().map_err(|e| CoreError::io(origin, e))?;
    Ok(())
}

/// A failed write is the file system's (a full disk, a lost mount), never the CSV's: say so.
fn csv_io(origin: &Path, e: csv::Error) -> CoreError {
    match e.into_kind() {
        csv::ErrorKind::Io(e) => CoreError::io(origin, e),
        other => CoreError::io(origin, std::io::Error::other(format!("{other:?}"))),
    }
}

/// The text a CSV writer into memory holds.
fn written(w: csv::Writer<Vec<u8>>, origin: &Path) -> Result<Vec<u8>, CoreError> {
    w.into_inner()
        .map_err(|e| CoreError::io(origin, std::io::Error::other(e.to_string())))
}

/// What formatting the rows of one recording needs.
struct RowText<'a> {
    rec: &'a Recording,
    names: &'a [String],
    limits: &'a [f64],
    exact_time: bool,
    origin: &'a Path,
}

impl RowText<'_> {
    /// The CSV text of `rows`.
    fn format(&self, rows: std::ops::Range<usize>) -> Result<Vec<u8>, CoreError> {
        use std::fmt::Write as _;
        let rec = self.rec;
        let mut w = csv::WriterBuilder::new().from_writer(Vec::with_capacity(rows.len() * 96));
        let mut values: Vec<(f64, usize)> = Vec::new();
        // The row's numbers as one text, and where each ends: no allocation per cell.
        let mut line = String::new();
        let mut ends: Vec<usize> = Vec::new();
        for r in rows {
            values.clear();
            values.push((rec.t_s[r], if self.exact_time { EXACT } else { 6 }));
            values.extend(rec.thr.iter().map(|m| (m[r], 6)));
            push3(&mut values, &rec.mag_ut[r], 4);
            for c in [&rec.bat_v, &rec.bat_a, &rec.temp_c].into_iter().flatten() {
                values.push((c[r], 4));
            }
            if let Some(i) = &rec.imu {
                push3(&mut values, &i.acc_mps2[r], 5);
                push3(&mut values, &i.gyr_rps[r], 6);
            }
            if let Some(q) = &rec.attitude {
                let q = q[r].quaternion();
                values.extend([q.w, q.i, q.j, q.k].map(|c| (c, 7)));
            }
            if let Some(g) = &rec.truth {
                push3(&mut values, &g.field_ut[r], 4);
                push3(&mut values, &g.dist_ut[r], 4);
                push3(&mut values, &g.sd_ut[r], 4);
            }
            line.clear();
            ends.clear();
            for (k, &(v, decimals)) in values.iter().enumerate() {
                if !crate::within(v, self.limits[k]) {
                    return Err(CoreError::BadCell {
                        path: self.origin.to_path_buf(),
                        row: r + 1,
                        column: self.names[k].clone(),
                        found: v.to_string(),
                        expected: format!(
                            "a finite number of magnitude at most {:e} (nothing was written)",
                            self.limits[k]
                        ),
                    });
                }
                // `+ 0.0` turns -0.0 into 0.0 so that signs of zero never differ between runs.
                match decimals {
                    // Infallible: writing to a String.
                    EXACT => {
                        let _ = write!(line, "{}", v + 0.0);
                    }
                    _ => crate::fixed_decimal::push_fixed(&mut line, v + 0.0, decimals),
                }
                ends.push(line.len());
            }
            let numbers = ends
                .iter()
                .scan(0, |from, &to| Some(&line[std::mem::replace(from, to)..to]));
            let extra = rec.extra.iter().map(|(_, c)| c[r].as_str());
            w.write_record(numbers.chain(extra))
                .map_err(|e| csv_io(self.origin, e))?;
        }
        written(w, self.origin)
    }
}

/// Marks a cell written with the shortest text that reads back as exactly the same number.
const EXACT: usize = usize::MAX;

/// Whether two times of `t_s` would print alike at 6 decimals (samples less than a
/// microsecond apart): the whole column is then written exactly, so that what is written
/// reads back with time still strictly increasing.
fn needs_exact_time(t_s: &[f64]) -> bool {
    let six = |t: f64| format!("{:.6}", t + 0.0).parse::<f64>().unwrap_or(t);
    t_s.windows(2)
        .any(|w| w[1] - w[0] < 2e-6 && six(w[1]) <= six(w[0]))
}

fn push3(values: &mut Vec<(f64, usize)>, v: &Vec3, decimals: usize) {
    values.extend((0..3).map(|k| (v[k], decimals)));
}

/// Writes a recording to a file atomically: the file appears complete or not at all.
pub fn write(rec: &Recording, path: impl AsRef<Path>) -> Result<(), CoreError> {
    stage(rec, path)?.commit()
}

/// Writes a recording beside `path`, staged: nothing at `path` changes until
/// [`atomic_file::Staged::commit`] (for files that must change together).
pub fn stage(rec: &Recording, path: impl AsRef<Path>) -> Result<atomic_file::Staged, CoreError> {
    let path: PathBuf = path.as_ref().to_path_buf();
    atomic_file::stage_with(&path, |w| write_to(rec, w, &path))
}

/// Formats a number the way [`write()`] formats extra numeric columns (6 decimals, no -0).
pub fn format_extra(x: f64) -> String {
    let mut s = String::new();
    crate::fixed_decimal::push_fixed(&mut s, x + 0.0, 6);
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = "t_s,thr_1,thr_2,mag_x_ut,mag_y_ut,mag_z_ut,bat_v,note\n\
                        0.0,0.0,0.0,20,1,-45,12.4,a\n\
                        0.5,0.4,0.6,21,2,-46,12.1,b\n";

    fn err(text: &str) -> String {
        read_str(text, "r.csv").unwrap_err().to_string()
    }

    #[test]
    fn reads_motors_optional_and_extra_columns() {
        let r = read_str(GOOD, "r.csv").unwrap();
        assert_eq!(r.motor_count(), 2);
        assert!(!r.overall_only);
        assert!((r.overall_throttle(1) - 0.5).abs() < 1e-15);
        assert_eq!(r.bat_v.as_deref(), Some(&[12.4, 12.1][..]));
        assert_eq!(
            r.extra,
            vec![("note".to_string(), vec!["a".to_string(), "b".to_string()])]
        );
    }

    /// An optional column left empty on rows where it was not measured is refused by name,
    /// with how to make it whole.
    #[test]
    fn an_empty_optional_cell_says_how_to_fill_it() {
        let e = err("t_s,thr,mag_x_ut,mag_y_ut,mag_z_ut,bat_v\n0,0,20,0,40,\n0.1,0,20,0,40,16\n");
        assert!(
            e.contains("row 1, column `bat_v`")
                && e.contains("fill them")
                && e.contains("leave the column out"),
            "{e}"
        );
    }

    /// A column a user meant to be read but named otherwise is carried through as extra and
    /// not used: the recording says so where the column it looks like is absent, and says
    /// nothing of the extra columns `import` writes or of a lookalike beside the real one.
    #[test]
    fn a_supply_voltage_that_drops_out_while_the_motors_run_is_doubted() {
        let text = |cells: &[&str]| {
            let mut t = String::from("t_s,thr,mag_x_ut,mag_y_ut,mag_z_ut,bat_v\n");
            for (r, c) in cells.iter().enumerate() {
                t += &format!("{}.0,{c},20,0,40,", r);
                t += if *c == "0" { "16.8\n" } else { "16.2\n" };
            }
            t
        };
        let mut rows = vec!["0", "0.5", "0.5", "0.5", "0.5", "0"];
        let clean = read_str(&text(&rows), "r.csv").unwrap();
        assert!(clean.doubts().is_empty(), "{:?}", clean.doubts());
        // A 0 V sample at the fourth data row while the motors run.
        let glitch = text(&rows).replacen("3.0,0.5,20,0,40,16.2", "3.0,0.5,20,0,40,0", 1);
        let d = read_str(&glitch, "r.csv").unwrap().doubts();
        assert!(
            d.len() == 1
                && d[0].contains("bat_v")
                && d[0].contains("on 1 of the rows")
                && d[0].contains("data row 4")
                && d[0].contains("16.200 V"),
            "{d:?}"
        );
        // A supply switched off with the motors (0 V while nothing is commanded) is no doubt.
        rows.push("0");
        let off = text(&rows).replace("5.0,0,20,0,40,16.8", "5.0,0,20,0,40,0");
        let off = read_str(&off, "r.csv").unwrap();
        assert!(off.doubts().is_empty(), "{:?}", off.doubts());
    }

    #[test]
    fn a_temperature_that_steps_faster_than_a_board_warms_is_doubted() {
        // One row a second, warming 0.5 °C a row: no doubt.
        let text = |glitch: Option<(usize, &str)>| {
            let mut t = String::from("t_s,thr,mag_x_ut,mag_y_ut,mag_z_ut,temp_c\n");
            for r in 0..8 {
                let temp = match glitch {
                    Some((g, v)) if g == r => v.to_string(),
                    _ => format!("{}", 25.0 + 0.5 * r as f64),
                };
                t += &format!("{r}.0,0.5,20,0,40,{temp}\n");
            }
            t
        };
        let clean = read_str(&text(None), "r.csv").unwrap();
        assert!(clean.doubts().is_empty(), "{:?}", clean.doubts());
        // An unread sensor's 0 °C at the sixth data row: a step down and one back up.
        let d = read_str(&text(Some((5, "0"))), "r.csv").unwrap().doubts();
        assert!(
            d.len() == 1
                && d[0].contains("temp_c")
                && d[0].contains("rows 2 time(s)")
                && d[0].contains("into data row 6")
                && d[0].contains("27.00 -> 0.00"),
            "{d:?}"
        );
        // Ten degrees over a 20-minute gap between two runs is a board cooling, not a doubt.
        let gap = "t_s,thr,mag_x_ut,mag_y_ut,mag_z_ut,temp_c\n\
                   0,0.5,20,0,40,25\n1,0.5,20,0,40,25.5\n2,0.5,20,0,40,26\n\
                   1202,0.5,20,0,40,16\n1203,0.5,20,0,40,16.5\n1204,0.5,20,0,40,17\n";
        let gap = read_str(gap, "r.csv").unwrap();
        assert!(gap.doubts().is_empty(), "{:?}", gap.doubts());
    }

    #[test]
    fn a_field_that_leaves_and_comes_back_within_a_row_is_doubted_on_a_stand() {
        // A stand's field: noise, then a step up where the motors start (no doubt).
        let text = |spike_ut: f64, attitude: bool| {
            let mut t = String::from("t_s,thr,mag_x_ut,mag_y_ut,mag_z_ut");
            t += if attitude {
                ",att_qw,att_qx,att_qy,att_qz\n"
            } else {
                "\n"
            };
            for r in 0..40 {
                let x = 20.0 + 0.1 * ((r * 7 % 5) as f64) + if r >= 20 { 15.0 } else { 0.0 };
                let x = if r == 30 { x + spike_ut } else { x };
                t += &format!("{r}.0,0.5,{x},0,40");
                t += if attitude { ",1,0,0,0\n" } else { "\n" };
            }
            t
        };
        let clean = read_str(&text(0.0, false), "r.csv").unwrap();
        assert!(clean.doubts().is_empty(), "{:?}", clean.doubts());
        let d = read_str(&text(300.0, false), "r.csv").unwrap().doubts();
        assert!(
            d.len() == 1
                && d[0].contains("on 1 row(s)")
                && d[0].contains("data row 31")
                && d[0].contains("mag_x_ut"),
            "{d:?}"
        );
        // In flight the Earth's field turns with the vehicle: not doubted.
        let flight = read_str(&text(300.0, true), "r.csv").unwrap();
        assert!(flight.doubts().is_empty(), "{:?}", flight.doubts());
    }

    #[test]
    fn unread_columns_that_look_meant_are_doubted() {
        let doubts = |header: &str, cells: &str| {
            let text =
                format!("t_s,thr_1,mag_x_ut,mag_y_ut,mag_z_ut,{header}\n0,0,20,0,40,{cells}\n");
            read_str(&text, "r.csv").unwrap().doubts()
        };
        let d = doubts("Bat_V,vbat,Temp,current_a,q0,ACC_X_MPS2", "12,12,25,3,1,0");
        assert_eq!(d.len(), 6, "{d:#?}");
        assert!(
            d[5].contains("`ACC_X_MPS2` is not read") && d[5].contains("`acc_x_mps2`"),
            "{d:#?}"
        );
        assert!(
            d[0].contains("`Bat_V` is not read") && d[0].contains("`bat_v`"),
            "{d:#?}"
        );
        for (i, (name, read)) in [
            ("vbat", "bat_v"),
            ("Temp", "temp_c"),
            ("current_a", "bat_a"),
            ("q0", "att_qw"),
        ]
        .into_iter()
        .enumerate()
        {
            let doubt = &d[i + 1];
            assert!(
                doubt.contains(&format!("`{name}` is not read"))
                    && doubt.contains(&format!("as `{read}`")),
                "doubt {i} of {d:#?}"
            );
        }
        // The read column is there: its lookalike is something else, said nothing of.
        assert_eq!(
            doubts("bat_v,vbat_raw,temp_c,temp_motor_c", "12,12,25,40"),
            Vec::<String>::new()
        );
        // `import`'s extra columns, and a time stamp (which holds `amp`).
        let import =
            "autopilot_throttle,armed,landed,segment,mag_slot,mag_to_body,esc_1_a,timestamp";
        assert_eq!(
            doubts(import, "0.1,1,0,flight,px4:0,1 0 0 0 1 0 0 0 1,3,5"),
            Vec::<String>::new()
        );
    }

    /// A logger's wall-clock stamps (Unix time) are past the time column's limit: the error
    /// names the file, the row and the column, and says what the column holds and how to get
    /// there.
    #[test]
    fn unix_time_stamps_are_refused_with_how_to_rebase_them() {
        let e = err("t_s,thr,mag_x_ut,mag_y_ut,mag_z_ut\n\
                     1764428400.000,0,1,2,3\n\
                     1764428400.020,0,1,2,3\n");
        for says in [
            "r.csv",
            "row 1",
            "t_s",
            "1764428400.000",
            "subtract the first row's",
        ] {
            assert!(e.contains(says), "{says:?} not in: {e}");
        }
        let e = err("t_s,thr,mag_x_ut,mag_y_ut,mag_z_ut\n0,0,1,2,3e6\n");
        assert!(e.contains("mag_z_ut") && !e.contains("subtract"), "{e}");
    }

    #[test]
    fn write_then_read_is_identity_at_written_precision() {
        let r = read_str(GOOD, "r.csv").unwrap();
        let mut buf = Vec::new();
        write_to(&r, &mut buf, Path::new("mem")).unwrap();
        let back = read_str(std::str::from_utf8(&buf).unwrap(), "mem").unwrap();
        assert_eq!(r, back);
    }

    #[test]
    fn attitude_round_trips_and_must_be_unit_and_complete() {
        let text = "t_s,thr,mag_x_ut,mag_y_ut,mag_z_ut,att_qw,att_qx,att_qy,att_qz\n\
                    0,0,1,2,3,1,0,0,0\n\
                    1,0,1,2,3,0.7071068,0,0,0.7071068\n";
        let r = read_str(text, "r.csv").unwrap();
        let q = r.attitude.as_ref().unwrap();
        // The second row is a yaw of 90 degrees: body x points east.
        let east = q[1] * Vec3::x();
        assert!((east - Vec3::y()).norm() < 1e-6, "{east:?}");
        let mut buf = Vec::new();
        write_to(&r, &mut buf, Path::new("mem")).unwrap();
        let back = read_str(std::str::from_utf8(&buf).unwrap(), "mem").unwrap();
        assert_eq!(r, back);
        let e = err(
            "t_s,thr,mag_x_ut,mag_y_ut,mag_z_ut,att_qw,att_qx,att_qy,att_qz\n0,0,1,2,3,2,0,0,0\n",
        );
        assert!(e.contains("row 1") && e.contains("unit quaternion"), "{e}");
        let e = err("t_s,thr,mag_x_ut,mag_y_ut,mag_z_ut,att_qw\n0,0,1,2,3,1\n");
        assert!(e.contains("att_qx"), "{e}");
    }

    #[test]
    fn missing_column_is_named() {
        let e = err("t_s,thr,mag_x_ut,mag_y_ut\n0,0,1,2\n");
        assert!(e.contains("r.csv") && e.contains("mag_z_ut"), "{e}");
        let e = err("t_s,mag_x_ut,mag_y_ut,mag_z_ut\n0,1,2,3\n");
        assert!(e.contains("`thr`"), "{e}");
    }

    #[test]
    fn a_header_that_is_not_a_recordings_says_why() {
        let e = err("t_s;thr;mag_x_ut;mag_y_ut;mag_z_ut\n0;0;1;2;3\n");
        assert!(e.contains("`t_s`") && e.contains("separated by `;`"), "{e}");
        let e = err("t_s\tthr\tmag_x_ut\n0\t0\t1\n");
        assert!(e.contains("separated by tabs"), "{e}");
        let e = err("# bench 3\nt_s,thr,mag_x_ut,mag_y_ut,mag_z_ut\n0,0,1,2,3\n");
        assert!(e.contains("line 1 is `# bench 3`"), "{e}");
        let e = err("T_S,THR,MAG_X_UT,MAG_Y_UT,MAG_Z_UT\n0,0,1,2,3\n");
        assert!(e.contains("the header has `T_S`"), "{e}");
        let e = err("t_s,thr,MAG_X_UT,MAG_Y_UT,MAG_Z_UT\n0,0,1,2,3\n");
        assert!(e.contains("`mag_x_ut`") && e.contains("`MAG_X_UT`"), "{e}");
        // A header that merely lacks the column gets no guess.
        let e = err("t_s,thr,mag_x_ut,mag_y_ut\n0,0,1,2\n");
        assert!(!e.contains(';'), "{e}");
    }

    #[test]
    fn a_flight_log_or_binary_file_is_named_as_such() {
        let read = |bytes: &[u8]| read_bytes(bytes, Path::new("f")).unwrap_err().to_string();
        let e = read(b"ULog\x01\x12\x35\x01\x00\x00");
        assert!(
            e.contains("a PX4 ULog log") && e.contains("import --ulog f"),
            "{e}"
        );
        let e = read(&[0xA3, 0x95, 0x80, 0x80, 0x59]);
        assert!(e.contains("DataFlash") && e.contains("--dataflash"), "{e}");
        let e = read(b"t_s,thr\x00,mag");
        assert!(e.contains("a binary file"), "{e}");
    }

    #[test]
    fn nan_and_text_cells_name_row_and_column() {
        let e = err("t_s,thr,mag_x_ut,mag_y_ut,mag_z_ut\n0,0,1,2,3\n1,0.5,NaN,2,3\n");
        assert!(
            e.contains("row 2") && e.contains("mag_x_ut") && e.contains("NaN"),
            "{e}"
        );
        let e = err("t_s,thr,mag_x_ut,mag_y_ut,mag_z_ut\n0,zero,1,2,3\n");
        assert!(e.contains("row 1") && e.contains("`thr`"), "{e}");
    }

    #[test]
    fn time_going_backwards_is_refused() {
        let e = err("t_s,thr,mag_x_ut,mag_y_ut,mag_z_ut\n1,0,1,2,3\n0.5,0,1,2,3\n");
        assert!(e.contains("row 2") && e.contains("t_s"), "{e}");
    }

    #[test]
    fn throttle_outside_unit_range_is_refused() {
        let e = err("t_s,thr,mag_x_ut,mag_y_ut,mag_z_ut\n0,1.5,1,2,3\n");
        assert!(e.contains("0..1") && e.contains("row 1"), "{e}");
    }

    #[test]
    fn ragged_rows_and_empty_files_are_refused() {
        let e = err("t_s,thr,mag_x_ut,mag_y_ut,mag_z_ut\n0,0,1,2\n");
        assert!(e.contains("row 1") && e.contains("malformed"), "{e}");
        let e = err("t_s,thr,mag_x_ut,mag_y_ut,mag_z_ut\n");
        assert!(e.contains("0 data rows"), "{e}");
        let e = err("t_s,thr,thr,mag_x_ut,mag_y_ut,mag_z_ut\n");
        assert!(e.contains("more than once"), "{e}");
    }

    #[test]
    fn partial_ground_truth_is_refused() {
        let e = err(
            "t_s,thr,mag_x_ut,mag_y_ut,mag_z_ut,true_dist_x_ut,true_dist_y_ut,true_dist_z_ut\n0,0,1,2,3,0,0,0\n",
        );
        assert!(e.contains("true_field_x_ut"), "{e}");
    }

    /// Regression: a full disk was reported as "row 0: malformed CSV", which sends a user
    /// looking for a bad cell. `/dev/full` fails every write with ENOSPC.
    #[test]
    #[cfg(target_os = "linux")]
    fn a_full_disk_is_named_as_such() {
        let rec = read_str(GOOD, "r.csv").unwrap();
        let full = std::fs::OpenOptions::new()
            .write(true)
            .open("/dev/full")
            .unwrap();
        let e = write_to(&rec, full, Path::new("out.csv"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("out.csv") && e.contains("No space left") && !e.contains("malformed"),
            "{e}"
        );
    }

    #[test]
    fn atomic_write_leaves_no_file_on_error() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("out.csv");
        let mut bad = read_str(GOOD, "r.csv").unwrap();
        bad.mag_ut.pop();
        assert!(write(&bad, &path).is_err());
        assert_eq!(
            std::fs::read_dir(dir.path()).unwrap().count(),
            0,
            "no file, no temporary left"
        );
    }

    /// Regression, found by the property test below: times less than a microsecond apart
    /// were written at 6 decimals as the same time, so the file written could not be read.
    #[test]
    fn sub_microsecond_times_are_written_exactly_and_read_back() {
        let text =
            "t_s,thr,mag_x_ut,mag_y_ut,mag_z_ut\n0.0,0,1,2,3\n0.0000001,0,1,2,3\n1.5,0,1,2,3\n";
        let rec = read_str(text, "fast.csv").unwrap();
        let mut out = Vec::new();
        write_to(&rec, &mut out, Path::new("fast.csv")).unwrap();
        let again = read_str(std::str::from_utf8(&out).unwrap(), "fast.csv").unwrap();
        assert_eq!(again.t_s, rec.t_s);
        // An ordinary clock keeps its fixed 6 decimals.
        let mut out = Vec::new();
        write_to(
            &read_str(GOOD, "r.csv").unwrap(),
            &mut out,
            Path::new("r.csv"),
        )
        .unwrap();
        let text = String::from_utf8(out).unwrap();
        assert!(text.contains("\n0.500000,"), "{text}");
    }

    /// One cell of a valid recording replaced by hostile text.
    fn hostile_cell() -> impl proptest::strategy::Strategy<Value = String> {
        use proptest::prelude::*;
        prop_oneof![
            Just("1e308".to_string()),
            Just("-1e308".to_string()),
            Just("1e-320".to_string()),
            Just("NaN".to_string()),
            Just("inf".to_string()),
            Just("".to_string()),
            Just("1e6".to_string()),
            Just("-0".to_string()),
            Just("0x10".to_string()),
            any::<f64>().prop_map(|x| x.to_string()),
            // Printable text without `"` and `,`, which change the row's structure rather
            // than a cell (arbitrary_text_never_panics covers those).
            "[ !#-+\\--~]{0,12}",
        ]
    }

    proptest::proptest! {
        #![proptest_config(crate::file_fuzzing::config(256))]

        #[test]
        fn arbitrary_text_never_panics(s in "(?s).{0,300}") {
            let _ = read_str(&s, "fuzz.csv");
        }

        /// A recording with one hostile cell is refused with the row and column named, or
        /// read with every number finite and written back unchanged.
        #[test]
        fn one_hostile_cell_is_refused_by_name_or_round_trips(
            row in 1usize..3,
            column in 0usize..7,
            cell in hostile_cell(),
        ) {
            let mut lines: Vec<Vec<String>> = GOOD
                .lines()
                .map(|l| l.split(',').map(str::to_string).collect())
                .collect();
            let name = lines[0][column].clone();
            lines[row][column] = cell.clone();
            let text: String = lines.iter().map(|l| l.join(",") + "\n").collect();
            match read_str(&text, "hostile.csv") {
                Err(e) => {
                    let e = e.to_string();
                    proptest::prop_assert!(
                        e.contains("hostile.csv") && e.contains(&name),
                        "{cell:?} in `{name}` row {row}: {e}"
                    );
                }
                Ok(rec) => {
                    let numbers = rec.t_s.iter().chain(rec.thr.iter().flatten())
                        .chain(rec.mag_ut.iter().flat_map(|v| v.iter()))
                        .chain(rec.bat_v.iter().flatten());
                    for x in numbers {
                        proptest::prop_assert!(x.is_finite(), "{cell:?} read as {x}");
                    }
                    let mut out = Vec::new();
                    write_to(&rec, &mut out, Path::new("again.csv")).unwrap();
                    let again = read_str(std::str::from_utf8(&out).unwrap(), "again.csv").unwrap();
                    proptest::prop_assert_eq!(again.len(), rec.len());
                }
            }
        }
    }
}
