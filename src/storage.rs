//! The parameter record kept in flash: every setting marked `Stored` in
//! [`crate::settings::SETTINGS`] (calibration, limits, gains, motion limits, referencing),
//! little-endian, with a magic word, a format version, the payload length and a CRC-32 over all
//! of it. Pure functions; the firmware's flash task only moves the bytes, and `host-sim serve`
//! keeps the very same bytes in its `--store` file. [`decode`] never panics on arbitrary bytes
//! and checks every value with the controller's own validator, so a record that decodes is one
//! the controller accepts, and a configuration the controller accepts can be stored.
//!
//! Layout (all little-endian):
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 4 | magic `"PZDP"` |
//! | 4 | 2 | format version ([`VERSION`]) |
//! | 6 | 2 | payload length ([`PAYLOAD_LEN`]) |
//! | 8 | [`PAYLOAD_LEN`] | the stored settings in table order, each in its type's width ([`crate::settings::Ty::size`]) |
//! | 8 + [`PAYLOAD_LEN`] | 4 | CRC-32 (ISO-HDLC, as zlib) of bytes 0 .. 8 + [`PAYLOAD_LEN`] |
//!
//! Not stored (board or build constants, taken from the defaults passed to [`decode`]): the loop
//! rate, the DAC/amplifier description, the encoder resolution and the motor table (the
//! motor's calibration against that table, `0x101B`–`0x101F`, is stored).
//!
//! Versions 2 to [`VERSION`] − 1 are this layout without the rows added since (each stored row's
//! `since` in the table: 3 added the moving mass, 4 the calibrated motor, 5 the lowest drive
//! frequency); those settings then come from the defaults.
//! Version 1 (before the settings table) still loads: it lacked the motion limits (`VEL`, `ACC`,
//! `DEC`) and the referencing settings, which then come from the defaults; its encoder
//! resolution (read-only, so always the build's) and the removed fine-mode gain are skipped.

use crate::controller::{validate_settings, Controller, ControllerConfig};
pub use crate::settings::FIRST_TABLE_VERSION;
use crate::settings::{Setting, Ty, Value, SETTINGS};

/// `"PZDP"` read as a little-endian u32.
pub const MAGIC: u32 = u32::from_le_bytes(*b"PZDP");
/// Format version: the newest stored row's `since` (a stored row added says `Stored since` one
/// more than this). Removing or reordering a stored setting or changing its type needs a new
/// version by hand and [`decode`] taught the old layout.
pub const VERSION: u16 = newest_since();
const HEADER_LEN: usize = 8;
const CRC_LEN: usize = 4;

/// Whether a record of format `version` (2 or later) holds row `s`.
const fn holds(version: u16, s: &Setting) -> bool {
    s.stored && s.since <= version
}

const fn newest_since() -> u16 {
    let mut v = FIRST_TABLE_VERSION;
    let mut rest = SETTINGS;
    while let [s, tail @ ..] = rest {
        if s.stored && s.since > v {
            v = s.since;
        }
        rest = tail;
    }
    v
}

/// Payload bytes of format `version` (2 or later): the rows it holds, each in its type's width.
pub const fn payload_len(version: u16) -> usize {
    let mut n = 0;
    let mut rest = SETTINGS;
    while let [s, tail @ ..] = rest {
        if holds(version, s) {
            n += s.ty.size();
        }
        rest = tail;
    }
    n
}

/// Payload bytes of format [`VERSION`].
pub const PAYLOAD_LEN: usize = payload_len(VERSION);
/// Whole record: header, payload, CRC.
pub const RECORD_LEN: usize = HEADER_LEN + PAYLOAD_LEN + CRC_LEN;

/// A field of a version-1 record: a setting (by id, in its table type) or bytes no longer used.
#[derive(Clone, Copy)]
enum Old {
    Setting(u32),
    Skip(usize),
}

/// Version 1's payload, in order.
const V1_FIELDS: [Old; 29] = [
    // Calibration: encoder resolution (skipped: read-only, the build's value counts), force cell.
    Old::Skip(4),
    Old::Setting(0x1011),
    Old::Setting(0x1012),
    Old::Setting(0x1013),
    Old::Setting(0x1014),
    Old::Setting(0x1015),
    // Limits: preload window, drive, following error, stall, encoder jump, travel, on target.
    Old::Setting(0x100F),
    Old::Setting(0x1010),
    Old::Setting(0x1002),
    Old::Setting(0x8),
    Old::Setting(0x100D),
    Old::Setting(0x100E),
    Old::Setting(0x30),
    Old::Setting(0x15),
    Old::Setting(0x36),
    Old::Setting(0x3F),
    // Gains.
    Old::Setting(0x1001),
    Old::Setting(0x1003),
    Old::Setting(0x1004),
    Old::Setting(0x1),
    Old::Setting(0x2),
    Old::Setting(0x1005),
    Old::Setting(0x1006),
    Old::Setting(0x1007),
    Old::Setting(0x1008),
    Old::Setting(0x1009),
    Old::Setting(0x100A),
    Old::Setting(0x100B),
    // The fine-mode gain (0x100C), which the controller never read: removed.
    Old::Skip(4),
];

