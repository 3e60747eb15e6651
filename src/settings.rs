//! Every controller setting, declared once: [`SETTINGS`], one row per setting with its GCS id,
//! its [`ControllerConfig`] field (the name), GCS unit, type, range, default, whether `WPA`
//! stores it, whether `SPA` may set it, its description and what a change of it invalidates.
//! Everything else is derived from this table:
//!
//! - `SPA`/`SPA?`/`HPA?` ([`crate::gcs`], through [`crate::gcs::params`]): the rows in table
//!   order, `HPA?` text `description (unit)`;
//! - the range check (`validate_settings` (the controller's): each row's [`Range`], plus the
//!   few rules that tie two settings together);
//! - the flash record ([`crate::storage`]): the stored rows in table order, each in its type's
//!   width;
//! - the defaults ([`crate::defaults`]): each row's fixed default, or its value from the
//!   hardware ([`Hardware`]);
//! - what a change forgets ([`invalidated`], used by `ConfigChange::prepare`): each row's
//!   [`Invalidates`] (the learned load, the learned mass).
//!
//! The struct [`ControllerConfig`] is where the controller reads the values; a setting is a
//! field there and a row here, nothing else.
//!
//! Adding a stored row changes the flash record: the row says `Stored since N` with N one more
//! than the present [`crate::storage::VERSION`], which follows (records of older formats are
//! read without it). Removing or reordering a stored row, or changing its type, needs a decoder
//! for the previous layout (see `storage`).

use crate::config::{ControllerConfig, ReferenceSignal, MAX_TRAVEL_NM};
use crate::fastmath::fx_from_f32;
use crate::hardware::Hardware;
use crate::Fx;

/// The first record format from the settings table (version 1 was written before it): a stored
/// row without a `since` of its own is in every record from this one on
/// ([`crate::storage::VERSION`] follows from the rows).
pub const FIRST_TABLE_VERSION: u16 = 2;

/// A setting's value in its field's own type, widened: f32 fields as `F32`, every integer field
/// (u16, u32, i32, i64, bool as 0/1, an enum as its code) as `Int`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Value {
    F32(f32),
    Int(i64),
}

/// The field's type: its width in the flash record and how the protocol shows it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Ty {
    F32,
    /// A length in whole nanometres; the protocol shows it in mm with six decimals.
    I64Nm,
    U32,
    I32,
    U16,
    /// A bool (0/1) or an enum's code.
    U8,
}

impl Ty {
    /// Bytes in the flash record (little-endian).
    pub const fn size(self) -> usize {
        match self {
            Ty::F32 | Ty::U32 | Ty::I32 => 4,
            Ty::I64Nm => 8,
            Ty::U16 => 2,
            Ty::U8 => 1,
        }
    }
}

/// How `SPA?` prints a value and `HPA?` names its type.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    Int,
    /// An f32 setting: `SPA?` prints as many significant digits as it takes to read back the
    /// same f32 (nine at most).
    Float,
    /// A length in mm kept as whole nanometres: `SPA?` prints six decimals, as `TMX?` does.
    Millimetre,
}

impl Kind {
    pub const fn of(ty: Ty) -> Kind {
        match ty {
            Ty::F32 => Kind::Float,
            Ty::I64Nm => Kind::Millimetre,
            Ty::U32 | Ty::I32 | Ty::U16 | Ty::U8 => Kind::Int,
        }
    }
    pub fn name(self) -> &'static str {
        match self {
            Kind::Int => "INT",
            Kind::Float | Kind::Millimetre => "FLOAT",
        }
    }
}

/// Allowed values, in the field's own unit (the unit its name ends in).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Range {
    /// Finite, `lo ≤ x ≤ hi` (`lo < x` when `lo_open`).
    Float { lo: f32, hi: f32, lo_open: bool },
    /// `lo ≤ x ≤ hi`.
    Int { lo: i64, hi: i64 },
}

impl Range {
    #[inline(always)]
    pub fn contains(&self, v: Value) -> bool {
        match (*self, v) {
            (Range::Float { lo, hi, lo_open }, Value::F32(x)) => {
                x.is_finite() && (if lo_open { x > lo } else { x >= lo }) && x <= hi
            }
            (Range::Int { lo, hi }, Value::Int(x)) => x >= lo && x <= hi,
            _ => false,
        }
    }
}

