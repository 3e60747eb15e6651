//! Preload force cell: ADC1 on PC0 with 16× hardware oversampling (shifted back to a 12-bit
//! word, the core's calibration unit) read at 1 kHz in a task of the communication executor; the word reaches the
//! control tick through an atomic, so neither side ever waits for the other.
//!
//! Open-input probe: every [`PROBE_EVERY`] samples the task pulls PC0 weakly down (GPIO input
//! mode, ~40 kΩ internal pull-down) for [`PROBE_SETTLE_US`], switches it back to analog and
//! converts at once, then the same with the pull-up. A bridge amplifier driving the pin barely
//! notices ~40 kΩ; an open pin follows the pulls. `piezo_drive::safety::probe` judges the two
//! readings and debounces; while the input is judged floating the task publishes
//! [`FLOATING_WORD`], outside the ADC's range, which the core treats as an invalid preload
//! (a preload-sensor fault while active; servo-on refused).

use core::sync::atomic::{AtomicU32, Ordering};

use embassy_stm32::adc::{Adc, AdcChannel, AnyAdcChannel, Resolution, SampleTime};
use embassy_stm32::pac;
use embassy_stm32::pac::adc::vals::{Rovsm, Trovs};
use embassy_stm32::pac::gpio::vals::{Moder, Pupdr};
use embassy_stm32::peripherals::{ADC1, PC0};
use embassy_stm32::Peri;
use embassy_time::{Duration, Ticker, Timer};
use piezo_drive::safety::probe::{probe_says_floating, FloatDetector};

/// Latest preload-cell word from this task, read by the tick (`control.rs`): the word in the low
/// 16 bits, a sample counter in the high 16 (so the tick sees when the task stops delivering).
pub static PRELOAD_WORD: AtomicU32 = AtomicU32::new(0);

/// Preload sampling period: the core filters the word (α = 0.01 per 100 µs tick), so 1 kHz is
/// ten times faster than anything the filter passes.
const PERIOD: Duration = Duration::from_millis(1);
/// Samples between two open-input probes (100 ms).
const PROBE_EVERY: u32 = 100;
/// Time under each pull before the conversion: ≫ 40 kΩ × (pin + sampling capacitance, ~15 pF).
const PROBE_SETTLE_US: u64 = 50;
/// Pulled readings this far apart (≈ 0.8 V) mean an open input.
const PROBE_THRESHOLD: u16 = 1024;
/// Published while the input floats: outside any 12-bit calibration window.
pub const FLOATING_WORD: u16 = u16::MAX;

/// PC0: GPIOC pin 0.
const PIN: usize = 0;

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

    /// One conversion after `pull` has held the pin for a while.
    async fn read_after_pull(&mut self, pull: Pupdr) -> u16 {
        pac::GPIOC.pupdr().modify(|w| w.set_pupdr(PIN, pull));
        pac::GPIOC.moder().modify(|w| w.set_moder(PIN, Moder::INPUT));
        Timer::after_micros(PROBE_SETTLE_US).await;
        pac::GPIOC.moder().modify(|w| w.set_moder(PIN, Moder::ANALOG));
        pac::GPIOC.pupdr().modify(|w| w.set_pupdr(PIN, Pupdr::FLOATING));
        self.adc.blocking_read(&mut self.pin)
    }
}

#[embassy_executor::task]
pub async fn preload_task(mut p: Preload) {
    let mut ticker = Ticker::every(PERIOD);
    let mut seq: u16 = 0;
    let mut detector = FloatDetector::new();
    let mut n: u32 = 0;
    loop {
        n = n.wrapping_add(1);
        if n % PROBE_EVERY == 0 {
            let down = p.read_after_pull(Pupdr::PULL_DOWN).await;
            let up = p.read_after_pull(Pupdr::PULL_UP).await;
            let was = detector.floating();
            let now = detector.record(probe_says_floating(down, up, PROBE_THRESHOLD));
            if now != was {
                if now {
                    defmt::error!(
                        "preload input floating (pulled reads {} / {}): sensor disconnected?",
                        down,
                        up
                    );
                } else {
                    defmt::info!("preload input driven again");
                }
            }
        }
        // One oversampled conversion: 16 × (47.5 + 12.5) ADC cycles, about 23 µs at 42.5 MHz.
        let mut word = p.adc.blocking_read(&mut p.pin);
        if detector.floating() {
            word = FLOATING_WORD;
        }
        // The counter in the high half tells the tick this is a new sample.
        seq = seq.wrapping_add(1);
        PRELOAD_WORD.store((u32::from(seq) << 16) | u32::from(word), Ordering::Relaxed);
        ticker.next().await;
    }
}
