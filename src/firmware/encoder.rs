//! Quadrature encoder on TIM3 (PA6 = A, PA7 = B): embassy's `Qei` (×4 counting, 16-bit count,
//! unwrapped by the core) plus the input filter embassy 0.4 does not expose, set through the PAC.
//! The optional index on PB10 is watched by an EXTI task that flags it for the next tick.

use core::sync::atomic::Ordering;

use embassy_stm32::exti::ExtiInput;
use embassy_stm32::pac;
use embassy_stm32::peripherals::{PA6, PA7, TIM3};
use embassy_stm32::timer::qei::{Qei, QeiPin};
use embassy_stm32::Peri;

use super::control::INDEX_SEEN;

/// Input filter on both channels: 8 equal samples at f_DTS/2 = 85 MHz (≈ 94 ns), which rejects
/// ringing on long encoder cables and still passes edges 2 MHz apart (50 nm counts at 100 mm/s).
const FILTER: pac::timer::vals::FilterValue = pac::timer::vals::FilterValue::FDTS_DIV2_N8;

pub struct Encoder {
    qei: Qei<'static, TIM3>,
}

impl Encoder {
    pub fn new(tim: Peri<'static, TIM3>, a: Peri<'static, PA6>, b: Peri<'static, PA7>) -> Self {
        let qei = Qei::new(tim, QeiPin::new(a), QeiPin::new(b));
        pac::TIM3.ccmr_input(0).modify(|w| {
            w.set_icf(0, FILTER);
            w.set_icf(1, FILTER);
        });
        Encoder { qei }
    }

    /// The 16-bit count (wraps; the core unwraps it).
    pub fn raw(&self) -> u16 {
        self.qei.count()
    }
}

/// Flags every rising edge of the index for the control tick.
#[embassy_executor::task]
pub async fn index_task(mut index: ExtiInput<'static>) {
    loop {
        index.wait_for_rising_edge().await;
        INDEX_SEEN.store(true, Ordering::Relaxed);
    }
}
