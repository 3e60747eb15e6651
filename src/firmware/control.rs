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
//! step is done, the tick counts an overrun and the watchdog is not fed; after
//! [`OVERRUN_SERVO_OFF`] late ticks in a row the tick switches the servo off.
//!
//! One tick: read the encoder count, the latest preload word and the index flag; run
//! `Controller::step`; write the 20 sample pairs into the free half; set the amplifier enable;
//! measure the tick with the DWT cycle counter; feed the IWDG if on time.
//!
//! Sharing the controller: the tick runs at priority 1 with interrupts enabled, so the UART,
//! time-driver and EXTI interrupts (priority 0, all short) preempt it and no received byte waits
//! for a control step. The UART task (thread mode) takes the controller through
//! [`TickLock::lock`], which masks only the TIM7 interrupt for its short `execute`; the tick
//! itself needs no lock, as nothing that touches the controller can preempt it.

use core::cell::UnsafeCell;
use core::sync::atomic::{compiler_fence, AtomicBool, AtomicU32, Ordering};

use cortex_m::peripheral::scb::VectActive;
use cortex_m::peripheral::{DWT, NVIC, SCB};
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

/// Data shared between the TIM7 tick and thread-mode code.
pub struct TickLock<T> {
    data: UnsafeCell<T>,
    busy: AtomicBool,
}

// SAFETY: access is serialised: thread mode only inside `lock` (TIM7 masked, thread mode is one
// context, `busy` refuses nesting), the tick only from its own handler, which cannot run while
// thread mode holds the lock and is not preempted by anything that touches this data.
unsafe impl<T: Send> Sync for TickLock<T> {}

impl<T> TickLock<T> {
    const fn new(v: T) -> Self {
        TickLock { data: UnsafeCell::new(v), busy: AtomicBool::new(false) }
    }

    /// Runs `f` with the TIM7 interrupt masked. For thread mode (tasks, `main`); keep `f` short,
    /// it delays the control tick. `None` (and `f` not run) when called from an interrupt or from
    /// inside another `lock` of the same data.
    pub fn lock<R>(&self, f: impl FnOnce(&mut T) -> R) -> Option<R> {
        if SCB::vect_active() != VectActive::ThreadMode || self.busy.swap(true, Ordering::Acquire) {
            return None;
        }
        let irq = interrupt::TIM7_DAC;
        let was_enabled = NVIC::is_enabled(irq);
        NVIC::mask(irq);
        // The mask takes effect before the next access.
        cortex_m::asm::dsb();
        cortex_m::asm::isb();
        compiler_fence(Ordering::SeqCst);
        // SAFETY: the tick cannot run now, and `busy` makes this the only thread-mode borrow.
        let r = f(unsafe { &mut *self.data.get() });
        compiler_fence(Ordering::SeqCst);
        if was_enabled {
            // SAFETY: restores the state found on entry.
            unsafe { NVIC::unmask(irq) };
        }
        self.busy.store(false, Ordering::Release);
        Some(r)
    }

    /// # Safety
    /// Only from the TIM7 handler.
    #[allow(clippy::mut_from_ref)]
    unsafe fn in_tick(&self) -> &mut T {
        // SAFETY: the caller is the tick; thread mode holds no reference while the tick runs.
        unsafe { &mut *self.data.get() }
    }
}

/// The controller, shared by the tick (every 100 µs) and the UART task (per command).
pub static CONTROLLER: TickLock<Option<Controller>> = TickLock::new(None);
/// Latest preload-cell word from the ADC task: the word in the low 16 bits, a sample counter in
/// the high 16 (so the tick sees when the task stops delivering).
pub static PRELOAD_WORD: AtomicU32 = AtomicU32::new(0);
/// Ticks without a new preload sample after which the tick hands the core an invalid word
/// (20 ms, twenty missed 1 kHz samples): a stuck ADC task becomes the core's preload-sensor fault
/// instead of a frozen force reading, while the watchdog only watches the tick.
const PRELOAD_STALE_TICKS: u32 = 200;
/// Set by the index task, taken by the next tick.
pub static INDEX_SEEN: AtomicBool = AtomicBool::new(false);

static STEP_CYCLES_LAST: AtomicU32 = AtomicU32::new(0);
static STEP_CYCLES_MAX: AtomicU32 = AtomicU32::new(0);
static OVERRUNS: AtomicU32 = AtomicU32::new(0);
static TICKS: AtomicU32 = AtomicU32::new(0);
/// Times the tick switched the servo off after [`OVERRUN_SERVO_OFF`] late ticks in a row.
pub static OVERRUN_SERVO_OFFS: AtomicU32 = AtomicU32::new(0);

