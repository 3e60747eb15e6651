//! The fixed-rate control loop: the TIM7 update interrupt at 10 kHz.
//!
//! Why TIM7 and not the drive DMA's half-/transfer-complete interrupt: embassy-stm32 0.4 defines
//! the interrupt handler of every DMA channel itself (its build script generates them), so the
//! firmware cannot own the DMA1_CH1 vector without patching embassy. TIM7 counts the same
//! 170 MHz clock as the sample timer (TIM6 or TIM1) with exactly 20× its period and both are
//! started in the same critical section, so the tick is phase-locked to the DMA for good: it comes
//! [`TICK_OFFSET_SAMPLES`] samples after the DMA crosses into a half.
//!
//! One tick, in this order (the sequence itself is core code, `piezo_drive::safety::tick`, run
//! by the host tests over a simulated board; this file binds it to the registers):
//! 1. **Refill first**: the samples the *previous* tick computed go into the half the DMA is not
//!    reading (found from NDTR), through the soft start (`piezo_drive::safety::soft_start`: rest
//!    word while the enable is low, a 20 ms ramp after it goes high), and the amplifier enable is
//!    set for them. The DMA reaches that half 18 samples (90 µs) after the tick's due time, and
//!    the refill is the first thing the tick does, so a long `step` no longer eats the deadline
//!    (the price: the drive follows the sensors one period later, 190 µs instead of 90 µs).
//! 2. **Lateness**: TIM5, a free-running 32-bit counter on the same clock started with TIM6/TIM7,
//!    gives the tick's due time; [`DeadlineMonitor`] says how late the tick started, whether the
//!    refill finished within the 90 µs, and how many whole periods went by without a tick (a tick
//!    a whole DMA lap late looks on time to NDTR alone). Late ticks fill a leaky bucket
//!    ([`OVERRUN_BUCKET`]: +10 late, −1 on time, trips at 40; a missed period trips at once). A
//!    trip drops the enable pin at once, latches the controller's `Overrun` fault (GCS error
//!    4100, `XFT?` 6) and records the fault in no-init RAM; `SVO` clears it as any motion error.
//! 3. **Step**: encoder count, preload word, index latch → `Controller::step`; its samples wait
//!    for the next tick; a disabled enable in its outputs drops the pin at once.
//!    Then the data recorder takes its points from the controller ([`RECORDER`]).
//! 4. **Watchdogs**: the IWDG (50 ms) and the WWDG (~1 ms, see `safety.rs`) are fed only by a
//!    tick that was on time.
//!
//! Sharing the controller: the tick runs at priority 1 with interrupts enabled, so the UART,
//! time-driver, EXTI and WWDG interrupts (priority 0, all short) preempt it. The UART task (on
//! the communication executor, priority 2) takes the controller through [`TickLock::lock`],
//! which masks the TIM7 interrupt: queries take a snapshot of it under the lock and format outside it; settings
//! commands check a copy of the settings outside it and set them under it; other commands run
//! under it (check and act). `piezo_drive::gcs::Gcs::execute_shared` decides which, and
//! `host-sim pil --gcs-locks` counts every locked section on the emulated M4.

use core::cell::UnsafeCell;
use core::mem::MaybeUninit;
use core::sync::atomic::{compiler_fence, AtomicBool, AtomicU32, Ordering};

use cortex_m::interrupt::InterruptNumber;
use cortex_m::peripheral::scb::VectActive;
use cortex_m::peripheral::{DWT, NVIC, SCB};
use embassy_stm32::gpio::{Input, Output};
use embassy_stm32::interrupt;
use embassy_stm32::interrupt::{InterruptExt, Priority};
use embassy_stm32::pac;
use embassy_stm32::peripherals::{TIM5, TIM7};
use embassy_stm32::timer::low_level::Timer;
use embassy_stm32::Peri;
use piezo_drive::controller::Controller;
use piezo_drive::gcs::LoopStats;
use piezo_drive::recorder::Recorder;
use piezo_drive::safety::fault_record::FaultKind;
use piezo_drive::safety::soft_start::SoftStart;
use piezo_drive::safety::tick::{Samples, Tick, TickBoard};
use piezo_drive::safety::timing::{DeadlineMonitor, LeakyBucket, OverrunSupervisor, TickTiming, Verdict};
use piezo_drive::safety::watchdog::Heartbeat;

use super::drive::Drive;
use super::encoder::{Encoder, INDEX_LATCH};
use super::preload::PRELOAD_WORD;
use super::ring;
use super::{AMP_REST_WORD, CORE_HZ, SAMPLE_COUNTS, SOFT_START_SAMPLES, TICK_COUNTS};

