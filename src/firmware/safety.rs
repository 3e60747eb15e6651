//! Safe state of the drive: the amplifier enable (PA10, active high; the amplifier input needs
//! an external pull-down so it is off while the pin floats in reset) goes low and the drive
//! outputs go to the amplifier's rest word
//! - on a controller fault: `Outputs::amp_enable == false`, which drops the pin in the same tick
//!   (see `control.rs`);
//! - on a control-loop overrun (leaky bucket on the tick's measured lateness, `control.rs`): the
//!   pin drops at once and the controller latches its `Overrun` fault;
//! - on panic: our `#[panic_handler]` writes GPIOA and the drive registers through the PAC before
//!   anything else, records the fault, logs it over defmt and waits for a watchdog reset;
//! - on HardFault (registers dumped into the fault record, logged at the next boot), NMI (a flash double-ECC
//!   error on the parameter page while it is read at boot is survivable: see `params_flash.rs`)
//!   or an unexpected interrupt: the same register writes, then a wait for the watchdogs;
//! - on the window watchdog's early warning (the tick stopped feeding it for ~1 ms): the same,
//!   from its interrupt, and the WWDG resets the chip one count (24 µs) later;
//! - when the independent watchdog fires (50 ms): the reset puts every pin in its reset state
//!   (the enable pin floats → pull-down → amplifier off; DAC off).
//!
//! Both watchdogs are fed only by a control tick that ran on time (`control.rs`). The last fault
//! survives the reset in a no-init RAM record (magic + CRC-32, `piezo_drive::safety::fault_record`)
//! and is logged at the next boot.

use core::mem::MaybeUninit;
use core::sync::atomic::{AtomicU32, Ordering};

use cortex_m::peripheral::SCB;
use embassy_stm32::interrupt;
use embassy_stm32::interrupt::{InterruptExt, Priority};
use embassy_stm32::pac;
use piezo_drive::safety::fault_record::{self, FaultKind, FaultRecord, DETAIL_WORDS, RECORD_WORDS};
use piezo_drive::safety::watchdog;

/// Amplifier enable: PA10.
const AMP_EN_PORT: pac::gpio::Gpio = pac::GPIOA;
const AMP_EN_PIN: usize = 10;

/// Independent watchdog timeout.
pub const WATCHDOG_TIMEOUT_US: u32 = 50_000;
/// Window watchdog: early warning this long after the last feed (rounded up to whole counts of
/// 24.1 µs: 42 counts, 1.012 ms; the reset follows one count later).
pub const WINDOW_WATCHDOG_US: u32 = 1_000;
/// APB1 clock of the WWDG (the APB1 prescaler is 1).
const PCLK1_HZ: u32 = super::CORE_HZ;

/// Drive off through registers only; usable from any context, any time.
pub fn force_safe() {
    AMP_EN_PORT.bsrr().write(|w| w.set_br(AMP_EN_PIN, true));
    super::drive::force_safe();
}

/// Reloads the IWDG (a no-op until the watchdog is started).
pub fn feed_independent_watchdog() {
    pac::IWDG.kr().write(|w| w.set_key(pac::iwdg::vals::Key::RESET));
}

static mut WWDG_RELOAD: u8 = watchdog::MAX_COUNT;

/// Control ticks since boot (wraps): the clock of the fault record, counted by the tick.
static TICKS: AtomicU32 = AtomicU32::new(0);

/// Called once per control tick (`control.rs`).
pub fn count_tick() {
    TICKS.store(TICKS.load(Ordering::Relaxed).wrapping_add(1), Ordering::Relaxed);
}

/// Control ticks since boot.
pub fn ticks() -> u32 {
    TICKS.load(Ordering::Relaxed)
}

/// Counted up by the communication executor's monitor task every 10 ms: its heartbeat.
pub static COMMS_BEAT: AtomicU32 = AtomicU32::new(0);

/// Reloads both watchdogs (the WWDG only once started): the WWDG on every on-time tick, the
/// IWDG only while the communication executor is `alive` (its heartbeat as the tick judges it,
/// `piezo_drive::safety::watchdog::Heartbeat`).
pub fn feed_watchdogs(comms_alive: bool) {
    if comms_alive {
        feed_independent_watchdog();
    }
    if pac::RCC.apb1enr1().read().wwdgen() {
        // SAFETY: written once by `start_window_watchdog` before the WWDG is enabled.
        let t = unsafe { core::ptr::addr_of!(WWDG_RELOAD).read_volatile() };
        pac::WWDG.cr().write(|w| {
            w.set_t(t);
            w.set_wdga(true);
        });
    }
}

