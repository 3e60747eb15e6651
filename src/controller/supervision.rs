//! Every period, before any control: read the sensors, then trip a fault (and so the safe
//! state) on an encoder jump, a preload outside its window or invalid, a following error above
//! its limit, a stall, a lost encoder, or an open-loop drive that makes no progress.

use super::supervisor::{
    ClosedLoopPeriod, LOSS_MIN_DRIVE_SHARE, PROGRESS_COUNTS, PROGRESS_MAX_S, PROGRESS_MIN_S, PROGRESS_SLACK,
};
use super::{Activity, CommandError, Controller, FaultCode, Inputs, Mode, State};
use crate::fastmath::clamp_f32;

impl Controller {
    pub(super) fn sense(&mut self, inputs: &Inputs) {
        if self.feedback.update(inputs.encoder_raw, inputs.preload_word, self.dt_s) {
            // The first reading: the encoder counts from 0 there.
            self.motion.profile_mut().reset(0);
        }
    }

    pub(super) fn supervise(&mut self) {
        // The hysteresis band follows the slider in every state: the watches judge by it.
        let moved_nm = self.supervisor.track(self.position_nm());
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
            self.supervisor.progress.stop();
            return;
        }
        match self.check_preload() {
            Err(CommandError::PreloadInvalid) => return self.trip(FaultCode::PreloadSensor),
            Err(_) => return self.trip(FaultCode::PreloadOutOfWindow),
            Ok(_) => {}
        }
        if let Some((dir, volts)) = self.open_loop_drive() {
            // Open-loop motion: no reference to follow; the drive must make progress.
            return self.watch_progress(dir, volts);
        }
        self.supervisor.progress.stop();
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
            // Progress out of the band: a flicker between two counts is no count.
            counted: moved_nm != 0,
            flicked: moved_nm == 0 && self.feedback.encoder().is_some_and(|e| e.last_delta() != 0),
            swing_v: self.fine.sine_swing_v(self.drive.generator.amplitude_v()),
            mass_kg: self.moving_mass_kg(),
        };
        let table = self.model.table();
        let thrust_at = |swing_v: f32, speed_nm_s: f32| table.map(|t| t.thrust_n(swing_v, speed_nm_s * 1e-6));
        if let Some(code) = self.supervisor.update(&period, thrust_at) {
            self.trip(code);
        }
    }

    /// The open-loop drive of referencing or open-loop stepping: direction and amplitude (V
    /// peak-to-peak).
    fn open_loop_drive(&self) -> Option<(i8, f32)> {
        match self.status.activity {
            Activity::Referencing(search) => Some((search.direction(), self.cfg.reference_drive_v)),
            Activity::OpenLoop(run) => Some((run.direction, run.volts)),
            _ => None,
        }
    }

    /// The progress watch of an open-loop drive: [`FaultCode::NoProgress`] when a window passes
    /// without the slider gaining [`PROGRESS_COUNTS`] along the drive. Below the share of the
    /// largest drive the model is trusted at, not watched (the reference timeout and the
    /// run's length bound it).
    fn watch_progress(&mut self, dir: i8, volts: f32) {
        if volts < LOSS_MIN_DRIVE_SHARE * self.cfg.max_drive_v {
            self.supervisor.progress.stop();
            return;
        }
        let here = self.position_nm();
        if !self.supervisor.progress.judging(dir) {
            let window = self.progress_window_ticks(volts);
            self.supervisor.progress.start(dir, window, here);
        }
        let need = self.supervisor.progress_need_nm();
        if self.supervisor.progress.update(here, need) {
            self.trip(FaultCode::NoProgress);
        }
    }

    /// The progress watch's window for a drive (control periods): the time the model's no-load
    /// speed takes for [`PROGRESS_SLACK`] times the gain it asks, within [`PROGRESS_MIN_S`] …
    /// [`PROGRESS_MAX_S`]. The speed is the model table's at full drive (at the closed loop's
    /// frequency: cached, no model evaluation in the tick) scaled to the drive's amplitude (the
    /// foot's speed is linear in it, eq. 1); without a table the longest window. Asked once per
    /// run or turn.
    pub fn progress_window_ticks(&self, volts: f32) -> u32 {
        let full_nm_s = self.cached_limits().map_or(0.0, |(_, v0_mm_s)| v0_mm_s * 1e6);
        let speed_nm_s = full_nm_s * volts / self.cfg.max_drive_v;
        let need_nm = PROGRESS_COUNTS as f32 * self.cfg.encoder_nm_per_count as f32;
        // Not above 0 (no table, or NaN): the longest window.
        let window_s = if speed_nm_s > 0.0 { PROGRESS_SLACK * need_nm / speed_nm_s } else { PROGRESS_MAX_S };
        self.cfg.ticks_for_s(clamp_f32(window_s, PROGRESS_MIN_S, PROGRESS_MAX_S))
    }

    /// A fault found outside the core (the board's loop timing): the same safe state as a fault
    /// of the core's own (servo off, outputs ramped to mid-range, amplifier disabled in the
    /// outputs from this period on), latched until [`Self::clear_fault`]. An active fault stays
    /// (the first cause is the one reported).
    pub fn trip_external(&mut self, code: FaultCode) {
        if code == FaultCode::Overrun {
            // Counted also during a fault: the protocol reports every overrun.
            self.supervisor.note_overrun();
        }
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
