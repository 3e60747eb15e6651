//! Firmware binary for the NUCLEO-G474RE motor-driver board: thin glue between the chip and the
//! `piezo_drive` control core. Peripherals are bound here, at the top of `main`; each task or
//! interrupt lives in its own module under `firmware/` (pin map in `firmware/mod.rs`).
#![cfg_attr(target_os = "none", no_std, no_main)]

mod firmware;

#[cfg(target_os = "none")]
mod board {
    use defmt_rtt as _;
    use embassy_executor::{InterruptExecutor, SendSpawner, Spawner};

    use embassy_stm32::gpio::{Input, Level, Output, Pull, Speed};
    use embassy_stm32::interrupt;
    use embassy_stm32::interrupt::InterruptExt;
    use embassy_stm32::time::Hertz;
    use embassy_stm32::usart::{self, BufferedUart};
    use embassy_stm32::wdg::IndependentWatchdog;
    use embassy_stm32::{bind_interrupts, peripherals, rcc};
    use embassy_time::Timer;
    use piezo_drive::controller::Controller;
    use piezo_drive::defaults;

    use crate::firmware::{control, encoder, model, monitor, params_flash, preload, safety, uart};
    use control::{COMMS_IRQ, COMMS_PRIORITY};

    bind_interrupts!(struct Irqs {
        LPUART1 => usart::BufferedInterruptHandler<peripherals::LPUART1>;
    });

    /// Communication and sensing (UART/GCS, preload, flash store, monitor, the model table's
    /// request and install) run here, on `control::COMMS_IRQ` below the tick's priority; thread
    /// mode keeps only the model table's build, which never yields (docs/firmware.md).
    static COMMS: InterruptExecutor = InterruptExecutor::new();

    #[interrupt]
    unsafe fn UART4() {
        // SAFETY: this is the vector of `control::COMMS_IRQ`, which `COMMS` was started on.
        unsafe { COMMS.on_interrupt() }
    }

