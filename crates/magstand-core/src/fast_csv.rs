//! The fast reader of a recording CSV: the whole file in memory, its rows cut into
//! line-aligned chunks parsed on every core in one pass, each number parsed where it lies and
//! written to its place in its column, with no allocation per row.
//!
//! It reads the plain form (no quoted cells, one record per line, `\n` or `\r\n` endings) and
//! gives up (`None`) on anything else or on any cell that would be an error, so that the
//! general reader ([`crate::recording_csv`]) handles it and its message names the row, the
//! column and the cell. Both give the same recording for every file this one accepts.
use std::path::Path;

use rayon::prelude::*;

use crate::recording_csv::{Layout, layout, magnitude_limit};
use crate::{Quat, Recording, Vec3};

/// Chunks per worker thread: enough to balance uneven lines.
const CHUNKS_PER_THREAD: usize = 4;

/// The recording in `bytes`, or `None` when the general reader must read it.
pub(crate) fn read(bytes: &[u8], path: &Path) -> Option<Recording> {
    let newline = memchr::memchr(b'\n', bytes)?;
    let header = std::str::from_utf8(&bytes[..newline]).ok()?;
    let body = &bytes[newline + 1..];
    if header.contains('"') {
        return None;
    }
    let names: Vec<String> = header
        .trim_end_matches('\r')
        .split(',')
        .map(|s| s.trim().to_string())
        .collect();
    let lay = layout(names, path).ok()?;
    let numeric: Vec<bool> = (0..lay.names.len())
        .map(|i| !lay.extra_cols.contains(&i))
        .collect();
    let limits: Vec<f64> = lay.names.iter().map(|n| magnitude_limit(n)).collect();
    let chunks = split_lines(body, rayon::current_num_threads() * CHUNKS_PER_THREAD);
    // Every line of a chunk is a row (a blank line sends the file to the general reader), so
    // each chunk's rows have their place in the columns before any is parsed.
    // The same pass finds any quote, which only the general reader takes, and checks that the
    // text is UTF-8 (a newline byte is never inside a character, so chunk by chunk suffices).
    let counts: Vec<usize> = chunks
        .par_iter()
        .map(|&c| {
            std::str::from_utf8(c).ok()?;
            let lines = memchr::memchr_iter(b'\n', c).count();
            memchr::memchr(b'"', c)
                .is_none()
                .then_some(lines + usize::from(!c.ends_with(b"\n")))
        })
        .collect::<Option<Vec<_>>>()?;
    let rows: usize = counts.iter().sum();
    if rows == 0 {
        return None;
    }
    let mut numbers: Vec<Vec<f64>> = numeric
        .iter()
        .map(|&num| if num { vec![0.0; rows] } else { Vec::new() })
        .collect();
    let mut places: Vec<Vec<&mut [f64]>> = chunks.iter().map(|_| Vec::new()).collect();
    for column in numbers.iter_mut() {
        let mut rest: &mut [f64] = column;
        for (k, &n) in counts.iter().enumerate() {
            let cut = n.min(rest.len());
            let (here, after) = std::mem::take(&mut rest).split_at_mut(cut);
            places[k].push(here);
            rest = after;
        }
    }
    let texts: Vec<Vec<Vec<String>>> = chunks
        .par_iter()
        .zip(places.par_iter_mut())
        .map(|(c, place)| parse_chunk(c, &numeric, &limits, place))
        .collect::<Option<Vec<_>>>()?;
    assemble(&lay, rows, numbers, texts)
}

/// `body` cut into about `parts` pieces, each ending at a line end.
fn split_lines(body: &[u8], parts: usize) -> Vec<&[u8]> {
    let mut out = Vec::with_capacity(parts);
    let mut rest = body;
    let size = body.len() / parts.max(1) + 1;
    while !rest.is_empty() {
        // Cut after a newline byte, which is always a character boundary.
        let cut = if rest.len() <= size {
            rest.len()
        } else {
            match memchr::memchr(b'\n', &rest[size..]) {
                Some(k) => size + k + 1,
                None => rest.len(),
            }
        };
        let (head, tail) = rest.split_at(cut);
        out.push(head);
        rest = tail;
    }
    out
}