/// Any finite value.
pub const ANY: Range = Range::Float { lo: -f32::MAX, hi: f32::MAX, lo_open: false };
/// Finite and ≥ 0.
pub const NON_NEGATIVE: Range = Range::Float { lo: 0.0, hi: f32::MAX, lo_open: false };
/// Finite and > 0.
pub const POSITIVE: Range = Range::Float { lo: 0.0, hi: f32::MAX, lo_open: true };
/// A share: 0 < x ≤ 1.
pub const FRACTION: Range = Range::Float { lo: 0.0, hi: 1.0, lo_open: true };
/// A position within the travel bound, ±[`MAX_TRAVEL_NM`].
pub const TRAVEL: Range = Range::Int { lo: -MAX_TRAVEL_NM, hi: MAX_TRAVEL_NM };
/// 0 or 1 (a bool, a two-way choice).
pub const FLAG: Range = Range::Int { lo: 0, hi: 1 };
/// Longest time setting (s): the timers count control periods in a u32 (at 10 kHz 4.9 days), and
/// an hour is far beyond any search or settle this stage makes.
pub const TIMEOUT_MAX_S: f32 = 3600.0;
/// A timeout: `0 < x ≤` [`TIMEOUT_MAX_S`].
pub const TIMEOUT: Range = Range::Float { lo: 0.0, hi: TIMEOUT_MAX_S, lo_open: true };
/// Any u16.
pub const WORD: Range = Range::Int { lo: 0, hi: u16::MAX as i64 };

/// Where a setting's default comes from.
#[derive(Clone, Copy)]
pub enum DefaultValue {
    /// The same on every board: sets the field to it.
    Fixed(fn(&mut ControllerConfig)),
    /// From the hardware the firmware is built for ([`Hardware`]): what it is, and what sets
    /// the field from the hardware and the rows before it (their defaults already set).
    Hardware(&'static str, fn(&Hardware, &mut ControllerConfig)),
}

/// Whether `WPA` keeps a setting and `SPA` may change it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Keep {
    /// Settable; `WPA` stores it in the flash record.
    Stored,
    /// Settable; lost at reset.
    Volatile,
    /// A fact of the hardware: `SPA` refuses it, the record does not hold it (the build's value
    /// counts).
    ReadOnly,
}

/// What the controller has learned that a change of a setting makes it forget (a set). Every
/// accepted change also drops the model table (it is built anew for the new settings).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Invalidates(u8);

impl Invalidates {
    pub const NOTHING: Invalidates = Invalidates(0);
    /// The load observer's learned load: it was the old motor model's error.
    pub const LEARNED_LOAD: Invalidates = Invalidates(1);
    /// The mass estimator's learned mass: what the speed-ups measured no longer holds.
    pub const LEARNED_MASS: Invalidates = Invalidates(2);

    /// Both sets together.
    pub const fn and(self, other: Invalidates) -> Invalidates {
        Invalidates(self.0 | other.0)
    }
    /// Whether everything in `other` is in this set.
    pub const fn contains(self, other: Invalidates) -> bool {
        self.0 & other.0 == other.0
    }
}

/// One setting's declaration (a row of [`SETTINGS`]).
pub struct Setting {
    /// GCS parameter id (`SPA 1 <id> <value>`).
    pub id: u32,
    /// The [`ControllerConfig`] field, e.g. `preload.zero_word`.
    pub name: &'static str,
    /// Function group for `HPA?`.
    pub group: &'static str,
    /// What it is, for `HPA?` (no `=`, no tab; the unit follows in parentheses).
    pub description: &'static str,
    /// Unit of the value in the protocol (`SPA`/`SPA?`); empty for a pure number.
    pub unit: &'static str,
    /// Field units per protocol unit (1e6 for a `_nm` field set in mm); f32 fields only (an
    /// `I64Nm` field is always nm ↔ mm).
    pub scale: f32,
    pub ty: Ty,
    pub kind: Kind,
    /// Allowed values in the field's unit.
    pub range: Range,
    pub default: DefaultValue,
    pub keep: Keep,
    /// A stored row: the record format ([`crate::storage::VERSION`]) that first held it; a
    /// record of an older format is read without it (its value then comes from the defaults).
    pub since: u16,
    /// What a change of it makes the controller forget ([`invalidated`]).
    pub invalidates: Invalidates,
    pub stored: bool,
    pub read_only: bool,
    /// The field's value.
    pub get: fn(&ControllerConfig) -> Value,
    /// Sets the field; false (nothing changed) when the value does not fit its type (range
    /// checks are `validate_settings` (the controller's)'s).
    pub set: fn(&mut ControllerConfig, Value) -> bool,
}

/// A field type a setting may have.
pub trait Field: Sized {
    const TY: Ty;
    fn to_value(self) -> Value;
    /// None when `v` is not of this type or does not fit.
    fn from_value(v: Value) -> Option<Self>;
    /// Whether the value is in `range` (inlined with a constant range, a compare or two).
    #[inline(always)]
    fn within(self, range: &Range) -> bool {
        range.contains(self.to_value())
    }
}

