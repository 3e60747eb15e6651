//! The parameter record kept in flash: the settable part of [`ControllerConfig`] (calibration,
//! limits, controller gains), little-endian, with a magic word, a format version, the payload
//! length and a CRC-32 over all of it. Pure functions; the firmware's flash task only moves the
//! bytes. [`decode`] never panics on arbitrary bytes and checks every value's range, so a record
//! that decodes is one the controller accepts.
//!
//! Layout (all little-endian):
//!
//! | offset | size | field |
//! |---|---|---|
//! | 0 | 4 | magic `"PZDP"` |
//! | 4 | 2 | format version ([`VERSION`]) |
//! | 6 | 2 | payload length ([`PAYLOAD_LEN`]) |
//! | 8 | [`PAYLOAD_LEN`] | fields, in the order of [`encode`] |
//! | 8 + [`PAYLOAD_LEN`] | 4 | CRC-32 (ISO-HDLC, as zlib) of bytes 0 .. 8 + [`PAYLOAD_LEN`] |
//!
//! Not stored (board or build constants, taken from the defaults passed to [`decode`]): the loop
//! rate, the DAC/amplifier description and the motor table.

use crate::controller::{Controller, ControllerConfig};

/// `"PZDP"` read as a little-endian u32.
pub const MAGIC: u32 = u32::from_le_bytes(*b"PZDP");
/// Format version; bump on any change of the payload.
pub const VERSION: u16 = 1;
const HEADER_LEN: usize = 8;
/// Payload bytes of format [`VERSION`].
pub const PAYLOAD_LEN: usize = 4 + 2 + 4 + 2 + 2 + 4 // calibration
    + 4 * 5 + 4 + 8 * 3 + 4 // limits
    + 4 * 5 + 1 + 4 * 7; // gains
/// Whole record: header, payload, CRC.
pub const RECORD_LEN: usize = HEADER_LEN + PAYLOAD_LEN + 4;

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
/// 0xFFFFFFFF. Bitwise: the record is 150 bytes and written rarely; no table needed.
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
    fn f32(&mut self, v: f32) {
        self.put(&v.to_le_bytes());
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
    fn u16(&mut self) -> Result<u16, StorageError> {
        Ok(u16::from_le_bytes(self.take()?))
    }
    fn u32(&mut self) -> Result<u32, StorageError> {
        Ok(u32::from_le_bytes(self.take()?))
    }
    fn i32(&mut self) -> Result<i32, StorageError> {
        Ok(i32::from_le_bytes(self.take()?))
    }
    fn i64(&mut self) -> Result<i64, StorageError> {
        Ok(i64::from_le_bytes(self.take()?))
    }
    fn f32(&mut self) -> Result<f32, StorageError> {
        Ok(f32::from_le_bytes(self.take()?))
    }
    fn bool(&mut self) -> Result<bool, StorageError> {
        match self.take::<1>()? {
            [0] => Ok(false),
            [1] => Ok(true),
            _ => Err(StorageError::OutOfRange),
        }
    }
}

/// The record for `cfg`.
pub fn encode(cfg: &ControllerConfig) -> [u8; RECORD_LEN] {
    let mut w = Writer { buf: [0; RECORD_LEN], pos: 0 };
    w.put(&MAGIC.to_le_bytes());
    w.put(&VERSION.to_le_bytes());
    w.put(&(PAYLOAD_LEN as u16).to_le_bytes());
    // Calibration.
    w.put(&cfg.encoder_nm_per_count.to_le_bytes());
    w.put(&cfg.preload.zero_word.to_le_bytes());
    w.f32(cfg.preload.newton_per_word);
    w.put(&cfg.preload.min_valid_word.to_le_bytes());
    w.put(&cfg.preload.max_valid_word.to_le_bytes());
    w.f32(cfg.preload.filter_alpha);
    // Limits.
    w.f32(cfg.preload_min_n);
    w.f32(cfg.preload_max_n);
    w.f32(cfg.max_drive_v);
    w.f32(cfg.following_error_limit_nm);
    w.f32(cfg.stall_time_s);
    w.put(&cfg.encoder_jump_counts.to_le_bytes());
    w.put(&cfg.travel_min_nm.to_le_bytes());
    w.put(&cfg.travel_max_nm.to_le_bytes());
    w.put(&cfg.on_target_window_nm.to_le_bytes());
    w.f32(cfg.settle_time_s);
    // Gains.
    w.f32(cfg.drive_freq_hz);
    w.f32(cfg.speed_fraction);
    w.f32(cfg.accel_fraction);
    w.f32(cfg.kp_per_s);
    w.f32(cfg.ki_n_per_nm_s);
    w.put(&[u8::from(cfg.feedforward)]);
    w.f32(cfg.fb_kp_v_per_nm);
    w.f32(cfg.fb_ki_v_per_nm_s);
    w.f32(cfg.expected_load_n);
    w.f32(cfg.profile_wait_lag_nm);
    w.f32(cfg.approach_speed_nm_s);
    w.f32(cfg.fine_window_nm);
    w.f32(cfg.fine_gain);
    debug_assert_eq!(w.pos, HEADER_LEN + PAYLOAD_LEN);
    let crc = crc32(w.buf.get(..HEADER_LEN + PAYLOAD_LEN).unwrap_or(&[]));
    w.put(&crc.to_le_bytes());
    w.buf
}

