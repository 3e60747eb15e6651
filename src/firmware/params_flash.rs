//! Parameters in flash: the core's record (`piezo_drive::storage`: version, length, CRC-32,
//! range-checked) in the last 2 KiB page of the flash, 0x0807_F800 (page 127 of bank 2 in the
//! STM32G474RE's factory dual-bank mode, DBANK = 1). `memory.x` keeps the firmware out of it, so
//! all code and constants live in bank 1.
//!
//! Our own small flash driver (registers through the PAC), not embassy's: embassy 0.4 erases
//! and programs inside a critical section, which would stop the control tick for the ~22 ms of
//! a page erase while the DMA loops one buffer into the amplifier, and would trip the 1 ms
//! window watchdog. Bank 2 is read-while-write capable: erasing or programming it does not stall
//! instruction fetches from bank 1, so the erase runs with interrupts on and the task polls the
//! busy flag between short sleeps. On top of that, a store is made only with the drive parked:
//! the controller idle (servo off, no motion; the protocol refuses `WPA` otherwise and this task
//! checks again), the amplifier enable low and both buffer halves at the rest word (the tick
//! does this on [`super::control::PARK_REQUEST`]); the enable comes back through the soft start.
//!
//! Reading at boot: a power cut during a store can leave a torn page whose words carry a double
//! ECC error, which raises an NMI on the read. The NMI handler (`safety.rs`) asks
//! [`param_page::ecc_error_while_reading`] whether the error lies in this page during a read; if so it clears
//! the flag and returns, the read reports [`ReadError::Ecc`] and the boot code erases the page
//! and runs on defaults. The independent watchdog is already running by then.
//!
//! If the option bytes say single-bank (DBANK = 0, 4 KiB pages) the layout does not match: the
//! firmware skips the flash, runs on defaults and refuses `WPA` (the README says how to set
//! DBANK back).

use core::sync::atomic::{AtomicU8, Ordering};

use embassy_stm32::pac;
use embassy_stm32::peripherals::FLASH;
use embassy_stm32::Peri;
use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
use embassy_sync::signal::Signal;
use embassy_time::{Duration, Timer};
use piezo_drive::controller::ControllerConfig;
use piezo_drive::storage::{self, StorageError, RECORD_LEN};

use super::control::{PARKED_TICKS, PARK_REQUEST};
use super::param_page::{self, BANK2_OFFSET, FLASH_BASE, PARAM_OFFSET, PARAM_PAGE_SIZE};

/// The page within bank 2 (erase page number, PNB with BKER = 1).
const PARAM_PAGE_IN_BANK: u8 = ((PARAM_OFFSET - BANK2_OFFSET) / PARAM_PAGE_SIZE) as u8;
/// Flash write unit (a double word).
const WRITE_SIZE: usize = 8;
/// The record padded to the write unit.
const PADDED_LEN: usize = RECORD_LEN.div_ceil(WRITE_SIZE) * WRITE_SIZE;
/// FLASH_SR error flags (OPERR, PROGERR, WRPERR, PGAERR, SIZERR, PGSERR, MISERR, FASTERR, RDERR,
/// OPTVERR) and EOP: all write-1-to-clear.
const SR_ERRORS: u32 = 0xC3FA;
const SR_EOP: u32 = 0x1;
/// Longest wait for the erase (datasheet: 22 ms typical per page) and for parking the drive.
const ERASE_TIMEOUT: Duration = Duration::from_millis(100);
const PARK_TIMEOUT: Duration = Duration::from_millis(20);

/// The settings to store: a copy taken under the controller's lock; encoded (range check, CRC)
/// by the flash task, outside it.
static REQUEST: Signal<CriticalSectionRawMutex, ControllerConfig> = Signal::new();

/// Last store: 0 none yet, 1 queued or being written, 2 written and verified, 3 failed and not
/// yet reported, 4 flash unavailable, 5 failed and reported (through `ERR?`).
pub static STORE_STATE: AtomicU8 = AtomicU8::new(0);

/// Whether a store is queued or being written.
pub fn store_pending() -> bool {
    STORE_STATE.load(Ordering::Relaxed) == 1
}

