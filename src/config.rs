//! The controller's settings as one struct: what the board, the motor table and the user set.
//! Each setting's id, unit, range, default and storage are declared once, in the settings table
//! (`SETTINGS` in settings.rs); the controller cuts each of its parts' settings from it. Kept
//! below both, so that the table can name the fields and the controller can read the table.

use crate::generator::DacConfig;
use crate::model::MotorConstants;
use crate::sensors::PreloadCalibration;

#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ControllerConfig {
    pub loop_hz: u32,
    pub dac: DacConfig,
    pub motor: MotorConstants,
    pub encoder_nm_per_count: u32,
    pub preload: PreloadCalibration,
    /// Usable preload window (N): below it contact is unreliable, above it the motor blocks.
    pub preload_min_n: f32,
    pub preload_max_n: f32,
    /// Highest drive frequency for coarse motion (Hz).
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
    /// How far the model's carriage may run under the coarse drive with the encoder silent before
    /// that is encoder loss (counts; 0: not watched).
    pub encoder_loss_counts: i32,
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
    /// The motor as calibrated (the model-gap workflow's fitted values, uploaded with `SPA`): the
    /// sliding friction coefficient μd, the stator's tangential scale λ (eq. 1) and normal force
    /// ratio ρ (eq. 3). The motor table was computed for its own λ and ρ
    /// ([`MotorConstants::tangential_scale`]) and is scaled by the ratios ([`Self::per_volt`]).
    pub mu_dynamic: f32,
    pub tangential_scale: f32,
    pub normal_force_ratio: f32,
    /// Guide friction of the carriage (the `rail_friction` effect): Coulomb and viscous, opposing
    /// the slider's motion. The model table takes it off the foot's thrust.
    pub rail_coulomb_n: f32,
    pub rail_viscous_n_s_per_m: f32,
    /// Lowest drive frequency the controller chooses (Hz): it drives, between this and
    /// [`Self::drive_freq_hz`], where its model with the moving mass gives the highest speed
    /// against the expected load (the controller's model cache). At or above
    /// `drive_freq_hz` the frequency is fixed there.
    pub drive_freq_min_hz: f32,
    /// `*IDN?` names the board "PD-SB1 (C-867 compatible)" instead of "PD-SB1": clients that
    /// pick their driver by PI's model name (EPICS motorPIGCS2) then take it for the PI motor
    /// controller whose command set it answers. Off by default: the identity stays our own.
    pub idn_c867_compatible: bool,
    /// The model table from the contact model (the stator's normal motion, the carriage's orbit
    /// on its friction layer) instead of the inertial model; the inertial table serves until the
    /// contact table is built.
    pub contact_table: bool,
    /// Limit switches: whether the board reads them, and the level (high or low) at which a
    /// switch is active.
    pub limit_switches_enabled: bool,
    pub limit_switch_active_high: bool,
}

/// What referencing looks for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ReferenceSignal {
    /// The encoder index if the scale has one: searched toward −x first; at the negative limit
    /// switch the search turns round; reaching the positive one means there is no index, and
    /// the search goes back to reference on the negative limit switch.
    #[default]
    Index,
    /// The negative limit switch (stages without an index).
    NegativeLimit,
}

/// Largest travel limit either way (1 m): positions stay far from i64 and f32 trouble.
pub const MAX_TRAVEL_NM: i64 = 1_000_000_000;