/// Data shared between the TIM7 tick and the code below it (communication executor, thread mode).
pub struct TickLock<T> {
    data: UnsafeCell<T>,
    busy: AtomicBool,
}

// SAFETY: access is serialised: thread mode and the communication executor only inside `lock`
// (TIM7 masked; from thread mode the communication executor's interrupt too, and that executor
// preempts thread mode, so neither can find the other inside; `busy` refuses nesting), the tick
// only from its own handler, which cannot run while either holds the lock and is not preempted
// by anything that touches this data.
unsafe impl<T: Send> Sync for TickLock<T> {}

impl<T> TickLock<T> {
    const fn new(v: T) -> Self {
        TickLock { data: UnsafeCell::new(v), busy: AtomicBool::new(false) }
    }

    /// Runs `f` with the TIM7 interrupt masked. From thread mode (the table build) the
    /// communication executor's interrupt is masked as well, so that executor never finds the
    /// lock taken: it cannot wait for a context it preempts. From the communication executor
    /// (UART, preload, flash store, monitor, the table's install) only TIM7 is masked. Keep `f`
    /// short, it delays the control tick. `None` (and `f` not run) when called from any other
    /// interrupt or from inside another `lock` of the same data.
    pub fn lock<R>(&self, f: impl FnOnce(&mut T) -> R) -> Option<R> {
        let from_thread = match SCB::vect_active() {
            VectActive::ThreadMode => true,
            VectActive::Interrupt { irqn } if irqn == COMMS_IRQ.number() as u8 => false,
            _ => return None,
        };
        if self.busy.swap(true, Ordering::Acquire) {
            return None;
        }
        let tick = interrupt::TIM7_DAC;
        let tick_was_enabled = NVIC::is_enabled(tick);
        let comms_was_enabled = from_thread && NVIC::is_enabled(COMMS_IRQ);
        NVIC::mask(tick);
        if comms_was_enabled {
            NVIC::mask(COMMS_IRQ);
        }
        // The mask takes effect before the next access.
        cortex_m::asm::dsb();
        cortex_m::asm::isb();
        compiler_fence(Ordering::SeqCst);
        // SAFETY: the tick cannot run now, nor (from thread mode) the communication executor;
        // `busy` makes this the only borrow outside the tick.
        let r = f(unsafe { &mut *self.data.get() });
        compiler_fence(Ordering::SeqCst);
        // SAFETY: restores the state found on entry.
        unsafe {
            if comms_was_enabled {
                NVIC::unmask(COMMS_IRQ);
            }
            if tick_was_enabled {
                NVIC::unmask(tick);
            }
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

/// The interrupt that runs the communication executor (`main.rs`): UART4's vector, unused by
/// the board. Its priority sits below the tick's and above thread mode (docs/firmware.md).
pub const COMMS_IRQ: interrupt::Interrupt = interrupt::UART4;
/// The tick's priority, and the communication executor's just below it.
pub const TICK_PRIORITY: Priority = Priority::P1;
pub const COMMS_PRIORITY: Priority = Priority::P2;

/// The controller, shared by the tick (every 100 µs), the communication executor's tasks (per
/// command, per poll) and the table build in thread mode (its install).
pub static CONTROLLER: TickLock<Slot<Controller>> = TickLock::new(Slot::EMPTY);

/// A value installed once at boot, empty until then. Unlike `Option<Controller>`, whose `None`
/// is not all zero bytes and so put the controller's 3.5 KiB in `.data` (copied from flash at
/// boot), an empty slot is zero and undefined bytes: it lives in `.bss` and costs no flash.
pub struct Slot<T> {
    ready: bool,
    value: MaybeUninit<T>,
}

impl<T> Slot<T> {
    const EMPTY: Self = Slot { ready: false, value: MaybeUninit::uninit() };

    pub fn as_ref(&self) -> Option<&T> {
        // SAFETY: `ready` is set only once `value` is written.
        self.ready.then(|| unsafe { self.value.assume_init_ref() })
    }

    pub fn as_mut(&mut self) -> Option<&mut T> {
        // SAFETY: as above.
        self.ready.then(|| unsafe { self.value.assume_init_mut() })
    }

    /// Puts `value` in (dropping one installed before).
    pub fn install(&mut self, value: T) {
        if self.ready {
            // SAFETY: ready, so initialised; it is overwritten right after.
            unsafe { self.value.assume_init_drop() };
        }
        self.value.write(value);
        self.ready = true;
    }
}
/// The data recorder (11.5 KiB of points, zero-initialised): the tick stores a point after each
/// step, the UART task reads it without a lock (atomics, see `piezo_drive::recorder`); the
/// commands that reconfigure or trigger it run with the controller locked, so never during a tick.
pub static RECORDER: Recorder = Recorder::new();
/// Drive parking, for the flash store (`params_flash.rs`): while `PARK_REQUEST` is set the tick
/// keeps the enable low and writes rest words; `PARKED_TICKS` counts the ticks it has done so.
pub static PARK_REQUEST: AtomicBool = AtomicBool::new(false);
pub static PARKED_TICKS: AtomicU32 = AtomicU32::new(0);

static STEP_CYCLES_LAST: AtomicU32 = AtomicU32::new(0);
static STEP_CYCLES_MAX: AtomicU32 = AtomicU32::new(0);
static OVERRUNS: AtomicU32 = AtomicU32::new(0);
/// Times the overrun bucket tripped (each one latched an `Overrun` fault).
pub static OVERRUN_TRIPS: AtomicU32 = AtomicU32::new(0);
/// Largest tick start latency seen, in 170 MHz counts.
pub static LATENCY_MAX: AtomicU32 = AtomicU32::new(0);

/// The overrun bucket: +10 per late tick, −1 per on-time tick, latches at 40: four late ticks in
/// a row, the fifth of an alternating late/on-time pattern, or a steady one in ten trip it (see
/// `tests/safety.rs` for the hand counts).
pub const OVERRUN_BUCKET: LeakyBucket = LeakyBucket::new(10, 1, 40);

/// The tick comes this many samples after the DMA enters a half.
pub const TICK_OFFSET_SAMPLES: u32 = 2;
/// TIM5 counts from the timers' start to the first tick's due time.
const FIRST_DUE_COUNTS: u32 = TICK_OFFSET_SAMPLES * SAMPLE_COUNTS;
/// The refill must be done before the DMA enters the half it writes: 18 samples after the due
/// time, less one sample of margin.
const REFILL_DEADLINE_COUNTS: u32 = (ring::HALF as u32 - TICK_OFFSET_SAMPLES - 1) * SAMPLE_COUNTS;

/// What only the tick touches: the peripherals it drives and reads, and the tick's own state.
pub struct TickCtx {
    hw: TickHw,
    tick: Tick,
}

/// The peripherals of the tick, as [`TickBoard`] for the core's [`Tick`].
pub struct TickHw {
    pub drive: Drive,
    pub encoder: Encoder,
    pub amp_enable: Output<'static>,
    /// DWT cycle count at the tick's entry, for the step's cost.
    entry_cycles: u32,
    /// The index edge interrupt is enabled.
    index_on: bool,
    /// The communication executor's heartbeat: the independent watchdog is fed only while it
    /// beats.
    heartbeat: Heartbeat,
    /// The limit switch inputs [negative, positive] (`firmware/mod.rs`'s pin map).
    limits: [Input<'static>; 2],
}

impl TickBoard for TickHw {
    fn timebase(&mut self) -> u32 {
        timebase()
    }
    fn dma_half(&mut self) -> usize {
        self.drive.dma_half()
    }
    fn write_half(&mut self, half: usize, samples: &Samples) {
        self.drive.write_half(half, samples);
    }
    fn set_enable(&mut self, on: bool) {
        self.amp_enable.set_level(on.into());
    }
    fn park_requested(&mut self) -> bool {
        PARK_REQUEST.load(Ordering::Relaxed)
    }
    fn parked(&mut self, parked: bool) {
        if parked {
            PARKED_TICKS.store(PARKED_TICKS.load(Ordering::Relaxed).saturating_add(1), Ordering::Relaxed);
        } else {
            PARKED_TICKS.store(0, Ordering::Relaxed);
        }
    }
    fn note_timing(&mut self, timing: &TickTiming, verdict: &Verdict) {
        if timing.latency > LATENCY_MAX.load(Ordering::Relaxed) {
            LATENCY_MAX.store(timing.latency, Ordering::Relaxed);
        }
        if verdict.late {
            bump(&OVERRUNS);
        }
    }
    fn record_overrun(&mut self, detail: [u32; 8]) {
        bump(&OVERRUN_TRIPS);
        super::safety::record_fault(FaultKind::Overrun, detail);
    }
    fn encoder_raw(&mut self) -> u16 {
        self.encoder.raw()
    }
    fn preload_sample(&mut self) -> (u16, u16) {
        let packed = PRELOAD_WORD.load(Ordering::Relaxed);
        ((packed >> 16) as u16, packed as u16)
    }
    fn index_latch(&mut self) -> (u16, u16) {
        let packed = INDEX_LATCH.load(Ordering::Relaxed);
        ((packed >> 16) as u16, packed as u16)
    }
    fn index_listening(&mut self, on: bool) {
        if on != self.index_on {
            self.index_on = on;
            super::encoder::listen_to_index(on);
        }
    }
    fn after_step(&mut self, controller: Option<&Controller>) {
        if let Some(c) = controller {
            RECORDER.sample(c);
        }
        let cycles = DWT::cycle_count().wrapping_sub(self.entry_cycles);
        STEP_CYCLES_LAST.store(cycles, Ordering::Relaxed);
        if cycles > STEP_CYCLES_MAX.load(Ordering::Relaxed) {
            STEP_CYCLES_MAX.store(cycles, Ordering::Relaxed);
        }
        super::safety::count_tick();
    }
    fn limit_pins(&mut self) -> Option<[bool; 2]> {
        // Read every tick (100 µs): the slider moves under 0.5 µm in that time, a switch's active
        // zone is millimetres long, so no pulse it makes is shorter than a tick.
        Some([self.limits[0].is_high(), self.limits[1].is_high()])
    }
    fn feed_watchdogs(&mut self) {
        let alive = self.heartbeat.alive(super::safety::COMMS_BEAT.load(Ordering::Relaxed));
        super::safety::feed_watchdogs(alive);
    }
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

/// Installs the controller.
pub fn install_controller(ctl: Controller) {
    let _ = CONTROLLER.lock(|c| c.install(ctl));
}

/// Sets up TIM7 (the tick) and TIM5 (the free-running timebase) and starts both together with
/// the drive's sample timer and DMA.
pub fn start(
    tim7: Peri<'static, TIM7>,
    tim5: Peri<'static, TIM5>,
    drive: Drive,
    encoder: Encoder,
    amp_enable: Output<'static>,
    limits: [Input<'static>; 2],
) {
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

    let base = Timer::new(tim5);
    let b = base.regs_gp32();
    b.cr1().modify(|w| w.set_cen(false));
    b.psc().write_value(0);
    b.arr().write_value(u32::MAX);
    b.cr1().modify(|w| w.set_urs(pac::timer::vals::Urs::COUNTER_ONLY));
    b.egr().write(|w| w.set_ug(true));
    b.sr().write(|w| w.set_uif(false));
    b.cnt().write_value(0);
    core::mem::forget(base);

    let _ = TICK.lock(|tick| {
        let ctx = tick.insert(TickCtx {
            hw: TickHw {
                drive,
                encoder,
                amp_enable,
                entry_cycles: 0,
                index_on: false,
                heartbeat: Heartbeat::default(),
                limits,
            },
            tick: Tick::new(
                OverrunSupervisor::new(
                    DeadlineMonitor::new(FIRST_DUE_COUNTS, TICK_COUNTS, REFILL_DEADLINE_COUNTS),
                    OVERRUN_BUCKET,
                ),
                SoftStart::new(AMP_REST_WORD, SOFT_START_SAMPLES),
                (INDEX_LATCH.load(Ordering::Relaxed) >> 16) as u16,
            ),
        });
        let preset = ring::tick_preset(TICK_COUNTS, FIRST_DUE_COUNTS);
        // The three counters start within a few cycles of each other (in one critical section);
        // from then on they share a clock.
        ctx.hw.drive.start_with(|| {
            pac::TIM7.cnt().write(|w| w.set_cnt(preset as u16));
            pac::TIM5.cr1().modify(|w| w.set_cen(true));
            pac::TIM7.cr1().modify(|w| w.set_cen(true));
        });
    });

    let irq = interrupt::TIM7_DAC;
    irq.set_priority(TICK_PRIORITY);
    // SAFETY: the handler touches `TICK` and `CONTROLLER` as `TickLock` allows, the rest are atomics.
    unsafe { irq.enable() };
}

/// The free-running timebase (170 MHz, wraps every 25 s).
fn timebase() -> u32 {
    pac::TIM5.cnt().read()
}

fn bump(counter: &AtomicU32) {
    counter.store(counter.load(Ordering::Relaxed).wrapping_add(1), Ordering::Relaxed);
}

#[interrupt]
fn TIM7_DAC() {
    let entry = timebase();
    pac::TIM7.sr().write(|w| w.set_uif(false));
    // SAFETY: this is the tick.
    let (tick, controller) = unsafe { (TICK.in_tick(), CONTROLLER.in_tick()) };
    let Some(t) = tick.as_mut() else { return };
    t.hw.entry_cycles = DWT::cycle_count();
    t.tick.run(&mut t.hw, controller.as_mut(), entry);
}
