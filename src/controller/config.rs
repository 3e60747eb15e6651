//! The controller's settings: what the board, the motor table and the user set. Each setting's
//! id, unit, range, default and storage are declared once, in [`crate::settings::SETTINGS`].

use super::fine::FineModeConfig;
use super::load_observer::LoadObserverConfig;
use super::plain_pi::PlainPiConfig;
use super::supervisor::SupervisorConfig;
use super::CommandError;
use crate::config::ControllerConfig;
use crate::fastmath::fx_from_f32;
use crate::model::PerVolt;
use crate::Fx;

/// How far a calibrated λ or ρ may stray from the motor table's: a factor of 4 either way. Beyond
/// that it is another motor, whose table must be regenerated, not scaled.
pub const CALIBRATION_RATIO_MAX: f32 = 4.0;

impl ControllerConfig {
    /// Calibrated over table λ and ρ: (tangential, normal); 1 when the table has none.
    pub fn calibration_ratios(&self) -> (f32, f32) {
        let ratio = |x: f32, t: f32| {
            if t > 0.0 {
                x / t
            } else {
                1.0
            }
        };
        (
            ratio(self.tangential_scale, self.motor.tangential_scale),
            ratio(self.normal_force_ratio, self.motor.normal_force_ratio),
        )
    }

    /// The per-volt amplitudes at the drive frequency for the calibrated motor: the table's,
    /// `kc·Yc` scaled by the ρ ratio, `ω·Xc` by the λ ratio (both linear, eqs. 1, 3 and 7; the
    /// table's interpolation commutes with the scaling), μ the calibrated one.
    pub fn per_volt(&self) -> PerVolt {
        self.per_volt_at(self.drive_freq_hz)
    }

    /// [`Self::per_volt`] at another drive frequency (Hz).
    pub fn per_volt_at(&self, frequency_hz: f32) -> PerVolt {
        let (tangential, normal) = self.calibration_ratios();
        let p = self.motor.at_frequency(fx_from_f32(frequency_hz / 1000.0));
        let scale = |x: Fx, r: f32| fx_from_f32(x.to_num::<f32>() * r);
        PerVolt {
            kc_yc_n_per_v: scale(p.kc_yc_n_per_v, normal),
            foot_speed_mm_s_per_v: scale(p.foot_speed_mm_s_per_v, tangential),
            mu: fx_from_f32(self.mu_dynamic),
            viscous_un_per_mm_s: p.viscous_un_per_mm_s,
        }
    }

    /// Control periods in `seconds` (rounded up; 0 for 0 or less): what a time setting counts
    /// to. The settings table bounds every time setting, so the count fits a u32 with room.
    pub fn ticks_for_s(&self, seconds: f32) -> u32 {
        let x = seconds * self.loop_hz as f32;
        // `as` saturates (and takes NaN to 0); one more where it truncated.
        let t = x as u32;
        if (t as f32) < x {
            t.saturating_add(1)
        } else {
            t
        }
    }

    /// The load observer's settings.
    pub(super) fn load_observer(&self) -> LoadObserverConfig {
        LoadObserverConfig {
            expected_load_n: self.expected_load_n,
            ki_n_per_nm_s: self.ki_n_per_nm_s,
            feedforward: self.feedforward,
        }
    }

    /// Plain feedback's gains and bound (feedforward off).
    pub(super) fn plain_pi(&self) -> PlainPiConfig {
        PlainPiConfig {
            kp_v_per_nm: self.fb_kp_v_per_nm,
            ki_v_per_nm_s: self.fb_ki_v_per_nm_s,
            max_v: self.max_drive_v,
        }
    }

    /// The supervisor's limits.
    pub(super) fn supervisor(&self) -> SupervisorConfig {
        SupervisorConfig {
            following_error_limit_nm: self.following_error_limit_nm,
            stall_ticks: self.ticks_for_s(self.stall_time_s),
            encoder_jump_counts: self.encoder_jump_counts,
            max_drive_v: self.max_drive_v,
            nm_per_count: self.encoder_nm_per_count as f32,
            loss_counts: self.encoder_loss_counts as f32,
        }
    }

    /// The fine mode's stroke (the largest common static offset that keeps both stacks in the
    /// DAC's range) and window.
    pub(super) fn fine_mode(&self) -> FineModeConfig {
        let d = &self.dac;
        FineModeConfig {
            room_v: (d.mid_v() - d.min_v).min(d.max_v - d.mid_v()),
            window_nm: self.fine_window_nm,
        }
    }

    /// Static foot displacement per volt of common offset (nm/V), for the calibrated λ.
    pub fn fine_nm_per_v(&self) -> f32 {
        self.motor.fine_nm_per_v.to_num::<f32>() * self.calibration_ratios().0
    }
}

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
        && c.drive_freq_min_hz >= d.min_freq_hz
        && c.drive_freq_min_hz <= d.max_freq_hz
        && c.max_drive_v <= d.max_v - d.min_v
        && c.reference_drive_v <= c.max_drive_v
        && c.preload_min_n < c.preload_max_n
        && c.travel_min_nm < c.travel_max_nm
        && calibration_fits_table(c)
        && p.newton_per_word != 0.0
        && p.min_valid_word < p.max_valid_word;
    if ok {
        Ok(())
    } else {
        Err(CommandError::InvalidValue)
    }
}

/// Whether the settings `new` may replace `old` at run time: what the hardware fixes (loop and
/// DAC rates, DAC range, encoder resolution, motor table) unchanged and the settings in range
/// together ([`validate_settings`]). The one check of a change: `SPA`, `VEL`/`ACC`/`DEC` and
/// `ConfigChange::prepare` use it.
pub fn validate_change(old: &ControllerConfig, new: &ControllerConfig) -> Result<(), CommandError> {
    if new.loop_hz != old.loop_hz
        || new.dac != old.dac
        || new.encoder_nm_per_count != old.encoder_nm_per_count
        || new.motor != old.motor
    {
        return Err(CommandError::InvalidValue);
    }
    validate_settings(new)
}

/// The calibration as a whole: λ and ρ within [`CALIBRATION_RATIO_MAX`] of the table's.
fn calibration_fits_table(c: &ControllerConfig) -> bool {
    let (t, n) = c.calibration_ratios();
    let lo = 1.0 / CALIBRATION_RATIO_MAX;
    (lo..=CALIBRATION_RATIO_MAX).contains(&t) && (lo..=CALIBRATION_RATIO_MAX).contains(&n)
}
