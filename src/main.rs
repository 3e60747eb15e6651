//! Firmware binary for the NUCLEO-G474RE motor-driver board: thin glue between the chip and the
//! `piezo_drive` control core. At this stage it brings the chip up at 170 MHz and blinks LD2.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod board {
    use defmt_rtt as _;
    use embassy_executor::Spawner;
    use embassy_stm32::gpio::{Level, Output, Speed};
    use embassy_stm32::rcc;
    use embassy_stm32::time::Hertz;
    use embassy_time::Timer;
    use panic_probe as _;

    /// 24 MHz HSE → PLL (M=6, N=85, R=2) → 170 MHz, boost mode (needed above 150 MHz).
    fn clocks() -> embassy_stm32::Config {
        let mut config = embassy_stm32::Config::default();
        config.rcc.hse = Some(rcc::Hse { freq: Hertz(24_000_000), mode: rcc::HseMode::Oscillator });
        config.rcc.pll = Some(rcc::Pll {
            source: rcc::PllSource::HSE,
            prediv: rcc::PllPreDiv::DIV6,
            mul: rcc::PllMul::MUL85,
            divp: None,
            divq: None,
            divr: Some(rcc::PllRDiv::DIV2),
        });
        config.rcc.sys = rcc::Sysclk::PLL1_R;
        config.rcc.boost = true;
        config
    }

    #[embassy_executor::main]
    async fn main(_spawner: Spawner) {
        let p = embassy_stm32::init(clocks());
        defmt::info!("piezo-drive {} up", env!("CARGO_PKG_VERSION"));
        // PA5 is LD2 on the Nucleo; it becomes DAC1_OUT2 once the drive output lands.
        let mut led = Output::new(p.PA5, Level::Low, Speed::Low);
        loop {
            led.toggle();
            Timer::after_millis(500).await;
        }
    }
}

/// Host stub so `cargo test --workspace` stays green: the firmware only runs on the target.
#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!("piezo-drive is firmware for thumbv7em-none-eabihf: build it with `cargo fw`.");
}
