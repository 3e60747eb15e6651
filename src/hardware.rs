//! The hardware a firmware build is for, as the settings table reads it (a leaf: the settings'
//! rows take their hardware defaults from it, and [`crate::defaults`] builds on both).

use crate::config::ControllerConfig;
use crate::generator::DacConfig;
use crate::model::MotorConstants;
use crate::Fx;

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

/// Points per data-recorder table the firmware's RAM holds (PI's controllers record at least
/// 1 024; the settings table reports it as `DATA_REC_SET_POINTS`, the recorder sizes by it).
pub const RECORDER_DEPTH: usize = 1024;

/// What the defaults depend on besides the settings table: the hardware the firmware is built
/// for (host-sim derives one from a parameter file). The rows that take their default from it
/// say how (`hardware(..)` in [`crate::settings::SETTINGS`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hardware {
    /// Control loop rate: one controller step per `DAC_SAMPLES_PER_STEP` (the controller's) DAC samples.
    pub loop_hz: u32,
    /// DAC and amplifier: output range, sample rate, drive band, slew limit.
    pub dac: DacConfig,
    /// The motor table.
    pub motor: MotorConstants,
    pub encoder_nm_per_count: u32,
    /// Force cell: newtons per ADC word and the full-scale word.
    pub force_cell_newton_per_word: f32,
    pub force_cell_max_word: u16,
}
