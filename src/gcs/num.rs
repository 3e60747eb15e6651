//! Numbers on the wire without std and without panics: a decimal parser that keeps the digits
//! exactly (so `2.5` mm is exactly 2 500 000 nm), conversions with overflow checks, and
//! fixed-precision formatters.

use heapless::Vec;

/// A parsed decimal number: `±mantissa × 10^exponent`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Decimal {
    pub negative: bool,
    pub mantissa: u64,
    pub exponent: i32,
}

/// Digits kept in the mantissa; later ones only move the exponent (integer part) or are dropped.
const MAX_DIGITS: u32 = 19;
/// Exponents beyond this are clamped (any such value overflows or rounds to zero anyway).
const MAX_EXPONENT: i32 = 9_999;

/// Parses `[+-]digits[.digits][(e|E)[+-]digits]` (at least one mantissa digit). Anything else,
/// including `nan`, `inf` and hex, is `None`.
pub fn parse_decimal(t: &[u8]) -> Option<Decimal> {
    let mut it = t.iter().copied().peekable();
    let mut negative = false;
    if let Some(&c) = it.peek() {
        if c == b'+' || c == b'-' {
            negative = c == b'-';
            it.next();
        }
    }
    let mut mantissa: u64 = 0;
    let mut kept: u32 = 0;
    let mut exponent: i32 = 0;
    let mut digits = 0u32;
    let mut seen_point = false;
    while let Some(&c) = it.peek() {
        match c {
            b'0'..=b'9' => {
                digits = digits.saturating_add(1);
                let d = u64::from(c - b'0');
                if kept < MAX_DIGITS {
                    if mantissa != 0 || d != 0 {
                        kept += 1;
                    }
                    mantissa = mantissa.saturating_mul(10).saturating_add(d);
                    if seen_point {
                        exponent = exponent.saturating_sub(1);
                    }
                } else if !seen_point {
                    exponent = exponent.saturating_add(1);
                }
            }
            b'.' if !seen_point => seen_point = true,
            _ => break,
        }
        it.next();
    }
    if digits == 0 {
        return None;
    }
    if let Some(&c) = it.peek() {
        if c != b'e' && c != b'E' {
            return None;
        }
        it.next();
        let mut eneg = false;
        if let Some(&s) = it.peek() {
            if s == b'+' || s == b'-' {
                eneg = s == b'-';
                it.next();
            }
        }
        let mut e: i32 = 0;
        let mut edigits = 0;
        for c in it {
            if !c.is_ascii_digit() {
                return None;
            }
            edigits += 1;
            e = e.saturating_mul(10).saturating_add(i32::from(c - b'0')).min(MAX_EXPONENT);
        }
        if edigits == 0 {
            return None;
        }
        exponent = exponent.saturating_add(if eneg { -e } else { e });
    }
    Some(Decimal { negative, mantissa, exponent: exponent.clamp(-2 * MAX_EXPONENT, 2 * MAX_EXPONENT) })
}

/// Powers of ten exact in f64 (up to 10^22): one multiplication or division instead of a loop
/// (f64 is software arithmetic on a Cortex-M4).
const POW10: [f64; 23] = [
    1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8, 1e9, 1e10, 1e11, 1e12, 1e13, 1e14, 1e15, 1e16, 1e17, 1e18,
    1e19, 1e20, 1e21, 1e22,
];

fn pow10_u128(n: u32) -> Option<u128> {
    10u128.checked_pow(n)
}

impl Decimal {
    /// The value × 10^`scale`, rounded half away from zero; `None` when it does not fit an i64.
    pub fn scaled_i64(&self, scale: i32) -> Option<i64> {
        if self.mantissa == 0 {
            return Some(0);
        }
        let e = self.exponent.checked_add(scale)?;
        let magnitude: u128 = if e >= 0 {
            u128::from(self.mantissa).checked_mul(pow10_u128(u32::try_from(e).ok()?)?)?
        } else {
            let n = e.unsigned_abs();
            if n > 30 {
                0
            } else {
                let p = pow10_u128(n)?;
                let m = u128::from(self.mantissa);
                let q = m / p;
                let r = m % p;
                if r.checked_mul(2)? >= p {
                    q + 1
                } else {
                    q
                }
            }
        };
        let v = i64::try_from(magnitude).ok()?;
        Some(if self.negative { -v } else { v })
    }

    /// The exact integer, `None` when it has a fraction or does not fit.
    pub fn integer(&self) -> Option<i64> {
        if self.exponent < 0 && self.mantissa != 0 {
            let p = pow10_u128(self.exponent.unsigned_abs())?;
            if u128::from(self.mantissa) % p != 0 {
                return None;
            }
        }
        self.scaled_i64(0)
    }

