//! Flash ECC errors: a double error (ECCD) raises an NMI and FLASH_ECCR says where: the bank
//! (BK_ECC) and the address within that bank (ADDR_ECC, a byte offset from the bank's start).
//! A torn write of the parameter page (power cut during `WPA`) can leave one; anywhere else the
//! flash holding code or constants is corrupt.

/// Whether an ECC error at `addr_in_bank` of bank 2 (`bank2`) lies in the page of `page_size`
/// bytes at `page_offset_in_bank` of bank `page_bank2`.
pub fn ecc_in_page(
    bank2: bool,
    addr_in_bank: u32,
    page_bank2: bool,
    page_offset_in_bank: u32,
    page_size: u32,
) -> bool {
    bank2 == page_bank2
        && addr_in_bank >= page_offset_in_bank
        && addr_in_bank - page_offset_in_bank < page_size
}

/// The parameter page's check as the firmware uses it, tolerant of how ADDR_ECC counts: the
/// reference manual gives it as a byte address "by bank", but whether a dual-bank part reports
/// it relative to the bank (with BK_ECC = 1 for bank 2) or from the start of the flash is not
/// verified on a board. Both readings are accepted for the page at `page_offset` bytes from the
/// flash start, with banks of `bank_size` bytes; a bank-1 offset that only matches as
/// bank-relative (i.e. code in bank 1) is not.
pub fn ecc_in_param_page(bk_ecc: bool, addr: u32, page_offset: u32, bank_size: u32, page_size: u32) -> bool {
    let page_in_bank2 = page_offset >= bank_size;
    let relative = ecc_in_page(bk_ecc, addr, page_in_bank2, page_offset.wrapping_sub(bank_size), page_size);
    let absolute = addr >= page_offset && addr - page_offset < page_size;
    (page_in_bank2 && relative) || absolute
}
