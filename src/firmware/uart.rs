//! UART on LPUART1 (PA2 TX, PA3 RX: the ST-LINK virtual COM port), 115200 8N1, embassy's
//! interrupt-driven `BufferedUart` (256-byte receive ring filled by the interrupt, so bytes keep
//! arriving while a command runs). Lines go to the core's protocol (`piezo_drive::gcs`): bytes
//! are collected outside any lock; only `execute` runs with the controller locked (the TIM7 tick
//! masked, see `control.rs`).

use embassy_stm32::usart::BufferedUart;
use embedded_io_async::{Read, Write};
use piezo_drive::controller::ControllerConfig;
use piezo_drive::gcs::{Board, Gcs, LoopStats, Reply};

use super::control::{loop_stats, CONTROLLER};
use super::params_flash;

pub const BAUD: u32 = 115_200;

/// The protocol's view of this board.
pub struct FwBoard;

impl Board for FwBoard {
    fn store_parameters(&mut self, cfg: &ControllerConfig) -> bool {
        params_flash::request_store(cfg)
    }
    fn serial_number(&self) -> u32 {
        // The 96-bit unique device ID folded to 32 bits.
        piezo_drive::storage::crc32(embassy_stm32::uid::uid())
    }
    fn loop_stats(&self) -> LoopStats {
        loop_stats()
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
            let _ = CONTROLLER.lock(|ctl| {
                if let Some(ctl) = ctl.as_mut() {
                    gcs.execute(&pending, ctl, &mut board, &mut reply);
                }
            });
            if !reply.is_empty() {
                if let Err(e) = uart.write_all(&reply).await {
                    defmt::warn!("uart: {}", e);
                }
            }
        }
    }
}
