//! When the drive frequency may change (issue 11): a frequency the model switched to during a
//! move goes on trial and is undone, for the rest of the move, when the slider falls behind and
//! slows down at it; a chosen frequency is kept until the load along the move has moved by a
//! share of the stall force. Which frequency is best is the model table's choice
//! (`frequency.rs`).

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
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct FrequencyTrial {
    /// The frequency left (Hz).
    from_hz: f32,
    /// The slider's speed along the move (nm/s) and its lag behind the reference (nm) then.
    speed_nm_s: f32,
    lag_nm: f32,
    age_s: f32,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct FrequencyPolicy {
    /// The profile's waiting lag (nm): a trial's lag allowance is a share of it.
    wait_lag_nm: f32,
    /// A frequency the model switched to during this move, on trial ...
    trial: Option<FrequencyTrial>,
    /// ... and the one the move went back to when the trial failed, kept to the move's end.
    pinned_hz: Option<f32>,
}

impl FrequencyPolicy {
    /// `wait_lag_nm`: the lag (nm) past which the profile waits for the slider.
    pub(super) fn new(wait_lag_nm: f32) -> Self {
        FrequencyPolicy { wait_lag_nm, trial: None, pinned_hz: None }
    }

    pub(super) fn configure(&mut self, wait_lag_nm: f32) {
        self.wait_lag_nm = wait_lag_nm;
    }

    /// A move starts: no trial, nothing pinned.
    pub(super) fn start_move(&mut self) {
        self.trial = None;
        self.pinned_hz = None;
    }

    /// The frequency a failed trial went back to, kept to the move's end.
    pub(super) fn pinned_hz(&self) -> Option<f32> {
        self.pinned_hz
    }

    /// The load the frequency is chosen for (N, opposing), from the estimate along +x: along the
    /// move's `sense` while moving (not the side of the target the slider is on: an overshoot at
    /// the end of a move must not flip the choice), either way otherwise.
    pub(super) fn choice_load_n(moving: bool, sense: f32, estimate_n: f32) -> f32 {
        if moving {
            (sense * estimate_n).max(0.0)
        } else {
            estimate_n.abs()
        }
    }

    /// Whether a table chosen for `chosen_for_n` (stall force `stall_n`) keeps its frequency for
    /// `load_n`: always between moves; while moving, until the load along the move has moved by
    /// [`RECHOOSE_LOAD_SHARE`] of the stall force (the observer learned an unknown load, or the
    /// move goes with the load), or for good once a trial failed.
    pub(super) fn keeps(&self, moving: bool, chosen_for_n: f32, stall_n: f32, load_n: f32) -> bool {
        !moving || self.pinned_hz.is_some() || (load_n - chosen_for_n).abs() <= RECHOOSE_LOAD_SHARE * stall_n
    }

    /// A table at `new_hz` is going in (from `old_hz`), the slider at `speed_nm_s` along the move
    /// and `lag_nm` behind: during a move, unless it undoes a failed switch, the new frequency
    /// goes on trial.
    pub(super) fn switched(&mut self, moving: bool, old_hz: f32, new_hz: f32, speed_nm_s: f32, lag_nm: f32) {
        if !moving || old_hz == new_hz || self.pinned_hz.is_some() {
            return;
        }
        self.trial = Some(FrequencyTrial { from_hz: old_hz, speed_nm_s, lag_nm, age_s: 0.0 });
    }

    /// One period of a trial: the trial once it has run its time (to be judged), else None.
    pub(super) fn matured_trial(&mut self, dt_s: f32) -> Option<FrequencyTrial> {
        let mut trial = self.trial?;
        trial.age_s += dt_s;
        if trial.age_s < TRIAL_S {
            self.trial = Some(trial);
            return None;
        }
        self.trial = None;
        Some(trial)
    }

    /// Judges a trial that has run its time, the slider now at `speed_nm_s` along the move and
    /// `lag_nm` behind: it fell behind and lost speed, so the move goes back to the frequency it
    /// left and keeps it to its end. True when it does. (At 10 N a 50 kg carriage against an
    /// unknown 2.48 N went from 2.2 to 1.2 kHz when its observer read 3.6 N; there the plant
    /// slows down and the move stalled.)
    pub(super) fn judge(
        &mut self,
        trial: &FrequencyTrial,
        moving: bool,
        speed_nm_s: f32,
        lag_nm: f32,
    ) -> bool {
        let behind = lag_nm - trial.lag_nm > TRIAL_LAG_SHARE * self.wait_lag_nm;
        let slower = speed_nm_s < (1.0 - TRIAL_SPEED_LOSS_SHARE) * trial.speed_nm_s;
        if moving && behind && slower {
            self.pinned_hz = Some(trial.from_hz);
        }
        self.pinned_hz.is_some()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const DT_S: f32 = 1e-4;

    fn policy() -> FrequencyPolicy {
        FrequencyPolicy::new(1000.0)
    }

    /// Periods until the trial matures (at most 1000) and the trial.
    fn run_trial(p: &mut FrequencyPolicy) -> (u32, FrequencyTrial) {
        for n in 1..=1000 {
            if let Some(t) = p.matured_trial(DT_S) {
                return (n, t);
            }
        }
        (0, FrequencyTrial { from_hz: 0.0, speed_nm_s: 0.0, lag_nm: 0.0, age_s: 0.0 })
    }

    #[test]
    fn a_switch_during_a_move_goes_on_trial_for_30_ms() {
        let mut p = policy();
        p.switched(false, 2200.0, 1200.0, 1e6, 100.0);
        assert_eq!(p.matured_trial(DT_S), None, "between moves: no trial");
        p.switched(true, 2200.0, 2200.0, 1e6, 100.0);
        assert_eq!(p.matured_trial(DT_S), None, "same frequency: no trial");
        p.switched(true, 2200.0, 1200.0, 1e6, 100.0);
        // 0.03 s at 0.1 ms: 300 periods (within one for the float sum).
        let (n, _) = run_trial(&mut p);
        assert!((299..=301).contains(&n), "{n}");
    }

    #[test]
    fn behind_and_slower_undoes_the_switch_for_the_move() {
        let mut p = policy();
        p.switched(true, 2200.0, 1200.0, 1e6, 100.0);
        let (_, t) = run_trial(&mut p);
        // 100 → 700 nm behind: 600 nm > half the 1000 nm waiting lag; 0.8 mm/s < 90 % of 1.
        assert!(p.judge(&t, true, 0.8e6, 700.0));
        assert_eq!(p.pinned_hz(), Some(2200.0));
        // Pinned: a later switch is no trial, and the frequency is kept whatever the load.
        p.switched(true, 1200.0, 2200.0, 1e6, 0.0);
        assert_eq!(p.matured_trial(DT_S), None);
        assert!(p.keeps(true, 0.0, 10.0, 9.0));
        p.start_move();
        assert_eq!(p.pinned_hz(), None);
    }

    #[test]
    fn keeping_up_keeps_the_switch() {
        for (speed, lag) in [(0.8e6, 500.0), (0.95e6, 700.0)] {
            let mut p = policy();
            p.switched(true, 2200.0, 1200.0, 1e6, 100.0);
            let (_, t) = run_trial(&mut p);
            assert!(!p.judge(&t, true, speed, lag), "{speed} {lag}");
        }
    }

    #[test]
    fn a_choice_holds_within_a_fifth_of_the_stall_force() {
        let p = policy();
        // Chosen for 1 N, stall 10 N: kept from −1 to 3 N while moving.
        assert!(p.keeps(true, 1.0, 10.0, 2.9));
        assert!(!p.keeps(true, 1.0, 10.0, 3.1));
        assert!(p.keeps(false, 1.0, 10.0, 9.0), "between moves always");
    }

    #[test]
    fn the_load_for_the_choice() {
        assert_eq!(FrequencyPolicy::choice_load_n(true, -1.0, -2.0), 2.0);
        assert_eq!(FrequencyPolicy::choice_load_n(true, 1.0, -2.0), 0.0, "assisting: no load");
        assert_eq!(FrequencyPolicy::choice_load_n(false, 1.0, -2.0), 2.0);
    }
}
