//! The last fault, kept in RAM the startup code does not initialise, so it survives a reset
//! (watchdog, software) but not a power cycle. A record is a fixed array of words: magic, kind,
//! the number of boots that have seen it, the control tick count, the number of faults that
//! came after it in the same boot, eight detail words (for a HardFault: stacked PC, LR, xPSR and
//! the fault status registers), and a CRC-32 over the rest. Random RAM after power-up does not
//! decode ([`decode`] checks magic and CRC). The first fault of a boot is the one kept
//! ([`merge`]): a later one (an overrun during a controller fault, a panic in a fault handler)
//! is only counted.

use crate::storage::crc32;

/// "PZFR" as a little-endian u32.
pub const MAGIC: u32 = u32::from_le_bytes(*b"PZFR");
/// Detail words in a record.
pub const DETAIL_WORDS: usize = 8;
/// Words in an encoded record.
pub const RECORD_WORDS: usize = 5 + DETAIL_WORDS + 1;

/// What stopped the drive.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[repr(u32)]
pub enum FaultKind {
    /// The control tick missed its deadline too often (leaky bucket) or missed a whole period.
    Overrun = 1,
    /// HardFault: details are PC, LR, xPSR, CFSR, HFSR, MMFAR, BFAR, SP.
    HardFault = 2,
    /// NMI other than a flash ECC error on the parameter page: details FLASH_ECCR, RCC_CIFR.
    Nmi = 3,
    /// Double ECC error reading the parameter page: detail FLASH_ECCR (the page was erased).
    FlashEcc = 4,
    /// The window watchdog's early warning: the tick stopped for about a millisecond.
    WindowWatchdog = 5,
    /// A panic.
    Panic = 6,
    /// An interrupt without a handler; detail the IRQ number.
    UnexpectedInterrupt = 7,
    /// A fault of the controller core; detail its `FaultCode` number.
    Controller = 8,
}

impl FaultKind {
    pub fn from_u32(v: u32) -> Option<Self> {
        Some(match v {
            1 => FaultKind::Overrun,
            2 => FaultKind::HardFault,
            3 => FaultKind::Nmi,
            4 => FaultKind::FlashEcc,
            5 => FaultKind::WindowWatchdog,
            6 => FaultKind::Panic,
            7 => FaultKind::UnexpectedInterrupt,
            8 => FaultKind::Controller,
            _ => return None,
        })
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FaultRecord {
    pub kind: FaultKind,
    /// Boots that have read this record (0 when written).
    pub boots_seen: u32,
    /// Control ticks since start when it happened.
    pub tick: u32,
    /// Faults after this one in the same boot (saturating): counted, not recorded.
    pub later_faults: u32,
    pub detail: [u32; DETAIL_WORDS],
}

fn checksum(words: &[u32]) -> u32 {
    let mut bytes = [0u8; 4 * (RECORD_WORDS - 1)];
    for (chunk, w) in bytes.chunks_exact_mut(4).zip(words.iter()) {
        chunk.copy_from_slice(&w.to_le_bytes());
    }
    crc32(&bytes)
}

/// The record as words, CRC last.
pub fn encode(r: &FaultRecord) -> [u32; RECORD_WORDS] {
    let mut w = [0u32; RECORD_WORDS];
    let head = [MAGIC, r.kind as u32, r.boots_seen, r.tick, r.later_faults];
    for (dst, src) in w.iter_mut().zip(head.iter().chain(r.detail.iter())) {
        *dst = *src;
    }
    let crc = checksum(w.get(..RECORD_WORDS - 1).unwrap_or(&[]));
    if let Some(last) = w.last_mut() {
        *last = crc;
    }
    w
}

/// The record in `w`, if the magic, the CRC and the kind are valid.
pub fn decode(w: &[u32; RECORD_WORDS]) -> Option<FaultRecord> {
    let (crc, body) = w.split_last()?;
    if body.first() != Some(&MAGIC) || checksum(body) != *crc {
        return None;
    }
    let kind = FaultKind::from_u32(*body.get(1)?)?;
    let mut detail = [0u32; DETAIL_WORDS];
    for (d, s) in detail.iter_mut().zip(body.iter().skip(5)) {
        *d = *s;
    }
    Some(FaultRecord {
        kind,
        boots_seen: *body.get(2)?,
        tick: *body.get(3)?,
        later_faults: *body.get(4)?,
        detail,
    })
}

/// What the record holds once `new` has happened, given what it holds now (`held`, decoded):
/// the first fault of this boot stays, the later ones counted in it; a record a boot has already
/// seen (from before the last reset) gives way to the new one.
pub fn merge(held: Option<FaultRecord>, new: FaultRecord) -> FaultRecord {
    match held {
        Some(first) if first.boots_seen == 0 => {
            FaultRecord { later_faults: first.later_faults.saturating_add(1), ..first }
        }
        _ => FaultRecord { later_faults: 0, ..new },
    }
}
