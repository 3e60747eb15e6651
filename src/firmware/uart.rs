//! UART on LPUART1 (PA2 TX, PA3 RX: the ST-LINK virtual COM port), 115200 8N1, embassy's
//! interrupt-driven `BufferedUart` (256-byte receive ring filled by the interrupt, so bytes keep
//! arriving while a command runs; 512-byte transmit ring). Bytes go to the core's protocol
//! (`piezo_drive::gcs::LinkSession`) as they are read, also while a reply is being written: a
//! `#24` stops at once and cuts the reply. Bytes are collected outside any lock. Each command
//! runs through
//! `Gcs::execute_shared` (`src/gcs/lock.rs`), which decides what runs with the controller
//! locked (the TIM7 tick masked) and what runs without; `host-sim pil --gcs-locks` counts every
//! locked section of every command on the emulated M4 (docs/firmware.md, Loop timing).

use core::future::{poll_fn, Future};
use core::pin::pin;
use core::task::Poll;
use embassy_stm32::usart::BufferedUart;
use embedded_io_async::{Read, Write};
use piezo_drive::controller::{Controller, ControllerConfig};
use piezo_drive::gcs::{Board, Gcs, LinkSession, LoopStats, SharedController, TableBuildStatus};
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
    fn table_build(&self) -> TableBuildStatus {
        super::model::build_status()
    }
}

/// The controller as the tick shares it: [`CONTROLLER`]'s lock (TIM7 masked).
struct TickShared;

impl SharedController for TickShared {
    fn lock<R>(&mut self, f: impl FnOnce(&mut Controller) -> R) -> Option<R> {
        CONTROLLER.lock(|ctl| ctl.as_mut().map(f)).flatten()
    }
}

/// What the task waits for: the transmit ring taking reply bytes, or received bytes.
enum Event {
    Sent(Result<usize, embassy_stm32::usart::Error>),
    Received(Result<usize, embassy_stm32::usart::Error>),
}

/// Reads and writes at once: received bytes are read while a reply is being written, so a `#24`
/// stops the motor within a control period of its arrival and cuts the reply, and no byte is
/// ever left to overflow the 256-byte receive ring (`LinkSession`, `src/gcs/session.rs`, decides
/// what runs and what is sent; this is glue). Both futures are cancel-safe: embassy copies bytes
/// only in the poll that completes them.
#[embassy_executor::task]
pub async fn uart_task(uart: BufferedUart<'static>) {
    let (mut tx, mut rx) = uart.split();
    let mut gcs = Gcs::new();
    let mut link = LinkSession::new();
    let mut board = FwBoard;
    let mut chunk = [0u8; 64];
    loop {
        let out = link.output();
        let event = if out.is_empty() {
            Event::Received(rx.read(&mut chunk).await)
        } else {
            let mut write = pin!(tx.write(out));
            let mut read = pin!(rx.read(&mut chunk));
            // Received bytes first: a #24 is never kept waiting behind transmit-ring room.
            poll_fn(|cx| {
                if let Poll::Ready(r) = read.as_mut().poll(cx) {
                    return Poll::Ready(Event::Received(r));
                }
                write.as_mut().poll(cx).map(Event::Sent)
            })
            .await
        };
        match event {
            Event::Received(Ok(n)) => {
                link.receive(chunk.get(..n).unwrap_or_default(), &mut gcs, &mut TickShared, &mut board)
            }
            Event::Sent(Ok(n)) => link.sent(n, &mut gcs, &mut TickShared, &mut board),
            Event::Received(Err(e)) | Event::Sent(Err(e)) => defmt::warn!("uart: {}", e),
        }
    }
}
