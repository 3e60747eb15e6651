//! Two flash pages for the parameter record ([`crate::storage`]), so that a power cut at any
//! moment of a store leaves the last good record loadable.
//!
//! A store writes the new record to the page that does not hold the current one, reads it back,
//! and only then writes that page's commit word: a sequence number one above the current page's
//! and its complement, in the double word after the record. The old page is never touched by the
//! store, so until the commit lands it is the newest valid page, and after it the new one is.
//! Loading picks the valid page with the higher sequence number; a page is valid when its commit
//! word is whole and its record decodes (magic, version, length, CRC, ranges). A cut during the
//! erase or the record leaves the target without a commit word; a cut during the commit leaves a
//! torn double word (the flash's ECC flags it on read, or the complement does not match). Either
//! way the old page loads.
//!
//! Page layout: the record at offset 0 padded with 0xFF to the flash's 8-byte write unit
//! ([`RECORD_SPAN`]), then the commit word (`seq` and `!seq`, little-endian u32s).
//!
//! Records written before there were two pages sit in page B with no commit word. Page B
//! without a commit word but with a record that decodes still loads, as the oldest possible page
//! (a first store then goes to page A). Page A never loads without its commit word: there it
//! means a store was cut before its commit.
//!
//! The flash itself (erase, program, read with ECC) is the board's, behind [`ParamPages`];
//! `tests/param_store.rs` runs the same store against a flash that can be cut at every step.

use crate::controller::ControllerConfig;
use crate::storage::{self, StorageError, RECORD_LEN};

/// The flash's write unit (a double word on the STM32G4).
pub const WRITE_SIZE: usize = 8;
/// The record padded to the write unit: the commit word starts here.
pub const RECORD_SPAN: usize = RECORD_LEN.div_ceil(WRITE_SIZE) * WRITE_SIZE;
/// Bytes of a page the store uses: the record span and the commit word.
pub const USED_LEN: usize = RECORD_SPAN + WRITE_SIZE;

/// The two parameter pages. `B` is where single-page firmware kept its record.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Page {
    A,
    B,
}

impl Page {
    pub const BOTH: [Page; 2] = [Page::A, Page::B];

    pub fn other(self) -> Page {
        match self {
            Page::A => Page::B,
            Page::B => Page::A,
        }
    }
}

/// Why a flash operation failed (the board's reason is logged by the board).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FlashFault {
    /// The flash reported an error or did not finish in time.
    Failed,
    /// A double ECC error while reading (a write torn by a power cut).
    Ecc,
}

/// The board's two parameter pages. Erase and program may take milliseconds and are awaited
/// (the board polls the flash between sleeps); the read is short.
// One executor thread on the board and plain polling in tests: no `Send` bound is wanted.
#[allow(async_fn_in_trait)]
pub trait ParamPages {
    /// Reads the first `buf.len()` (≤ [`USED_LEN`]) bytes of `page`.
    fn read(&mut self, page: Page, buf: &mut [u8]) -> Result<(), FlashFault>;
    /// Erases `page` (all bytes 0xFF).
    async fn erase(&mut self, page: Page) -> Result<(), FlashFault>;
    /// Programs `data` (a multiple of [`WRITE_SIZE`] bytes) at `offset` (a multiple of it) of an
    /// erased part of `page`.
    async fn program(&mut self, page: Page, offset: usize, data: &[u8]) -> Result<(), FlashFault>;
}

/// What one page holds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PageState {
    /// A committed record (or page B's record from before the commit word).
    Valid { seq: u32 },
    /// Erased, or a store that never reached its commit.
    Empty,
    /// Read failed (a torn write caught by ECC), or a commit word over a record that does not
    /// decode.
    Damaged,
}

/// A page's commit word for sequence number `seq`.
fn commit_word(seq: u32) -> [u8; WRITE_SIZE] {
    let mut w = [0u8; WRITE_SIZE];
    let (lo, hi) = w.split_at_mut(4);
    lo.copy_from_slice(&seq.to_le_bytes());
    hi.copy_from_slice(&(!seq).to_le_bytes());
    w
}

/// The sequence number in a commit word, if it is whole.
fn commit_seq(bytes: &[u8]) -> Option<u32> {
    let word = |at: usize| -> Option<u32> {
        let b: [u8; 4] = bytes.get(at..at + 4)?.try_into().ok()?;
        Some(u32::from_le_bytes(b))
    };
    let (seq, inverse) = (word(0)?, word(4)?);
    (seq == !inverse).then_some(seq)
}

