//! Parameters in flash: the core's record (`piezo_drive::storage`: version, length, CRC-32,
//! range-checked) in two 2 KiB pages at the end of the flash, 0x0807_F000 and 0x0807_F800 (pages
//! 126 and 127 of bank 2 in the STM32G474RE's factory dual-bank mode, DBANK = 1), kept by
//! `piezo_drive::param_store`: a store writes the page that is not current and commits it last,
//! so a power cut at any moment leaves the last good record loadable. `memory.x` keeps the
//! firmware out of both pages, so all code and constants live in bank 1.
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
//! Reading: a power cut during a store can leave a torn double word that carries a double ECC
//! error, which raises an NMI on the read. The NMI handler (`safety.rs`) asks
//! [`param_page::ecc_error_while_reading`] whether the error lies in these pages during a read;
//! if so it clears the flag and returns, and the read reports [`FlashFault::Ecc`]. Such a page is
//! never the current one (its commit word is written last); the next store erases it.
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
use piezo_drive::param_store::{self, FlashFault, Page, PageState, ParamPages, StoreError, WRITE_SIZE};
use piezo_drive::storage::StorageError;

use super::control::{PARKED_TICKS, PARK_REQUEST};
use super::param_page::{self, BANK2_OFFSET, FLASH_BASE, PARAM_OFFSET, PARAM_PAGE_SIZE};

/// A page's offset from the start of flash.
fn page_offset(page: Page) -> u32 {
    match page {
        Page::A => PARAM_OFFSET,
        Page::B => PARAM_OFFSET + PARAM_PAGE_SIZE,
    }
}

/// A page's number within bank 2 (erase page number, PNB with BKER = 1): 126 and 127.
fn page_in_bank(page: Page) -> u8 {
    ((page_offset(page) - BANK2_OFFSET) / PARAM_PAGE_SIZE) as u8
}
/// FLASH_SR error flags (OPERR, PROGERR, WRPERR, PGAERR, SIZERR, PGSERR, MISERR, FASTERR, RDERR,
/// OPTVERR) and EOP: all write-1-to-clear.
const SR_ERRORS: u32 = 0xC3FA;
const SR_EOP: u32 = 0x1;
/// Longest wait for the erase (datasheet: 22 ms typical per page) and for parking the drive (the
/// tick ramps it down over the soft start's 20 ms before it drops the enable).
const ERASE_TIMEOUT: Duration = Duration::from_millis(100);
/// Longest wait for one double word to program: a hundred times its ~85 µs.
const PROGRAM_TIMEOUT: Duration = Duration::from_millis(10);
const PARK_TIMEOUT: Duration = Duration::from_millis(50);

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

/// Why the flash itself failed (logged; the store reports [`FlashFault::Failed`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, defmt::Format)]
pub enum FlashError {
    /// FLASH_SR error flags after the operation.
    Status(u32),
    Timeout,
}

/// Why a store was not made, beyond the store's own errors.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum NotStored {
    /// The drive did not park (the tick is not running?).
    NotParked,
    /// The controller is not idle.
    NotIdle,
    Store(StoreError),
}

/// The two parameter pages.
pub struct ParamFlash {
    _flash: Peri<'static, FLASH>,
    /// A read hit a double ECC error since boot (a store torn by a power cut).
    ecc_seen: bool,
}

