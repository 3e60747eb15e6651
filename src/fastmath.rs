//! The one square root of the core. On the Cortex-M4F it is the FPU's VSQRT (14 cycles); on
//! other targets (host tests, host-sim) Newton iterations in f64, rounded to the same bits.

/// √x for x ≥ 0; 0 for negative numbers and NaN.
///
/// Hand-written rather than micromath's `sqrt` (the design card's f32 crate), by measurement on
/// QEMU's Cortex-M4F (`tools/pil/run`, 4007 values 1e-6…1e6): this one 143 instructions a call
/// and correctly rounded, micromath's 264 and up to 6.1 % off. Bit identity with the host build
/// is what keeps `host-sim pil` free of differing periods.
#[inline]
pub fn sqrt_f32(x: f32) -> f32 {
    // Written so NaN takes the early return too.
    if x.is_nan() || x <= 0.0 {
        return 0.0;
    }
    hw_sqrt(x)
}

/// acos(x) in radians for x in [−1, 1] (clamped; NaN gives π/2), within 7e-5 rad: the
/// polynomial of Abramowitz & Stegun 4.4.45, √(1 − |x|)·(a0 + a1|x| + a2|x|² + a3|x|³), mirrored
/// for negative x. The model table's column of φp needs a tenth of its 0.098 rad spacing at most.
/// Measured on QEMU's Cortex-M4F (`tools/pil/run`, 4001 values over [−1, 1]): 64 instructions a
/// call; micromath's `acos` takes 45 but is up to 0.029 rad off (a third of a grid column), the
/// fixed-point `trig::acos` 86 plus its conversions to and from f32. Plain f32 operations and
/// VSQRT only, so host and target builds agree bit for bit.
#[inline]
pub fn acos_f32(x: f32) -> f32 {
    let a = if x.is_nan() { 0.0 } else { clamp_f32(x, -1.0, 1.0) };
    let m = if a < 0.0 { -a } else { a };
    let p = ((-0.018_729_3 * m + 0.074_261_0) * m - 0.212_114_4) * m + 1.570_728_8;
    let r = sqrt_f32(1.0 - m) * p;
    if a < 0.0 {
        core::f32::consts::PI - r
    } else {
        r
    }
}

#[cfg(all(target_arch = "arm", target_abi = "eabihf"))]
#[inline]
fn hw_sqrt(x: f32) -> f32 {
    let r: u32;
    // SAFETY: VSQRT reads and writes one FPU register (s0, caller-saved and declared clobbered);
    // the hard-float ABI guarantees the FPU is there and enabled by the runtime.
    unsafe {
        core::arch::asm!(
            "vmov s0, {x}",
            "vsqrt.f32 s0, s0",
            "vmov {r}, s0",
            x = in(reg) x.to_bits(),
            r = out(reg) r,
            out("s0") _,
            options(pure, nomem, nostack),
        );
    }
    f32::from_bits(r)
}

#[cfg(not(all(target_arch = "arm", target_abi = "eabihf")))]
#[inline]
fn hw_sqrt(x: f32) -> f32 {
    if x.is_infinite() {
        return x;
    }
    // Newton in f64 from the exponent halved (within a factor √2 of the root): the relative
    // error squares each step, so seven steps reach f64 precision, and rounding that to f32 gives
    // the correctly rounded root — the very bits the M4F's VSQRT returns (IEEE 754), so host and
    // target builds of the core agree bit for bit (`host-sim pil` counts any difference).
    let xd = f64::from(x);
    let mut r = f64::from(f32::from_bits((x.to_bits() >> 1) + 0x1fc0_0000));
    for _ in 0..7 {
        r = 0.5 * (r + xd / r);
    }
    r as f32
}

/// `x` limited to `lo..=hi`, as `f32::clamp` for ordered bounds, but never panics: `f32::clamp`
/// asserts `lo <= hi` and that neither bound is NaN, which links a panic path into every caller
/// (the control tick included). Here a NaN bound is ignored (the comparison is false) and
/// `lo > hi` gives `lo` below `lo`, `hi` above `hi`. A NaN `x` stays NaN, as with `f32::clamp`.
#[inline]
pub fn clamp_f32(x: f32, lo: f32, hi: f32) -> f32 {
    if x < lo {
        lo
    } else if x > hi {
        hi
    } else {
        x
    }
}

/// `x` limited to `-lim..=lim` without a panic path (see [`clamp_f32`]).
#[inline]
pub fn clamp_sym_f32(x: f32, lim: f32) -> f32 {
    clamp_f32(x, -lim, lim)
}

/// `Ord::clamp` for i32 without its `lo <= hi` assertion.
#[inline]
pub fn clamp_i32(x: i32, lo: i32, hi: i32) -> i32 {
    if x < lo {
        lo
    } else if x > hi {
        hi
    } else {
        x
    }
}

/// `Fx::saturating_from_num(x)` without its panic: that function panics on NaN, which links a
/// panic path into the control tick. Same result for every non-NaN `x` (round to nearest, ties
/// to even; saturating at the type's limits; `tests/safety.rs` compares the two), 0 for NaN.
#[inline]
pub fn fx_from_f32(x: f32) -> crate::Fx {
    // Scaling by 2¹⁶ is exact (a power of two; below 2⁻¹²⁶ the value rounds to 0 either way).
    let s = x * 65536.0;
    let bits = if s.is_nan() {
        0
    } else if s >= 2_147_483_647.0 {
        i32::MAX
    } else if s <= -2_147_483_648.0 {
        i32::MIN
    } else if s.abs() >= 8_388_608.0 {
        // |s| ≥ 2²³: already a whole number.
        s as i32
    } else if s >= 0.0 {
        // Adding and removing 2²³ rounds to a whole number, to nearest with ties to even (the
        // IEEE default, which Rust never changes).
        ((s + 8_388_608.0) - 8_388_608.0) as i32
    } else {
        ((s - 8_388_608.0) + 8_388_608.0) as i32
    };
    crate::Fx::from_bits(bits)
}