    /// 24 MHz HSE → PLL (M=6, N=85, R=2) → 170 MHz, boost mode (needed above 150 MHz); ADC12 on
    /// the system clock (embassy picks the prescaler).
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
        config.rcc.mux.adc12sel = rcc::mux::Adcsel::SYS;
        config
    }

    #[embassy_executor::main]
    async fn main(spawner: Spawner) {
        let reset = safety::take_reset_cause();
        let last_fault = safety::take_last_fault();
        let p = embassy_stm32::init(clocks());
        // Amplifier off before anything else is set up.
        let amp_enable = Output::new(p.PA10, Level::Low, Speed::Low);
        safety::freeze_on_debug_halt();
        // The independent watchdog runs from here on (item: a torn parameter page must not hang
        // the boot); until the tick feeds it, `main` does. It is configured before the tick
        // runs: the tick's reloads (KR writes) would otherwise re-lock PR/RLR between embassy's
        // unlock and its writes (RM0440 IWDG).
        let mut wdg = IndependentWatchdog::new(p.IWDG, safety::WATCHDOG_TIMEOUT_US);
        wdg.unleash();
        defmt::info!("piezo-drive {} up at 170 MHz; reset cause {}", env!("CARGO_PKG_VERSION"), reset);
        if reset.independent_watchdog {
            defmt::warn!("the last reset came from the independent watchdog");
        }
        if reset.window_watchdog {
            defmt::warn!("the last reset came from the window watchdog");
        }
        match last_fault {
            Some(f) => defmt::warn!(
                "last recorded fault (kept across resets): kind {} (1 overrun, 2 HardFault, 3 NMI, 4 flash ECC, 5 WWDG, 6 panic, 7 unexpected interrupt, 8 controller) at tick {}, seen by {} boots, detail {=[?]:08x}",
                f.kind as u32,
                f.tick,
                f.boots_seen,
                f.detail[..]
            ),
            None => defmt::info!("no fault recorded since power-up"),
        }

        // DWT cycle counter for the loop timing.
        if let Some(mut cp) = cortex_m::Peripherals::take() {
            cp.DCB.enable_trace();
            cp.DWT.enable_cycle_counter();
        } else {
            defmt::warn!("core peripherals taken: loop timing reads 0");
        }

        // Parameters: flash record or defaults.
        let defaults = defaults::controller_config();
        let mut flash = params_flash::open(p.FLASH);
        let (cfg, loaded) = params_flash::load(flash.as_mut(), &defaults);
        wdg.pet();
        match loaded {
            Ok(page) => defmt::info!("parameters loaded from flash page {}", defmt::Debug2Format(&page)),
            Err(e) => defmt::info!("parameters: defaults ({})", defmt::Debug2Format(&e)),
        }
        let ctl = match Controller::new(cfg) {
            Ok(c) => c,
            Err(e) => {
                defmt::error!("stored parameters refused ({}); defaults", defmt::Debug2Format(&e));
                match Controller::new(defaults) {
                    Ok(c) => c,
                    Err(_) => panic!("default controller settings invalid"),
                }
            }
        };
        control::install_controller(ctl);

        // Drive output (at the amplifier's rest word until the first enable ramps it up).
        #[cfg(feature = "dac-drive")]
        let drive = crate::firmware::drive::Drive::new(p.DAC1, p.PA4, p.PA5, p.TIM6, p.DMA1_CH1);
        #[cfg(all(feature = "pwm-drive", not(feature = "dac-drive")))]
        let drive = crate::firmware::drive::Drive::new(p.TIM1, p.PA8, p.PA9, p.DMA1_CH1);

        // Sensors.
        let enc = encoder::Encoder::new(p.TIM3, p.PA6, p.PA7);
        encoder::start_index(p.PB10);
        let cell = preload::Preload::new(p.ADC1, p.PC0);

        // UART on the ST-LINK virtual COM port.
        let mut ucfg = usart::Config::default();
        ucfg.baudrate = uart::BAUD;
        let (Some(tx_buf), Some(rx_buf)) =
            (cortex_m::singleton!(: [u8; 512] = [0; 512]), cortex_m::singleton!(: [u8; 256] = [0; 256]))
        else {
            panic!("uart buffers taken twice")
        };
        let serial = match BufferedUart::new(p.LPUART1, p.PA3, p.PA2, tx_buf, rx_buf, Irqs, ucfg) {
            Ok(s) => s,
            Err(_) => panic!("LPUART1 configuration refused"),
        };

        COMMS_IRQ.set_priority(COMMS_PRIORITY);
        let comms = COMMS.start(COMMS_IRQ);
        spawn("preload", comms.spawn(preload::preload_task(cell)));
        spawn("uart", comms.spawn(uart::uart_task(serial)));
        if let Some(flash) = flash {
            spawn("flash", comms.spawn(params_flash::flash_task(flash, defaults)));
        } else {
            defmt::warn!("flash in single-bank mode (DBANK=0): parameters not persistent");
        }

        // Give the preload filter a few samples before the loop starts.
        Timer::after_millis(5).await;
        wdg.pet();
        // Limit switches (docs/hardware.md): pulled up, so a switch closing to ground reads low;
        // setting 0x1026 says which level is active, 0x1025 has them read.
        let limits = [Input::new(p.PB5, Pull::Up), Input::new(p.PC7, Pull::Up)];
        control::start(p.TIM7, p.TIM5, drive, enc, amp_enable, limits);
        defmt::info!("control loop running at {} Hz", defaults::LOOP_HZ);
        // From here the tick feeds both watchdogs; the window watchdog starts once it runs.
        Timer::after_millis(1).await;
        safety::start_window_watchdog();
        // `wdg` is not fed from here on (it has no `Drop`; the IWDG keeps running).

        // From here the log's view of the loop (state changes, faults, statistics) is a task.
        spawn("monitor", comms.spawn(monitor::monitor_task()));
        spawn_table_tasks(&spawner, comms);
    }

    /// The model table: its request and install beside the other communication tasks, its build
    /// in thread mode. Spawned last: a build holds thread mode for seconds, and `main` (thread
    /// mode too) has to have started the loop and the watchdogs first.
    fn spawn_table_tasks(thread: &Spawner, comms: SendSpawner) {
        spawn("table link", comms.spawn(model::table_link_task()));
        spawn("table build", thread.spawn(model::table_build_task()));
    }

    fn spawn(name: &str, r: Result<(), embassy_executor::SpawnError>) {
        if r.is_err() {
            defmt::error!("task {} not spawned", name);
        }
    }
}

/// Host stub so `cargo test --workspace` stays green: the firmware only runs on the target.
#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!("piezo-drive is firmware for thumbv7em-none-eabihf: build it with `cargo fw`.");
}