/// Starts the window watchdog: no window (W = 0x7F, a feed is welcome any time), early-warning
/// interrupt at priority 0 (above the tick's 1). Once started it cannot be stopped: call it only
/// with the control tick running, and keep every critical section far below a millisecond (the
/// flash store does not block: `params_flash.rs`).
pub fn start_window_watchdog() {
    let reload = watchdog::reload_for(PCLK1_HZ, 0, WINDOW_WATCHDOG_US).unwrap_or(watchdog::MAX_COUNT);
    // SAFETY: thread mode, before the WWDG runs: nothing reads it concurrently yet.
    unsafe { core::ptr::addr_of_mut!(WWDG_RELOAD).write_volatile(reload) };
    pac::RCC.apb1enr1().modify(|w| w.set_wwdgen(true));
    // The enable takes effect after a couple of bus cycles.
    let _ = pac::RCC.apb1enr1().read();
    pac::WWDG.cfr().write(|w| {
        w.set_w(watchdog::MAX_COUNT);
        w.set_wdgtb(pac::wwdg::vals::Wdgtb::DIV1);
        w.set_ewi(true);
    });
    pac::WWDG.sr().write(|w| w.set_ewif(false));
    let irq = interrupt::WWDG;
    irq.set_priority(Priority::P0);
    // SAFETY: the handler only writes registers and the fault record.
    unsafe { irq.enable() };
    pac::WWDG.cr().write(|w| {
        w.set_t(reload);
        w.set_wdga(true);
    });
    defmt::info!(
        "window watchdog on: early warning {} counts of {} ns after a feed",
        reload - watchdog::EWI_COUNT,
        watchdog::count_ns(PCLK1_HZ, 0)
    );
}

#[interrupt]
fn WWDG() {
    force_safe();
    pac::WWDG.sr().write(|w| w.set_ewif(false));
    record_fault(FaultKind::WindowWatchdog, [ticks(), 0, 0, 0, 0, 0, 0, 0]);
    // The reset follows within one counter step (24 µs); no logging, no feeding.
    loop {
        force_safe();
    }
}

/// Why the chip last reset, read from RCC_CSR (then cleared).
#[derive(Debug, Clone, Copy, defmt::Format)]
pub struct ResetCause {
    pub independent_watchdog: bool,
    pub window_watchdog: bool,
    pub software: bool,
    pub pin: bool,
    pub brown_out: bool,
    pub low_power: bool,
    pub option_bytes: bool,
}

/// Reads and clears the reset flags. Call before `embassy_stm32::init`.
pub fn take_reset_cause() -> ResetCause {
    let csr = pac::RCC.csr().read();
    let cause = ResetCause {
        independent_watchdog: csr.iwdgrstf(),
        window_watchdog: csr.wwdgrstf(),
        software: csr.sftrstf(),
        pin: csr.pinrstf(),
        brown_out: csr.borrstf(),
        low_power: csr.lpwrrstf(),
        option_bytes: csr.oblrstf(),
    };
    pac::RCC.csr().modify(|w| w.set_rmvf(true));
    cause
}

/// While a debugger halts the core, freeze both watchdogs and the drive/tick/timebase timers, so
/// a breakpoint neither resets the chip nor leaves the DMA looping one buffer into the amplifier.
pub fn freeze_on_debug_halt() {
    pac::DBGMCU.apb1lfzr().modify(|w| {
        w.set_iwdg(true);
        w.set_wwdg(true);
        w.set_tim5(true);
        w.set_tim6(true);
        w.set_tim7(true);
    });
    pac::DBGMCU.apb2fzr().modify(|w| w.set_tim1(true));
}

// ---- the last fault, across a reset ----

/// Not initialised by the startup code (cortex-m-rt's `.uninit` section), so a reset keeps it.
/// Declared `MaybeUninit`: after a power-up it holds whatever the RAM came up with, which Rust
/// may not read as an integer; [`load_word`] takes the words out as the hardware holds them.
#[link_section = ".uninit.FAULT_RECORD"]
static mut FAULT_RECORD: MaybeUninit<[u32; RECORD_WORDS]> = MaybeUninit::uninit();

fn record_ptr() -> *mut u32 {
    core::ptr::addr_of_mut!(FAULT_RECORD).cast::<u32>()
}

/// Word `i` of the record as the RAM holds it. A `read_volatile::<u32>` of memory Rust considers
/// uninitialised is undefined behaviour as written (never-written RAM after a power-up is just
/// that); a load in inline assembly hands back whatever bits the RAM holds as a defined `u32`
/// (the compiler cannot see into it), which [`fault_record::decode`] then judges by magic and
/// CRC. `None` past the record's end.
fn load_word(i: usize) -> Option<u32> {
    if i >= RECORD_WORDS {
        return None;
    }
    let p = record_ptr().wrapping_add(i);
    let v: u32;
    // SAFETY: `p` is word-aligned and inside the static (i < RECORD_WORDS); the load only reads
    // it, touches no stack and no flags.
    unsafe {
        core::arch::asm!("ldr {v}, [{p}]", v = out(reg) v, p = in(reg) p, options(nostack, readonly, preserves_flags));
    }
    Some(v)
}

