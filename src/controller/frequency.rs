//! The drive frequency: chosen with the model table, where the model with the carriage's moving
//! mass gives the highest full-drive speed against the load along the move (issue 11). A light
//! carriage rides the foot and runs faster at a lower frequency (0.05 kg: 0.41 mm/s at 1.2 kHz
//! against 0.23 at 2.2 kHz, the plant 0.41 and 0.27); a load near the top frequency's stall force
//! moves faster where the contact force is larger (5 kg against 4 N: stalled at 2.2 kHz, settles
//! at 1.2 kHz). The candidates run from `0x1022` (the motor table's lowest frequency where eq. 7
//! holds) up to `0x1001`; the request carries their per-volt amplitudes, and the table build picks
//! one before it builds ([`ModelRequest::chosen`]) off the tick.

use super::frequency_choice::FrequencyChoice;
use super::frequency_policy::FrequencyPolicy;
use super::model_cache::{with_guide_friction, ModelRequest, ModelTable};
use super::{Controller, State};
use crate::fastmath::fx_from_f32;
use crate::inertia::Orbits;

impl ModelRequest {
    /// This request at the candidate frequency where the model gives the highest speed at full
    /// drive against the choice's load (the carriage's periodic motion where its speed ripples,
    /// eq. 19 otherwise; net of the guide's friction); itself when there is no choice or no
    /// candidate moves against the load. Ties go to the higher frequency.
    pub fn chosen(&self) -> ModelRequest {
        if self.choice.len <= 1 {
            return *self;
        }
        let mut best = (0.0, *self);
        for i in 0..self.choice.len {
            self.rank_candidate(i, &mut best);
        }
        self.with_choice_made(best)
    }

    /// Candidate `i`'s speed at full drive against the choice's load; it becomes `best` (the
    /// fastest so far, and its request) when faster. Past the model's stall force at every
    /// candidate the model cannot rank them (each speed is zero, or a root below it): the
    /// frequency of the request stays. At 5 N a 50 kg carriage's observer read 1.95 N against the
    /// model's 1.75 N stall, the drive went from 2.2 to 1.8 kHz, where the plant runs at a quarter
    /// of the speed, and the move tripped the following-error limit.
    pub(super) fn rank_candidate(&self, i: usize, best: &mut (f32, ModelRequest)) {
        let c = &self.choice;
        let (Some(&f), Some(pv)) = (c.frequency_hz.get(i), c.per_volt.get(i)) else { return };
        let full = pv.point(fx_from_f32(self.preload_n), fx_from_f32(self.max_drive_v.max(0.0)));
        let orbits = Orbits::new(&full, f, self.moving_mass_kg);
        let speed = with_guide_friction(self, c.load_n.max(0.0), |foot_load| {
            if orbits.inertia_matters() {
                orbits.mean_speed_mm_s(foot_load).unwrap_or(0.0)
            } else {
                full.speed_at_load_near(fx_from_f32(foot_load), f32::NAN).to_num()
            }
        });
        if speed > best.0 {
            *best = (speed, ModelRequest { per_volt: *pv, frequency_hz: f, ..*self });
        }
    }

    /// [`Self::chosen`] by another model of the carriage: `speed_at(candidate)`, the speed
    /// (mm/s) at full drive against the choice's load at the candidate request's frequency (net
    /// of the guide's friction, as the candidate's own model would give it). For hosts that
    /// build tables from another model ([`ModelTable::from_speed_law`]).
    pub fn chosen_with(&self, mut speed_at: impl FnMut(&ModelRequest) -> f32) -> ModelRequest {
        if self.choice.len <= 1 {
            return *self;
        }
        let c = &self.choice;
        let mut best = (0.0, *self);
        for (&f, pv) in c.frequency_hz.iter().zip(&c.per_volt).take(c.len) {
            let candidate = ModelRequest { per_volt: *pv, frequency_hz: f, ..*self };
            let speed = speed_at(&candidate);
            if speed > best.0 {
                best = (speed, candidate);
            }
        }
        self.with_choice_made(best)
    }

    /// The request the choice's `best` makes (itself without a choice), its choice fixed there.
    pub(super) fn with_choice_made(&self, best: (f32, ModelRequest)) -> ModelRequest {
        if self.choice.len <= 1 {
            return *self;
        }
        let mut chosen = best.1;
        chosen.choice = FrequencyChoice::fixed(chosen.frequency_hz, chosen.per_volt, self.choice.load_n);
        chosen
    }
}

impl Controller {
    /// The load the frequency is chosen for (N, opposing): along the move while moving, either way
    /// otherwise.
    pub(super) fn choice_load_n(&self) -> f32 {
        let moving = self.state() == State::Moving;
        FrequencyPolicy::choice_load_n(moving, self.load.move_sense(), self.load.estimate_n())
    }

    /// The slider's speed along the move (nm/s) and its lag behind the reference (nm).
    fn along_the_move(&self) -> (f32, f32) {
        let sense = self.load.move_sense();
        let lag = (self.motion.profile().position_nm() - self.position_nm()) as f32 * sense;
        (sense * self.feedback.speed_nm_s(), lag)
    }

    /// A table at `new_hz` is going in (from `old_hz`): during a move it may go on trial.
    pub(super) fn frequency_switched(&mut self, old_hz: f32, new_hz: f32) {
        let moving = self.state() == State::Moving;
        let (speed_nm_s, lag_nm) = self.along_the_move();
        self.frequency.switched(moving, old_hz, new_hz, speed_nm_s, lag_nm);
    }

    /// Judges a frequency on trial once it has run its time (every period of a move).
    pub(super) fn judge_frequency_trial(&mut self) {
        let Some(trial) = self.frequency.matured_trial(self.dt_s) else { return };
        let (speed, lag) = self.along_the_move();
        let moving = self.state() == State::Moving;
        self.frequency.judge(&trial, moving, speed, lag);
    }

    /// Whether table `t` keeps its frequency for `load_n` ([`FrequencyPolicy::keeps`]). A table
    /// built during a move takes over within it: the generator changes frequency without a phase
    /// jump.
    pub(super) fn keeps_frequency(&self, t: &ModelTable, load_n: f32) -> bool {
        let moving = self.state() == State::Moving;
        self.frequency.keeps(moving, t.request().choice.load_n, t.stall_n(), load_n)
    }
}
