//! The commands a host gives (GCS `SVO`, `MOV`, `MVR`, `HLT`, `STP`, `XOS`, `FRF`, `SPA`…):
//! each checks what it needs and sets the state the next [`Controller::step`] acts on.

use super::model_cache::TableSettings;
use super::open_loop::OpenLoopRun;
use super::referencing::ReferenceSearch;
use super::{validate_change, Activity, CommandError, Controller, ControllerConfig, Mode, State};
use crate::model::PerVolt;
use crate::settings::Invalidates;

impl Controller {
    /// Replaces the settings after checking them. What the hardware fixes (loop and DAC rates,
    /// DAC range, encoder resolution, motor table) cannot change at run time.
    pub fn set_config(&mut self, cfg: ControllerConfig) -> Result<(), CommandError> {
        let change = ConfigChange::prepare(&self.cfg, self.model.generation, cfg)?;
        self.apply_config(&change)
    }

    /// The settings' generation: bumped by every accepted settings change (a [`ConfigChange`]
    /// prepared from an older one is refused).
    pub fn config_generation(&self) -> u32 {
        self.model.generation
    }

    /// Takes a settings change prepared off the lock ([`ConfigChange::prepare`]): what is left
    /// is copying it in. Refused (`Busy`) when the settings changed since it was prepared.
    pub fn apply_config(&mut self, change: &ConfigChange) -> Result<(), CommandError> {
        if change.from_generation != self.model.generation {
            return Err(CommandError::Busy);
        }
        let cfg = &change.cfg;
        self.load.configure(cfg.load_observer(), change.forget_load);
        self.pi.configure(cfg.plain_pi());
        self.supervisor.configure(cfg.supervisor());
        self.fine.configure(cfg.fine_mode());
        self.frequency.configure(cfg.profile_wait_lag_nm);
        self.feedback.configure(cfg.preload);
        // What the speed-ups measured stays through a speed or limit change (`VEL`, `ACC`, …),
        // not through a new mass or calibration (the rows' `invalidates`).
        self.mass.configure(cfg.moving_mass_kg, change.forget_mass);
        self.cfg = *cfg;
        self.model.reconfigure_with(change.per_volt, change.fine_nm_per_v, change.table_changed);
        Ok(())
    }

    pub fn set_servo(&mut self, on: bool) -> Result<(), CommandError> {
        if let State::Fault(code) = self.state() {
            return Err(CommandError::Faulted(code));
        }
        if on {
            self.check_preload()?;
        }
        self.status.servo = on;
        if on {
            self.fine.forget_misses();
            if let Mode::Fine(f) = &mut self.status.mode {
                f.forget_check();
            }
            let here = self.position_nm();
            self.motion.profile_mut().reset(here);
            self.enter_hold();
        } else {
            self.status.activity = Activity::Idle;
            self.drive.generator.ramp_to_quiet();
        }
        Ok(())
    }

    pub fn move_to(&mut self, target_nm: i64) -> Result<(), CommandError> {
        if let State::Fault(code) = self.state() {
            return Err(CommandError::Faulted(code));
        }
        if self.state() == State::Referencing {
            return Err(CommandError::Busy);
        }
        if !self.status.servo {
            return Err(CommandError::ServoOff);
        }
        if target_nm < self.cfg.travel_min_nm || target_nm > self.cfg.travel_max_nm {
            return Err(CommandError::OutOfTravel);
        }
        let preload_n = self.check_preload()?;
        self.mass.start_move(preload_n);
        self.load.start_move(target_nm < self.position_nm());
        self.motion.profile_mut().set_target(target_nm);
        // The braking rate is fixed for the whole move: a braking curve that changed under the
        // profile's feet would arrive with speed left over. Without a model table yet it is 0,
        // and the first table sets it (`regulate`).
        let decel = self.accel_limit_nm_s2();
        self.motion.set_decel_nm_s2(decel);
        self.frequency.start_move();
        self.supervisor.start_move();
        self.motion.restart_on_target();
        self.status.activity = Activity::Moving;
        let to_target = (target_nm - self.position_nm()) as f32;
        if !matches!(self.status.mode, Mode::Coarse) && to_target.abs() > self.cfg.fine_window_nm {
            self.status.mode = Mode::Coarse;
        } else if matches!(self.status.mode, Mode::Coarse)
            && self.drive.generator.amplitude_v() == 0.0
            && self.fine_takes(to_target)
        {
            // A small move with the sine quiet (a hold just after the servo came on) is the
            // fine mode's: in the coarse mode a drive period carries a 0.1 kg carriage 300 nm,
            // and its 100 nm step from there overshot 268 nm.
            self.status.mode = Mode::FineEntering;
        }
        Ok(())
    }