/// Late ticks in a row after which the tick switches the servo off (the controller ramps the
/// drive to quiet): a loop that cannot keep its rate must not keep driving the motor. The IWDG
/// (not fed by late ticks) resets the chip if even that does not bring the loop back on time.
pub const OVERRUN_SERVO_OFF: u32 = 10;

/// The tick comes this many samples after the DMA enters a half.
pub const TICK_OFFSET_SAMPLES: u32 = 2;

impl TickCtx {
    /// The latest preload word, or `u16::MAX` once the ADC task has delivered nothing new for
    /// [`PRELOAD_STALE_TICKS`]: outside the 12-bit ADC's range, so outside any calibration window
    /// that matches the ADC (the default is 0–4095).
    fn fresh_preload_word(&mut self) -> u16 {
        let packed = PRELOAD_WORD.load(Ordering::Relaxed);
        let seq = (packed >> 16) as u16;
        if seq != self.preload_seq {
            self.preload_seq = seq;
            self.preload_age_ticks = 0;
        } else {
            self.preload_age_ticks = self.preload_age_ticks.saturating_add(1);
        }
        if self.preload_age_ticks > PRELOAD_STALE_TICKS {
            u16::MAX
        } else {
            packed as u16
        }
    }
}

/// What only the tick touches.
pub struct TickCtx {
    pub drive: Drive,
    pub encoder: Encoder,
    pub amp_enable: Output<'static>,
    refill: Refill,
    late_in_a_row: u32,
    preload_seq: u16,
    preload_age_ticks: u32,
}

/// Set up by `start` (TIM7 interrupt still off), then used by the tick alone.
static TICK: TickLock<Option<TickCtx>> = TickLock::new(None);

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
    let _ = CONTROLLER.lock(|c| *c = Some(ctl));
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

    let _ = TICK.lock(|tick| {
        let ctx = tick.insert(TickCtx {
            drive,
            encoder,
            amp_enable,
            refill: Refill::default(),
            late_in_a_row: 0,
            preload_seq: 0,
            preload_age_ticks: 0,
        });
        let preset = ring::tick_preset(TICK_COUNTS, TICK_OFFSET_SAMPLES * SAMPLE_COUNTS);
        // Both counters start within a few cycles of each other (in one critical section); from
        // then on they share a clock.
        ctx.drive.start_with(|| {
            pac::TIM7.cnt().write(|w| w.set_cnt(preset as u16));
            pac::TIM7.cr1().modify(|w| w.set_cen(true));
        });
    });

    let irq = interrupt::TIM7_DAC;
    irq.set_priority(Priority::P1);
    // SAFETY: the handler touches `TICK` and `CONTROLLER` as `TickLock` allows, the rest are atomics.
    unsafe { irq.enable() };
}

#[interrupt]
fn TIM7_DAC() {
    pac::TIM7.sr().write(|w| w.set_uif(false));
    // SAFETY: this is the tick.
    let (tick, controller) = unsafe { (TICK.in_tick(), CONTROLLER.in_tick()) };
    let Some(t) = tick.as_mut() else { return };
    let start = DWT::cycle_count();

    let (half, slipped) = t.refill.on_tick(t.drive.dma_half());
    // `..Default::default()` keeps this building when the protocol issue adds input fields.
    #[allow(clippy::needless_update)]
    let inputs = Inputs {
        encoder_raw: t.encoder.raw(),
        preload_word: t.fresh_preload_word(),
        index: INDEX_SEEN.swap(false, Ordering::Relaxed),
        ..Default::default()
    };
    match controller.as_mut().map(|c| c.step(&inputs)) {
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
        t.late_in_a_row = t.late_in_a_row.saturating_add(1);
        if t.late_in_a_row == OVERRUN_SERVO_OFF {
            if let Some(c) = controller.as_mut() {
                // Any motion, closed loop or not (open-loop stepping and referencing run with
                // the servo off): servo off ramps the drive to quiet and leaves the state idle.
                if !matches!(
                    c.state(),
                    piezo_drive::controller::State::Idle | piezo_drive::controller::State::Fault(_)
                ) {
                    let _ = c.set_servo(false);
                    OVERRUN_SERVO_OFFS.fetch_add(1, Ordering::Relaxed);
                }
            }
        }
    } else {
        t.late_in_a_row = 0;
        super::safety::feed_watchdog();
    }
}
