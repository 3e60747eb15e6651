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