const fn setting_size(id: u32) -> usize {
    let mut rest = SETTINGS;
    while let [s, tail @ ..] = rest {
        if s.id == id {
            return s.ty.size();
        }
        rest = tail;
    }
    usize::MAX / 2 // not a setting: fails the length check below
}

const fn v1_len() -> usize {
    let mut n = 0;
    let mut rest: &[Old] = &V1_FIELDS;
    while let [field, tail @ ..] = rest {
        n += match *field {
            Old::Setting(id) => setting_size(id),
            Old::Skip(k) => k,
        };
        rest = tail;
    }
    n
}

// The formats written so far are fixed: a change of a row that was in one of them (its type,
// its `since`, its place among the stored rows) fails here, not on a board's stored record.
const _: () = assert!(payload_len(2) == 140);
const _: () = assert!(payload_len(3) == 144);
const _: () = assert!(payload_len(4) == 164);
const _: () = assert!(payload_len(5) == 168);

/// Payload bytes of format version 1.
pub const V1_PAYLOAD_LEN: usize = 119;
const _: () = assert!(v1_len() == V1_PAYLOAD_LEN);

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum StorageError {
    /// Fewer bytes than a record.
    TooShort,
    /// No record (erased flash reads 0xFF…).
    NoRecord,
    WrongVersion(u16),
    WrongLength(u16),
    BadCrc,
    /// CRC fine but a value is outside its allowed range.
    OutOfRange,
}

/// CRC-32/ISO-HDLC (the zlib/Ethernet CRC): reflected polynomial 0xEDB88320, init and final XOR
/// 0xFFFFFFFF. Bitwise: the record is about 150 bytes and written rarely; no table needed.
pub fn crc32(bytes: &[u8]) -> u32 {
    let mut crc = 0xFFFF_FFFFu32;
    for &b in bytes {
        crc ^= u32::from(b);
        for _ in 0..8 {
            let mask = (crc & 1).wrapping_neg();
            crc = (crc >> 1) ^ (0xEDB8_8320 & mask);
        }
    }
    !crc
}

struct Writer {
    buf: [u8; RECORD_LEN],
    pos: usize,
}

impl Writer {
    fn put(&mut self, bytes: &[u8]) {
        for &b in bytes {
            if let Some(slot) = self.buf.get_mut(self.pos) {
                *slot = b;
            }
            self.pos += 1;
        }
    }
    /// `v` in the width of `ty` (a value of the field's own type, so the casts are exact).
    fn value(&mut self, ty: Ty, v: Value) {
        match (ty, v) {
            (Ty::F32, Value::F32(x)) => self.put(&x.to_le_bytes()),
            (Ty::I64Nm, Value::Int(x)) => self.put(&x.to_le_bytes()),
            (Ty::U32, Value::Int(x)) => self.put(&(x as u32).to_le_bytes()),
            (Ty::I32, Value::Int(x)) => self.put(&(x as i32).to_le_bytes()),
            (Ty::U16, Value::Int(x)) => self.put(&(x as u16).to_le_bytes()),
            (Ty::U8, Value::Int(x)) => self.put(&[x as u8]),
            // A row whose type and value disagree cannot be built (see `settings::Field`).
            _ => self.put([0; 8].get(..ty.size()).unwrap_or(&[])),
        }
    }
}