    /// Nearest f64 (within a few ulp); `None` when it overflows.
    pub fn to_f64(&self) -> Option<f64> {
        if self.mantissa == 0 {
            return Some(0.0);
        }
        let mut v = self.mantissa as f64;
        let mut e = self.exponent;
        // Chunks of 10^22 (exact in f64), then the rest.
        while e > 22 {
            v *= 1e22;
            e -= 22;
            if !v.is_finite() {
                return None;
            }
        }
        while e < -22 {
            v /= 1e22;
            e += 22;
            if v == 0.0 {
                return Some(0.0);
            }
        }
        let p = POW10.get(e.unsigned_abs() as usize).copied().unwrap_or(1e22);
        v = if e >= 0 { v * p } else { v / p };
        if !v.is_finite() {
            return None;
        }
        Some(if self.negative { -v } else { v })
    }
}

/// Parses a strict integer: `[+-]digits`, or `0x` + hex digits.
pub fn parse_int(t: &[u8]) -> Option<i64> {
    if let Some(hex) = t.strip_prefix(b"0x").or_else(|| t.strip_prefix(b"0X")) {
        if hex.is_empty() {
            return None;
        }
        let mut v: i64 = 0;
        for &c in hex {
            let d = char::from(c).to_digit(16)?;
            v = v.checked_mul(16)?.checked_add(i64::from(d))?;
        }
        return Some(v);
    }
    let (neg, digits) = match t.first() {
        Some(b'-') => (true, t.get(1..)?),
        Some(b'+') => (false, t.get(1..)?),
        _ => (false, t),
    };
    if digits.is_empty() {
        return None;
    }
    let mut v: i64 = 0;
    for &c in digits {
        if !c.is_ascii_digit() {
            return None;
        }
        v = v.checked_mul(10)?.checked_add(i64::from(c - b'0'))?;
    }
    Some(if neg { -v } else { v })
}

/// Bytes sink that never panics: reports whether everything fitted.
pub trait Sink {
    fn put(&mut self, bytes: &[u8]) -> bool;
}

impl<const N: usize> Sink for Vec<u8, N> {
    fn put(&mut self, bytes: &[u8]) -> bool {
        self.extend_from_slice(bytes).is_ok()
    }
}

/// Decimal digits of an unsigned integer.
pub fn write_u64(out: &mut dyn Sink, mut v: u64) -> bool {
    let mut buf = [0u8; 20];
    let mut i = buf.len();
    loop {
        i -= 1;
        if let Some(slot) = buf.get_mut(i) {
            *slot = b'0' + (v % 10) as u8;
        }
        v /= 10;
        if v == 0 || i == 0 {
            break;
        }
    }
    buf.get(i..).is_some_and(|digits| out.put(digits))
}

pub fn write_i64(out: &mut dyn Sink, v: i64) -> bool {
    (v >= 0 || out.put(b"-")) && write_u64(out, v.unsigned_abs())
}

/// `value / 10^decimals` with exactly `decimals` digits after the point (`2500000`, 6 →
/// `2.500000`); `decimals` up to 18.
pub fn write_scaled(out: &mut dyn Sink, value: i64, decimals: u32) -> bool {
    let decimals = decimals.min(18);
    let p = 10u64.pow(decimals);
    let m = value.unsigned_abs();
    if value < 0 && !out.put(b"-") {
        return false;
    }
    if !write_u64(out, m / p) {
        return false;
    }
    if decimals == 0 {
        return true;
    }
    let frac = m % p;
    let mut buf = [b'0'; 18];
    let mut f = frac;
    for i in (0..decimals as usize).rev() {
        if let Some(slot) = buf.get_mut(i) {
            *slot = b'0' + (f % 10) as u8;
        }
        f /= 10;
    }
    out.put(b".") && buf.get(..decimals as usize).is_some_and(|d| out.put(d))
}

/// Fixed notation with `decimals` digits after the point, rounded half away from zero. Values
/// beyond ±9.2e18 / 10^decimals saturate; NaN prints as 0.
pub fn write_fixed(out: &mut dyn Sink, v: f64, decimals: u32) -> bool {
    let decimals = decimals.min(18);
    let p = POW10.get(decimals as usize).copied().unwrap_or(1e18);
    let x = v * p;
    let r = if x >= 0.0 { x + 0.5 } else { x - 0.5 };
    // `as` saturates and maps NaN to 0.
    write_scaled(out, r as i64, decimals)
}

/// Decimal exponent of the leading digit of `a` ≥ 0, by a bounded search between `lowest` and
/// `highest` (0 for 0).
fn leading_exponent<F>(a: F, one: F, highest: i32, lowest: i32) -> i32
where
    F: Copy + PartialOrd + core::ops::Mul<Output = F> + core::ops::Div<Output = F> + From<u8>,
{
    let ten = F::from(10u8);
    let zero = F::from(0u8);
    let (mut e, mut p) = (0, one);
    if a >= one {
        while a >= p * ten && e < highest {
            p = p * ten;
            e += 1;
        }
    } else if a > zero {
        while a < p && e > lowest {
            p = p / ten;
            e -= 1;
        }
    }
    e
}

/// Trailing zeros of a fraction trimmed, and the point when nothing follows it: `2.500` → `2.5`,
/// `40.0` → `40`; integers unchanged.
fn trim_fraction_zeros(mut s: &[u8]) -> &[u8] {
    if s.contains(&b'.') {
        while let Some(rest) = s.strip_suffix(b"0") {
            s = rest;
        }
        if let Some(rest) = s.strip_suffix(b".") {
            s = rest;
        }
    }
    s
}

