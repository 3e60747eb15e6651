//! Where the two parameter pages lie in flash, and the guard around reading them: a double ECC
//! error in a page (a store cut off by a power loss) raises an NMI; the NMI handler (`safety.rs`)
//! asks [`ecc_error_while_reading`] whether the error is in the parameter pages during a guarded
//! read and, if so, survives it, and the reader (`params_flash.rs`) sees the error reported
//! instead. A leaf module, so that the fault handlers and the flash store need not import each
//! other.

use core::sync::atomic::{AtomicBool, Ordering};

use piezo_drive::safety::flash_ecc::ecc_in_param_page;

/// Offset of the parameter pages from the start of flash (0x0800_0000): pages 126 (A) and 127
/// (B) of bank 2, the last 4 KiB. Single-page firmware kept its record in page 127.
pub const PARAM_OFFSET: u32 = 0x7_F000;
pub const PARAM_PAGE_SIZE: u32 = 2048;
/// Both pages.
pub const PARAM_AREA_SIZE: u32 = 2 * PARAM_PAGE_SIZE;
pub const FLASH_BASE: u32 = 0x0800_0000;
/// Bank 2 starts half-way through the 512 KiB in dual-bank mode.
pub const BANK2_OFFSET: u32 = 0x4_0000;

/// A read of a parameter page is under way / hit a double ECC error (set by the NMI).
static READING: AtomicBool = AtomicBool::new(false);
static ECC_HIT: AtomicBool = AtomicBool::new(false);

/// For the NMI handler: whether a double ECC error at (`bank2`, `addr_in_bank`) is one of ours —
/// in the parameter pages while one is being read — and so survivable. Records it for the reader.
pub fn ecc_error_while_reading(bank2: bool, addr_in_bank: u32) -> bool {
    let ours = READING.load(Ordering::Relaxed)
        && ecc_in_param_page(bank2, addr_in_bank, PARAM_OFFSET, BANK2_OFFSET, PARAM_AREA_SIZE);
    if ours {
        ECC_HIT.store(true, Ordering::Relaxed);
    }
    ours
}

/// Runs `read` with the guard up; true when a double ECC error in the pages was survived meanwhile.
pub fn guarded_read(read: impl FnOnce()) -> bool {
    ECC_HIT.store(false, Ordering::Relaxed);
    READING.store(true, Ordering::SeqCst);
    read();
    cortex_m::asm::dsb();
    READING.store(false, Ordering::SeqCst);
    ECC_HIT.load(Ordering::Relaxed)
}
