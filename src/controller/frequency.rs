//! The drive frequency: chosen with the model table, where the model with the carriage's moving
//! mass gives the highest full-drive speed against the load along the move (issue 11). A light
//! carriage rides the foot and runs faster at a lower frequency (0.05 kg: 0.41 mm/s at 1.2 kHz
//! against 0.23 at 2.2 kHz, the plant 0.41 and 0.27); a load near the top frequency's stall force
//! moves faster where the contact force is larger (5 kg against 4 N: stalled at 2.2 kHz, settles
//! at 1.2 kHz). The candidates run from `0x1022` (the motor table's lowest frequency where eq. 7
//! holds) up to `0x1001`; the request carries their per-volt amplitudes, and the table build picks
//! one before it builds ([`ModelRequest::chosen`]) off the tick.

use super::frequency_choice::FrequencyChoice;
use super::model_cache::{with_guide_friction, ModelRequest, ModelTable};
use super::{Controller, State};
use crate::fastmath::fx_from_f32;
use crate::inertia::Orbits;

/// A chosen frequency is kept while the load along the move stays within this share of the
/// stall force of the load it was chosen for (a new choice costs a dozen model evaluations off
/// the tick, and an observer learning an unknown load should not ask for one every few ms).
const RECHOOSE_LOAD_SHARE: f32 = 0.2;

/// How long a frequency the model switched to during a move is on trial (s) ...
const TRIAL_S: f32 = 0.03;
/// ... and how much further behind the reference (a share of the profile's waiting lag) the
/// slider may fall meanwhile, its speed down by over [`TRIAL_SPEED_LOSS_SHARE`], before the
/// switch is undone for the rest of the move.
const TRIAL_LAG_SHARE: f32 = 0.5;
const TRIAL_SPEED_LOSS_SHARE: f32 = 0.1;

/// A drive frequency switched to during a move, on trial: where the model's ranking and the
/// motor disagree (near the stall force, at low preload), the slider shows it within tens of ms.
#[derive(Debug, Clone, Copy)]
pub(super) struct FrequencyTrial {
    /// The frequency left (Hz).
    from_hz: f32,
    /// The slider's speed along the move (nm/s) and its lag behind the reference (nm) then.
    speed_nm_s: f32,
    lag_nm: f32,
    age_s: f32,
}

impl ModelRequest {
    /// This request at the candidate frequency where the model gives the highest speed at full
    /// drive against the choice's load (the carriage's periodic motion where its speed ripples,
    /// eq. 19 otherwise; net of the guide's friction); itself when there is no choice or no
    /// candidate moves against the load. Ties go to the higher frequency.
    pub fn chosen(&self) -> ModelRequest {
        let c = &self.choice;
        if c.len <= 1 {
            return *self;
        }
        let preload = fx_from_f32(self.preload_n);
        let top = fx_from_f32(self.max_drive_v.max(0.0));
        // Past the model's stall force at every candidate the model cannot rank them (each speed
        // is zero, or a root below it): the frequency of the request stays. At 5 N a 50 kg
        // carriage's observer read 1.95 N against the model's 1.75 N stall, the drive went from
        // 2.2 to 1.8 kHz, where the plant runs at a quarter of the speed, and the move tripped
        // the following-error limit.
        let mut best = (0.0, *self);
        for (&f, pv) in c.frequency_hz.iter().zip(c.per_volt.iter()).take(c.len) {
            let full = pv.point(preload, top);
            let orbits = Orbits::new(&full, f, self.moving_mass_kg);
            let speed = with_guide_friction(self, c.load_n.max(0.0), |foot_load| {
                if orbits.inertia_matters() {
                    orbits.mean_speed_mm_s(foot_load).unwrap_or(0.0)
                } else {
                    full.speed_at_load_near(fx_from_f32(foot_load), f32::NAN).to_num()
                }
            });
            if speed > best.0 {
                best = (speed, ModelRequest { per_volt: *pv, frequency_hz: f, ..*self });
            }
        }
        let mut chosen = best.1;
        chosen.choice = FrequencyChoice::fixed(chosen.frequency_hz, chosen.per_volt, c.load_n);
        chosen
    }
}

impl Controller {
    /// The load the frequency is chosen for (N, opposing): along the move while moving, either way
    /// otherwise.
    pub(super) fn choice_load_n(&self) -> f32 {
        if self.state() == State::Moving {
            // The move's sense, not the side of the target the slider is on: an overshoot at
            // the end of a move must not flip the choice.
            (self.load.move_sense() * self.load.estimate_n()).max(0.0)
        } else {
            self.load.estimate_n().abs()
        }
    }

    /// The slider's speed along the move (nm/s) and its lag behind the reference (nm).
    fn along_the_move(&self) -> (f32, f32) {
        let sense = self.load.move_sense();
        let lag = (self.profile.position_nm() - self.position_nm()) as f32 * sense;
        (sense * self.speed_nm_s, lag)
    }

    /// A table at `new_hz` is going in (from `old_hz`): during a move, unless it undoes a
    /// failed switch, the new frequency goes on trial.
    pub(super) fn frequency_switched(&mut self, old_hz: f32, new_hz: f32) {
        if self.state() != State::Moving || old_hz == new_hz || self.pinned_frequency_hz.is_some() {
            return;
        }
        let (speed_nm_s, lag_nm) = self.along_the_move();
        self.frequency_trial = Some(FrequencyTrial { from_hz: old_hz, speed_nm_s, lag_nm, age_s: 0.0 });
    }

    /// Judges a frequency on trial (every period of a move): the slider fell behind and lost
    /// speed at it, so the move goes back to the frequency it left and keeps it to its end.
    /// (At 10 N a 50 kg carriage against an unknown 2.48 N went from 2.2 to 1.2 kHz when its
    /// observer read 3.6 N; there the plant slows down and the move stalled.)
    pub(super) fn judge_frequency_trial(&mut self) {
        let Some(mut trial) = self.frequency_trial else { return };
        trial.age_s += self.dt_s;
        if trial.age_s < TRIAL_S {
            self.frequency_trial = Some(trial);
            return;
        }
        self.frequency_trial = None;
        let (speed, lag) = self.along_the_move();
        let behind = lag - trial.lag_nm > TRIAL_LAG_SHARE * self.cfg.profile_wait_lag_nm;
        let slower = speed < (1.0 - TRIAL_SPEED_LOSS_SHARE) * trial.speed_nm_s;
        if self.state() == State::Moving && behind && slower {
            self.pinned_frequency_hz = Some(trial.from_hz);
        }
    }

    /// Whether table `t` keeps its frequency for `load_n`: always between moves; while moving,
    /// until the load along the move has moved by [`RECHOOSE_LOAD_SHARE`] of the stall force (the
    /// observer learned an unknown load, or the move goes with the load). A table built during a
    /// move takes over within it: the generator changes frequency without a phase jump.
    pub(super) fn keeps_frequency(&self, t: &ModelTable, load_n: f32) -> bool {
        self.state() != State::Moving
            || self.pinned_frequency_hz.is_some()
            || (load_n - t.request().choice.load_n).abs() <= RECHOOSE_LOAD_SHARE * t.stall_n()
    }
}