fn in_range(v: f32, lo: f32, hi: f32) -> bool {
    v.is_finite() && v >= lo && v <= hi
}

/// Whether the settable fields of `cfg` are within the ranges [`decode`] accepts (also usable
/// before storing a configuration changed over the protocol).
pub fn validate(cfg: &ControllerConfig) -> Result<(), StorageError> {
    let p = &cfg.preload;
    let dac = &cfg.dac;
    let ok = (1..=1_000_000).contains(&cfg.encoder_nm_per_count)
        && p.newton_per_word.is_finite()
        && p.newton_per_word != 0.0
        && p.newton_per_word.abs() <= 10.0
        && p.min_valid_word < p.max_valid_word
        && in_range(p.filter_alpha, 1e-4, 1.0)
        && in_range(cfg.preload_min_n, 0.0, 1000.0)
        && in_range(cfg.preload_max_n, cfg.preload_min_n, 1000.0)
        && cfg.preload_max_n > cfg.preload_min_n
        && in_range(cfg.max_drive_v, 0.0, dac.max_v - dac.min_v)
        && cfg.max_drive_v > 0.0
        && in_range(cfg.following_error_limit_nm, 1.0, 1e9)
        && in_range(cfg.stall_time_s, 1e-3, 10.0)
        && (1..=i32::from(i16::MAX)).contains(&cfg.encoder_jump_counts)
        && cfg.travel_min_nm < cfg.travel_max_nm
        && (0..=1_000_000_000).contains(&cfg.on_target_window_nm)
        && in_range(cfg.settle_time_s, 0.0, 10.0)
        && in_range(cfg.drive_freq_hz, dac.min_freq_hz, dac.max_freq_hz)
        && in_range(cfg.speed_fraction, 1e-3, 1.0)
        && in_range(cfg.accel_fraction, 1e-3, 1.0)
        && in_range(cfg.kp_per_s, 0.0, 1e4)
        && in_range(cfg.ki_n_per_nm_s, 0.0, 1.0)
        && in_range(cfg.fb_kp_v_per_nm, 0.0, 1e3)
        && in_range(cfg.fb_ki_v_per_nm_s, 0.0, 1e6)
        && in_range(cfg.expected_load_n, -1000.0, 1000.0)
        && in_range(cfg.profile_wait_lag_nm, 1.0, 1e9)
        && in_range(cfg.approach_speed_nm_s, 0.0, 1e9)
        && in_range(cfg.fine_window_nm, 0.0, 1e6)
        && in_range(cfg.fine_gain, 0.0, 1.0);
    if ok && Controller::new(*cfg).is_ok() {
        Ok(())
    } else {
        Err(StorageError::OutOfRange)
    }
}

/// Reads a record from the start of `bytes` (extra bytes after it are ignored, so a whole flash
/// page can be passed). Fields not in the record come from `defaults`.
pub fn decode(bytes: &[u8], defaults: &ControllerConfig) -> Result<ControllerConfig, StorageError> {
    let mut r = Reader { bytes, pos: 0 };
    let magic = r.u32()?;
    if magic != MAGIC {
        return Err(StorageError::NoRecord);
    }
    let version = r.u16()?;
    if version != VERSION {
        return Err(StorageError::WrongVersion(version));
    }
    let len = r.u16()?;
    if usize::from(len) != PAYLOAD_LEN {
        return Err(StorageError::WrongLength(len));
    }
    let body = bytes.get(..HEADER_LEN + PAYLOAD_LEN).ok_or(StorageError::TooShort)?;
    let stored_crc = {
        let mut c = Reader { bytes, pos: HEADER_LEN + PAYLOAD_LEN };
        c.u32()?
    };
    if crc32(body) != stored_crc {
        return Err(StorageError::BadCrc);
    }
    let mut cfg = *defaults;
    cfg.encoder_nm_per_count = r.u32()?;
    cfg.preload.zero_word = r.u16()?;
    cfg.preload.newton_per_word = r.f32()?;
    cfg.preload.min_valid_word = r.u16()?;
    cfg.preload.max_valid_word = r.u16()?;
    cfg.preload.filter_alpha = r.f32()?;
    cfg.preload_min_n = r.f32()?;
    cfg.preload_max_n = r.f32()?;
    cfg.max_drive_v = r.f32()?;
    cfg.following_error_limit_nm = r.f32()?;
    cfg.stall_time_s = r.f32()?;
    cfg.encoder_jump_counts = r.i32()?;
    cfg.travel_min_nm = r.i64()?;
    cfg.travel_max_nm = r.i64()?;
    cfg.on_target_window_nm = r.i64()?;
    cfg.settle_time_s = r.f32()?;
    cfg.drive_freq_hz = r.f32()?;
    cfg.speed_fraction = r.f32()?;
    cfg.accel_fraction = r.f32()?;
    cfg.kp_per_s = r.f32()?;
    cfg.ki_n_per_nm_s = r.f32()?;
    cfg.feedforward = r.bool()?;
    cfg.fb_kp_v_per_nm = r.f32()?;
    cfg.fb_ki_v_per_nm_s = r.f32()?;
    cfg.expected_load_n = r.f32()?;
    cfg.profile_wait_lag_nm = r.f32()?;
    cfg.approach_speed_nm_s = r.f32()?;
    cfg.fine_window_nm = r.f32()?;
    cfg.fine_gain = r.f32()?;
    validate(&cfg)?;
    Ok(cfg)
}