impl Field for f32 {
    const TY: Ty = Ty::F32;
    #[inline(always)]
    fn to_value(self) -> Value {
        Value::F32(self)
    }
    fn from_value(v: Value) -> Option<Self> {
        match v {
            Value::F32(x) => Some(x),
            Value::Int(_) => None,
        }
    }
}

macro_rules! int_field {
    ($t:ty, $ty:expr) => {
        impl Field for $t {
            const TY: Ty = $ty;
            #[inline(always)]
            fn to_value(self) -> Value {
                Value::Int(i64::from(self))
            }
            fn from_value(v: Value) -> Option<Self> {
                match v {
                    Value::Int(x) => <$t>::try_from(x).ok(),
                    Value::F32(_) => None,
                }
            }
        }
    };
}
int_field!(i64, Ty::I64Nm);
int_field!(u32, Ty::U32);
int_field!(i32, Ty::I32);
int_field!(u16, Ty::U16);

impl Field for bool {
    const TY: Ty = Ty::U8;
    #[inline(always)]
    fn to_value(self) -> Value {
        Value::Int(i64::from(self))
    }
    fn from_value(v: Value) -> Option<Self> {
        match v {
            Value::Int(0) => Some(false),
            Value::Int(1) => Some(true),
            _ => None,
        }
    }
}

impl Field for ReferenceSignal {
    const TY: Ty = Ty::U8;
    #[inline(always)]
    fn to_value(self) -> Value {
        Value::Int(match self {
            ReferenceSignal::Index => 0,
            ReferenceSignal::NegativeLimit => 1,
        })
    }
    fn from_value(v: Value) -> Option<Self> {
        match v {
            Value::Int(0) => Some(ReferenceSignal::Index),
            Value::Int(1) => Some(ReferenceSignal::NegativeLimit),
            _ => None,
        }
    }
}

/// Encoder counts per mm as a fraction in lowest terms (numerator, denominator), from the
/// encoder's nm per count: 50 nm gives 20000/1, 3 nm 1000000/3.
pub fn counts_per_mm(nm_per_count: u32) -> (u32, u32) {
    let (mut a, mut b) = (1_000_000u32, nm_per_count.max(1));
    while b != 0 {
        (a, b) = (b, a % b);
    }
    (1_000_000 / a, nm_per_count.max(1) / a)
}

/// The largest value the row with this id accepts, in its field's unit (0 for no such row).
fn top_of(id: u32) -> f32 {
    match find(i64::from(id)).map(|s| s.range) {
        Some(Range::Float { hi, .. }) => hi,
        Some(Range::Int { hi, .. }) => hi as f32,
        None => 0.0,
    }
}

/// The preload at which 0x50 turns a speed into the reference drive and back: the middle of
/// the preload window (the model's no-load speed changes little across it, physics.md §2).
fn reference_preload_n(c: &ControllerConfig) -> f32 {
    0.5 * (c.preload_min_n + c.preload_max_n)
}

/// 0x50 from 0x1018: the model's no-load speed (nm/s) at the reference drive amplitude and the
/// drive frequency the search uses.
fn reference_speed_nm_s(c: &ControllerConfig) -> f32 {
    let pv = c.per_volt();
    let at = pv.point(fx_from_f32(reference_preload_n(c)), fx_from_f32(c.reference_drive_v));
    at.no_load_speed_mm_s().to_num::<f32>() * 1e6
}

/// 0x1018 from 0x50: the drive amplitude (to 0.01 V) at which the model runs at `speed_nm_s`
/// with no load; false when the speed is not positive or even full drive is slower.
fn set_reference_speed_nm_s(c: &mut ControllerConfig, speed_nm_s: f32) -> bool {
    let mm_s = speed_nm_s / 1e6;
    if !(mm_s.is_finite() && mm_s > 0.0) {
        return false;
    }
    let pv = c.per_volt();
    let preload = fx_from_f32(reference_preload_n(c));
    let v = pv.voltage_for(preload, fx_from_f32(mm_s), Fx::ZERO, fx_from_f32(c.max_drive_v));
    // voltage_for answers full drive when that is not enough: refuse rather than search slower
    // than asked without saying so (1 % for the 0.01 V steps).
    if pv.point(preload, v).no_load_speed_mm_s().to_num::<f32>() < 0.99 * mm_s {
        return false;
    }
    c.reference_drive_v = v.to_num();
    true
}

/// A row's hardware default: what `get` makes of the hardware and the rows before it (the
/// argument types fixed here, so that a row's closure needs none).
#[inline(always)]
fn from_hardware<T>(get: fn(&Hardware, &ControllerConfig) -> T, hw: &Hardware, c: &ControllerConfig) -> T {
    get(hw, c)
}

