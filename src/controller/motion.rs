//! The reference the closed loop follows: the trapezoidal profile, the acceleration the
//! feedforward counts as M·a, the move's braking rate, the time on target, and the speed-up limit
//! cached across periods.

use crate::profile::Profile;

#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Motion {
    profile: Profile,
    /// The profile's acceleration in the last period (nm/s²; 0 while it waits for the slider).
    accel_ref_nm_s2: f32,
    /// The move's braking rate (nm/s², fixed at its command; 0 until a model table gives one).
    decel_nm_s2: f32,
    /// Time holding within the on-target window (s).
    on_target_ticks: u32,
    /// Control periods since start (wraps): the speed-up limit (a model evaluation) is
    /// refreshed on odd periods only; the profile's acceleration changes little in 100 µs.
    tick: u32,
    /// The speed-up limit from the last odd period (nm/s²).
    speedup_nm_s2: f32,
}

impl Motion {
    pub(super) fn new() -> Self {
        Motion {
            profile: Profile::at_rest(0),
            accel_ref_nm_s2: 0.0,
            decel_nm_s2: 1.0,
            on_target_ticks: 0,
            tick: 0,
            speedup_nm_s2: 0.0,
        }
    }

    pub(super) fn profile(&self) -> &Profile {
        &self.profile
    }

    pub(super) fn profile_mut(&mut self) -> &mut Profile {
        &mut self.profile
    }

    /// A control period begins.
    pub(super) fn tick(&mut self) {
        self.tick = self.tick.wrapping_add(1);
    }

    pub(super) fn accel_ref_nm_s2(&self) -> f32 {
        self.accel_ref_nm_s2
    }

    pub(super) fn decel_nm_s2(&self) -> f32 {
        self.decel_nm_s2
    }

    pub(super) fn set_decel_nm_s2(&mut self, decel_nm_s2: f32) {
        self.decel_nm_s2 = decel_nm_s2;
    }

    /// Periods on target in a row.
    pub(super) fn on_target_ticks(&self) -> u32 {
        self.on_target_ticks
    }

    /// The time on target starts again (a new hold or move).
    pub(super) fn restart_on_target(&mut self) {
        self.on_target_ticks = 0;
    }

    /// On-target bookkeeping: `within` the window this period, or the time starts again.
    pub(super) fn count_on_target(&mut self, within: bool) {
        if within {
            self.on_target_ticks = self.on_target_ticks.saturating_add(1);
        } else {
            self.on_target_ticks = 0;
        }
    }

    /// One period of the profile within `v_max_nm_s`, speeding up within `speedup_limit()` (a
    /// model evaluation, asked for on odd periods or while none is cached) and braking at the
    /// move's rate. `waiting`: the profile slows down for a lagging slider, which asks for no
    /// braking: fed forward as M·a it took the drive away from a slider that was already behind
    /// (5 kg against an unknown 2 N: 97 V fell to 33 V, and the slider slid back 0.8 µm).
    pub(super) fn step(
        &mut self,
        dt_s: f32,
        v_max_nm_s: f32,
        waiting: bool,
        speedup_limit: impl FnOnce() -> f32,
    ) {
        let v_before = self.profile.velocity_nm_s();
        let decel = self.decel_nm_s2;
        let odd = self.tick & 1 == 1;
        let cached = &mut self.speedup_nm_s2;
        let up = || {
            if odd || *cached <= 0.0 {
                *cached = speedup_limit();
            }
            *cached
        };
        self.profile.step(dt_s, v_max_nm_s, up, decel);
        self.accel_ref_nm_s2 = (self.profile.velocity_nm_s() - v_before) / dt_s;
        if waiting && self.accel_ref_nm_s2 * v_before < 0.0 {
            self.accel_ref_nm_s2 = 0.0;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const DT_S: f32 = 1e-4;

    #[test]
    fn speeds_up_at_the_limit_and_reports_it() {
        // 1e9 nm/s² for 0.1 ms: 1e5 nm/s after one period, and the acceleration is the limit.
        let mut m = Motion::new();
        m.profile_mut().set_target(1_000_000);
        m.set_decel_nm_s2(1e9);
        m.tick();
        m.step(DT_S, 1e6, false, || 1e9);
        assert!((m.profile().velocity_nm_s() - 1e5).abs() < 1.0);
        assert!((m.accel_ref_nm_s2() - 1e9).abs() < 1e4);
    }

    #[test]
    fn the_speedup_limit_is_asked_for_on_odd_periods_only() {
        let mut m = Motion::new();
        m.profile_mut().set_target(1_000_000_000);
        m.set_decel_nm_s2(1e9);
        let mut asked = 0;
        for _ in 0..10 {
            m.tick();
            m.step(DT_S, 1e9, false, || {
                asked += 1;
                1e9
            });
        }
        assert_eq!(asked, 5);
    }

    #[test]
    fn waiting_asks_for_no_braking() {
        let mut m = Motion::new();
        m.profile_mut().set_target(1_000_000_000);
        m.set_decel_nm_s2(1e9);
        for _ in 0..10 {
            m.tick();
            m.step(DT_S, 1e9, false, || 1e9);
        }
        // Down to 0.5 mm/s from 1 mm/s: braking at 1e9 nm/s², unless the profile waits.
        let mut braking = m;
        braking.step(DT_S, 5e5, false, || 1e9);
        assert!((braking.accel_ref_nm_s2() + 1e9).abs() < 1e4);
        m.step(DT_S, 5e5, true, || 1e9);
        assert_eq!(m.accel_ref_nm_s2(), 0.0);
    }

    #[test]
    fn time_on_target_adds_up_and_restarts() {
        let mut m = Motion::new();
        for _ in 0..10 {
            m.count_on_target(true);
        }
        assert_eq!(m.on_target_ticks(), 10);
        m.count_on_target(false);
        assert_eq!(m.on_target_ticks(), 0);
    }
}
