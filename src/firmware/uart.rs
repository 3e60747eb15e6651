//! UART on LPUART1 (PA2 TX, PA3 RX: the ST-LINK virtual COM port), 115200 8N1, embassy's
//! interrupt-driven `BufferedUart` (256-byte receive ring filled by the interrupt, so bytes keep
//! arriving while a command runs). Lines go to the core's protocol (`piezo_drive::gcs`): bytes
//! are collected outside any lock. Each command runs through
//! `Gcs::execute_shared` (`src/gcs/lock.rs`), which decides what runs with the controller
//! locked (the TIM7 tick masked) and what runs without; `host-sim pil --gcs-locks` counts every
//! locked section of every command on the emulated M4 (docs/firmware.md, Loop timing).

use embassy_stm32::usart::BufferedUart;
use embedded_io_async::{Read, Write};
use piezo_drive::controller::{Controller, ControllerConfig};
use piezo_drive::gcs::{Board, Gcs, LoopStats, Reply, SharedController};
use piezo_drive::recorder::Recorder;

use super::control::{loop_stats, CONTROLLER, RECORDER};
use super::params_flash;

pub const BAUD: u32 = 115_200;

/// The protocol's view of this board.
pub struct FwBoard;

impl Board for FwBoard {
    fn store_parameters(&mut self, cfg: &ControllerConfig) -> bool {
        params_flash::request_store(cfg)
    }
    fn store_pending(&self) -> bool {
        params_flash::store_pending()
    }
    fn take_store_failure(&mut self) -> bool {
        params_flash::take_store_failure()
    }
    fn serial_number(&self) -> u32 {
        // The 96-bit unique device ID folded to 32 bits.
        piezo_drive::storage::crc32(embassy_stm32::uid::uid())
    }
    fn loop_stats(&self) -> LoopStats {
        loop_stats()
    }
    fn recorder(&self) -> Option<&Recorder> {
        Some(&RECORDER)
    }
}

/// The controller as the tick shares it: [`CONTROLLER`]'s lock (TIM7 masked).
struct TickShared;

impl SharedController for TickShared {
    fn lock<R>(&mut self, f: impl FnOnce(&mut Controller) -> R) -> Option<R> {
        CONTROLLER.lock(|ctl| ctl.as_mut().map(f)).flatten()
    }
}

#[embassy_executor::task]
pub async fn uart_task(mut uart: BufferedUart<'static>) {
    let mut gcs = Gcs::new();
    let mut reply = Reply::new();
    let mut board = FwBoard;
    let mut chunk = [0u8; 64];
    loop {
        let n = match uart.read(&mut chunk).await {
            Ok(n) => n,
            Err(e) => {
                defmt::warn!("uart: {}", e);
                continue;
            }
        };
        for &byte in chunk.iter().take(n) {
            let Some(pending) = gcs.push_byte(byte) else { continue };
            reply.clear();
            gcs.execute_shared(&pending, &mut TickShared, &mut board, &mut reply);
            if !reply.is_empty() {
                if let Err(e) = uart.write_all(&reply).await {
                    defmt::warn!("uart: {}", e);
                }
            }
            // A reply longer than the buffer (`DRR?`): part by part, formatted without a lock.
            while gcs.reply_pending() {
                reply.clear();
                gcs.continue_reply(&board, &mut reply);
                if let Err(e) = uart.write_all(&reply).await {
                    defmt::warn!("uart: {}", e);
                }
            }
        }
    }
}