/// One row: `id, group, field: type = default; unit, scale, range, keep, description`; a stored
/// row added after the first record format from the table (2) says since when: `Stored since 6`;
/// and `, invalidates WHAT | WHAT` when a change of it makes the controller forget something
/// ([`Invalidates`]); the default is a value of the field's type or
/// `hardware(|hw, c| value, "where it comes from")` (from the [`Hardware`] and the rows before
/// it). `@check c;` and a row: whether `c`'s field is in the row's range. A read-only row that is no field of its
/// own but follows from others: `id, group, name: type = derived(|c| value, "from what");
/// unit, scale, range, ReadOnly, description`.
macro_rules! setting {
    (@since) => {
        FIRST_TABLE_VERSION
    };
    (@since $since:literal) => {
        $since
    };
    (@check $c:ident; $id:literal, $group:literal, $name:ident : $t:ty = derived($get:expr, $what:literal);
     $($rest:tt)*) => {
        true
    };
    ($id:literal, $group:literal, $name:ident : $t:ty = derived($get:expr, $what:literal);
     $unit:literal, $scale:literal, $range:expr, ReadOnly, $desc:literal) => {
        Setting {
            id: $id,
            name: stringify!($name),
            group: $group,
            description: $desc,
            unit: $unit,
            scale: $scale,
            ty: <$t as Field>::TY,
            kind: Kind::of(<$t as Field>::TY),
            range: $range,
            // Follows from other fields: nothing to set.
            default: DefaultValue::Hardware($what, |_: &Hardware, _: &mut ControllerConfig| {}),
            keep: Keep::ReadOnly,
            since: FIRST_TABLE_VERSION,
            invalidates: Invalidates::NOTHING,
            stored: false,
            read_only: true,
            get: |c: &ControllerConfig| {
                let get: fn(&ControllerConfig) -> $t = $get;
                Field::to_value(get(c))
            },
            set: |_: &mut ControllerConfig, _: Value| false,
        }
    };
    (@check $c:ident; $id:literal, $group:literal, $name:ident : $t:ty = alias($get:ident, $set:ident, $what:literal);
     $($rest:tt)*) => {
        true
    };
    ($id:literal, $group:literal, $name:ident : $t:ty = alias($get:ident, $set:ident, $what:literal);
     $unit:literal, $scale:literal, $range:expr, $desc:literal) => {
        Setting {
            id: $id,
            name: stringify!($name),
            group: $group,
            description: $desc,
            unit: $unit,
            scale: $scale,
            ty: <$t as Field>::TY,
            kind: Kind::of(<$t as Field>::TY),
            range: $range,
            // Another row's value: nothing of its own to set, store or check.
            default: DefaultValue::Hardware($what, |_: &Hardware, _: &mut ControllerConfig| {}),
            keep: Keep::Volatile,
            since: FIRST_TABLE_VERSION,
            invalidates: Invalidates::NOTHING,
            stored: false,
            read_only: false,
            get: |c: &ControllerConfig| Field::to_value($get(c)),
            set: |c: &mut ControllerConfig, v: Value| match <$t as Field>::from_value(v) {
                Some(x) => $set(c, x),
                None => false,
            },
        }
    };
    (@check $c:ident; $id:literal, $group:literal, $($f:ident).+ : $t:ty = hardware($get:expr, $what:literal);
     $unit:literal, $scale:literal, $range:expr, $($rest:tt)*) => {
        Field::within($c.$($f).+, &$range)
    };
    (@check $c:ident; $id:literal, $group:literal, $($f:ident).+ : $t:ty = $default:expr;
     $unit:literal, $scale:literal, $range:expr, $($rest:tt)*) => {
        Field::within($c.$($f).+, &$range)
    };
    ($id:literal, $group:literal, $($f:ident).+ : $t:ty = hardware($get:expr, $what:literal);
     $($rest:tt)*) => {
        setting!(@row $id, $group, $($f).+ : $t,
            DefaultValue::Hardware($what, |hw: &Hardware, c: &mut ControllerConfig| {
                c.$($f).+ = from_hardware::<$t>($get, hw, c);
            }); $($rest)*)
    };
    ($id:literal, $group:literal, $($f:ident).+ : $t:ty = $default:expr; $($rest:tt)*) => {
        setting!(@row $id, $group, $($f).+ : $t,
            DefaultValue::Fixed(|c: &mut ControllerConfig| c.$($f).+ = $default); $($rest)*)
    };
    (@row $id:literal, $group:literal, $($f:ident).+ : $t:ty, $default:expr;
     $unit:literal, $scale:literal, $range:expr, $keep:ident $(since $since:literal)?, $desc:literal
     $(, invalidates $($inv:ident)|+)?) => {
        Setting {
            id: $id,
            name: stringify!($($f).+),
            group: $group,
            description: $desc,
            unit: $unit,
            scale: $scale,
            ty: <$t as Field>::TY,
            kind: Kind::of(<$t as Field>::TY),
            range: $range,
            default: $default,
            keep: Keep::$keep,
            since: setting!(@since $($since)?),
            invalidates: Invalidates::NOTHING $($(.and(Invalidates::$inv))+)?,
            stored: matches!(Keep::$keep, Keep::Stored),
            read_only: matches!(Keep::$keep, Keep::ReadOnly),
            get: |c: &ControllerConfig| Field::to_value(c.$($f).+),
            set: |c: &mut ControllerConfig, v: Value| match <$t as Field>::from_value(v) {
                Some(x) => {
                    c.$($f).+ = x;
                    true
                }
                None => false,
            },
        }
    };
}

