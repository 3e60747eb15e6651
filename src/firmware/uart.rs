//! UART on LPUART1 (PA2 TX, PA3 RX: the ST-LINK virtual COM port), 115200 8N1, embassy's
//! interrupt-driven `BufferedUart` (256-byte receive ring filled by the interrupt, so bytes keep
//! arriving while a command runs). Lines go to the core's protocol (`piezo_drive::gcs`): bytes
//! are collected outside any lock. A read-only command (`…?`, #5, #7: `Gcs::is_read_only`)
//! runs on a copy of the controller taken with the TIM7 tick masked for the copy only (a memcpy
//! of the controller, a few hundred cycles), so formatting a long reply (`SPA?`, `HPA?`, `HLP?`:
//! tens of thousands of instructions of software f64) never holds the tick off. A settings
//! command (`SPA`, `VEL`, `ACC`, `DEC`: `Gcs::is_settings_only`) is parsed and checked on a copy
//! too, and only `Controller::set_config` runs locked. Every other command that changes the
//! controller runs with it locked (parse, check, set: about 1 000 instructions). Measured on the
//! emulated M4: `tools/pil/run` (README, Loop timing).

use embassy_stm32::usart::BufferedUart;
use embedded_io_async::{Read, Write};
use piezo_drive::controller::ControllerConfig;
use piezo_drive::gcs::{Board, Gcs, LoopStats, Pending, Reply};
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

fn execute(gcs: &mut Gcs, pending: &Pending, board: &mut FwBoard, reply: &mut Reply) {
    if Gcs::is_read_only(pending) {
        // The copy is taken with the tick masked; the reply is formatted without.
        if let Some(Some(mut copy)) = CONTROLLER.lock(|ctl| ctl.clone()) {
            gcs.execute(pending, &mut copy, board, reply);
        }
    } else if Gcs::is_settings_only(pending) {
        // Parsed and checked on a copy; the real controller only takes the new settings.
        if let Some(Some(mut copy)) = CONTROLLER.lock(|ctl| ctl.clone()) {
            gcs.execute(pending, &mut copy, board, reply);
            let new = *copy.config();
            let _ = CONTROLLER.lock(|ctl| {
                if let Some(ctl) = ctl.as_mut() {
                    if *ctl.config() != new {
                        // Cannot fail: the copy accepted the same settings from the same ones.
                        let _ = ctl.set_config(new);
                    }
                }
            });
        }
    } else {
        let _ = CONTROLLER.lock(|ctl| {
            if let Some(ctl) = ctl.as_mut() {
                gcs.execute(pending, ctl, board, reply);
            }
        });
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
            execute(&mut gcs, &pending, &mut board, &mut reply);
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
