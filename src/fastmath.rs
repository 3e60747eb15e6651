//! The one square root of the core. On the Cortex-M4F it is the FPU's VSQRT (14 cycles); on
//! other targets (host tests, host-sim) Newton iterations in f64, rounded to the same bits.

/// √x for x ≥ 0; 0 for negative numbers and NaN.
#[inline]
pub fn sqrt_f32(x: f32) -> f32 {
    // Written so NaN takes the early return too.
    if x.is_nan() || x <= 0.0 {
        return 0.0;
    }
    hw_sqrt(x)
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