/// A store that failed and was not reported yet; reports it (once).
pub fn take_store_failure() -> bool {
    STORE_STATE.compare_exchange(3, 5, Ordering::Relaxed, Ordering::Relaxed).is_ok()
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, defmt::Format)]
pub enum FlashError {
    /// FLASH_SR error flags after the operation.
    Status(u32),
    Timeout,
    /// The drive did not park (the tick is not running?).
    NotParked,
    /// The controller is not idle.
    NotIdle,
    Verify,
    /// A setting outside its range (the record would not load back).
    OutOfRange,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ReadError {
    /// A double ECC error in the page (a torn write).
    Ecc,
}

/// The parameter page.
pub struct ParamFlash {
    _flash: Peri<'static, FLASH>,
}

/// The flash, when the option bytes match the layout (dual bank).
pub fn open(flash: Peri<'static, FLASH>) -> Option<ParamFlash> {
    if pac::FLASH.optr().read().dbank() {
        Some(ParamFlash { _flash: flash })
    } else {
        STORE_STATE.store(4, Ordering::Relaxed);
        None
    }
}

fn busy() -> bool {
    pac::FLASH.sr().read().bsy()
}

fn clear_status() {
    pac::FLASH.sr().write_value(pac::flash::regs::Sr(SR_ERRORS | SR_EOP));
}

fn status_errors() -> u32 {
    pac::FLASH.sr().read().0 & SR_ERRORS
}

fn unlock() {
    if pac::FLASH.cr().read().lock() {
        pac::FLASH.keyr().write_value(0x4567_0123);
        pac::FLASH.keyr().write_value(0xCDEF_89AB);
    }
}

fn lock() {
    pac::FLASH.cr().modify(|w| {
        w.set_per(false);
        w.set_pg(false);
        w.set_lock(true);
    });
}

/// Drops the flash data cache's lines (they may hold the page as it was before a store).
fn flush_data_cache() {
    pac::FLASH.acr().modify(|w| w.set_dcen(false));
    pac::FLASH.acr().modify(|w| w.set_dcrst(true));
    pac::FLASH.acr().modify(|w| w.set_dcrst(false));
    pac::FLASH.acr().modify(|w| w.set_dcen(true));
}

impl ParamFlash {
    /// Reads the start of the page. A double ECC error in it is reported, not fatal.
    pub fn read(&mut self, buf: &mut [u8]) -> Result<(), ReadError> {
        let base = (FLASH_BASE + PARAM_OFFSET) as *const u8;
        let ecc_hit = param_page::guarded_read(|| {
            for (i, b) in buf.iter_mut().take(PARAM_PAGE_SIZE as usize).enumerate() {
                // SAFETY: inside the 2 KiB parameter page, memory-mapped flash.
                *b = unsafe { base.add(i).read_volatile() };
            }
        });
        if ecc_hit {
            Err(ReadError::Ecc)
        } else {
            Ok(())
        }
    }

    fn start_erase(&mut self) {
        clear_status();
        unlock();
        pac::FLASH.cr().modify(|w| {
            w.set_pg(false);
            w.set_per(true);
            w.set_bker(true);
            w.set_pnb(PARAM_PAGE_IN_BANK);
        });
        pac::FLASH.cr().modify(|w| w.set_strt(true));
    }

    fn finish(&mut self) -> Result<(), FlashError> {
        let errors = status_errors();
        lock();
        flush_data_cache();
        if errors != 0 {
            Err(FlashError::Status(errors))
        } else {
            Ok(())
        }
    }

    /// Erases the page, busy-waiting (boot only, before the tick and the WWDG run; the IWDG
    /// allows 50 ms and the erase takes ~22 ms).
    pub fn erase_blocking(&mut self) -> Result<(), FlashError> {
        while busy() {}
        self.start_erase();
        while busy() {}
        self.finish()
    }

    /// Erases the page without blocking anything: polls the busy flag between 1 ms sleeps.
    async fn erase(&mut self) -> Result<(), FlashError> {
        let mut waited = Duration::from_ticks(0);
        while busy() {
            Timer::after_millis(1).await;
        }
        self.start_erase();
        while busy() {
            if waited > ERASE_TIMEOUT {
                lock();
                return Err(FlashError::Timeout);
            }
            Timer::after_millis(1).await;
            waited += Duration::from_millis(1);
        }
        self.finish()
    }

