//! Parameters for `SPA`/`SPA?`/`HPA?`/`WPA`: the controller settings a user may read and change,
//! in GCS units (mm, mm/s, s, N, V, Hz). IDs 0x1–0x3F follow PI's numbering where PI has the
//! same meaning; 0x1001 and up are ours.

use crate::controller::{ControllerConfig, ReferenceSignal};

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
    pub fn name(self) -> &'static str {
        match self {
            Kind::Int => "INT",
            Kind::Float | Kind::Millimetre => "FLOAT",
        }
    }
}

pub struct Param {
    pub id: u32,
    pub kind: Kind,
    pub read_only: bool,
    /// Function group and description for `HPA?` (no `=`, no tab).
    pub group: &'static str,
    pub description: &'static str,
    pub get: fn(&ControllerConfig) -> f64,
    /// Stores the value; false when it cannot be represented (the range check of the whole
    /// configuration follows in [`crate::controller::validate_settings`]).
    pub set: fn(&mut ControllerConfig, f64) -> bool,
}

fn nm(mm: f64) -> Option<i64> {
    let x = mm * 1e6;
    let r = if x >= 0.0 { x + 0.5 } else { x - 0.5 };
    (x.is_finite() && r.abs() < 9.0e18).then_some(r as i64)
}
fn f32_of(v: f64) -> Option<f32> {
    let f = v as f32;
    f.is_finite().then_some(f)
}
fn u16_of(v: f64) -> Option<u16> {
    (v >= 0.0 && v <= f64::from(u16::MAX)).then_some(v as u16)
}
fn read_only(_: &mut ControllerConfig, _: f64) -> bool {
    false
}

macro_rules! float_param {
    ($id:expr, $group:expr, $desc:expr, |$c:ident| $get:expr, |$cm:ident, $v:ident| $set:expr) => {
        Param {
            id: $id,
            kind: Kind::Float,
            read_only: false,
            group: $group,
            description: $desc,
            get: |$c: &ControllerConfig| -> f64 { $get },
            set: |$cm: &mut ControllerConfig, $v: f64| -> bool { $set },
        }
    };
}

/// Sets an f32 field from a value times a factor.
macro_rules! f32_field {
    ($id:expr, $group:expr, $desc:expr, $($field:ident).+, $factor:expr) => {
        float_param!(
            $id,
            $group,
            $desc,
            // f32 division: hardware on the board; the value is an f32 anyway.
            |c| f64::from(c.$($field).+ / ($factor as f32)),
            |c, v| match f32_of(v * $factor) {
                Some(x) => {
                    c.$($field).+ = x;
                    true
                }
                None => false,
            }
        )
    };
}

/// Sets an i64 nanometre field from millimetres.
macro_rules! mm_field {
    ($id:expr, $group:expr, $desc:expr, $field:ident) => {
        Param {
            kind: Kind::Millimetre,
            ..float_param!($id, $group, $desc, |c| c.$field as f64 * 1e-6, |c, v| match nm(v) {
                Some(x) => {
                    c.$field = x;
                    true
                }
                None => false,
            })
        }
    };
}

macro_rules! u16_field {
    ($id:expr, $group:expr, $desc:expr, $($field:ident).+) => {
        Param {
            id: $id,
            kind: Kind::Int,
            read_only: false,
            group: $group,
            description: $desc,
            get: |c: &ControllerConfig| -> f64 { f64::from(c.$($field).+) },
            set: |c: &mut ControllerConfig, v: f64| -> bool {
                match u16_of(v) {
                    Some(x) => {
                        c.$($field).+ = x;
                        true
                    }
                    None => false,
                }
            },
        }
    };
}

