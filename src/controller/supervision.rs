//! Every period, before any control: read the sensors, then trip a fault (and so the safe
//! state) on an encoder jump, a preload outside its window or invalid, a following error above
//! its limit, or a stall.

use super::{Activity, CommandError, Controller, FaultCode, Inputs, Mode, State};
use crate::sensors::Encoder;

/// Share of each period's encoder speed taken into the speed estimate: a first-order filter of
/// 20 periods (2 ms at 10 kHz).
pub(super) const SPEED_FILTER: f32 = 0.05;

impl Controller {
    pub(super) fn sense(&mut self, inputs: &Inputs) {
        self.preload.update(inputs.preload_word);
        self.prev_speed_nm_s = self.speed_nm_s;
        match self.encoder.as_mut() {
            None => {
                self.encoder = Some(Encoder::new(inputs.encoder_raw, self.cfg.encoder_nm_per_count));
                self.profile.reset(0);
            }
            Some(e) => {
                let delta = e.update(inputs.encoder_raw);
                let v = delta as f32 * e.nm_per_count() as f32 / self.dt_s;
                // 2 ms speed filter: the encoder quantum (50 nm per 100 µs) is 0.5 mm/s.
                self.speed_nm_s += SPEED_FILTER * (v - self.speed_nm_s);
            }
        }
    }

    pub(super) fn supervise(&mut self) {
        if let State::Fault(_) = self.state() {
            return;
        }
        let active =
            matches!(self.state(), State::Moving | State::Holding | State::Referencing | State::OpenLoop);
        if let Some(e) = self.encoder {
            if e.last_delta().abs() > self.cfg.encoder_jump_counts {
                self.trip(FaultCode::EncoderJump);
                return;
            }
        }
        if !active {
            return;
        }
        match self.check_preload() {
            Err(CommandError::PreloadInvalid) => return self.trip(FaultCode::PreloadSensor),
            Err(_) => return self.trip(FaultCode::PreloadOutOfWindow),
            Ok(_) => {}
        }
        if matches!(self.state(), State::Referencing | State::OpenLoop) {
            // Open-loop motion: no reference to follow, no stall judgement.
            return;
        }
        // Stall/slip: the foot is driven near full but the slider does not move the driven way
        // (commanded foot speed against encoder speed). Near full: below it the controller still
        // has thrust to give, and a heavy carriage creeping up to its target against an unknown
        // load at half the drive is no stall (50 kg against 2 N, half its stall force, tripped at
        // 54 V with the threshold at 50 %; now it settles).
        let dir = f32::from(self.generator.direction());
        let driving = matches!(self.mode, Mode::Coarse) && self.drive_v > 0.9 * self.cfg.max_drive_v;
        let foot_speed = self.cached_limits().map_or(0.0, |(_, v0)| v0 * 1e6);
        let not_following = driving && dir * self.speed_nm_s < 0.1 * foot_speed;
        let err = (self.profile.position_nm() - self.position_nm()) as f32;
        self.max_following_error_nm = self.max_following_error_nm.max(err.abs());
        if err.abs() > self.cfg.following_error_limit_nm {
            // A light carriage under a load above the stall force is dragged back fast enough
            // to exceed the following error before the stall timer runs out: with the full
            // drive pushing towards the reference and the slider not going that way, the cause
            // is a stall.
            let full_drive_towards = self.drive_v >= 0.95 * self.cfg.max_drive_v && dir * err > 0.0;
            let code = if not_following && full_drive_towards {
                FaultCode::Stall
            } else {
                FaultCode::FollowingError
            };
            return self.trip(code);
        }
        if not_following {
            // Sliding backwards under full drive is the clearest sign: count it five times faster.
            // (only at full drive: below it the controller may still be finding the load).
            let backwards =
                dir * self.speed_nm_s < -0.1 * foot_speed && self.drive_v >= 0.95 * self.cfg.max_drive_v;
            self.stall_s += if backwards { 5.0 * self.dt_s } else { self.dt_s };
            if self.stall_s >= self.cfg.stall_time_s {
                self.trip(FaultCode::Stall);
            }
        } else {
            self.stall_s = 0.0;
        }
    }

    /// A fault found outside the core (the board's loop timing): the same safe state as a fault
    /// of the core's own (servo off, outputs ramped to mid-range, amplifier disabled in the
    /// outputs from this period on), latched until [`Self::clear_fault`]. An active fault stays
    /// (the first cause is the one reported).
    pub fn trip_external(&mut self, code: FaultCode) {
        if !matches!(self.state(), State::Fault(_)) {
            self.trip(code);
        }
    }

    pub(super) fn trip(&mut self, code: FaultCode) {
        self.faults = self.faults.wrapping_add(1);
        self.activity = Activity::Fault(code);
        self.servo = false;
        self.mode = Mode::Coarse;
        self.generator.ramp_to_quiet();
    }
}