    pub fn move_relative(&mut self, delta_nm: i64) -> Result<(), CommandError> {
        self.move_to(self.motion.profile().target_nm().saturating_add(delta_nm))
    }

    /// Smooth stop: decelerate along the profile and hold where it ends. Referencing and
    /// open-loop stepping stop at once.
    pub fn halt(&mut self) {
        match self.state() {
            State::Moving => self.brake_to_a_stop(self.accel_limit_nm_s2()),
            State::Referencing | State::OpenLoop => self.stop(),
            _ => {}
        }
    }

    /// Stop as fast as the motor can (PI's STP): a closed-loop move brakes along the profile at
    /// the model's braking rate, whatever the deceleration limit says — the slider's inertia
    /// makes a stop on the spot impossible, and a reference that stopped dead would only build
    /// up following error. Referencing and open-loop stepping end at once: hold there (servo on)
    /// or go quiet (servo off).
    pub fn stop(&mut self) {
        if self.state() == State::Moving {
            let a = self.model_brake_nm_s2();
            self.brake_to_a_stop(a);
            if a > 0.0 {
                self.motion.set_decel_nm_s2(a);
            }
            return;
        }
        if matches!(self.state(), State::Holding | State::Referencing | State::OpenLoop) {
            self.hold_here_or_quiet();
        }
    }

    /// The profile brakes at `rate_nm_s2` to where that stops it. In the period after a setting
    /// change there is no model table and the model's rate is 0: the move's own braking rate
    /// then, and with none either (the move has not started) the reference stops where the slider
    /// is. A rate of 0 put the stopping point kilometres away, and the slider ran on to the end
    /// of travel.
    fn brake_to_a_stop(&mut self, rate_nm_s2: f32) {
        let a = if rate_nm_s2 > 0.0 { rate_nm_s2 } else { self.motion.decel_nm_s2() };
        if a > 0.0 {
            let p = self.motion.profile().stopping_point_nm(a);
            self.motion.profile_mut().set_target(p);
        } else {
            self.hold_here_or_quiet();
        }
    }

    /// Open-loop stepping with the servo off: `cycles` drive periods (the sign gives the
    /// direction) at `amplitude_v` peak-to-peak and `frequency_hz`, then quiet.
    pub fn open_loop_step(
        &mut self,
        cycles: i32,
        amplitude_v: f32,
        frequency_hz: f32,
    ) -> Result<(), CommandError> {
        if let State::Fault(code) = self.state() {
            return Err(CommandError::Faulted(code));
        }
        if self.status.servo {
            return Err(CommandError::ServoOn);
        }
        if self.state() == State::Referencing {
            return Err(CommandError::Busy);
        }
        let d = &self.cfg.dac;
        let amplitude_ok =
            amplitude_v.is_finite() && amplitude_v >= 0.0 && amplitude_v <= self.cfg.max_drive_v;
        let freq_ok =
            frequency_hz.is_finite() && frequency_hz >= d.min_freq_hz && frequency_hz <= d.max_freq_hz;
        if !amplitude_ok || !freq_ok || cycles == 0 {
            return Err(CommandError::InvalidValue);
        }
        self.check_preload()?;
        // Periods of the control loop that hold `cycles` drive periods, rounded to nearest.
        let periods =
            f64::from(cycles.unsigned_abs()) * f64::from(self.cfg.loop_hz) / f64::from(frequency_hz);
        let run = OpenLoopRun {
            periods: (periods + 0.5).min(f64::from(u32::MAX)) as u32,
            volts: amplitude_v,
            frequency_hz,
            direction: if cycles > 0 { 1 } else { -1 },
        };
        self.status.mode = Mode::Coarse;
        self.status.activity = Activity::OpenLoop(run);
        self.supervisor.start_run();
        Ok(())
    }

