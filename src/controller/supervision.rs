//! Every period, before any control: read the sensors, then trip a fault (and so the safe
//! state) on an encoder jump, a preload outside its window or invalid, a following error above
//! its limit, or a stall.

use super::supervisor::ClosedLoopPeriod;
use super::{Activity, CommandError, Controller, FaultCode, Inputs, Mode, State};

impl Controller {
    pub(super) fn sense(&mut self, inputs: &Inputs) {
        if self.feedback.update(inputs.encoder_raw, inputs.preload_word, self.dt_s) {
            // The first reading: the encoder counts from 0 there.
            self.motion.profile_mut().reset(0);
        }
    }

    pub(super) fn supervise(&mut self) {
        if let State::Fault(_) = self.state() {
            return;
        }
        let active =
            matches!(self.state(), State::Moving | State::Holding | State::Referencing | State::OpenLoop);
        if let Some(e) = self.feedback.encoder() {
            if self.supervisor.encoder_jumped(e.last_delta()) {
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
        let coarse = matches!(self.status.mode, Mode::Coarse);
        let dir = f32::from(self.drive.generator.direction());
        let period = ClosedLoopPeriod {
            err_nm: (self.motion.profile().position_nm() - self.position_nm()) as f32,
            dir,
            speed_nm_s: self.feedback.speed_nm_s(),
            drive_v: self.drive.commanded_v,
            coarse,
            foot_speed_nm_s: self.cached_limits().map_or(0.0, |(_, v0)| v0 * 1e6),
            dt_s: self.dt_s,
            counted: self.feedback.encoder().is_some_and(|e| e.last_delta() != 0),
            swing_v: self.fine.sine_swing_v(self.drive.generator.amplitude_v()),
            mass_kg: self.moving_mass_kg(),
        };
        let table = self.model.table();
        let thrust_at = |swing_v: f32, speed_nm_s: f32| table.map(|t| t.thrust_n(swing_v, speed_nm_s * 1e-6));
        if let Some(code) = self.supervisor.update(&period, thrust_at) {
            self.trip(code);
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
        self.supervisor.note_fault();
        self.status.activity = Activity::Fault(code);
        self.status.servo = false;
        self.status.mode = Mode::Coarse;
        self.drive.generator.ramp_to_quiet();
    }
}
