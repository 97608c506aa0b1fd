//! Numbers with a fixed number of decimals, written as `format!("{:.N}", v)` writes them, at a
//! fraction of its cost: a recording of a million rows holds ten million numbers.
//!
//! A finite double is `m 2^e` with `m < 2^53`, so `v 10^N` is the exact integer `m 10^N`
//! shifted by `e`; for `N <= 9` and `|v| < 2^63` that fits in 128 bits. The shifted-out bits
//! decide the rounding exactly, half to even, as the standard library rounds. Anything
//! else is left to the standard library.
use std::fmt::Write;

/// Most decimals the fast path writes.
const MAX_DECIMALS: usize = 9;

/// Appends `v` with `decimals` decimals to `out`, exactly as `write!(out, "{:.*}", decimals, v)`
/// would.
pub fn push_fixed(out: &mut String, v: f64, decimals: usize) {
    if !fast(out, v, decimals) {
        // Infallible: writing to a String.
        let _ = write!(out, "{:.*}", decimals, v);
    }
}

/// The fast path; false (nothing written) where it does not apply.
fn fast(out: &mut String, v: f64, decimals: usize) -> bool {
    if decimals > MAX_DECIMALS || !v.is_finite() || v.abs() >= 9.2e18 {
        return false;
    }
    let bits = v.to_bits();
    let negative = bits >> 63 == 1;
    let biased = ((bits >> 52) & 0x7ff) as i32;
    let fraction = bits & ((1u64 << 52) - 1);
    // v = m 2^e, subnormals included.
    let (m, e) = if biased == 0 {
        (fraction, -1074)
    } else {
        (fraction | (1u64 << 52), biased - 1075)
    };
    let scale = 10u128.pow(decimals as u32);
    let scaled: u128 = if e >= 0 {
        // An integer below 2^63: shifted, it still fits.
        ((m as u128) << e) * scale
    } else {
        let shift = (-e) as u32;
        let num = m as u128 * scale;
        if shift >= 127 {
            // Below half a unit of the last decimal: rounds to zero.
            0
        } else {
            let q = num >> shift;
            let rest = num - (q << shift);
            let half = 1u128 << (shift - 1);
            if rest > half || (rest == half && q & 1 == 1) {
                q + 1
            } else {
                q
            }
        }
    };
    if negative {
        out.push('-');
    }
    // 64-bit division where the number fits, as it nearly always does (128-bit division is
    // a library call).
    let (whole, frac) = match (u64::try_from(scaled), u64::try_from(scale)) {
        (Ok(n), Ok(s)) => ((n / s) as u128, n % s),
        _ => (scaled / scale, (scaled % scale) as u64),
    };
    match u64::try_from(whole) {
        Ok(w) => push_digits(out, w, 0),
        Err(_) => {
            let _ = write!(out, "{whole}");
        }
    }
    if decimals > 0 {
        out.push('.');
        push_digits(out, frac, decimals);
    }
    true
}

/// Appends `n` in decimal, left-padded with zeros to `width` digits.
fn push_digits(out: &mut String, mut n: u64, width: usize) {
    let mut digits = [0u8; 20];
    let mut i = digits.len();
    loop {
        i -= 1;
        digits[i] = b'0' + (n % 10) as u8;
        n /= 10;
        if n == 0 && digits.len() - i >= width {
            break;
        }
    }
    for &d in &digits[i..] {
        out.push(d as char);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check(v: f64, decimals: usize) {
        let mut fast = String::new();
        push_fixed(&mut fast, v, decimals);
        let std = format!("{:.*}", decimals, v);
        assert_eq!(
            fast,
            std,
            "{v:e} ({:#x}) with {decimals} decimals",
            v.to_bits()
        );
    }

    #[test]
    fn writes_what_the_standard_library_writes() {
        // Ties (exact halves) in every direction, signs, zero, subnormals, large integers.
        for v in [
            0.0,
            -0.0,
            0.5,
            1.5,
            2.5,
            -2.5,
            0.25,
            0.125,
            1.125,
            -0.125,
            3.0625,
            1e-10,
            -1e-10,
            5e-324,
            -5e-324,
            1e-300,
            123456789.0,
            9.1e18,
            -9.1e18,
            0.05,
            0.15,
            0.35,
            1e15 + 0.5,
        ] {
            for d in 0..=12 {
                check(v, d);
            }
        }
        // Random doubles over the magnitudes a recording holds, and exact dyadic ties.
        let mut x: u64 = 0x9e37_79b9_7f4a_7c15;
        let mut next = || {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x
        };
        for _ in 0..400_000 {
            let r = next();
            let mantissa = (r >> 11) as f64 / (1u64 << 53) as f64;
            let magnitude = 10f64.powi((r % 20) as i32 - 10);
            let sign = if r & 1 == 1 { -1.0 } else { 1.0 };
            let d = (next() % 10) as usize;
            check(sign * mantissa * magnitude, d);
            // k / 2^j: exactly representable, many of them halfway between two decimals.
            let tie = (next() % 1_000_000) as f64 / (1u64 << (next() % 30)) as f64;
            check(sign * tie, d);
        }
    }
}
