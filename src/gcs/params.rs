//! Parameters for `SPA`/`SPA?`/`HPA?`/`WPA`: the settings table ([`crate::settings::SETTINGS`])
//! seen from the protocol, in GCS units (mm, mm/s, s, N, V, Hz). Only the unit conversions live
//! here; ids, ranges, descriptions and what is stored are the table's.

use super::num::{write_f32, write_general, write_i64, write_scaled, Decimal, Sink};
use crate::settings::Value;
pub use crate::settings::{find, Kind, Setting as Param, SETTINGS as PARAMS};

fn nm(mm: f64) -> Option<i64> {
    let x = mm * 1e6;
    let r = if x >= 0.0 { x + 0.5 } else { x - 0.5 };
    (x.is_finite() && r.abs() < 9.0e18).then_some(r as i64)
}

fn f32_of(v: f64) -> Option<f32> {
    let f = v as f32;
    f.is_finite().then_some(f)
}

/// The row with this id, looked up when the firmware is built (an id not in the table fails
/// the build): the PI-named commands (`VEL`, `ACC`, `DEC`, `TMN?`, `TMX?`) name their row so.
/// For constants only.
#[allow(clippy::panic, reason = "evaluated in constants: a missing id fails the build")]
pub const fn row(id: u32) -> &'static Param {
    let mut rest = PARAMS;
    while let [p, tail @ ..] = rest {
        if p.id == id {
            return p;
        }
        rest = tail;
    }
    panic!("no setting with this id")
}

/// The field value `SPA` sets from a number in the protocol's unit; None when the field's type
/// cannot hold it (not an integer for an integer setting, beyond f32, beyond ±9e18 nm). The
/// range check of the whole configuration follows in [`crate::controller::validate_settings`].
pub fn from_gcs(p: &Param, v: &Decimal) -> Option<Value> {
    match p.kind {
        Kind::Int => v.integer().map(Value::Int),
        // f64 product, then f32: an f32 setting holds the nearest f32 of the value sent.
        Kind::Float => f32_of(v.to_f64()? * f64::from(p.scale)).map(Value::F32),
        Kind::Millimetre => nm(v.to_f64()?).map(Value::Int),
    }
}

/// Writes `p`'s value `v` in the protocol's unit: integers as they are, lengths in mm with six
/// decimals, f32 settings with as many significant digits as it takes to read back the same
/// f32. False when the sink is full.
pub fn write_gcs(out: &mut dyn Sink, p: &Param, v: Value) -> bool {
    match (p.kind, v) {
        (Kind::Millimetre, Value::Int(nm)) => write_scaled(out, nm, 6),
        (_, Value::Int(x)) => write_i64(out, x),
        // f32 division: hardware on the board; the value is an f32 anyway.
        (_, Value::F32(x)) => write_f32(out, x / p.scale),
    }
}

/// Writes `p`'s value `v` as the PI-named queries (`VEL?`, `ACC?`, `DEC?`) show it: an f32
/// setting in the protocol's unit with about seven significant digits ([`write_general`]),
/// anything else as [`write_gcs`]. False when the sink is full.
pub fn write_short(out: &mut dyn Sink, p: &Param, v: Value) -> bool {
    match v {
        // f32 division, as `write_gcs`'s.
        Value::F32(x) => write_general(out, f64::from(x / p.scale)),
        Value::Int(_) => write_gcs(out, p, v),
    }
}
