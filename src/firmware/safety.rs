//! Safe state of the drive: the amplifier enable (PA10, active high; the amplifier input needs
//! an external pull-down so it is off while the pin floats in reset) goes low and the drive
//! outputs go to mid-scale
//! - on a controller fault: `Outputs::amp_enable == false` (see `control.rs`);
//! - on panic: our `#[panic_handler]` writes GPIOA and the drive registers through the PAC before
//!   anything else, then logs over defmt and waits for the watchdog to reset the chip;
//! - on HardFault, NMI or an unexpected interrupt: the same register writes, then a wait for the
//!   watchdog (cortex-m-rt's default handlers would spin with the drive running);
//! - when the independent watchdog fires: the reset puts every pin in its reset state (the enable
//!   pin floats → pull-down → amplifier off; DAC off), and the next boot reports the IWDG reset.
//!
//! The IWDG (50 ms) is fed only by a control tick that ran on time (`control.rs`): a stopped,
//! stuck or persistently late loop resets the chip.

use embassy_stm32::pac;

/// Amplifier enable: PA10.
const AMP_EN_PORT: pac::gpio::Gpio = pac::GPIOA;
const AMP_EN_PIN: usize = 10;

/// Watchdog timeout.
pub const WATCHDOG_TIMEOUT_US: u32 = 50_000;

/// Drive off through registers only; usable from any context, any time.
pub fn force_safe() {
    AMP_EN_PORT.bsrr().write(|w| w.set_br(AMP_EN_PIN, true));
    super::drive::force_safe();
}

/// Reloads the IWDG (a no-op until the watchdog is started).
pub fn feed_watchdog() {
    pac::IWDG.kr().write(|w| w.set_key(pac::iwdg::vals::Key::RESET));
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

/// While a debugger halts the core, freeze the watchdog and the drive/tick timers, so a
/// breakpoint neither resets the chip nor leaves the DMA looping one buffer into the amplifier.
pub fn freeze_on_debug_halt() {
    pac::DBGMCU.apb1lfzr().modify(|w| {
        w.set_iwdg(true);
        w.set_tim6(true);
        w.set_tim7(true);
    });
    pac::DBGMCU.apb2fzr().modify(|w| w.set_tim1(true));
}

#[cortex_m_rt::exception]
unsafe fn HardFault(_frame: &cortex_m_rt::ExceptionFrame) -> ! {
    loop {
        force_safe();
    }
}

#[cortex_m_rt::exception]
unsafe fn NonMaskableInt() {
    // E.g. a double ECC error reading flash: nothing here can be trusted to continue.
    loop {
        force_safe();
    }
}

#[cortex_m_rt::exception]
unsafe fn DefaultHandler(_irqn: i16) {
    loop {
        force_safe();
    }
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    cortex_m::interrupt::disable();
    force_safe();
    defmt::error!("panic: {}", defmt::Display2Format(info));
    // Not fed any more: the IWDG resets the chip within its timeout (if it was started).
    loop {
        force_safe();
        cortex_m::asm::nop();
    }
}