/// What `page` holds, and its settings if it is valid. `defaults` fill the settings a record
/// does not carry.
fn read_settings(
    flash: &mut impl ParamPages,
    page: Page,
    defaults: &ControllerConfig,
) -> (PageState, Option<ControllerConfig>) {
    let mut bytes = [0u8; USED_LEN];
    if flash.read(page, &mut bytes).is_err() {
        return (PageState::Damaged, None);
    }
    let (record, commit) = bytes.split_at(RECORD_SPAN);
    let decoded = storage::decode(record, defaults);
    let state = match (commit_seq(commit), &decoded) {
        (Some(seq), Ok(_)) => PageState::Valid { seq },
        // Single-page firmware's record: older than any committed page.
        (None, Ok(_)) if page == Page::B && commit.iter().all(|b| *b == 0xFF) => {
            PageState::Valid { seq: LEGACY_SEQ }
        }
        (Some(_), Err(_)) => PageState::Damaged,
        (None, _) => PageState::Empty,
    };
    (state, decoded.ok())
}

/// What `page` holds.
pub fn read_page(flash: &mut impl ParamPages, page: Page, defaults: &ControllerConfig) -> PageState {
    read_settings(flash, page, defaults).0
}

/// The sequence number a record without a commit word stands for: below every committed one
/// (the first store commits `LEGACY_SEQ + 1`).
const LEGACY_SEQ: u32 = 0;

/// Whether sequence number `a` is newer than `b` (wrapping: the later of two numbers less than
/// half the range apart).
fn newer(a: u32, b: u32) -> bool {
    (a.wrapping_sub(b) as i32) > 0
}

/// The newest valid page of both, with its sequence number.
pub fn current(states: &[PageState; 2]) -> Option<(Page, u32)> {
    let mut best: Option<(Page, u32)> = None;
    for (page, state) in Page::BOTH.iter().zip(states) {
        if let PageState::Valid { seq } = *state {
            if best.is_none_or(|(_, s)| newer(seq, s)) {
                best = Some((*page, seq));
            }
        }
    }
    best
}

/// The settings to boot with: the newest valid page's, else `defaults`; with both pages' states
/// (for the log) and, without a valid page, why (`NoRecord` when both are empty).
pub fn load(
    flash: &mut impl ParamPages,
    defaults: &ControllerConfig,
) -> (ControllerConfig, [PageState; 2], Result<Page, StorageError>) {
    let states = Page::BOTH.map(|p| read_page(flash, p, defaults));
    let Some((page, seq)) = current(&states) else {
        return (*defaults, states, Err(StorageError::NoRecord));
    };
    // Read once more for the settings (one page's worth of stack, not two).
    match read_settings(flash, page, defaults) {
        (PageState::Valid { seq: again }, Some(cfg)) if again == seq => (cfg, states, Ok(page)),
        _ => (*defaults, states, Err(StorageError::NoRecord)),
    }
}

/// Why a store failed. The page that was current before it still is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum StoreError {
    /// A setting outside its range: the record would not load back.
    OutOfRange,
    Flash(FlashFault),
    /// The record or the commit word read back differs from what was written.
    Verify,
}

impl From<FlashFault> for StoreError {
    fn from(f: FlashFault) -> Self {
        StoreError::Flash(f)
    }
}

/// Stores `cfg` in the page that is not current: erase, record, read back, commit, read back.
/// Returns the page that is current afterwards.
pub async fn store(
    flash: &mut impl ParamPages,
    cfg: &ControllerConfig,
    defaults: &ControllerConfig,
) -> Result<Page, StoreError> {
    storage::validate(cfg).map_err(|_| StoreError::OutOfRange)?;
    let (target, seq) = match current(&Page::BOTH.map(|p| read_page(flash, p, defaults))) {
        Some((page, seq)) => (page.other(), seq.wrapping_add(1)),
        None => (Page::A, LEGACY_SEQ.wrapping_add(1)),
    };
    let mut record = [0xFFu8; RECORD_SPAN];
    for (d, s) in record.iter_mut().zip(storage::encode(cfg).iter()) {
        *d = *s;
    }
    flash.erase(target).await?;
    flash.program(target, 0, &record).await?;
    let mut back = [0u8; RECORD_SPAN];
    flash.read(target, &mut back)?;
    if back != record {
        return Err(StoreError::Verify);
    }
    // The commit: from here on the new page is the current one.
    flash.program(target, RECORD_SPAN, &commit_word(seq)).await?;
    match read_page(flash, target, defaults) {
        PageState::Valid { seq: s, .. } if s == seq => Ok(target),
        _ => Err(StoreError::Verify),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_commit_word_holds_its_number_and_a_torn_one_does_not() {
        for seq in [0u32, 1, 0x1234_5678, u32::MAX] {
            assert_eq!(commit_seq(&commit_word(seq)), Some(seq));
        }
        // Erased flash, and a word whose second half never landed.
        assert_eq!(commit_seq(&[0xFF; 8]), None);
        let mut torn = commit_word(7);
        torn[4..].copy_from_slice(&[0xFF; 4]);
        assert_eq!(commit_seq(&torn), None);
    }

    #[test]
    fn the_later_sequence_number_wins_across_the_wrap() {
        assert!(newer(2, 1));
        assert!(!newer(1, 2));
        assert!(!newer(5, 5));
        assert!(newer(0, u32::MAX));
        assert!(newer(3, u32::MAX - 3));
    }
}