/// About seven significant digits (the settings are f32), trailing zeros trimmed: `0.92`,
/// `2200`, `0.0002`, `-50`. Computed in f32, which the Cortex-M4F does in hardware.
pub fn write_general(out: &mut dyn Sink, v: f64) -> bool {
    let v = v as f32;
    let a = if v < 0.0 { -v } else { v };
    let e = leading_exponent(a, 1.0f32, 18, -18);
    let decimals = (6 - e).clamp(0, 18) as u32;
    let mut scale = 1.0f32;
    for _ in 0..decimals {
        scale *= 10.0;
    }
    let x = v * scale;
    let r = if x >= 0.0 { x + 0.5 } else { x - 0.5 };
    let mut buf: Vec<u8, 48> = Vec::new();
    // `as` saturates and maps NaN to 0.
    if !write_scaled(&mut buf, r as i64, decimals) {
        return false;
    }
    let mut s = trim_fraction_zeros(&buf);
    if s == b"-0" {
        s = b"0";
    }
    out.put(s)
}

/// An f32 with the fewest significant digits (nine at most) that read back as the same f32
/// through [`parse_decimal`] and [`Decimal::to_f64`]; trailing zeros trimmed: `40`, `0.01`,
/// `12.3456793`; from 1e18 up in exponent form, `3.40282347e32`. NaN and infinities print as
/// 0. Computed in f64 (software on the Cortex-M4F; only `SPA?` uses it).
pub fn write_f32(out: &mut dyn Sink, v: f32) -> bool {
    let v = if v.is_finite() { v } else { 0.0 };
    let x = f64::from(v);
    let a = if x < 0.0 { -x } else { x };
    let e = leading_exponent(a, 1.0f64, 40, -46);
    if a >= 1e18 {
        return write_f32_exponent(out, v, a, e);
    }
    let mut best: (i64, u32) = (0, 0);
    for digits in 1..=9i32 {
        let decimals = (digits - 1 - e).clamp(0, 18) as u32;
        let scale = POW10.get(decimals as usize).copied().unwrap_or(1e18);
        let r = a * scale + 0.5;
        // `as` saturates.
        let m = r as i64;
        best = (m, decimals);
        // What parse_decimal and to_f64 make of the printed digits.
        if (m as f64 / scale) as f32 == (if v < 0.0 { -v } else { v }) {
            break;
        }
    }
    let (m, decimals) = best;
    let mut buf: Vec<u8, 48> = Vec::new();
    if !write_scaled(&mut buf, m, decimals) {
        return false;
    }
    let s = trim_fraction_zeros(&buf);
    if v < 0.0 && m != 0 && !out.put(b"-") {
        return false;
    }
    out.put(s)
}

/// [`write_f32`] for |v| ≥ 1e18 (`a` = |v|, 10^`e` ≤ a): `d.ddde<e>` with the fewest mantissa
/// digits (nine at most) that read back as the same f32, checked by parsing the text.
fn write_f32_exponent(out: &mut dyn Sink, v: f32, a: f64, e: i32) -> bool {
    let mut best: Vec<u8, 24> = Vec::new();
    for digits in 1..=9i32 {
        // a / 10^(e + 1 − digits), in exact chunks of at most 10^22 as `to_f64` multiplies.
        let mut k = e + 1 - digits;
        let mut m = a;
        while k > 0 {
            let step = k.min(22);
            m /= POW10.get(step as usize).copied().unwrap_or(1e22);
            k -= step;
        }
        let mut m = (m + 0.5) as u64;
        let mut exp = e;
        if m >= 10u64.pow(digits as u32) {
            // Rounded up to one more digit (9.99… → 10.0…).
            m /= 10;
            exp += 1;
        }
        let mut text: Vec<u8, 24> = Vec::new();
        let mut digits_buf: Vec<u8, 24> = Vec::new();
        if !write_u64(&mut digits_buf, m) {
            return false;
        }
        let (first, rest) = digits_buf.split_at(1);
        let _ = text.extend_from_slice(first);
        let rest = trim_trailing(rest, b'0');
        if !rest.is_empty() {
            let _ = text.push(b'.');
            let _ = text.extend_from_slice(rest);
        }
        let _ = text.push(b'e');
        if !write_i64(&mut text, i64::from(exp)) {
            return false;
        }
        best = text;
        if parse_decimal(&best).and_then(|d| d.to_f64()).map(|y| y as f32)
            == Some(if v < 0.0 { -v } else { v })
        {
            break;
        }
    }
    if v < 0.0 && !out.put(b"-") {
        return false;
    }
    out.put(&best)
}

fn trim_trailing(s: &[u8], c: u8) -> &[u8] {
    let mut end = s.len();
    while end > 0 && s.get(end - 1) == Some(&c) {
        end -= 1;
    }
    s.get(..end).unwrap_or(s)
}