/// The flash, when the option bytes match the layout (dual bank).
pub fn open(flash: Peri<'static, FLASH>) -> Option<ParamFlash> {
    if pac::FLASH.optr().read().dbank() {
        Some(ParamFlash { _flash: flash, ecc_seen: false })
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

fn flash_fault(e: FlashError) -> FlashFault {
    defmt::error!("parameter flash: {}", e);
    FlashFault::Failed
}

impl ParamFlash {
    fn start_erase(&mut self, page: Page) {
        clear_status();
        unlock();
        pac::FLASH.cr().modify(|w| {
            w.set_pg(false);
            w.set_per(true);
            w.set_bker(true);
            w.set_pnb(page_in_bank(page));
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

    /// Erases a page without blocking anything: polls the busy flag between 1 ms sleeps.
    async fn erase_page(&mut self, page: Page) -> Result<(), FlashError> {
        let mut waited = Duration::from_ticks(0);
        // An operation left running (none should be): waited for as long as an erase, no more.
        while busy() {
            if waited > ERASE_TIMEOUT {
                lock();
                return Err(FlashError::Timeout);
            }
            Timer::after_millis(1).await;
            waited += Duration::from_millis(1);
        }
        waited = Duration::from_ticks(0);
        self.start_erase(page);
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

    /// Programs `data` at `offset` of an erased page, one double word at a time (~85 µs each),
    /// yielding between them.
    async fn program_at(&mut self, page: Page, offset: usize, data: &[u8]) -> Result<(), FlashError> {
        clear_status();
        unlock();
        pac::FLASH.cr().modify(|w| {
            w.set_per(false);
            w.set_pg(true);
        });
        let base = (FLASH_BASE + page_offset(page)) as *mut u32;
        let first_word = offset / 4;
        for (i, chunk) in data.chunks_exact(WRITE_SIZE).enumerate() {
            let word = |at: usize| {
                let b = chunk.get(at..at + 4).and_then(|b| <[u8; 4]>::try_from(b).ok());
                u32::from_le_bytes(b.unwrap_or([0xFF; 4]))
            };
            let at = first_word + 2 * i;
            if (at + 2) * 4 > PARAM_PAGE_SIZE as usize {
                break;
            }
            // SAFETY: inside the parameter page (checked above), word-aligned; PG is set, so
            // these writes program the double word (first word, then second, back to back).
            unsafe {
                base.add(at).write_volatile(word(0));
                base.add(at + 1).write_volatile(word(4));
            }
            cortex_m::asm::dsb();
            // A double word takes ~85 µs (RM0440); a flash that never finishes faults the store
            // (and the task releases the drive) instead of holding it parked for good.
            let mut waited = Duration::from_ticks(0);
            while busy() {
                if waited > PROGRAM_TIMEOUT {
                    pac::FLASH.cr().modify(|w| w.set_pg(false));
                    lock();
                    return Err(FlashError::Timeout);
                }
                Timer::after_micros(50).await;
                waited += Duration::from_micros(50);
            }
            if status_errors() != 0 {
                break;
            }
        }
        self.finish()
    }
}

impl ParamPages for ParamFlash {
    /// Reads the start of a page. A double ECC error in it is reported, not fatal.
    fn read(&mut self, page: Page, buf: &mut [u8]) -> Result<(), FlashFault> {
        let base = (FLASH_BASE + page_offset(page)) as *const u8;
        let ecc_hit = param_page::guarded_read(|| {
            for (i, b) in buf.iter_mut().take(PARAM_PAGE_SIZE as usize).enumerate() {
                // SAFETY: inside the 2 KiB parameter page, memory-mapped flash.
                *b = unsafe { base.add(i).read_volatile() };
            }
        });
        if ecc_hit {
            self.ecc_seen = true;
            Err(FlashFault::Ecc)
        } else {
            Ok(())
        }
    }

    async fn erase(&mut self, page: Page) -> Result<(), FlashFault> {
        self.erase_page(page).await.map_err(flash_fault)
    }

    async fn program(&mut self, page: Page, offset: usize, data: &[u8]) -> Result<(), FlashFault> {
        self.program_at(page, offset, data).await.map_err(flash_fault)
    }
}

/// Boot parameters: the newest committed record of the two pages, else `defaults` (and why).
/// A page torn by a power cut (double ECC error) is logged and recorded as a fault; it is never
/// the current page, and the next store erases it.
pub fn load(
    flash: Option<&mut ParamFlash>,
    defaults: &ControllerConfig,
) -> (ControllerConfig, Result<Page, StorageError>) {
    let Some(flash) = flash else { return (*defaults, Err(StorageError::NoRecord)) };
    let (cfg, states, current) = param_store::load(flash, defaults);
    for (page, state) in Page::BOTH.iter().zip(states.iter()) {
        if *state == PageState::Damaged {
            defmt::warn!(
                "parameter page {}: damaged (a store cut off?); not used",
                defmt::Debug2Format(page)
            );
        }
    }
    if flash.ecc_seen {
        super::safety::record_fault(
            piezo_drive::safety::fault_record::FaultKind::FlashEcc,
            [pac::FLASH.eccr().read().0, 0, 0, 0, 0, 0, 0, 0],
        );
    }
    (cfg, current)
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

/// Parks the drive (ramped down to rest, then the enable low) and waits until the tick confirms.
async fn park() -> Result<(), NotStored> {
    PARK_REQUEST.store(true, Ordering::SeqCst);
    let mut waited = Duration::from_ticks(0);
    while PARKED_TICKS.load(Ordering::Relaxed) < super::PARK_TICKS {
        if waited > PARK_TIMEOUT {
            return Err(NotStored::NotParked);
        }
        Timer::after_micros(200).await;
        waited += Duration::from_micros(200);
    }
    Ok(())
}

async fn store(
    flash: &mut ParamFlash,
    cfg: &ControllerConfig,
    defaults: &ControllerConfig,
) -> Result<Page, NotStored> {
    if !controller_idle() {
        return Err(NotStored::NotIdle);
    }
    park().await?;
    // Idle still (a command may have come in while parking).
    if !controller_idle() {
        return Err(NotStored::NotIdle);
    }
    param_store::store(flash, cfg, defaults).await.map_err(NotStored::Store)
}

#[embassy_executor::task]
pub async fn flash_task(mut flash: ParamFlash, defaults: ControllerConfig) {
    loop {
        let cfg = REQUEST.wait().await;
        let result = store(&mut flash, &cfg, &defaults).await;
        PARK_REQUEST.store(false, Ordering::SeqCst);
        match result {
            Ok(page) => {
                defmt::info!(
                    "parameters stored in page {} at 0x{:08x}",
                    defmt::Debug2Format(&page),
                    FLASH_BASE + page_offset(page)
                );
                STORE_STATE.store(2, Ordering::Relaxed);
            }
            Err(e) => {
                defmt::error!("parameter store failed: {}", defmt::Debug2Format(&e));
                STORE_STATE.store(3, Ordering::Relaxed);
            }
        }
    }
}
