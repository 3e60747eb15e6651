//! The controller's settings: what the board, the motor table and the user set. Each setting's
//! id, unit, range, default and storage are declared once, in [`crate::settings::SETTINGS`].

use super::{CommandError, ReferenceSignal};
use crate::generator::DacConfig;
use crate::model::MotorConstants;
use crate::sensors::PreloadCalibration;

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ControllerConfig {
    pub loop_hz: u32,
    pub dac: DacConfig,
    pub motor: MotorConstants,
    pub encoder_nm_per_count: u32,
    pub preload: PreloadCalibration,
    /// Usable preload window (N): below it contact is unreliable, above it the motor blocks.
    pub preload_min_n: f32,
    pub preload_max_n: f32,
    /// Drive frequency for coarse motion (Hz).
    pub drive_freq_hz: f32,
    /// Largest peak-to-peak drive voltage the controller commands.
    pub max_drive_v: f32,
    /// Share of the model's no-load speed / stall acceleration the profile may use.
    pub speed_fraction: f32,
    pub accel_fraction: f32,
    /// Position → speed feedback gain (1/s).
    pub kp_per_s: f32,
    /// Load-estimate integrator gain (N per nm·s).
    pub ki_n_per_nm_s: f32,
    /// Thrust-model feedforward on; off leaves plain PI feedback from position error to volts.
    pub feedforward: bool,
    /// Plain-feedback gains (feedforward off): volts per nm of error and per nm·s.
    pub fb_kp_v_per_nm: f32,
    pub fb_ki_v_per_nm_s: f32,
    /// Known steady load the motor pushes against along +x (N; e.g. 2.0 for a 2 N weight pulling
    /// toward −x). The load observer starts from it and refines it while moving.
    pub expected_load_n: f32,
    /// Past this lag behind the profile the profile waits for the slider (nm).
    pub profile_wait_lag_nm: f32,
    /// Least speed command while approaching the target after the profile has ended (nm/s).
    pub approach_speed_nm_s: f32,
    /// Hand-off to the static fine mode within this distance of the target (nm).
    pub fine_window_nm: f32,
    /// On-target window and settle time (as PI's ONT?).
    pub on_target_window_nm: i64,
    pub settle_time_s: f32,
    pub following_error_limit_nm: f32,
    pub stall_time_s: f32,
    pub encoder_jump_counts: i32,
    pub travel_min_nm: i64,
    pub travel_max_nm: i64,
    /// Closed-loop speed, speed-up and braking limits (as PI's VEL, ACC, DEC). The profile uses
    /// the lower of these and what the thrust model allows at the measured preload.
    pub velocity_max_nm_s: f32,
    pub accel_max_nm_s2: f32,
    pub decel_max_nm_s2: f32,
    /// Referencing: the mark, the position it is given, the drive used to search for it and how
    /// long the search may take.
    pub reference_signal: ReferenceSignal,
    pub reference_position_nm: i64,
    pub reference_drive_v: f32,
    pub reference_timeout_s: f32,
    /// Moving mass of the carriage and its payload (kg): braking, speeding up and the load
    /// observer's inertia term, and the model table's periodic motion (`crate::inertia`).
    pub moving_mass_kg: f32,
}

/// Largest travel limit either way (1 m): positions stay far from i64 and f32 trouble.
pub const MAX_TRAVEL_NM: i64 = 1_000_000_000;

/// Checks the settings for values the controller can work with: each setting within its range
/// (declared in [`crate::settings::SETTINGS`]), and the rules that tie settings to each other or
/// to the hardware. The one validator: `SPA`, `VEL`/`ACC`/`DEC`, [`super::Controller::new`] and
/// the flash record ([`crate::storage`]) all use it.
pub fn validate_settings(c: &ControllerConfig) -> Result<(), CommandError> {
    let d = &c.dac;
    let p = &c.preload;
    let ok = crate::settings::each_in_range(c)
        && c.drive_freq_hz >= d.min_freq_hz
        && c.drive_freq_hz <= d.max_freq_hz
        && c.max_drive_v <= d.max_v - d.min_v
        && c.reference_drive_v <= c.max_drive_v
        && c.preload_min_n < c.preload_max_n
        && c.travel_min_nm < c.travel_max_nm
        && p.newton_per_word != 0.0
        && p.min_valid_word < p.max_valid_word;
    if ok {
        Ok(())
    } else {
        Err(CommandError::InvalidValue)
    }
}