/// The record in RAM now, if it decodes.
fn held_record() -> Option<FaultRecord> {
    let mut words = [0u32; RECORD_WORDS];
    for (i, w) in words.iter_mut().enumerate() {
        *w = load_word(i)?;
    }
    fault_record::decode(&words)
}

fn store_record(r: &FaultRecord) {
    for (i, w) in fault_record::encode(r).iter().enumerate().take(RECORD_WORDS) {
        // SAFETY: i < RECORD_WORDS; writing initialises the word (volatile, so a reset right
        // after finds it).
        unsafe { record_ptr().add(i).write_volatile(*w) };
    }
}

/// Records a fault (any context): the first of this boot stays, a later one is counted in it
/// (`fault_record::merge`).
pub fn record_fault(kind: FaultKind, detail: [u32; DETAIL_WORDS]) {
    let new = FaultRecord { kind, boots_seen: 0, tick: ticks(), later_faults: 0, detail };
    // With interrupts masked, so an interrupt that faults in turn cannot interleave its record
    // with this one (HardFault and NMI cannot be masked: they read the record as it stands).
    cortex_m::interrupt::free(|_| store_record(&fault_record::merge(held_record(), new)));
}

/// The record left before the last reset, if any (random RAM after a power-up does not decode);
/// the record stays, with its boot count raised, so a reset loop shows how often it was seen
/// (and a fault of this boot replaces it rather than being counted in it).
pub fn take_last_fault() -> Option<FaultRecord> {
    let mut r = held_record()?;
    r.boots_seen = r.boots_seen.saturating_add(1);
    store_record(&r);
    Some(r)
}

// ---- exception handlers ----

#[cortex_m_rt::exception]
unsafe fn HardFault(frame: &cortex_m_rt::ExceptionFrame) -> ! {
    force_safe();
    // SAFETY: read-only access to the fault status registers.
    let scb = unsafe { &*SCB::PTR };
    let detail = [
        frame.pc(),
        frame.lr(),
        frame.xpsr(),
        scb.cfsr.read(),
        scb.hfsr.read(),
        scb.mmfar.read(),
        scb.bfar.read(),
        frame as *const _ as u32,
    ];
    record_fault(FaultKind::HardFault, detail);
    // No logging here: defmt can itself fault or panic, and the panic handler would overwrite
    // this record. The next boot logs it (`take_last_fault`).
    loop {
        force_safe();
    }
}

#[cortex_m_rt::exception]
unsafe fn NonMaskableInt() {
    let eccr = pac::FLASH.eccr().read();
    if eccr.eccd() {
        // Write 1 to clear the double-error flag (writing 0 leaves the correction flag).
        let mut clear = eccr;
        clear.set_eccc(false);
        clear.set_eccd(true);
        pac::FLASH.eccr().write_value(clear);
        if super::param_page::ecc_error_while_reading(eccr.bk_ecc(), eccr.addr_ecc()) {
            // A torn parameter page: the reader treats the page as absent and erases it.
            return;
        }
    }
    // Anything else (ECC error in code or constants, the clock security system): not survivable.
    force_safe();
    record_fault(FaultKind::Nmi, [eccr.0, pac::RCC.cifr().read().0, 0, 0, 0, 0, 0, 0]);
    loop {
        force_safe();
    }
}

#[cortex_m_rt::exception]
unsafe fn DefaultHandler(irqn: i16) {
    force_safe();
    record_fault(FaultKind::UnexpectedInterrupt, [irqn as u32, 0, 0, 0, 0, 0, 0, 0]);
    loop {
        force_safe();
    }
}

/// Set by the first panic: a panic inside the panic handler (its logging) keeps the first record.
static PANICKING: core::sync::atomic::AtomicBool = core::sync::atomic::AtomicBool::new(false);

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    cortex_m::interrupt::disable();
    force_safe();
    if PANICKING.swap(true, core::sync::atomic::Ordering::SeqCst) {
        loop {
            force_safe();
            cortex_m::asm::nop();
        }
    }
    let line = info.location().map_or(0, |l| l.line());
    record_fault(FaultKind::Panic, [line, 0, 0, 0, 0, 0, 0, 0]);
    defmt::error!("panic: {}", defmt::Display2Format(info));
    // Not fed any more: the watchdogs reset the chip (if they were started).
    loop {
        force_safe();
        cortex_m::asm::nop();
    }
}
