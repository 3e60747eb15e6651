//! The firmware's default settings: the prototype motor (baked table in [`crate::motor_table`])
//! on the reference board — 12-bit DAC at 200 kS/s into a 0–100 V amplifier, 50 nm encoder,
//! 12-bit force-cell word over 0–50 N — and controller gains tuned in host-sim against the plant.
//! host-sim derives its board from a parameter file and a test checks that, for the prototype
//! file, it arrives at exactly these values.

use crate::controller::{ControllerConfig, ReferenceSignal, DAC_SAMPLES_PER_STEP};
use crate::generator::DacConfig;
use crate::motor_table::PROTOTYPE_MOTOR;
use crate::sensors::PreloadCalibration;
use crate::Fx;

/// DAC sample rate of the drive (samples/s per channel).
pub const DAC_RATE_HZ: u32 = 200_000;
/// Control loop rate: one controller step per [`DAC_SAMPLES_PER_STEP`] DAC samples.
pub const LOOP_HZ: u32 = DAC_RATE_HZ / DAC_SAMPLES_PER_STEP as u32;
/// Drive frequency of the coarse mode (Hz): the top of the band gives the highest speed.
pub const DRIVE_FREQ_HZ: f32 = 2200.0;

/// Highest preload at which the drive still lifts the foot off at full voltage: above it the
/// foot never leaves the slider and the motor blocks (physics.md §2).
pub fn full_contact_preload_n(cfg: &ControllerConfig) -> f32 {
    cfg.motor
        .full_contact_preload_n(
            Fx::saturating_from_num(cfg.max_drive_v),
            Fx::saturating_from_num(cfg.drive_freq_hz / 1000.0),
        )
        .to_num()
}

/// Defaults for the reference board and the prototype motor.
pub fn controller_config() -> ControllerConfig {
    let mut cfg = ControllerConfig {
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
        preload: PreloadCalibration {
            zero_word: 0,
            newton_per_word: 50.0 / 4095.0,
            min_valid_word: 0,
            max_valid_word: 4095,
            filter_alpha: 0.01,
        },
        // Below about 3 N contact is unreliable (physics.md §2); the top is set below.
        preload_min_n: 3.0,
        preload_max_n: 0.0,
        drive_freq_hz: DRIVE_FREQ_HZ,
        max_drive_v: 100.0,
        speed_fraction: 0.92,
        accel_fraction: 0.8,
        kp_per_s: 40.0,
        ki_n_per_nm_s: 1e-3,
        feedforward: true,
        // Plain PI (feedforward off): full drive at 20 µm of error, integral time 10 ms.
        fb_kp_v_per_nm: 100.0 / 20_000.0,
        fb_ki_v_per_nm_s: 100.0 / 20_000.0 / 0.01,
        expected_load_n: 0.0,
        profile_wait_lag_nm: 2_000.0,
        approach_speed_nm_s: 200_000.0,
        fine_window_nm: 300.0,
        fine_gain: 0.5,
        on_target_window_nm: 50,
        settle_time_s: 0.01,
        following_error_limit_nm: 50_000.0,
        stall_time_s: 0.05,
        encoder_jump_counts: 200,
        travel_min_nm: -50_000_000,
        travel_max_nm: 50_000_000,
        // VEL/ACC/DEC: high enough that the thrust model's limits govern unless a user lowers them.
        velocity_max_nm_s: 10_000_000.0,
        accel_max_nm_s2: 1e9,
        decel_max_nm_s2: 1e9,
        reference_signal: ReferenceSignal::Index,
        reference_position_nm: 0,
        reference_drive_v: 50.0,
        reference_timeout_s: 200.0,
    };
    cfg.preload_max_n = full_contact_preload_n(&cfg);
    cfg
}