struct Reader<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl Reader<'_> {
    fn take<const N: usize>(&mut self) -> Result<[u8; N], StorageError> {
        let end = self.pos.checked_add(N).ok_or(StorageError::TooShort)?;
        let s = self.bytes.get(self.pos..end).ok_or(StorageError::TooShort)?;
        self.pos = end;
        s.try_into().map_err(|_| StorageError::TooShort)
    }
    fn skip(&mut self, n: usize) -> Result<(), StorageError> {
        let end = self.pos.checked_add(n).ok_or(StorageError::TooShort)?;
        self.bytes.get(self.pos..end).ok_or(StorageError::TooShort)?;
        self.pos = end;
        Ok(())
    }
    fn u16(&mut self) -> Result<u16, StorageError> {
        Ok(u16::from_le_bytes(self.take()?))
    }
    fn u32(&mut self) -> Result<u32, StorageError> {
        Ok(u32::from_le_bytes(self.take()?))
    }
    fn value(&mut self, ty: Ty) -> Result<Value, StorageError> {
        Ok(match ty {
            Ty::F32 => Value::F32(f32::from_le_bytes(self.take()?)),
            Ty::I64Nm => Value::Int(i64::from_le_bytes(self.take()?)),
            Ty::U32 => Value::Int(i64::from(self.u32()?)),
            Ty::I32 => Value::Int(i64::from(i32::from_le_bytes(self.take()?))),
            Ty::U16 => Value::Int(i64::from(self.u16()?)),
            Ty::U8 => {
                let [b] = self.take::<1>()?;
                Value::Int(i64::from(b))
            }
        })
    }
    /// Reads `s`'s value into `cfg`; out of range when it does not fit the field (a bool byte
    /// other than 0 or 1, an unknown choice).
    fn setting(&mut self, s: &Setting, cfg: &mut ControllerConfig) -> Result<(), StorageError> {
        let v = self.value(s.ty)?;
        if (s.set)(cfg, v) {
            Ok(())
        } else {
            Err(StorageError::OutOfRange)
        }
    }
}

/// The record for `cfg`.
pub fn encode(cfg: &ControllerConfig) -> [u8; RECORD_LEN] {
    let mut w = Writer { buf: [0; RECORD_LEN], pos: 0 };
    w.put(&MAGIC.to_le_bytes());
    w.put(&VERSION.to_le_bytes());
    w.put(&(PAYLOAD_LEN as u16).to_le_bytes());
    for s in SETTINGS.iter().filter(|s| s.stored) {
        w.value(s.ty, (s.get)(cfg));
    }
    let crc = crc32(w.buf.get(..HEADER_LEN + PAYLOAD_LEN).unwrap_or(&[]));
    w.put(&crc.to_le_bytes());
    w.buf
}

/// Offset in the record of a stored setting's value (None for an id not stored).
pub fn offset_of(id: u32) -> Option<usize> {
    let mut at = HEADER_LEN;
    for s in SETTINGS.iter().filter(|s| s.stored) {
        if s.id == id {
            return Some(at);
        }
        at += s.ty.size();
    }
    None
}

/// Whether `cfg` may be stored: what the controller accepts ([`validate_settings`], and the
/// board constants fit together), nothing else.
pub fn validate(cfg: &ControllerConfig) -> Result<(), StorageError> {
    if validate_settings(cfg).is_ok() && Controller::new(*cfg).is_ok() {
        Ok(())
    } else {
        Err(StorageError::OutOfRange)
    }
}

/// Reads a record (this [`VERSION`] or any older one) from the start of `bytes` (extra bytes
/// after it are ignored, so a whole flash page can be passed). Settings not in the record come from
/// `defaults`.
pub fn decode(bytes: &[u8], defaults: &ControllerConfig) -> Result<ControllerConfig, StorageError> {
    let mut r = Reader { bytes, pos: 0 };
    let magic = r.u32()?;
    if magic != MAGIC {
        return Err(StorageError::NoRecord);
    }
    let version = r.u16()?;
    let payload_len = match version {
        1 => V1_PAYLOAD_LEN,
        FIRST_TABLE_VERSION..=VERSION => payload_len(version),
        _ => return Err(StorageError::WrongVersion(version)),
    };
    let len = r.u16()?;
    if usize::from(len) != payload_len {
        return Err(StorageError::WrongLength(len));
    }
    let body = bytes.get(..HEADER_LEN + payload_len).ok_or(StorageError::TooShort)?;
    let stored_crc = Reader { bytes, pos: HEADER_LEN + payload_len }.u32()?;
    if crc32(body) != stored_crc {
        return Err(StorageError::BadCrc);
    }
    let mut cfg = *defaults;
    if version >= FIRST_TABLE_VERSION {
        // Older formats are this layout without the rows added since.
        for s in SETTINGS.iter().filter(|s| holds(version, s)) {
            r.setting(s, &mut cfg)?;
        }
    } else {
        for field in V1_FIELDS {
            match field {
                Old::Setting(id) => {
                    let s = SETTINGS.iter().find(|s| s.id == id).ok_or(StorageError::OutOfRange)?;
                    r.setting(s, &mut cfg)?;
                }
                Old::Skip(n) => r.skip(n)?,
            }
        }
    }
    validate(&cfg)?;
    Ok(cfg)
}
