//! Parameters in flash: the core's record (`piezo_drive::storage`: version, length, CRC-32,
//! range-checked) in the last 2 KiB page of the flash, 0x0807_F800 (page 127 of bank 2 in the
//! STM32G474RE's factory dual-bank mode, DBANK = 1). `memory.x` keeps the firmware out of it.
//! Loaded at boot (defaults when missing or invalid); written by a task on request (`WPA`), so
//! the UART never waits for the ~20 ms page erase. embassy 0.4 erases and programs inside a
//! critical section, so no interrupt — not the control tick — runs for those ~20 ms: a store is
//! therefore only carried out while the controller is idle (servo off, no motion; the protocol
//! refuses `WPA` otherwise and this task checks again), when the DMA replays quiet samples.
//!
//! If the option bytes say single-bank (DBANK = 0, 4 KiB pages) the layout embassy was built for
//! (`dual-bank`) does not match: embassy's `Flash` would panic, so the firmware skips the flash,
//! runs on defaults and refuses `WPA` (the README says how to set DBANK back).

use core::sync::atomic::{AtomicU8, Ordering};

use embassy_stm32::flash::{Blocking, Flash, WRITE_SIZE};
use embassy_stm32::pac;
use embassy_stm32::peripherals::FLASH;
use embassy_stm32::Peri;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::signal::Signal;
use piezo_drive::controller::ControllerConfig;
use piezo_drive::storage::{self, StorageError, RECORD_LEN};

/// Offset of the parameter page from the start of flash (0x0800_0000).
pub const PARAM_OFFSET: u32 = 0x7_F800;
pub const PARAM_PAGE_SIZE: u32 = 2048;
/// The record padded to the flash write unit (8 bytes on the G4).
const PADDED_LEN: usize = RECORD_LEN.div_ceil(WRITE_SIZE) * WRITE_SIZE;

static REQUEST: Signal<CriticalSectionRawMutex, [u8; RECORD_LEN]> = Signal::new();

/// Last store: 0 none yet, 1 queued, 2 written and verified, 3 failed, 4 flash unavailable.
pub static STORE_STATE: AtomicU8 = AtomicU8::new(0);

/// The flash, when the option bytes match the layout embassy was built for.
pub fn open(flash: Peri<'static, FLASH>) -> Option<Flash<'static, Blocking>> {
    if pac::FLASH.optr().read().dbank() {
        Some(Flash::new_blocking(flash))
    } else {
        STORE_STATE.store(4, Ordering::Relaxed);
        None
    }
}

/// Boot parameters: the stored record if valid, else `defaults` (and why).
pub fn load(
    flash: Option<&mut Flash<'static, Blocking>>,
    defaults: &ControllerConfig,
) -> (ControllerConfig, Result<(), StorageError>) {
    let mut bytes = [0u8; RECORD_LEN];
    let read = match flash {
        Some(f) => f.blocking_read(PARAM_OFFSET, &mut bytes).is_ok(),
        None => false,
    };
    if !read {
        return (*defaults, Err(StorageError::NoRecord));
    }
    match storage::decode(&bytes, defaults) {
        Ok(cfg) => (cfg, Ok(())),
        Err(e) => (*defaults, Err(e)),
    }
}

/// Queues `cfg` for storing; false when it is out of range or there is no usable flash.
/// Cheap: called from the protocol with the controller locked.
pub fn request_store(cfg: &ControllerConfig) -> bool {
    if STORE_STATE.load(Ordering::Relaxed) == 4 || storage::validate(cfg).is_err() {
        return false;
    }
    STORE_STATE.store(1, Ordering::Relaxed);
    REQUEST.signal(storage::encode(cfg));
    true
}

#[embassy_executor::task]
pub async fn flash_task(mut flash: Flash<'static, Blocking>, defaults: ControllerConfig) {
    loop {
        let record = REQUEST.wait().await;
        let idle = super::control::CONTROLLER
            .lock(|c| c.as_ref().is_some_and(|c| c.state() == piezo_drive::controller::State::Idle))
            .unwrap_or(false);
        if !idle {
            defmt::error!("parameter store refused: the controller is not idle (servo off first)");
            STORE_STATE.store(3, Ordering::Relaxed);
            continue;
        }
        let mut padded = [0xFFu8; PADDED_LEN];
        for (d, s) in padded.iter_mut().zip(record.iter()) {
            *d = *s;
        }
        let written = flash
            .blocking_erase(PARAM_OFFSET, PARAM_OFFSET + PARAM_PAGE_SIZE)
            .and_then(|()| flash.blocking_write(PARAM_OFFSET, &padded));
        let mut back = [0u8; RECORD_LEN];
        let verified = written.is_ok()
            && flash.blocking_read(PARAM_OFFSET, &mut back).is_ok()
            && back == record
            && storage::decode(&back, &defaults).is_ok();
        if verified {
            defmt::info!("parameters stored at 0x{:08x}", 0x0800_0000 + PARAM_OFFSET);
            STORE_STATE.store(2, Ordering::Relaxed);
        } else {
            defmt::error!("parameter store failed: {}", written);
            STORE_STATE.store(3, Ordering::Relaxed);
        }
    }
}