/// The table and the range check, from the rows (each in parentheses): the check is straight
/// code, field by field, as cheap as one written by hand (it runs in `Controller::set_config`,
/// which the board calls with the control tick held off).
macro_rules! settings {
    ($(#[$doc:meta])* pub static $name:ident; $(($($row:tt)*)),* $(,)?) => {
        $(#[$doc])*
        pub static $name: &[Setting] = &[$(setting!($($row)*)),*];

        /// Whether every setting of `c` is within its own range (the rules between settings
        /// are `validate_settings` (the controller's)'s).
        pub fn each_in_range(c: &ControllerConfig) -> bool {
            true $(&& setting!(@check c; $($row)*))*
        }
    };
}

settings! {
    /// The settings, in `SPA?`/`HPA?` order (by id). IDs 0x1–0x3F follow PI's numbering where PI
    /// has the same meaning; 0x1001 and up are ours. Ranges are in the field's unit (its name's
    /// suffix); the unit column is the protocol's.
    pub static SETTINGS;

    // id, group, field: type = default; GCS unit, field units per GCS unit (f32 fields; an i64 nm
    // field is always shown in mm), range in the field's unit, keep [since the record format
    // that first held it], description [, invalidates what a change of it forgets]
    // 400 /s: measured on the sweep at 100, 200, 300, 400 and 600 /s, the peak following errors
    // fall up to 400 /s (by 1.5–2× against unknown loads, the light carriages' 10 µm overshoot
    // 2.4–2.5× less); at 600 /s the 50 kg carriage's 1 µm step rings (14 ms, was 7). The loop's
    // delay (a control period plus half a drive period, 0.33 ms) costs 8° of phase at 400 rad/s.
    (0x1, "Servo", kp_per_s: f32 = 400.0;
        "1/s", 1.0, NON_NEGATIVE, Stored, "Position feedback gain"),
    (0x2, "Servo", ki_n_per_nm_s: f32 = 1e-3;
        "N per nm*s", 1.0, NON_NEGATIVE, Stored, "Load integrator gain"),
    (0x8, "Servo", following_error_limit_nm: f32 = 50_000.0;
        "mm", 1e6, POSITIVE, Stored, "Maximum position error"),
    // VEL/ACC/DEC: high enough that the thrust model's limits govern unless a user lowers them.
    (0xA, "Motion", velocity_max_nm_s: f32 = 10_000_000.0;
        "mm/s", 1e6, POSITIVE, Stored, "Maximum closed-loop velocity"),
    (0xB, "Motion", accel_max_nm_s2: f32 = 1e9;
        "mm/s^2", 1e6, POSITIVE, Stored, "Closed-loop acceleration"),
    (0xC, "Motion", decel_max_nm_s2: f32 = 1e9;
        "mm/s^2", 1e6, POSITIVE, Stored, "Closed-loop deceleration"),
    // PI's counts per unit (numerator 0xE over denominator 0xF): encoder counts per mm, from
    // the encoder's resolution in lowest terms. EPICS motorPIGCS2 reads them as its resolution.
    (0xE, "Hardware",
        counts_per_mm_numerator: u32 = derived(|c| counts_per_mm(c.encoder_nm_per_count).0, "the encoder's resolution");
        "", 1.0, Range::Int { lo: 1, hi: u32::MAX as i64 }, ReadOnly, "Counts per unit numerator (counts per mm)"),
    (0xF, "Hardware",
        counts_per_mm_denominator: u32 = derived(|c| counts_per_mm(c.encoder_nm_per_count).1, "the encoder's resolution");
        "", 1.0, Range::Int { lo: 1, hi: u32::MAX as i64 }, ReadOnly, "Counts per unit denominator"),
    (0x15, "Motion", travel_max_nm: i64 = 50_000_000;
        "mm", 1.0, TRAVEL, Stored, "Maximum travel in positive direction"),
    (0x30, "Motion", travel_min_nm: i64 = -50_000_000;
        "mm", 1.0, TRAVEL, Stored, "Maximum travel in negative direction"),
    (0x36, "Servo", on_target_window_nm: i64 = 50;
        "mm", 1.0, Range::Int { lo: 0, hi: MAX_TRAVEL_NM }, Stored, "Settling window"),
    (0x3F, "Servo", settle_time_s: f32 = 0.01;
        "s", 1.0, Range::Float { lo: 0.0, hi: TIMEOUT_MAX_S, lo_open: false }, Stored, "Settling time"),
    // PI's maximum closed-loop acceleration and deceleration: the most 0xB and 0xC accept. The
    // profile also keeps within what the thrust model allows at the measured preload (XTM?).
    (0x4A, "Motion",
        accel_limit_nm_s2: f32 = derived(|_| top_of(0xB), "the range of 0xB");
        "mm/s^2", 1e6, POSITIVE, ReadOnly, "Maximum closed-loop acceleration"),
    (0x4B, "Motion",
        decel_limit_nm_s2: f32 = derived(|_| top_of(0xC), "the range of 0xC");
        "mm/s^2", 1e6, POSITIVE, ReadOnly, "Maximum closed-loop deceleration"),
    // PI's velocity for reference moves: the search drives open loop at 0x1018, so this is
    // 0x1018 seen as the model's speed with no load (at the middle of the preload window);
    // setting it sets 0x1018 (and `WPA` stores that). Refused (17) when full drive is too slow.
    (0x50, "Referencing",
        reference_speed_nm_s: f32 = alias(reference_speed_nm_s, set_reference_speed_nm_s, "0x1018");
        "mm/s", 1e6, POSITIVE, "Velocity of the reference search with no load (sets 0x1018)"),
    // The top of the band gives a 0.3 kg and heavier carriage its highest speed; the DAC's band
    // is checked too.
    (0x1001, "Drive", drive_freq_hz: f32 = 2200.0;
        "Hz", 1.0, POSITIVE, Stored, "Highest drive frequency of coarse motion"),
    (0x1002, "Drive", max_drive_v: f32 =
        hardware(|hw, _| hw.dac.max_v - hw.dac.min_v, "the amplifier's output range");
        "V peak-to-peak", 1.0, POSITIVE, Stored, "Maximum drive amplitude"),
    (0x1003, "Motion", speed_fraction: f32 = 0.92;
        "", 1.0, FRACTION, Stored, "Share of the model no-load speed the profile uses"),
    (0x1004, "Motion", accel_fraction: f32 = 0.8;
        "", 1.0, FRACTION, Stored, "Share of the model thrust the profile uses"),
    (0x1005, "Servo", feedforward: bool = true;
        "", 1.0, FLAG, Stored, "Thrust-model feedforward (1 on, 0 plain PI feedback)"),
    // Plain PI (feedforward off): full drive at 20 µm of error, integral time 10 ms.
    (0x1006, "Servo", fb_kp_v_per_nm: f32 = 100.0 / 20_000.0;
        "V per nm", 1.0, NON_NEGATIVE, Stored, "Plain-feedback proportional gain"),
    (0x1007, "Servo", fb_ki_v_per_nm_s: f32 = 100.0 / 20_000.0 / 0.01;
        "V per nm*s", 1.0, NON_NEGATIVE, Stored, "Plain-feedback integral gain"),
    (0x1008, "Servo", expected_load_n: f32 = 0.0;
        "N", 1.0, ANY, Stored, "Expected load along +x"),
    (0x1009, "Motion", profile_wait_lag_nm: f32 = 2_000.0;
        "mm", 1e6, POSITIVE, Stored, "Lag at which the profile waits for the slider"),
    (0x100A, "Motion", approach_speed_nm_s: f32 = 200_000.0;
        "mm/s", 1e6, POSITIVE, Stored, "Least final approach speed"),
    (0x100B, "Servo", fine_window_nm: f32 = 300.0;
        "mm", 1e6, NON_NEGATIVE, Stored, "Fine-mode window"),
    (0x100D, "Supervision", stall_time_s: f32 = 0.05;
        "s", 1.0, TIMEOUT, Stored, "Stall detection time"),
    // The 16-bit encoder counter is unwrapped by its change per period, taken as an i16: a
    // larger limit could never trip.
    (0x100E, "Supervision", encoder_jump_counts: i32 = 200;
        "counts per period", 1.0, Range::Int { lo: 1, hi: i16::MAX as i64 }, Stored,
        "Encoder jump limit"),
    // Below about 3 N contact is unreliable (physics.md §2).
    (0x100F, "Preload", preload_min_n: f32 = 3.0;
        "N", 1.0, NON_NEGATIVE, Stored, "Preload window minimum"),
    (0x1010, "Preload", preload_max_n: f32 =
        hardware(|_, c| crate::hardware::full_contact_preload_n(c),
            "the highest preload at which full drive still lifts the foot off, physics.md §2");
        "N", 1.0, NON_NEGATIVE, Stored, "Preload window maximum"),
    (0x1011, "Preload", preload.zero_word: u16 = 0;
        "", 1.0, WORD, Stored, "Force cell zero word"),
    (0x1012, "Preload", preload.newton_per_word: f32 =
        hardware(|hw, _| hw.force_cell_newton_per_word, "the force cell's full scale over its full-scale word");
        "N per word", 1.0, ANY, Stored, "Force cell scale"),
    (0x1013, "Preload", preload.min_valid_word: u16 = 0;
        "", 1.0, WORD, Stored, "Force cell lowest valid word"),
    (0x1014, "Preload", preload.max_valid_word: u16 =
        hardware(|hw, _| hw.force_cell_max_word, "the force cell's full-scale word");
        "", 1.0, WORD, Stored, "Force cell highest valid word"),
    (0x1015, "Preload", preload.filter_alpha: f32 = 0.01;
        "", 1.0, FRACTION, Stored, "Force cell filter coefficient per period"),
    (0x1016, "Referencing", reference_signal: ReferenceSignal = ReferenceSignal::Index;
        "", 1.0, FLAG, Stored, "Reference signal (0 encoder index, 1 negative limit switch)"),
    (0x1017, "Referencing", reference_position_nm: i64 = 0;
        "mm", 1.0, TRAVEL, Stored, "Position given to the reference mark"),
    (0x1018, "Referencing", reference_drive_v: f32 = 50.0;
        "V", 1.0, POSITIVE, Stored, "Drive amplitude of the reference search"),
    (0x1019, "Referencing", reference_timeout_s: f32 = 200.0;
        "s", 1.0, TIMEOUT, Stored, "Reference search timeout"),
    (0x101A, "Motor", moving_mass_kg: f32 =
        hardware(|hw, _| hw.motor.moving_mass_kg.to_num(), "the motor table's moving mass");
        "kg", 1.0, Range::Float { lo: 1e-3, hi: 1e3, lo_open: false }, Stored since 3,
        "Moving mass of the carriage and payload", invalidates LEARNED_MASS),
    // The motor as calibrated (`host-sim calibrate` uploads the model-gap workflow's fit). What
    // the load observer learned was the old model's error, and the speed-ups were timed against
    // it.
    (0x101B, "Motor", mu_dynamic: f32 =
        hardware(|hw, _| hw.motor.mu.to_num(), "the motor table's friction coefficient");
        "", 1.0, Range::Float { lo: 0.0, hi: 2.0, lo_open: true }, Stored since 4,
        "Sliding friction coefficient of the drive foot", invalidates LEARNED_LOAD | LEARNED_MASS),
    (0x101C, "Motor", tangential_scale: f32 =
        hardware(|hw, _| hw.motor.tangential_scale, "the motor table's tangential scale");
        "", 1.0, POSITIVE, Stored since 4,
        "Tangential scale of the stator (within 4x of the table's)", invalidates LEARNED_LOAD | LEARNED_MASS),
    (0x101D, "Motor", normal_force_ratio: f32 =
        hardware(|hw, _| hw.motor.normal_force_ratio, "the motor table's normal force ratio");
        "", 1.0, POSITIVE, Stored since 4,
        "Normal force ratio of the stator (within 4x of the table's)", invalidates LEARNED_LOAD | LEARNED_MASS),
    (0x101E, "Motor", rail_coulomb_n: f32 = 0.0;
        "N", 1.0, Range::Float { lo: 0.0, hi: 100.0, lo_open: false }, Stored since 4,
        "Guide Coulomb friction of the carriage", invalidates LEARNED_LOAD | LEARNED_MASS),
    (0x101F, "Motor", rail_viscous_n_s_per_m: f32 = 0.0;
        "N per m/s", 1.0, Range::Float { lo: 0.0, hi: 10_000.0, lo_open: false }, Stored since 4,
        "Guide viscous friction of the carriage", invalidates LEARNED_LOAD | LEARNED_MASS),
    (0x1020, "Hardware", encoder_nm_per_count: u32 =
        hardware(|hw, _| hw.encoder_nm_per_count, "the encoder's resolution");
        "nm per count", 1.0, Range::Int { lo: 1, hi: 1_000_000 }, ReadOnly, "Encoder resolution"),
    (0x1021, "Hardware", loop_hz: u32 =
        hardware(|hw, _| hw.loop_hz, "the DAC rate over 20 samples per period");
        "Hz", 1.0, Range::Int { lo: 1, hi: u32::MAX as i64 }, ReadOnly, "Control loop rate"),
    // The controller chooses the drive frequency from here up to 0x1001, where its model (with the
    // moving mass) gives the highest speed against the load it expects; at or above 0x1001 the
    // drive frequency is fixed at 0x1001.
    (0x1022, "Drive", drive_freq_min_hz: f32 = hardware(|hw, _| hw.motor.lowest_model_freq_hz,
        "the motor table's lowest frequency where eq. 7 holds");
        "Hz", 1.0, POSITIVE, Stored since 5, "Lowest drive frequency the controller chooses"),
    // The coarse mode's encoder-loss watch (`controller/supervisor.rs`): 40 counts (2 µm at
    // 50 nm) is a tenth of the fine window's reach and 0.7 ms of the 1 kg carriage's cruise; a
    // slider the model misjudges by 2× still shows 20 counts. A stage whose model is further off
    // (or with a finer encoder) sets more; 0 leaves only the stall check.
    (0x1023, "Supervision", encoder_loss_counts: i32 = 40;
        "counts", 1.0, Range::Int { lo: 0, hi: i16::MAX as i64 }, Stored since 6,
        "Encoder loss limit under the coarse drive (0: off)"),
    // The model table's source (`controller/contact_build.rs`): the contact model is within 2 %
    // of the sourced plant on every carriage where the inertial model is 20-76 % off, and costs
    // the board a build of seconds in thread mode (docs/firmware.md); the inertial table serves
    // meanwhile. Off by default until the controller is tuned on the sourced motor.
    (0x1024, "Drive", contact_table: bool = false;
        "", 1.0, FLAG, Stored since 8, "Model table from the contact model (1) or the inertial model (0)"),
    // Limit switches (two inputs, one per end of travel): read only when enabled, a switch
    // active at this level. Off by default: a board with nothing on the pins reads their pulls.
    (0x1025, "Supervision", limit_switches_enabled: bool = false;
        "", 1.0, FLAG, Stored since 9, "Limit switches read (0 ignored, 1 read)"),
    (0x1026, "Supervision", limit_switch_active_high: bool = false;
        "", 1.0, FLAG, Stored since 9, "Limit switch active level (0 low, 1 high)"),
    // The identity clients see first (`*IDN?`); 0x1040 and up: the interface's settings.
    (0x1040, "Interface", idn_c867_compatible: bool = false;
        "", 1.0, FLAG, Stored since 7,
        "Identify as C-867 compatible in *IDN? (0 no, 1 yes: for EPICS motorPIGCS2)"),
    // PI's SERVO_UPDATE_TIME: PIPython's data recorder tools read it (`RTR` counts these).
    (0x0E000200, "Hardware",
        servo_update_time_s: f32 = derived(|c| 1.0 / c.loop_hz.max(1) as f32, "one period of the control loop");
        "s", 1.0, POSITIVE, ReadOnly, "Servo update time"),
    // PI's DATA_REC_SET_POINTS: PIPython's data recorder tools ask for it before `HDR?`.
    (0x16000201, "Recorder",
        recorder_points: u32 = derived(|_| crate::hardware::RECORDER_DEPTH as u32, "the recorder's table depth");
        "", 1.0, Range::Int { lo: 1, hi: u32::MAX as i64 }, ReadOnly, "Data recorder points per table"),
}

/// The setting with this GCS id.
pub fn find(id: i64) -> Option<&'static Setting> {
    SETTINGS.iter().find(|s| i64::from(s.id) == id)
}

/// What changing the settings `old` into `new` makes the controller forget: what the changed
/// rows invalidate, together.
pub fn invalidated(old: &ControllerConfig, new: &ControllerConfig) -> Invalidates {
    SETTINGS
        .iter()
        .filter(|s| s.invalidates != Invalidates::NOTHING && (s.get)(old) != (s.get)(new))
        .fold(Invalidates::NOTHING, |all, s| all.and(s.invalidates))
}

/// Sets every setting to its default for `hw`, row by row in table order (a row's hardware
/// default may read the rows before it).
pub fn apply_defaults(hw: &Hardware, c: &mut ControllerConfig) {
    for s in SETTINGS {
        match s.default {
            DefaultValue::Fixed(apply) => apply(c),
            DefaultValue::Hardware(_, apply) => apply(hw, c),
        }
    }
}

const fn ids_ascending() -> bool {
    let mut rest = SETTINGS;
    while let [a, b, ..] = rest {
        if a.id >= b.id {
            return false;
        }
        if let [_, tail @ ..] = rest {
            rest = tail;
        }
    }
    true
}
// The table is in id order (SPA?/HPA? list it so, find() relies on no duplicates).
const _: () = assert!(ids_ascending());