    /// Programs `data` (a multiple of 8 bytes) at the start of the erased page, one double word
    /// at a time (~85 µs each), yielding between them.
    async fn program(&mut self, data: &[u8; PADDED_LEN]) -> Result<(), FlashError> {
        clear_status();
        unlock();
        pac::FLASH.cr().modify(|w| {
            w.set_per(false);
            w.set_pg(true);
        });
        let base = (FLASH_BASE + PARAM_OFFSET) as *mut u32;
        let mut words = [u32::MAX; PADDED_LEN / 4];
        for (w, c) in words.iter_mut().zip(data.chunks_exact(4)) {
            *w = u32::from_le_bytes(<[u8; 4]>::try_from(c).unwrap_or([0xFF; 4]));
        }
        for (i, pair) in words.chunks_exact(2).enumerate() {
            let &[lo, hi] = pair else { break };
            // SAFETY: inside the parameter page, word-aligned; PG is set, so these writes
            // program the double word (first word, then second, back to back).
            unsafe {
                base.add(2 * i).write_volatile(lo);
                base.add(2 * i + 1).write_volatile(hi);
            }
            cortex_m::asm::dsb();
            while busy() {
                Timer::after_micros(50).await;
            }
            if status_errors() != 0 {
                break;
            }
        }
        self.finish()
    }
}

/// Boot parameters: the stored record if valid, else `defaults` (and why). A torn page (double
/// ECC error) is erased so the next boot reads it cleanly; `feed` keeps the watchdog quiet.
pub fn load(
    flash: Option<&mut ParamFlash>,
    defaults: &ControllerConfig,
    feed: &mut dyn FnMut(),
) -> (ControllerConfig, Result<(), StorageError>) {
    let Some(flash) = flash else { return (*defaults, Err(StorageError::NoRecord)) };
    let mut bytes = [0u8; RECORD_LEN];
    if flash.read(&mut bytes) == Err(ReadError::Ecc) {
        defmt::error!("parameter page: double ECC error (torn write?): erasing it, running on defaults");
        super::safety::record_fault(
            piezo_drive::safety::fault_record::FaultKind::FlashEcc,
            [pac::FLASH.eccr().read().0, 0, 0, 0, 0, 0, 0, 0],
        );
        feed();
        match flash.erase_blocking() {
            Ok(()) => defmt::info!("parameter page erased"),
            Err(e) => defmt::error!("parameter page erase failed: {}", e),
        }
        feed();
        return (*defaults, Err(StorageError::NoRecord));
    }
    match storage::decode(&bytes, defaults) {
        Ok(cfg) => (cfg, Ok(())),
        Err(e) => (*defaults, Err(e)),
    }
}

/// Queues `cfg` for storing; false when there is no usable flash. A copy and a signal: called
/// from the protocol with the controller locked, so the range check, encoding and CRC (about
/// 23,000 instructions, more than a control period) are left to the flash task.
pub fn request_store(cfg: &ControllerConfig) -> bool {
    if STORE_STATE.load(Ordering::Relaxed) == 4 {
        return false;
    }
    STORE_STATE.store(1, Ordering::Relaxed);
    REQUEST.signal(*cfg);
    true
}

fn controller_idle() -> bool {
    super::control::CONTROLLER
        .lock(|c| c.as_ref().is_some_and(|c| c.state() == piezo_drive::controller::State::Idle))
        .unwrap_or(false)
}

/// Parks the drive (enable low, rest words in both halves) and waits until the tick confirms.
async fn park() -> Result<(), FlashError> {
    PARK_REQUEST.store(true, Ordering::SeqCst);
    let mut waited = Duration::from_ticks(0);
    while PARKED_TICKS.load(Ordering::Relaxed) < super::PARK_TICKS {
        if waited > PARK_TIMEOUT {
            return Err(FlashError::NotParked);
        }
        Timer::after_micros(200).await;
        waited += Duration::from_micros(200);
    }
    Ok(())
}

async fn store(
    flash: &mut ParamFlash,
    record: &[u8; RECORD_LEN],
    defaults: &ControllerConfig,
) -> Result<(), FlashError> {
    if !controller_idle() {
        return Err(FlashError::NotIdle);
    }
    park().await?;
    // Idle still (a command may have come in while parking).
    if !controller_idle() {
        return Err(FlashError::NotIdle);
    }
    let mut padded = [0xFFu8; PADDED_LEN];
    for (d, s) in padded.iter_mut().zip(record.iter()) {
        *d = *s;
    }
    flash.erase().await?;
    flash.program(&padded).await?;
    let mut back = [0u8; RECORD_LEN];
    let read = flash.read(&mut back);
    if read.is_ok() && back == *record && storage::decode(&back, defaults).is_ok() {
        Ok(())
    } else {
        Err(FlashError::Verify)
    }
}

#[embassy_executor::task]
pub async fn flash_task(mut flash: ParamFlash, defaults: ControllerConfig) {
    loop {
        let cfg = REQUEST.wait().await;
        let result = match storage::validate(&cfg) {
            Ok(()) => store(&mut flash, &storage::encode(&cfg), &defaults).await,
            Err(_) => Err(FlashError::OutOfRange),
        };
        PARK_REQUEST.store(false, Ordering::SeqCst);
        match result {
            Ok(()) => {
                defmt::info!("parameters stored at 0x{:08x}", FLASH_BASE + PARAM_OFFSET);
                STORE_STATE.store(2, Ordering::Relaxed);
            }
            Err(e) => {
                defmt::error!("parameter store failed: {}", e);
                STORE_STATE.store(3, Ordering::Relaxed);
            }
        }
    }
}