/// Parses the lines of a chunk into `place` (one slice per numeric column, as long as the
/// chunk's lines) and returns the text columns; `None` on a line the general reader must
/// judge.
fn parse_chunk(
    bytes: &[u8],
    numeric: &[bool],
    limits: &[f64],
    place: &mut [&mut [f64]],
) -> Option<Vec<Vec<String>>> {
    let n = numeric.len();
    let mut texts: Vec<Vec<String>> = vec![Vec::new(); n];
    let mut row = 0;
    let mut pos = 0;
    while pos < bytes.len() {
        let mut slot = 0;
        for i in 0..n {
            let last = i + 1 == n;
            if numeric[i] {
                // The plain form in the same pass that finds the cell's end; anything else
                // is cut at the delimiter and given to the standard parser.
                let (v, end) = match plain_number(bytes, pos) {
                    Some(found) => found,
                    None => {
                        let end = cell_end(bytes, pos);
                        (parse_number(trim_cr(&bytes[pos..end], last))?, end)
                    }
                };
                if !crate::within(v, limits[i]) {
                    return None;
                }
                *place[slot].get_mut(row)? = v;
                slot += 1;
                pos = end;
            } else {
                let end = cell_end(bytes, pos);
                // A cut at an ASCII comma leaves valid UTF-8.
                let cell = trim_cr(&bytes[pos..end], last);
                texts[i].push(std::str::from_utf8(cell).ok()?.to_string());
                pos = end;
            }
            let end_of_line = pos == bytes.len() || bytes[pos] == b'\n';
            if last != end_of_line {
                // Too few or too many cells (or a blank line).
                return None;
            }
            pos += 1;
        }
        row += 1;
    }
    (place.iter().all(|p| p.len() == row)).then_some(texts)
}

/// Where the cell starting at `pos` ends: the next comma or newline, or the end.
fn cell_end(bytes: &[u8], pos: usize) -> usize {
    bytes[pos..]
        .iter()
        .position(|&b| b == b',' || b == b'\n')
        .map_or(bytes.len(), |k| pos + k)
}

/// The last cell of a line without its `\r` (a `\r\n` line end).
fn trim_cr(cell: &[u8], last: bool) -> &[u8] {
    if last {
        cell.strip_suffix(b"\r").unwrap_or(cell)
    } else {
        cell
    }
}

/// The plain decimal number at `pos` (`-12.345`, nothing around it) and where its cell ends
/// (at the comma, the newline or the `\r` before it, or the end), when it is exactly
/// representable as Clinger's fast path needs; `None` for any other cell.
#[inline(always)]
fn plain_number(bytes: &[u8], pos: usize) -> Option<(f64, usize)> {
    let negative = bytes.get(pos) == Some(&b'-');
    let start = pos + usize::from(negative);
    // The digits are most of a recording's bytes: each run in one tight loop (`digit_run`).
    let (mut mantissa, whole) = digit_run(bytes, start, 0);
    let mut end = start + whole;
    let mut decimals = 0;
    if bytes.get(end) == Some(&b'.') {
        (mantissa, decimals) = digit_run(bytes, end + 1, mantissa);
        end += 1 + decimals;
    }
    match bytes.get(end) {
        None | Some(b',' | b'\n') => {}
        // `\r\n`: the cell ends here; the caller steps over the `\r`.
        Some(b'\r') if matches!(bytes.get(end + 1), None | Some(b'\n')) => end += 1,
        Some(_) => return None,
    }
    // More than 19 digits may have wrapped the mantissa; those go to the standard parser.
    let count = whole + decimals;
    if count == 0 || count > 19 || mantissa > 1 << 53 || decimals >= EXACT_POWERS_OF_TEN.len() {
        return None;
    }
    let v = mantissa as f64 / EXACT_POWERS_OF_TEN[decimals];
    Some((if negative { -v } else { v }, end))
}

/// The run of decimal digits at `pos` appended to `value` (wrapping past 19 digits, which the
/// caller refuses), and its length. A digit at a time: a recording's runs are short and of the
/// same length row after row, so the loop's branch is predicted, and it was faster than reading
/// eight bytes at once with integer arithmetic (115 against 145 ms on the bench's file).
#[inline(always)]
fn digit_run(bytes: &[u8], mut pos: usize, mut value: u64) -> (u64, usize) {
    let start = pos;
    while let Some(&b) = bytes.get(pos) {
        let d = b.wrapping_sub(b'0');
        if d > 9 {
            break;
        }
        value = value.wrapping_mul(10).wrapping_add(u64::from(d));
        pos += 1;
    }
    (value, pos - start)
}

/// Powers of ten that are exact in an f64.
const EXACT_POWERS_OF_TEN: [f64; 23] = [
    1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16,
    1e17, 1e18, 1e19, 1e20, 1e21, 1e22,
];

/// A cell as `cell.trim().parse::<f64>()` reads it, bit for bit. The plain decimal form
/// (`-12.345`) with at most 2^53 as its digits and at most 22 decimals is one exact integer
/// divided by one exact power of ten, which IEEE division rounds correctly, as the standard
/// parser does (Clinger's fast path, [`plain_number`]); any other form goes to the standard parser.
fn parse_number(cell: &[u8]) -> Option<f64> {
    let s = cell.trim_ascii();
    match plain_number(s, 0) {
        Some((v, end)) if end == s.len() => Some(v),
        _ => standard(s),
    }
}

