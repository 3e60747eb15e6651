//! Quadrature encoder on TIM3 (PA6 = A, PA7 = B): embassy's `Qei` (×4 counting, 16-bit count,
//! unwrapped by the core) plus the input filter embassy 0.4 does not expose, set through the PAC.
//!
//! The optional index on PB10: EXTI line 10, rising edge, our own `EXTI15_10` handler at
//! priority 0 (above the tick) latches TIM3's count at the edge into
//! [`INDEX_LATCH`]; the tick hands it to the core (`Inputs::index_raw`), which
//! references on the edge itself. (Earlier an embassy EXTI task in thread mode flagged the edge,
//! up to a long command late.) embassy's `exti` feature is off so that the vector is ours.

use core::sync::atomic::{AtomicU32, Ordering};

use embassy_stm32::gpio::{Input, Pull};
use embassy_stm32::interrupt;
use embassy_stm32::interrupt::{InterruptExt, Priority};
use embassy_stm32::pac;
use embassy_stm32::peripherals::{PA6, PA7, PB10, TIM3};
use embassy_stm32::timer::qei::{Qei, QeiPin};
use embassy_stm32::Peri;

/// Index latch, written by the EXTI handler below and read by the tick (`control.rs`): the
/// encoder count at the edge in the low 16 bits, an edge counter in the high 16. The producer
/// owns its mailbox.
pub static INDEX_LATCH: AtomicU32 = AtomicU32::new(0);

/// Input filter on both channels: 8 equal samples at f_DTS/2 = 85 MHz (≈ 94 ns), which rejects
/// ringing on long encoder cables and still passes edges 2 MHz apart (50 nm counts at 100 mm/s).
const FILTER: pac::timer::vals::FilterValue = pac::timer::vals::FilterValue::FDTS_DIV2_N8;
/// EXTI line and port of the index (PB10: line 10, port B = 1).
const INDEX_LINE: usize = 10;
const INDEX_PORT_B: u8 = 1;

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

/// Unmasks (or masks) the index edge interrupt; an edge pending from before is dropped first.
pub fn listen_to_index(on: bool) {
    if on {
        pac::EXTI.pr(0).write(|w| w.set_line(INDEX_LINE, true));
    }
    pac::EXTI.imr(0).modify(|w| w.set_line(INDEX_LINE, on));
}

/// PB10 as a pulled-down input on EXTI line 10, rising edge, interrupt at priority 0 (masked
/// until the controller references).
pub fn start_index(pin: Peri<'static, PB10>) {
    let input = Input::new(pin, Pull::Down);
    // The pin stays configured for the life of the firmware.
    core::mem::forget(input);
    pac::SYSCFG.exticr(INDEX_LINE / 4).modify(|w| w.set_exti(INDEX_LINE % 4, INDEX_PORT_B));
    pac::EXTI.rtsr(0).modify(|w| w.set_line(INDEX_LINE, true));
    pac::EXTI.ftsr(0).modify(|w| w.set_line(INDEX_LINE, false));
    pac::EXTI.pr(0).write(|w| w.set_line(INDEX_LINE, true));
    // Masked until the controller references (the tick unmasks it: `listen_to_index`).
    pac::EXTI.imr(0).modify(|w| w.set_line(INDEX_LINE, false));
    let irq = interrupt::EXTI15_10;
    irq.set_priority(Priority::P0);
    // SAFETY: the handler reads a timer count and writes an atomic.
    unsafe { irq.enable() };
}

#[interrupt]
fn EXTI15_10() {
    // The count first: every cycle here is slider travel.
    let count = pac::TIM3.cnt().read().cnt();
    let pending = pac::EXTI.pr(0).read();
    // Write 1 to clear, our line only (no other line of this vector is enabled).
    pac::EXTI.pr(0).write(|w| w.set_line(INDEX_LINE, true));
    if pending.line(INDEX_LINE) {
        let seq = (INDEX_LATCH.load(Ordering::Relaxed) >> 16).wrapping_add(1) & 0xFFFF;
        INDEX_LATCH.store((seq << 16) | u32::from(count), Ordering::Relaxed);
    }
}
