//! Board-independent bookkeeping of the drive's circular DMA buffer, kept free of registers so it
//! is unit-tested on the host: which half the DMA is reading, which half the control tick
//! refills, overrun detection, the packing of the core's DAC words into DAC1's dual-channel
//! holding register, and their scaling to PWM compare values.

use piezo_drive::controller::DAC_SAMPLES_PER_STEP;

/// Samples per buffer half (one control period).
pub const HALF: usize = DAC_SAMPLES_PER_STEP;
/// Samples in the whole circular buffer.
pub const SAMPLES: usize = 2 * HALF;
/// Largest DAC word (12 bit).
pub const DAC_MAX: u16 = 4095;

/// Half (0 or 1) the DMA is reading now, from its remaining-transfer count (`NDTR`) for a
/// circular transfer of `total` items. The next item it moves is `total − remaining`.
pub fn dma_half(remaining: u16, total: u16) -> usize {
    let next = total.saturating_sub(remaining);
    if next < total / 2 {
        0
    } else {
        1
    }
}

/// Remembers which half the previous tick wrote, so a tick that finds the DMA in the same half
/// as last time (a whole half period slipped) is counted as an overrun. The firmware now measures
/// lateness on the TIM5 timebase (`piezo_drive::safety::timing`), which also sees whole laps;
/// this stays as host-tested bookkeeping.
#[cfg_attr(target_os = "none", allow(dead_code))]
#[derive(Debug, Default, Clone, Copy, PartialEq, Eq)]
pub struct Refill {
    last_written: Option<usize>,
}

#[cfg_attr(target_os = "none", allow(dead_code))]
impl Refill {
    /// For the DMA in `dma_half_now`: the half to refill (the other one) and whether this tick is
    /// late (it would refill the same half as the previous tick).
    pub fn on_tick(&mut self, dma_half_now: usize) -> (usize, bool) {
        let write = 1 - (dma_half_now & 1);
        let slipped = self.last_written == Some(write);
        self.last_written = Some(write);
        (write, slipped)
    }
}

// Each drive variant uses one of these two; the host tests use both.
#[allow(dead_code)]
/// One dual-channel DHR12RD word: channel 1 in bits 0..12, channel 2 in bits 16..28.
pub fn pack_dac(words: [u16; 2]) -> u32 {
    u32::from(words[0].min(DAC_MAX)) | (u32::from(words[1].min(DAC_MAX)) << 16)
}

#[allow(dead_code)]
/// DAC word (0..=4095) → compare value for a PWM period of `period` timer counts (ARR + 1):
/// 0 → 0 % duty, 4095 → 100 % duty, rounded to nearest.
pub fn pwm_compare(word: u16, period: u32) -> u32 {
    let w = u32::from(word.min(DAC_MAX));
    (w * period + u32::from(DAC_MAX) / 2) / u32::from(DAC_MAX)
}

/// Counter preset for the tick timer (period `tick_counts`) so that its first update comes
/// `offset_counts` after both timers start together (0 < offset ≤ tick_counts).
pub fn tick_preset(tick_counts: u32, offset_counts: u32) -> u32 {
    // `max`/`min` rather than `clamp`, which asserts 1 ≤ tick_counts (a panic path).
    tick_counts.saturating_sub(offset_counts.max(1).min(tick_counts))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dma_half_from_remaining_count() {
        // 40 samples: remaining 40..=21 → reading the first half, 20..=1 → the second.
        assert_eq!(dma_half(40, 40), 0);
        assert_eq!(dma_half(21, 40), 0);
        assert_eq!(dma_half(20, 40), 1);
        assert_eq!(dma_half(1, 40), 1);
        // PWM burst: two transfers per sample, 80 in all.
        assert_eq!(dma_half(80, 80), 0);
        assert_eq!(dma_half(41, 80), 0);
        assert_eq!(dma_half(40, 80), 1);
        // Nonsense counts do not panic.
        assert_eq!(dma_half(100, 40), 0);
        assert_eq!(dma_half(0, 0), 1);
    }

    #[test]
    fn refill_alternates_and_flags_slips() {
        let mut r = Refill::default();
        assert_eq!(r.on_tick(0), (1, false));
        assert_eq!(r.on_tick(1), (0, false));
        assert_eq!(r.on_tick(0), (1, false));
        // The DMA is still (again) in half 0: a half period was lost.
        assert_eq!(r.on_tick(0), (1, true));
        assert_eq!(r.on_tick(1), (0, false));
    }

    #[test]
    fn packing_and_clamping() {
        assert_eq!(pack_dac([0x123, 0xABC]), 0x0ABC_0123);
        assert_eq!(pack_dac([u16::MAX, 5000]), 0x0FFF_0FFF);
    }

    #[test]
    fn pwm_compare_endpoints_and_monotonic() {
        let period = 850;
        assert_eq!(pwm_compare(0, period), 0);
        assert_eq!(pwm_compare(4095, period), period);
        assert_eq!(pwm_compare(u16::MAX, period), period);
        assert_eq!(pwm_compare(2048, period), 425);
        let mut last = 0;
        for w in 0..=4095u16 {
            let c = pwm_compare(w, period);
            assert!(c >= last && c <= period);
            last = c;
        }
    }

    #[test]
    fn tick_preset_offsets_first_update() {
        assert_eq!(tick_preset(17_000, 1_700), 15_300);
        assert_eq!(tick_preset(17_000, 0), 16_999);
        assert_eq!(tick_preset(17_000, 99_999), 0);
    }
}