    pub fn clear_fault(&mut self) {
        if matches!(self.state(), State::Fault(_)) {
            self.status.activity = Activity::Idle;
            self.status.servo = false;
            let here = self.position_nm();
            self.motion.profile_mut().reset(here);
        }
    }

    /// Declares the present position to be `position_nm` (referencing on a mark).
    pub fn set_reference_here(&mut self, position_nm: i64) {
        self.feedback.set_position_nm(position_nm);
        let here = self.position_nm();
        self.motion.profile_mut().reset(here);
        self.status.referenced = true;
    }

    /// Moves open loop toward negative positions until the encoder index is seen, then sets the
    /// position there to zero.
    ///
    /// With [`ReferenceSignal::Index`] the search turns round at the negative limit switch and,
    /// finding no index up to the positive one, references on the negative switch after all;
    /// with [`ReferenceSignal::NegativeLimit`] the switch is the mark.
    /// The mark's position becomes `reference_position_nm`. Afterwards the controller holds there
    /// (servo on) or goes quiet (servo off). A search that runs out of time or switches fails:
    /// not referenced, [`Self::reference_failure_count`] counts it.
    pub fn start_referencing(&mut self) -> Result<(), CommandError> {
        if let State::Fault(code) = self.state() {
            return Err(CommandError::Faulted(code));
        }
        self.check_preload()?;
        self.status.activity = Activity::Referencing(ReferenceSearch::start());
        self.status.mode = Mode::Coarse;
        self.status.referenced = false;
        Ok(())
    }
}

/// A settings change, checked and with what it derives computed, from the settings it replaces:
/// all of [`Controller::set_config`]'s work that does not need the controller itself, so that a
/// board can do it without holding the control tick off ([`Controller::apply_config`] is the
/// rest).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ConfigChange {
    cfg: ControllerConfig,
    per_volt: PerVolt,
    fine_nm_per_v: f32,
    /// A changed setting invalidates the learned load ([`Invalidates::LEARNED_LOAD`]).
    forget_load: bool,
    /// A changed setting invalidates the learned mass ([`Invalidates::LEARNED_MASS`]).
    forget_mass: bool,
    /// A changed setting enters the model table ([`TableSettings`]).
    table_changed: bool,
    /// The generation of the settings it replaces.
    from_generation: u32,
}

impl ConfigChange {
    /// `cfg` in place of `current` (of settings generation `generation`): refused if it changes
    /// what is fixed by the board (loop rate, DAC, encoder, motor table) or fails the range checks.
    pub fn prepare(
        current: &ControllerConfig,
        generation: u32,
        cfg: ControllerConfig,
    ) -> Result<Self, CommandError> {
        validate_change(current, &cfg)?;
        let forgets = crate::settings::invalidated(current, &cfg);
        Ok(ConfigChange {
            per_volt: cfg.per_volt(),
            fine_nm_per_v: cfg.fine_nm_per_v(),
            forget_load: forgets.contains(Invalidates::LEARNED_LOAD),
            forget_mass: forgets.contains(Invalidates::LEARNED_MASS),
            table_changed: TableSettings::of(current) != TableSettings::of(&cfg),
            from_generation: generation,
            cfg,
        })
    }
}
