//! `runs.csv`: one row per run and method, every figure a summary needs, so that shards merged
//! from their files give the same summary as one machine would.
//!
//! Numbers are written in Rust's shortest round-trip form, so reading a file back gives the
//! same bits; a figure that does not apply (parameter errors of a non-fixed structure, an empty
//! throttle bin, a failed fit) is an empty cell.
use std::path::Path;

use crate::StudyError;
use crate::crlb::{PARAMS_PER_AXIS, parameter_names};
use crate::run::{BINS, Figures, MethodOutcome};
use crate::summary::FigureId;
use magstand_core::{AXES, atomic_file};

/// The scalar figures' columns, in the file's order (the reader takes them in this order).
const SCALARS: [FigureId; 7] = [
    FigureId::RmseXUt,
    FigureId::RmseYUt,
    FigureId::RmseZUt,
    FigureId::RmseUt,
    FigureId::E20RmsPct,
    FigureId::HeadingBeforeDeg,
    FigureId::HeadingAfterDeg,
];

/// Largest magnitude of a figure in `runs.csv` (errors in µT or degrees, ratios, parameter
/// errors): far beyond any real result, and small enough that the summary's squares and sums
/// over millions of runs stay finite.
pub const MAX_FIGURE: f64 = 1e12;

/// The header of `runs.csv`.
pub fn header() -> Vec<String> {
    let mut h: Vec<String> = ["run", "seed", "method", "error"]
        .iter()
        .map(|s| s.to_string())
        .collect();
    h.extend(SCALARS.iter().map(|s| s.name().to_string()));
    h.extend((0..BINS).map(|b| format!("bin_{b}_rmse_ut")));
    for prefix in ["perr", "crlb"] {
        for axis in AXES {
            for p in parameter_names() {
                h.push(format!("{prefix}_{axis}_{p}"));
            }
        }
    }
    h
}

fn number(v: f64) -> String {
    if v.is_finite() {
        format!("{v}")
    } else {
        String::new()
    }
}

fn flat(v: &Option<[Vec<f64>; 3]>) -> Vec<String> {
    match v {
        Some(axes) => axes.iter().flatten().map(|&x| number(x)).collect(),
        None => vec![String::new(); 3 * PARAMS_PER_AXIS],
    }
}

/// The file's bytes.
pub fn to_bytes(outcomes: &[MethodOutcome]) -> Result<Vec<u8>, csv::Error> {
    let mut w = csv::Writer::from_writer(Vec::new());
    w.write_record(header())?;
    for o in outcomes {
        let mut row = vec![
            o.run.to_string(),
            o.seed.to_string(),
            o.method.clone(),
            o.error.clone().unwrap_or_default(),
        ];
        match &o.figures {
            Some(f) => {
                row.extend(SCALARS.map(|id| number(id.of(f))));
                row.extend(f.bin_rmse_ut.map(number));
                row.extend(flat(&f.param_error));
                row.extend(flat(&f.crlb_diag));
            }
            None => row.extend(vec![String::new(); header().len() - 4]),
        }
        w.write_record(&row)?;
    }
    w.into_inner().map_err(|e| e.into_error().into())
}

/// Writes `runs.csv` atomically.
pub fn write(outcomes: &[MethodOutcome], path: &Path) -> Result<(), StudyError> {
    let bytes = to_bytes(outcomes).map_err(|e| StudyError::Malformed {
        path: path.into(),
        message: e.to_string(),
    })?;
    Ok(atomic_file::write_bytes(path, &bytes)?)
}

/// Reads `runs.csv`.
pub fn read(path: &Path) -> Result<Vec<MethodOutcome>, StudyError> {
    let bad = |message: String| StudyError::Malformed {
        path: path.into(),
        message,
    };
    let file =
        magstand_core::input_file::open(path, magstand_core::input_file::MAX_RECORDING_BYTES)
            .map_err(|source| StudyError::Io {
                path: path.into(),
                source,
            })?;
    let mut r = csv::Reader::from_reader(std::io::BufReader::new(file));
    let want = header();
    let got: Vec<String> = r
        .headers()
        .map_err(|e| bad(e.to_string()))?
        .iter()
        .map(str::to_string)
        .collect();
    if got != want {
        let first = want
            .iter()
            .zip(got.iter().map(Some).chain(std::iter::repeat(None)))
            .find(|(w, g)| Some(*w) != *g)
            .map(|(w, g)| format!("column `{w}` expected, found {g:?}"))
            .unwrap_or_else(|| format!("{} columns expected, found {}", want.len(), got.len()));
        return Err(bad(format!("not a magstand runs.csv header: {first}")));
    }
    let mut out = Vec::new();
    for (i, rec) in r.records().enumerate() {
        let row = i + 2;
        let rec = rec.map_err(|e| bad(format!("row {row}: {e}")))?;
        let cell = |c: usize| rec.get(c).unwrap_or("");
        let num = |c: usize| -> Result<f64, StudyError> {
            let s = cell(c);
            if s.is_empty() {
                return Ok(f64::NAN);
            }
            s.parse::<f64>()
                .ok()
                .filter(|&v| magstand_core::within(v, MAX_FIGURE))
                .ok_or_else(|| {
                    bad(format!(
                        "row {row}, column `{}`: expected a finite number of magnitude at most {MAX_FIGURE:e} or nothing, found `{}`",
                        want[c],
                        magstand_core::recording_csv::shown(s)
                    ))
                })
        };
        let int = |c: usize| -> Result<u64, StudyError> {
            cell(c).parse().map_err(|_| {
                bad(format!(
                    "row {row}, column `{}`: expected a whole number, found `{}`",
                    want[c],
                    cell(c)
                ))
            })
        };
        let error = Some(cell(3).to_string()).filter(|e| !e.is_empty());
        let figures = if error.is_some() {
            None
        } else {
            let s: Vec<f64> = (4..11).map(num).collect::<Result<_, _>>()?;
            let bins: Vec<f64> = (11..11 + BINS).map(num).collect::<Result<_, _>>()?;
            let params = |start: usize| -> Result<Option<[Vec<f64>; 3]>, StudyError> {
                let v: Vec<f64> = (start..start + 3 * PARAMS_PER_AXIS)
                    .map(num)
                    .collect::<Result<_, _>>()?;
                Ok(if v.iter().all(|x| x.is_nan()) {
                    None
                } else {
                    Some(std::array::from_fn(|a| {
                        v[a * PARAMS_PER_AXIS..(a + 1) * PARAMS_PER_AXIS].to_vec()
                    }))
                })
            };
            let p0 = 11 + BINS;
            Some(Figures {
                rmse_axis_ut: [s[0], s[1], s[2]],
                rmse_ut: s[3],
                e20_rms_pct: s[4],
                heading_before_deg: s[5],
                heading_after_deg: s[6],
                bin_rmse_ut: std::array::from_fn(|b| bins[b]),
                param_error: params(p0)?,
                crlb_diag: params(p0 + 3 * PARAMS_PER_AXIS)?,
            })
        };
        out.push(MethodOutcome {
            run: int(0)? as usize,
            seed: int(1)?,
            method: cell(2).to_string(),
            error,
            figures,
        });
    }
    Ok(out)
}
