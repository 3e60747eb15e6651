//! The firmware's default settings: the prototype motor (baked table in [`crate::motor_table`])
//! on the reference board ([`REFERENCE_BOARD`]), with the fixed defaults of the settings table
//! ([`crate::settings::SETTINGS`]: controller gains tuned in host-sim against the plant). host-sim
//! derives its [`Hardware`] from a parameter file and a test checks that, for the prototype
//! file, it arrives at exactly these values.

use crate::controller::{ControllerConfig, ReferenceSignal, DAC_SAMPLES_PER_STEP};
use crate::generator::DacConfig;
use crate::motor_table::PROTOTYPE_MOTOR;
use crate::sensors::PreloadCalibration;

/// DAC sample rate of the drive (samples/s per channel).
pub const DAC_RATE_HZ: u32 = 200_000;
/// Control loop rate: one controller step per [`DAC_SAMPLES_PER_STEP`] DAC samples.
pub const LOOP_HZ: u32 = DAC_RATE_HZ / DAC_SAMPLES_PER_STEP as u32;

pub use crate::hardware::{full_contact_preload_n, Hardware};

/// The reference board with the prototype motor: 12-bit DAC at 200 kS/s into a 0–100 V
/// amplifier, 50 nm encoder, 12-bit force-cell word over 0–50 N.
pub const REFERENCE_BOARD: Hardware = Hardware {
    loop_hz: LOOP_HZ,
    dac: DacConfig {
        full_scale_v: 100.0,
        min_v: 0.0,
        max_v: 100.0,
        sample_rate_hz: DAC_RATE_HZ,
        min_freq_hz: 500.0,
        max_freq_hz: 2200.0,
        slew_v_per_sample: 0.5,
    },
    motor: PROTOTYPE_MOTOR,
    encoder_nm_per_count: 50,
    force_cell_newton_per_word: 50.0 / 4095.0,
    force_cell_max_word: 4095,
};

/// Defaults for the reference board and the prototype motor.
pub fn controller_config() -> ControllerConfig {
    controller_config_for(&REFERENCE_BOARD)
}

/// Defaults for `hw`: every setting's default from its row of [`crate::settings::SETTINGS`] (a
/// fixed value or one from the hardware).
pub fn controller_config_for(hw: &Hardware) -> ControllerConfig {
    with_defaults(hw, Unset::Zero)
}

/// What a setting holds before its default is applied (see [`with_defaults`]).
#[doc(hidden)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Unset {
    Zero,
    /// NaN, all-ones integers, true, the second choice.
    Odd,
}

/// The defaults for `hw`, starting from every setting at `unset`: the result does not depend
/// on `unset` exactly when every setting gets its default from the table or the hardware
/// (`tests/storage.rs` checks that).
#[doc(hidden)]
pub fn with_defaults(hw: &Hardware, unset: Unset) -> ControllerConfig {
    let odd = unset == Unset::Odd;
    let (f, w, n) = if odd { (f32::NAN, u16::MAX, -1i64) } else { (0.0, 0, 0) };
    let reference_signal = if odd { ReferenceSignal::NegativeLimit } else { ReferenceSignal::Index };
    // Rust needs every field for the struct; the settings' values come from their rows, the
    // rest is the hardware's.
    let mut cfg = ControllerConfig {
        loop_hz: n as u32,
        dac: hw.dac,
        motor: hw.motor,
        encoder_nm_per_count: n as u32,
        preload: PreloadCalibration {
            zero_word: w,
            newton_per_word: f,
            min_valid_word: w,
            max_valid_word: w,
            filter_alpha: f,
        },
        preload_min_n: f,
        preload_max_n: f,
        drive_freq_hz: f,
        max_drive_v: f,
        speed_fraction: f,
        accel_fraction: f,
        kp_per_s: f,
        ki_n_per_nm_s: f,
        feedforward: odd,
        fb_kp_v_per_nm: f,
        fb_ki_v_per_nm_s: f,
        expected_load_n: f,
        profile_wait_lag_nm: f,
        approach_speed_nm_s: f,
        fine_window_nm: f,
        on_target_window_nm: n,
        settle_time_s: f,
        following_error_limit_nm: f,
        stall_time_s: f,
        encoder_jump_counts: n as i32,
        travel_min_nm: n,
        travel_max_nm: n,
        velocity_max_nm_s: f,
        accel_max_nm_s2: f,
        decel_max_nm_s2: f,
        reference_signal,
        reference_position_nm: n,
        reference_drive_v: f,
        reference_timeout_s: f,
        moving_mass_kg: f,
        mu_dynamic: f,
        tangential_scale: f,
        normal_force_ratio: f,
        rail_coulomb_n: f,
        rail_viscous_n_s_per_m: f,
        drive_freq_min_hz: f,
    };
    crate::settings::apply_defaults(hw, &mut cfg);
    cfg
}
