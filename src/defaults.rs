//! The firmware's default settings: the prototype motor (baked table in [`crate::motor_table`])
//! on the reference board ([`REFERENCE_BOARD`]), with the fixed defaults of the settings table
//! ([`crate::settings::SETTINGS`]: controller gains tuned in host-sim against the plant). host-sim
//! derives its [`Hardware`] from a parameter file and a test checks that, for the prototype
//! file, it arrives at exactly these values.

use crate::controller::{ControllerConfig, DAC_SAMPLES_PER_STEP};
use crate::generator::DacConfig;
use crate::motor_table::PROTOTYPE_MOTOR;

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
    with_defaults(hw, ControllerConfig::default())
}

/// The defaults for `hw`, over `start`: the DAC and the motor table are the hardware's, every
/// other field takes its row's default. The result does not depend on `start` exactly when every
/// setting has a row (`tests/storage.rs` starts from zeros and from odd values).
#[doc(hidden)]
pub fn with_defaults(hw: &Hardware, start: ControllerConfig) -> ControllerConfig {
    let mut cfg = ControllerConfig { dac: hw.dac, motor: hw.motor, ..start };
    crate::settings::apply_defaults(hw, &mut cfg);
    cfg
}
