//! Fixed-point trigonometry from one compile-time sine table.
//!
//! The table is computed by a `const fn` from a Taylor series in f64 at build time; at run time
//! only integer arithmetic is used. Angles are either a `u32` turn fraction (2³² = one turn, as
//! the phase accumulator uses) or radians in [`Fx`].

use crate::Fx;

/// log2 of the number of table intervals per turn.
const TABLE_BITS: u32 = 10;
const TABLE_LEN: usize = 1 << TABLE_BITS;
/// Fraction bits of the table entries (sin · 2³⁰).
const TABLE_FRAC: u32 = 30;

/// sin(2πk/1024) · 2³⁰ for k = 0..=1024 (the last entry repeats the first for interpolation).
static SINE_Q30: [i32; TABLE_LEN + 1] = sine_table();

/// sin by its Taylor series, for compile-time tables; x in [-π/2, π/2] (12 terms: < 1e-15).
pub(crate) const fn taylor_sin(x: f64) -> f64 {
    let x2 = x * x;
    let mut term = x;
    let mut sum = x;
    let mut n = 1.0;
    let mut i = 0;
    while i < 12 {
        term = -term * x2 / ((n + 1.0) * (n + 2.0));
        sum += term;
        n += 2.0;
        i += 1;
    }
    sum
}

// Runs at compile time: an index out of range fails the build, not the device.
#[allow(clippy::indexing_slicing)]
const fn sine_table() -> [i32; TABLE_LEN + 1] {
    let mut t = [0i32; TABLE_LEN + 1];
    let mut k = 0;
    while k <= TABLE_LEN {
        // Reduce to [-π/2, π/2] by symmetry so the series converges fast.
        let turn = (k % TABLE_LEN) as f64 / TABLE_LEN as f64;
        let x = core::f64::consts::TAU * turn;
        let s = if turn <= 0.25 {
            taylor_sin(x)
        } else if turn <= 0.75 {
            taylor_sin(core::f64::consts::PI - x)
        } else {
            taylor_sin(x - core::f64::consts::TAU)
        };
        let v = s * (1u64 << TABLE_FRAC) as f64;
        t[k] = if v >= 0.0 { (v + 0.5) as i32 } else { (v - 0.5) as i32 };
        k += 1;
    }
    t
}

/// sin of a turn fraction, as Q30 (±2³⁰), linearly interpolated (error < 5e-6).
pub fn sin_turn_q30(turn: u32) -> i32 {
    let idx = (turn >> (32 - TABLE_BITS)) as usize;
    let frac = i64::from(turn & ((1 << (32 - TABLE_BITS)) - 1));
    let a = SINE_Q30.get(idx).copied().unwrap_or(0);
    let b = SINE_Q30.get(idx + 1).copied().unwrap_or(0);
    let d = i64::from(b) - i64::from(a);
    (i64::from(a) + ((d * frac) >> (32 - TABLE_BITS))) as i32
}

/// 2³² / 2π: radians (Q16) → turn fraction, by multiplying and shifting 16 bits.
const TURNS_PER_RAD_Q32: i64 = 683_565_276;

fn rad_to_turn(angle: Fx) -> u32 {
    // Wrapping to u32 is exactly the reduction modulo one turn.
    ((i64::from(angle.to_bits()) * TURNS_PER_RAD_Q32) >> 16) as u32
}

fn q30_to_fx(v: i32) -> Fx {
    Fx::from_bits(v >> (TABLE_FRAC - 16))
}

pub fn sin(angle: Fx) -> Fx {
    q30_to_fx(sin_turn_q30(rad_to_turn(angle)))
}

pub fn cos(angle: Fx) -> Fx {
    q30_to_fx(sin_turn_q30(rad_to_turn(angle).wrapping_add(1 << 30)))
}

/// asin(x)·2¹⁶ on x = k/256 · √½ for k = 0..=256, for interpolation on [0, √½].
static ASIN_Q16: [i32; 257] = asin_table();

// Runs at compile time: an index out of range fails the build, not the device.
#[allow(clippy::indexing_slicing)]
const fn asin_table() -> [i32; 257] {
    let mut t = [0i32; 257];
    let mut k = 0;
    while k <= 256 {
        let x = k as f64 / 256.0 * core::f64::consts::FRAC_1_SQRT_2;
        // asin by its series: converges for |x| ≤ √½ with 60 terms to ~1e-12.
        let mut term = x;
        let mut sum = x;
        let mut n = 0;
        while n < 60 {
            let a = (2 * n + 1) as f64;
            term = term * x * x * a * a / ((a + 1.0) * (a + 2.0));
            sum += term;
            n += 1;
        }
        t[k] = (sum * 65536.0 + 0.5) as i32;
        k += 1;
    }
    t
}

fn asin_small(x: Fx) -> Fx {
    // x in [0, √½]; index = x / √½ · 256.
    const INV_STEP: i64 = 362; // 256 / √½ = 362.04
    let pos = i64::from(x.to_bits()) * INV_STEP; // Q16 index
    let idx = (pos >> 16) as usize;
    let frac = pos & 0xFFFF;
    let a = i64::from(ASIN_Q16.get(idx).copied().unwrap_or(ASIN_Q16[256]));
    let b = i64::from(ASIN_Q16.get(idx + 1).copied().unwrap_or(ASIN_Q16[256]));
    Fx::from_bits((a + (((b - a) * frac) >> 16)) as i32)
}

/// asin on [-1, 1] (clamped), error < 1e-4 rad.
pub fn asin(x: Fx) -> Fx {
    let half_pi = Fx::FRAC_PI_2;
    let neg = x < 0;
    let a = x.abs().min(Fx::ONE);
    let root_half = Fx::FRAC_1_SQRT_2;
    let r = if a <= root_half {
        asin_small(a)
    } else {
        // asin(a) = π/2 − asin(√(1 − a²)), with √(1 − a²) < √½ here.
        let c = crate::fastmath::fx_from_f32(crate::fastmath::sqrt_f32((Fx::ONE - a * a).to_num::<f32>()));
        half_pi - asin_small(c)
    };
    if neg {
        -r
    } else {
        r
    }
}

/// acos on [-1, 1] (clamped).
pub fn acos(x: Fx) -> Fx {
    Fx::FRAC_PI_2 - asin(x)
}