pub static PARAMS: &[Param] = &[
    f32_field!(0x1, "Servo", "Position feedback gain (1/s)", kp_per_s, 1.0),
    f32_field!(0x2, "Servo", "Load integrator gain (N per nm*s)", ki_n_per_nm_s, 1.0),
    f32_field!(0x8, "Servo", "Maximum position error (mm)", following_error_limit_nm, 1e6),
    f32_field!(0xA, "Motion", "Maximum closed-loop velocity (mm/s)", velocity_max_nm_s, 1e6),
    f32_field!(0xB, "Motion", "Closed-loop acceleration (mm/s^2)", accel_max_nm_s2, 1e6),
    f32_field!(0xC, "Motion", "Closed-loop deceleration (mm/s^2)", decel_max_nm_s2, 1e6),
    mm_field!(0x15, "Motion", "Maximum travel in positive direction (mm)", travel_max_nm),
    mm_field!(0x30, "Motion", "Maximum travel in negative direction (mm)", travel_min_nm),
    mm_field!(0x36, "Servo", "Settling window (mm)", on_target_window_nm),
    f32_field!(0x3F, "Servo", "Settling time (s)", settle_time_s, 1.0),
    f32_field!(0x1001, "Drive", "Drive frequency of coarse motion (Hz)", drive_freq_hz, 1.0),
    f32_field!(0x1002, "Drive", "Maximum drive amplitude (V peak-to-peak)", max_drive_v, 1.0),
    f32_field!(0x1003, "Motion", "Share of the model no-load speed the profile uses", speed_fraction, 1.0),
    f32_field!(0x1004, "Motion", "Share of the model thrust the profile uses", accel_fraction, 1.0),
    Param {
        id: 0x1005,
        kind: Kind::Int,
        read_only: false,
        group: "Servo",
        description: "Thrust-model feedforward (1 on, 0 plain PI feedback)",
        get: |c| if c.feedforward { 1.0 } else { 0.0 },
        set: |c, v| {
            c.feedforward = v == 1.0;
            v == 0.0 || v == 1.0
        },
    },
    f32_field!(0x1006, "Servo", "Plain-feedback proportional gain (V per nm)", fb_kp_v_per_nm, 1.0),
    f32_field!(0x1007, "Servo", "Plain-feedback integral gain (V per nm*s)", fb_ki_v_per_nm_s, 1.0),
    f32_field!(0x1008, "Servo", "Expected load along +x (N)", expected_load_n, 1.0),
    f32_field!(
        0x1009,
        "Motion",
        "Lag at which the profile waits for the slider (mm)",
        profile_wait_lag_nm,
        1e6
    ),
    f32_field!(0x100A, "Motion", "Least final approach speed (mm/s)", approach_speed_nm_s, 1e6),
    f32_field!(0x100B, "Servo", "Fine-mode window (mm)", fine_window_nm, 1e6),
    f32_field!(0x100C, "Servo", "Fine-mode gain", fine_gain, 1.0),
    f32_field!(0x100D, "Supervision", "Stall detection time (s)", stall_time_s, 1.0),
    Param {
        id: 0x100E,
        kind: Kind::Int,
        read_only: false,
        group: "Supervision",
        description: "Encoder jump limit (counts per period)",
        get: |c| f64::from(c.encoder_jump_counts),
        set: |c, v| {
            let ok = (1.0..=f64::from(i32::MAX)).contains(&v);
            if ok {
                c.encoder_jump_counts = v as i32;
            }
            ok
        },
    },
    f32_field!(0x100F, "Preload", "Preload window minimum (N)", preload_min_n, 1.0),
    f32_field!(0x1010, "Preload", "Preload window maximum (N)", preload_max_n, 1.0),
    u16_field!(0x1011, "Preload", "Force cell zero word", preload.zero_word),
    f32_field!(0x1012, "Preload", "Force cell scale (N per word)", preload.newton_per_word, 1.0),
    u16_field!(0x1013, "Preload", "Force cell lowest valid word", preload.min_valid_word),
    u16_field!(0x1014, "Preload", "Force cell highest valid word", preload.max_valid_word),
    f32_field!(0x1015, "Preload", "Force cell filter coefficient per period", preload.filter_alpha, 1.0),
    Param {
        id: 0x1016,
        kind: Kind::Int,
        read_only: false,
        group: "Referencing",
        description: "Reference signal (0 encoder index, 1 negative limit switch)",
        get: |c| match c.reference_signal {
            ReferenceSignal::Index => 0.0,
            ReferenceSignal::NegativeLimit => 1.0,
        },
        set: |c, v| {
            if v == 0.0 {
                c.reference_signal = ReferenceSignal::Index;
            } else if v == 1.0 {
                c.reference_signal = ReferenceSignal::NegativeLimit;
            }
            v == 0.0 || v == 1.0
        },
    },
    mm_field!(0x1017, "Referencing", "Position given to the reference mark (mm)", reference_position_nm),
    f32_field!(0x1018, "Referencing", "Drive amplitude of the reference search (V)", reference_drive_v, 1.0),
    f32_field!(0x1019, "Referencing", "Reference search timeout (s)", reference_timeout_s, 1.0),
    Param {
        id: 0x1020,
        kind: Kind::Int,
        read_only: true,
        group: "Hardware",
        description: "Encoder resolution (nm per count)",
        get: |c| f64::from(c.encoder_nm_per_count),
        set: read_only,
    },
    Param {
        id: 0x1021,
        kind: Kind::Int,
        read_only: true,
        group: "Hardware",
        description: "Control loop rate (Hz)",
        get: |c| f64::from(c.loop_hz),
        set: read_only,
    },
];

pub fn find(id: i64) -> Option<&'static Param> {
    PARAMS.iter().find(|p| i64::from(p.id) == id)
}
