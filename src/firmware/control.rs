//! The fixed-rate control loop: the TIM7 update interrupt at 10 kHz.
//!
//! Why TIM7 and not the drive DMA's half-/transfer-complete interrupt: embassy-stm32 0.4 defines
//! the interrupt handler of every DMA channel itself (its build script generates them), so the
//! firmware cannot own the DMA1_CH1 vector without patching embassy. TIM7 counts the same
//! 170 MHz clock as the sample timer (TIM6 or TIM1) with exactly 20× its period and both are
//! started in the same critical section, so the tick is phase-locked to the DMA for good: it comes
//! [`TICK_OFFSET_SAMPLES`] samples after the DMA crosses into a half. Each tick reads the DMA's
//! position (NDTR) and refills the other half, which the DMA reaches 90 µs later; if the DMA is
//! found in the same half as last time, or has entered the half just written by the time the
//! step is done, the tick counts an overrun and the watchdog is not fed.
//!
//! One tick: read the encoder count, the latest preload word and the index flag; run
//! `Controller::step` (under the controller's critical-section mutex, which the UART task also
//! takes for its short `execute`); write the 20 sample pairs into the free half; set the
//! amplifier enable; measure the tick with the DWT cycle counter; feed the IWDG if on time.

use core::cell::RefCell;
use core::sync::atomic::{AtomicBool, AtomicU32, Ordering};

use cortex_m::peripheral::DWT;
use critical_section::Mutex;
use embassy_stm32::gpio::Output;
use embassy_stm32::interrupt;
use embassy_stm32::interrupt::{InterruptExt, Priority};
use embassy_stm32::pac;
use embassy_stm32::peripherals::TIM7;
use embassy_stm32::timer::low_level::Timer;
use embassy_stm32::Peri;
use piezo_drive::controller::{Controller, Inputs};
use piezo_drive::gcs::LoopStats;

use super::drive::Drive;
use super::encoder::Encoder;
use super::ring::{self, Refill};
use super::{CORE_HZ, SAMPLE_COUNTS, TICK_COUNTS};

/// The controller, shared by the tick (every 100 µs) and the UART task (per command).
pub static CONTROLLER: Mutex<RefCell<Option<Controller>>> = Mutex::new(RefCell::new(None));
/// Latest preload-cell word from the ADC task (u16 in a u32).
pub static PRELOAD_WORD: AtomicU32 = AtomicU32::new(0);
/// Set by the index task, taken by the next tick.
pub static INDEX_SEEN: AtomicBool = AtomicBool::new(false);

static STEP_CYCLES_LAST: AtomicU32 = AtomicU32::new(0);
static STEP_CYCLES_MAX: AtomicU32 = AtomicU32::new(0);
static OVERRUNS: AtomicU32 = AtomicU32::new(0);
static TICKS: AtomicU32 = AtomicU32::new(0);

/// The tick comes this many samples after the DMA enters a half.
pub const TICK_OFFSET_SAMPLES: u32 = 2;

/// What only the tick touches.
pub struct TickCtx {
    pub drive: Drive,
    pub encoder: Encoder,
    pub amp_enable: Output<'static>,
    refill: Refill,
}

static TICK: Mutex<RefCell<Option<TickCtx>>> = Mutex::new(RefCell::new(None));

pub fn loop_stats() -> LoopStats {
    LoopStats {
        step_cycles_last: STEP_CYCLES_LAST.load(Ordering::Relaxed),
        step_cycles_max: STEP_CYCLES_MAX.load(Ordering::Relaxed),
        overruns: OVERRUNS.load(Ordering::Relaxed),
        core_clock_hz: CORE_HZ,
    }
}

pub fn ticks() -> u32 {
    TICKS.load(Ordering::Relaxed)
}

/// Installs the controller.
pub fn install_controller(ctl: Controller) {
    critical_section::with(|cs| *CONTROLLER.borrow_ref_mut(cs) = Some(ctl));
}

/// Sets up TIM7 and starts it together with the drive's sample timer and DMA.
pub fn start(tim7: Peri<'static, TIM7>, drive: Drive, encoder: Encoder, amp_enable: Output<'static>) {
    let timer = Timer::new(tim7);
    let r = timer.regs_basic();
    r.cr1().modify(|w| w.set_cen(false));
    r.psc().write_value(0);
    r.arr().write(|w| w.set_arr((TICK_COUNTS - 1) as u16));
    // Load PSC/ARR without an interrupt (URS: only counter overflow raises UIF).
    r.cr1().modify(|w| w.set_urs(pac::timer::vals::Urs::COUNTER_ONLY));
    r.egr().write(|w| w.set_ug(true));
    r.sr().write(|w| w.set_uif(false));
    r.dier().modify(|w| w.set_uie(true));
    // The timer's clock must stay on for the life of the firmware; `Timer`'s drop would stop it.
    core::mem::forget(timer);

    critical_section::with(|cs| {
        let mut ctx = TickCtx { drive, encoder, amp_enable, refill: Refill::default() };
        let preset = ring::tick_preset(TICK_COUNTS, TICK_OFFSET_SAMPLES * SAMPLE_COUNTS);
        // Both counters start within a few cycles of each other; from then on they share a clock.
        ctx.drive.start_with(|| {
            pac::TIM7.cnt().write(|w| w.set_cnt(preset as u16));
            pac::TIM7.cr1().modify(|w| w.set_cen(true));
        });
        *TICK.borrow_ref_mut(cs) = Some(ctx);
    });

    let irq = interrupt::TIM7_DAC;
    irq.set_priority(Priority::P1);
    // SAFETY: the handler below only touches state behind critical-section mutexes and atomics.
    unsafe { irq.enable() };
}

#[interrupt]
fn TIM7_DAC() {
    pac::TIM7.sr().write(|w| w.set_uif(false));
    critical_section::with(|cs| {
        let mut tick = TICK.borrow_ref_mut(cs);
        let Some(t) = tick.as_mut() else { return };
        let start = DWT::cycle_count();

        let (half, slipped) = t.refill.on_tick(t.drive.dma_half());
        // `..Default::default()` keeps this building when the protocol issue adds input fields.
        #[allow(clippy::needless_update)]
        let inputs = Inputs {
            encoder_raw: t.encoder.raw(),
            preload_word: PRELOAD_WORD.load(Ordering::Relaxed) as u16,
            index: INDEX_SEEN.swap(false, Ordering::Relaxed),
            ..Default::default()
        };
        let out = CONTROLLER.borrow_ref_mut(cs).as_mut().map(|c| c.step(&inputs));
        match out {
            Some(out) => {
                t.drive.write_half(half, &out.dac);
                t.amp_enable.set_level(out.amp_enable.into());
            }
            None => {
                t.amp_enable.set_low();
                t.drive.write_half_safe(half);
            }
        }
        // The DMA already in the half just written: part of it played stale samples.
        let late = t.drive.dma_half() == half;

        let cycles = DWT::cycle_count().wrapping_sub(start);
        STEP_CYCLES_LAST.store(cycles, Ordering::Relaxed);
        if cycles > STEP_CYCLES_MAX.load(Ordering::Relaxed) {
            STEP_CYCLES_MAX.store(cycles, Ordering::Relaxed);
        }
        TICKS.store(TICKS.load(Ordering::Relaxed).wrapping_add(1), Ordering::Relaxed);
        if slipped || late {
            OVERRUNS.store(OVERRUNS.load(Ordering::Relaxed).wrapping_add(1), Ordering::Relaxed);
        } else {
            super::safety::feed_watchdog();
        }
    });
}