/// The standard parser, for every form the fast path leaves.
fn standard(s: &[u8]) -> Option<f64> {
    std::str::from_utf8(s).ok()?.parse().ok()
}

/// The columns joined into a recording, with the checks of the general reader; `None` where
/// one fails.
fn assemble(
    lay: &Layout,
    rows: usize,
    mut numbers: Vec<Vec<f64>>,
    chunk_texts: Vec<Vec<Vec<String>>>,
) -> Option<Recording> {
    let t = &numbers[lay.t_col];
    if t.windows(2).any(|w| w[1] <= w[0]) {
        return None;
    }
    if lay
        .thr_cols
        .iter()
        .any(|&c| numbers[c].iter().any(|v| !(0.0..=1.0).contains(v)))
    {
        return None;
    }
    if lay
        .bat_v
        .is_some_and(|c| numbers[c].iter().any(|v| *v < 0.0))
    {
        return None;
    }
    let vec3 = |c: [usize; 3]| -> Vec<Vec3> {
        (0..rows)
            .map(|r| Vec3::new(numbers[c[0]][r], numbers[c[1]][r], numbers[c[2]][r]))
            .collect()
    };
    let mut rec = lay.empty_recording();
    rec.mag_ut = vec3(lay.mag_cols);
    if let Some(imu) = rec.imu.as_mut() {
        let zeros = || vec![Vec3::zeros(); rows];
        imu.acc_mps2 = lay.acc.map_or_else(zeros, vec3);
        imu.gyr_rps = lay.gyr.map_or_else(zeros, vec3);
    }
    if let (Some(c), Some(q)) = (lay.att, rec.attitude.as_mut()) {
        for r in 0..rows {
            let v = nalgebra::Vector4::new(
                numbers[c[1]][r],
                numbers[c[2]][r],
                numbers[c[3]][r],
                numbers[c[0]][r],
            );
            if (v.norm() - 1.0).abs() > 1e-3 {
                return None;
            }
            q.push(Quat::from_quaternion(nalgebra::Quaternion::from(v)));
        }
    }
    if let (Some([f, d, s]), Some(g)) = (lay.truth, rec.truth.as_mut()) {
        g.field_ut = vec3(f);
        g.dist_ut = vec3(d);
        g.sd_ut = vec3(s);
    }
    for (k, &c) in lay.extra_cols.iter().enumerate() {
        rec.extra[k].1 = chunk_texts
            .iter()
            .flat_map(|t| t[c].iter().cloned())
            .collect();
    }
    for (col, dst) in [
        (lay.bat_v, &mut rec.bat_v),
        (lay.bat_a, &mut rec.bat_a),
        (lay.temp_c, &mut rec.temp_c),
    ] {
        if let (Some(c), Some(d)) = (col, dst.as_mut()) {
            *d = std::mem::take(&mut numbers[c]);
        }
    }
    for (k, &c) in lay.thr_cols.iter().enumerate() {
        rec.thr[k] = std::mem::take(&mut numbers[c]);
    }
    rec.t_s = std::mem::take(&mut numbers[lay.t_col]);
    Some(rec)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The fast reader accepts a file only where the general one gives the same recording.
    fn same_or_declined(text: &str) {
        let path = Path::new("t.csv");
        let general = crate::recording_csv::read_general(text.as_bytes(), path);
        if let Some(fast) = read(text.as_bytes(), path) {
            match general {
                Ok(g) => assert_eq!(fast, g, "{text:?}"),
                Err(e) => {
                    panic!("fast reader accepted what the general one refuses ({e}): {text:?}")
                }
            }
        }
    }

    #[test]
    fn the_fast_reader_agrees_with_the_general_one_or_declines() {
        let head = "t_s,thr_1,thr_2,mag_x_ut,mag_y_ut,mag_z_ut,note\n";
        for body in [
            "0.0,0.1,0.2,1,2,3,a\n0.1,0.3,0.4,4,5,6,b\n",
            "0.0,0.1,0.2,1,2,3,a\r\n0.1,0.3,0.4,4,5,6,b\r\n",
            "0.0,0.1,0.2,1,2,3,a\n0.1,0.3,0.4,4,5,6,b",
            "0.0,0.1,0.2,1,2,3,a\n\n0.1,0.3,0.4,4,5,6,b\n",
            "0.0,0.1,0.2,1,2,3,a\n0.1,0.3,0.4,4,5,6,b\n\n\n",
            "0.0, 0.1 ,0.2,1,2,3,é ü\n0.1,0.3,0.4,4,5,6,\n",
            "0.0,0.1,0.2,1,2,3,\"q,uoted\"\n0.1,0.3,0.4,4,5,6,b\n",
            "0.0,0.1,0.2,1,2,3\n",
            "0.0,0.1,0.2,1,2,3,a,extra\n",
            "0.1,0.1,0.2,1,2,3,a\n0.1,0.3,0.4,4,5,6,b\n",
            "0.0,1.5,0.2,1,2,3,a\n",
            "0.0,0.1,0.2,1e300,2,3,a\n",
            "0.0,0.1,0.2,nan,2,3,a\n",
            "",
        ] {
            same_or_declined(&format!("{head}{body}"));
        }
        // A supply voltage cannot be negative: both readers refuse one.
        let head = "t_s,thr_1,mag_x_ut,mag_y_ut,mag_z_ut,bat_v\n";
        for (volts, read) in [
            ("12.0", true),
            ("0", true),
            ("-0.001", false),
            ("-1.5", false),
        ] {
            let text = format!("{head}0.0,0.1,1,2,3,12.1\n0.1,0.3,4,5,6,{volts}\n");
            same_or_declined(&text);
            let general = crate::recording_csv::read_general(text.as_bytes(), Path::new("t.csv"));
            assert_eq!(general.is_ok(), read, "bat_v {volts}: {general:?}");
        }
    }

    #[test]
    fn numbers_parse_bit_for_bit_as_the_standard_parser_does() {
        let mut cases: Vec<String> = [
            "0",
            "-0",
            "-0.0",
            "+1.5",
            "1.",
            ".5",
            "0.1",
            "0.3",
            "1e5",
            "1E-3",
            "inf",
            "nan",
            "12345678901234567",
            "9007199254740993",
            "0.1234567890123456789012",
            " 3.25 ",
            "1.2.3",
            "",
            "-",
            ".",
            "1,5",
            "0x10",
            "123456.789012",
            // Runs of digits about the 19-digit limit (where the mantissa could wrap), the
            // bytes beside the digits' range, and a character of several bytes.
            "-.5",
            "1234567890123456789",
            "12345678901234567890",
            "1.234567890123456789",
            "0000000000000000000001.5",
            "0.00000000000000000000000001",
            "5/",
            "5:",
            "5é",
            "é5",
        ]
        .iter()
        .map(|s| s.to_string())
        .collect();
        // Printed the way magstand writes numbers, and arbitrary decimal strings.
        let mut x: u64 = 0x9e37_79b9_7f4a_7c15;
        for _ in 0..20_000 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            let v = (x >> 11) as f64 / (1u64 << 53) as f64 * 2e4 - 1e4;
            cases.push(format!("{v:.6}"));
            cases.push(format!("{v}"));
            cases.push(format!("{}.{}", x % 100_000, x % 1_000_000_007));
        }
        for c in &cases {
            let fast = parse_number(c.as_bytes());
            let std = c.trim().parse::<f64>().ok();
            assert_eq!(
                fast.map(f64::to_bits),
                std.map(f64::to_bits),
                "{c:?}: fast {fast:?}, standard {std:?}"
            );
            // The one-pass form agrees wherever it takes a cell, at any delimiter.
            for end in [",", "\n", "\r\n", ""].iter().filter(|_| !c.contains(',')) {
                let cell = format!("{c}{end}");
                if let Some((v, at)) = plain_number(cell.as_bytes(), 0) {
                    assert_eq!(Some(v.to_bits()), std.map(f64::to_bits), "{cell:?}");
                    assert_eq!(
                        &cell.as_bytes()[at..],
                        end.trim_start_matches('\r').as_bytes(),
                        "{cell:?}"
                    );
                }
            }
        }
    }

    #[test]
    fn the_plain_form_is_read_by_the_fast_reader() {
        let mut text = String::from("t_s,thr,mag_x_ut,mag_y_ut,mag_z_ut,bat_v\n");
        for k in 0..5000 {
            text += &format!("{}.5,0.{},1.25,-2.5,{k},12.0\n", k, k % 10);
        }
        let fast = read(text.as_bytes(), Path::new("t.csv")).expect("declined the plain form");
        assert_eq!(fast.len(), 5000);
        assert_eq!(
            fast,
            crate::recording_csv::read_general(text.as_bytes(), Path::new("t.csv")).unwrap()
        );
    }

    #[test]
    fn chunks_end_at_line_ends_whatever_the_characters() {
        let body = "0.0,ü€,x\n".repeat(1000);
        for parts in [1, 2, 3, 7, 64] {
            let chunks = split_lines(body.as_bytes(), parts);
            assert_eq!(chunks.concat(), body.as_bytes(), "{parts} parts");
            assert!(chunks.iter().all(|c| c.ends_with(b"\n")), "{parts} parts");
            assert!(
                chunks.iter().all(|c| std::str::from_utf8(c).is_ok()),
                "{parts} parts: a chunk cut inside a character"
            );
        }
    }
}
