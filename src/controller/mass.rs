//! The carriage's moving mass as the controller uses it: the `0x101A` parameter, or more when a
//! move's speed-up shows a heavier carriage (a payload nobody told the controller about).
//!
//! Momentum: over the speed-up, ∫(F − L) dt = M·Δv, with F the thrust the model says the applied
//! drive gives at the measured speed and L the load estimate. Timed from the move's command until
//! the slider has half the profile's top speed; the speed filter's lag (it reports the speed of
//! [`super::supervision::SPEED_FILTER`]'s time constant ago) is taken off the impulse. Only a
//! speed-up long against that lag counts (two time constants: carriages of a few kg and more,
//! whose braking the mass limits; lighter ones brake within the drive-period spread anyway).
//! Only heavier than told counts: a mass overestimated brakes gently, one underestimated plans a
//! stop the carriage cannot make (the 50 kg carriage told 25 kg overshot 1 mm by 8.4 µm).
//!
//! Two readings of a measurement, against the learned mass (the told one until something is
//! learned; issue 11 item 3):
//! - Over 1.5× it is a payload, used for this move and until the next speed-up is timed.
//! - Within that, from a speed-up at least ten filter time constants long, it is the model's
//!   thrust error (a plant that pushes k× the model's thrust accelerates like a carriage 1/k as
//!   heavy, and so it brakes and takes the feedforward's M·a): the learned mass takes in half of
//!   it, is kept across moves, never falls below the told mass and is forgotten when the preload
//!   is more than 1 N from where it was learned. The model's thrust is taken at the filtered
//!   speed, which lags the slider's; the learning corrects that once at the end, for a
//!   stall-limited speed-up. A shorter speed-up reads heavy by itself (5 kg with μ right:
//!   5.8–6.1 kg), so it teaches nothing.

use super::{Controller, Mode, State};

/// A measured mass above this share of the learned one is a payload; below, it is the model's
/// thrust error (μ 15 % off moves the estimate by as much), learned only from long speed-ups.
const HEAVIER_SHARE: f32 = 1.5;
/// At most this many times the parameter (a speed-up disturbed by a load step must not make the
/// controller think the carriage tons).
const MOST_TIMES: f32 = 4.0;
/// A measurement within [`HEAVIER_SHARE`] of the learned mass moves it this share of the way.
const LEARN_SHARE: f32 = 0.5;
/// Only speed-ups this many filter time constants long teach the thrust error.
const LEARN_FILTER_TIMES: f32 = 10.0;
/// A learned mass holds within this much of the preload it was learned at (N).
const MASS_PRELOAD_SPAN_N: f32 = 1.0;
/// Speed-up shorter than this many speed-filter time constants: not timed.
const LEAST_FILTER_TIMES: f32 = 2.0;

/// A speed-up being timed: time since the command (s) and the impulse along the move (N·s).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct SpeedUp {
    t_s: f32,
    impulse_n_s: f32,
}

impl SpeedUp {
    pub(super) fn start() -> Self {
        SpeedUp { t_s: 0.0, impulse_n_s: 0.0 }
    }
}

impl Controller {
    /// The moving mass for braking, speeding up and the feedforward (kg).
    pub fn moving_mass_kg(&self) -> f32 {
        self.mass_kg.max(1e-3)
    }

    /// At a move's command: a mass learned at another preload is forgotten (what a long
    /// speed-up teaches beyond the told mass is the model's thrust error there, and that changes
    /// with the preload). A payload in use stays: it is mass, whatever the preload.
    pub(super) fn forget_mass_off_its_preload(&mut self, preload_n: f32) {
        let told = self.cfg.moving_mass_kg;
        if self.learned_mass_kg != told && (preload_n - self.mass_preload_n).abs() > MASS_PRELOAD_SPAN_N {
            if self.mass_kg == self.learned_mass_kg {
                self.mass_kg = told;
            }
            self.learned_mass_kg = told;
        }
    }

    /// Back to the told mass, learned and measured alike (a new mass parameter or calibration).
    pub(super) fn forget_mass(&mut self) {
        self.mass_kg = self.cfg.moving_mass_kg;
        self.learned_mass_kg = self.cfg.moving_mass_kg;
    }

    /// One period of the speed-up's timing: `thrust_x_n` is what the model says the drive gave
    /// along +x this period.
    pub(super) fn time_speedup(&mut self, thrust_x_n: f32) {
        let Some(mut s) = self.speedup else { return };
        let v = self.profile.velocity_nm_s();
        let braking = self.accel_ref_nm_s2 * v < 0.0;
        if self.state() != State::Moving || braking || !matches!(self.mode, Mode::Coarse) || v == 0.0 {
            self.speedup = None;
            return;
        }
        let sense = v.signum();
        let net_n = sense * (thrust_x_n - self.load.estimate_n());
        s.t_s += self.dt_s;
        s.impulse_n_s += net_n * self.dt_s;
        let half = 0.5 * self.speed_limit_nm_s();
        let along = sense * self.speed_nm_s;
        if half <= 0.0 || along < half {
            self.speedup = Some(s);
            return;
        }
        self.speedup = None;
        let lag_s = self.dt_s / super::supervision::SPEED_FILTER;
        if s.t_s < LEAST_FILTER_TIMES * lag_s {
            return;
        }
        let impulse = s.impulse_n_s - net_n * lag_s;
        let measured_kg = impulse / (along * 1e-9);
        let told = self.cfg.moving_mass_kg;
        let before = self.mass_kg;
        let learned = self.learned_mass_kg;
        let measured_kg = measured_kg.min(MOST_TIMES * told);
        self.mass_kg = if measured_kg > HEAVIER_SHARE * learned {
            measured_kg
        } else if s.t_s >= LEARN_FILTER_TIMES * lag_s {
            // The thrust was taken at the filtered speed, which lags the slider's, and the thrust
            // falls with speed: the impulse read high by ∫(F(v_f) − F(v)) dt ≈ −F′·∫(v − v_f) dt,
            // and for the first-order filter ∫(v − v_f) dt = τ·Δv_f. F′ is the full-drive line's
            // (a long speed-up is stall-limited), stall force over no-load speed, both cached:
            // no table lookup in the tick. Without this a right model taught the 50 kg carriage
            // 54.9 kg.
            let fall_n = self
                .model
                .table
                .as_ref()
                .map_or(0.0, |t| t.stall_n() * (along * 1e-6 / t.no_load_mm_s().max(1e-3)).min(1.0));
            let measured_kg = measured_kg - fall_n.max(0.0) * lag_s / (along * 1e-9);
            self.learned_mass_kg = (learned + LEARN_SHARE * (measured_kg - learned)).max(told);
            self.mass_preload_n = self.preload.force_n();
            self.learned_mass_kg
        } else {
            learned
        };
        if self.mass_kg > before {
            // The braking rate was set at the command from the lighter mass; the profile has not
            // begun to brake yet (checked above).
            self.decel_nm_s2 = self.decel_nm_s2.min(self.accel_limit_nm_s2());
        }
    }
}
