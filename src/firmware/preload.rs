//! Preload force cell: ADC1 on PC0 with 16× hardware oversampling (shifted back to a 12-bit
//! word, the core's calibration unit) read at 1 kHz in a thread-mode task; the word reaches the
//! control tick through an atomic, so neither side ever waits for the other.

use core::sync::atomic::Ordering;

use embassy_stm32::adc::{Adc, AdcChannel, AnyAdcChannel, Resolution, SampleTime};
use embassy_stm32::pac::adc::vals::{Rovsm, Trovs};
use embassy_stm32::peripherals::{ADC1, PC0};
use embassy_stm32::Peri;
use embassy_time::{Duration, Ticker};

use super::control::PRELOAD_WORD;

/// Preload sampling period: the core filters the word (α = 0.01 per 100 µs tick), so 1 kHz is
/// ten times faster than anything the filter passes.
const PERIOD: Duration = Duration::from_millis(1);

pub struct Preload {
    adc: Adc<'static, ADC1>,
    pin: AnyAdcChannel<ADC1>,
}

impl Preload {
    pub fn new(adc: Peri<'static, ADC1>, pin: Peri<'static, PC0>) -> Self {
        let mut adc = Adc::new(adc);
        adc.set_resolution(Resolution::BITS12);
        adc.set_sample_time(SampleTime::CYCLES47_5);
        // 16 conversions summed (OVSR = 3 → ×16), shifted right by 4: a 12-bit average.
        adc.set_oversampling_ratio(3);
        adc.set_oversampling_shift(4);
        adc.enable_regular_oversampling_mode(Rovsm::CONTINUED, Trovs::AUTOMATIC, true);
        Preload { adc, pin: pin.degrade_adc() }
    }
}

#[embassy_executor::task]
pub async fn preload_task(mut p: Preload) {
    let mut ticker = Ticker::every(PERIOD);
    let mut seq: u16 = 0;
    loop {
        // One oversampled conversion: 16 × (47.5 + 12.5) ADC cycles, about 23 µs at 42.5 MHz.
        let word = p.adc.blocking_read(&mut p.pin);
        // The counter in the high half tells the tick this is a new sample.
        seq = seq.wrapping_add(1);
        PRELOAD_WORD.store((u32::from(seq) << 16) | u32::from(word), Ordering::Relaxed);
        ticker.next().await;
    }
}
