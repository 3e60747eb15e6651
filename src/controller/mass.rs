//! The carriage's moving mass as the controller uses it: the `0x101A` parameter, or more when a
//! move's speed-up shows a heavier carriage (a payload nobody told the controller about).
//!
//! Momentum: over the speed-up, ∫(F − L) dt = M·Δv, with F the thrust the model says the applied
//! drive gives at the measured speed and L the load estimate. Timed from the move's command until
//! the slider has half the profile's top speed; the speed filter's lag (it reports the speed of
//! [`super::feedback::SPEED_FILTER`]'s time constant ago) is taken off the impulse. Only a
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
struct SpeedUp {
    t_s: f32,
    impulse_n_s: f32,
}

/// One period of a move as the speed-up's timing sees it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct SpeedUpPeriod {
    /// Still speeding up: moving in the coarse mode, the profile running and not braking.
    pub(super) speeding_up: bool,
    /// The profile's sense (±1).
    pub(super) sense: f32,
    /// What the model says the drive gave along +x, and the load estimate along +x (N).
    pub(super) thrust_x_n: f32,
    pub(super) load_x_n: f32,
    /// The slider's filtered speed (nm/s along +x) and half the profile's top speed (nm/s).
    pub(super) speed_nm_s: f32,
    pub(super) half_top_nm_s: f32,
    pub(super) dt_s: f32,
    /// The model's stall force (N) and no-load speed (mm/s) at full drive, if it has a table.
    pub(super) limits: Option<(f32, f32)>,
    /// The measured preload (N): where a learned mass holds.
    pub(super) preload_n: f32,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct MassEstimator {
    /// The told mass (the `0x101A` parameter, kg).
    told_kg: f32,
    /// The moving mass in use (kg): the told one, a payload a speed-up measured, or the learned.
    mass_kg: f32,
    /// What long speed-ups taught beyond the told mass (kg) ...
    learned_kg: f32,
    /// ... at this preload (N).
    learned_preload_n: f32,
    /// The move's speed-up while it is being timed.
    speedup: Option<SpeedUp>,
}

impl MassEstimator {
    pub(super) fn new(told_kg: f32) -> Self {
        MassEstimator {
            told_kg,
            mass_kg: told_kg,
            learned_kg: told_kg,
            learned_preload_n: 0.0,
            speedup: None,
        }
    }

    /// A new told mass; `forget`: back to it, learned and measured alike (a new mass parameter or
    /// calibration).
    pub(super) fn configure(&mut self, told_kg: f32, forget: bool) {
        self.told_kg = told_kg;
        if forget {
            self.mass_kg = told_kg;
            self.learned_kg = told_kg;
        }
    }

    /// The moving mass for braking, speeding up and the feedforward (kg).
    pub(super) fn mass_kg(&self) -> f32 {
        self.mass_kg.max(1e-3)
    }

    /// A speed-up is being timed.
    pub(super) fn timing(&self) -> bool {
        self.speedup.is_some()
    }

    /// At a move's command, at `preload_n`: a mass learned at another preload is forgotten (what
    /// a long speed-up teaches beyond the told mass is the model's thrust error there, and that
    /// changes with the preload). A payload in use stays: it is mass, whatever the preload. The
    /// move's speed-up is timed from here.
    pub(super) fn start_move(&mut self, preload_n: f32) {
        let told = self.told_kg;
        if self.learned_kg != told && (preload_n - self.learned_preload_n).abs() > MASS_PRELOAD_SPAN_N {
            if self.mass_kg == self.learned_kg {
                self.mass_kg = told;
            }
            self.learned_kg = told;
        }
        self.speedup = Some(SpeedUp { t_s: 0.0, impulse_n_s: 0.0 });
    }

    /// One period of the speed-up's timing. True when the mass in use grew (the braking rate,
    /// set at the command from the lighter mass, must follow).
    pub(super) fn update(&mut self, p: &SpeedUpPeriod) -> bool {
        let Some(mut s) = self.speedup else { return false };
        if !p.speeding_up {
            self.speedup = None;
            return false;
        }
        let net_n = p.sense * (p.thrust_x_n - p.load_x_n);
        s.t_s += p.dt_s;
        s.impulse_n_s += net_n * p.dt_s;
        let along_nm_s = p.sense * p.speed_nm_s;
        if p.half_top_nm_s <= 0.0 || along_nm_s < p.half_top_nm_s {
            self.speedup = Some(s);
            return false;
        }
        self.speedup = None;
        let lag_s = p.dt_s / super::feedback::SPEED_FILTER;
        if s.t_s < LEAST_FILTER_TIMES * lag_s {
            return false;
        }
        let impulse = s.impulse_n_s - net_n * lag_s;
        let measured_kg = impulse / (along_nm_s * 1e-9);
        let before = self.mass_kg;
        self.mass_kg = self.reading_kg(measured_kg, s.t_s, lag_s, along_nm_s, p);
        self.mass_kg > before
    }

    /// What a speed-up's `measured_kg` (timed over `t_s`, the filter's lag `lag_s`, up to
    /// `along_nm_s`) makes the mass in use: a payload, the learned mass moved toward it, or
    /// unchanged.
    fn reading_kg(
        &mut self,
        measured_kg: f32,
        t_s: f32,
        lag_s: f32,
        along_nm_s: f32,
        p: &SpeedUpPeriod,
    ) -> f32 {
        let told = self.told_kg;
        let learned = self.learned_kg;
        let measured_kg = measured_kg.min(MOST_TIMES * told);
        if measured_kg > HEAVIER_SHARE * learned {
            measured_kg
        } else if t_s >= LEARN_FILTER_TIMES * lag_s {
            // The thrust was taken at the filtered speed, which lags the slider's, and the thrust
            // falls with speed: the impulse read high by ∫(F(v_f) − F(v)) dt ≈ −F′·∫(v − v_f) dt,
            // and for the first-order filter ∫(v − v_f) dt = τ·Δv_f. F′ is the full-drive line's
            // (a long speed-up is stall-limited), stall force over no-load speed, both cached:
            // no table lookup in the tick. Without this a right model taught the 50 kg carriage
            // 54.9 kg.
            let fall_n =
                p.limits.map_or(0.0, |(stall, v0)| stall * (along_nm_s * 1e-6 / v0.max(1e-3)).min(1.0));
            let measured_kg = measured_kg - fall_n.max(0.0) * lag_s / (along_nm_s * 1e-9);
            self.learned_kg = (learned + LEARN_SHARE * (measured_kg - learned)).max(told);
            self.learned_preload_n = p.preload_n;
            self.learned_kg
        } else {
            learned
        }
    }
}

impl Controller {
    /// The moving mass for braking, speeding up and the feedforward (kg).
    pub fn moving_mass_kg(&self) -> f32 {
        self.mass.mass_kg()
    }

    /// One period of the speed-up's timing: `thrust_x_n` is what the model says the drive gave
    /// along +x this period.
    pub(super) fn time_speedup(&mut self, thrust_x_n: f32) {
        if !self.mass.timing() {
            return;
        }
        let v = self.motion.profile().velocity_nm_s();
        let braking = self.motion.accel_ref_nm_s2() * v < 0.0;
        let speeding_up =
            self.state() == State::Moving && !braking && matches!(self.status.mode, Mode::Coarse) && v != 0.0;
        let period = SpeedUpPeriod {
            speeding_up,
            sense: v.signum(),
            thrust_x_n,
            load_x_n: self.load.estimate_n(),
            speed_nm_s: self.feedback.speed_nm_s(),
            half_top_nm_s: if speeding_up { 0.5 * self.speed_limit_nm_s() } else { 0.0 },
            dt_s: self.dt_s,
            limits: self.cached_limits(),
            preload_n: self.feedback.preload_force_n(),
        };
        if self.mass.update(&period) {
            // The braking rate was set at the command from the lighter mass; the profile has not
            // begun to brake yet (checked above).
            let decel = self.motion.decel_nm_s2().min(self.accel_limit_nm_s2());
            self.motion.set_decel_nm_s2(decel);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::controller::feedback::SPEED_FILTER;

    const DT_S: f32 = 1e-4;

    /// A speed-up of a carriage of `true_kg` under a net `force_n` from rest, seen through the
    /// controller's speed filter, up to half of `top_nm_s`: the mass estimator's state after it.
    fn speed_up(m: &mut MassEstimator, true_kg: f32, force_n: f32, top_nm_s: f32) -> bool {
        let accel_nm_s2 = force_n / true_kg * 1e9;
        let (mut v, mut filtered) = (0.0f32, 0.0f32);
        let mut grew = false;
        for _ in 0..100_000 {
            v += accel_nm_s2 * DT_S;
            filtered += SPEED_FILTER * (v - filtered);
            let p = SpeedUpPeriod {
                speeding_up: true,
                sense: 1.0,
                thrust_x_n: force_n,
                load_x_n: 0.0,
                speed_nm_s: filtered,
                half_top_nm_s: 0.5 * top_nm_s,
                dt_s: DT_S,
                limits: None,
                preload_n: 10.0,
            };
            grew |= m.update(&p);
            if !m.timing() {
                break;
            }
        }
        grew
    }

    #[test]
    fn a_payload_is_measured_as_mass() {
        // Told 1 kg, the carriage 2 kg: 2 N gives 1 m/s²; half of 100 mm/s takes 50 ms, 25 filter
        // time constants: the impulse over the filtered speed is F·(t − τ)/(a·(t − τ)) = M.
        let mut m = MassEstimator::new(1.0);
        m.start_move(10.0);
        assert!(speed_up(&mut m, 2.0, 2.0, 1.0e8));
        assert!((m.mass_kg() - 2.0).abs() < 0.02, "{}", m.mass_kg());
    }

    #[test]
    fn a_payload_is_bounded_at_four_times_the_told_mass() {
        let mut m = MassEstimator::new(1.0);
        m.start_move(10.0);
        speed_up(&mut m, 10.0, 2.0, 1.0e7);
        assert_eq!(m.mass_kg(), 4.0);
    }

    #[test]
    fn a_small_excess_is_learned_halfway() {
        // 1.2 kg against a told 1: within 1.5×, a long speed-up: 1 + 0.5·(1.2 − 1) = 1.1 kg.
        let mut m = MassEstimator::new(1.0);
        m.start_move(10.0);
        speed_up(&mut m, 1.2, 2.0, 1.0e8);
        assert!((m.mass_kg() - 1.1).abs() < 0.01, "{}", m.mass_kg());
        // Kept at the same preload, forgotten more than 1 N away.
        m.start_move(10.5);
        assert!((m.mass_kg() - 1.1).abs() < 0.01);
        m.start_move(11.5);
        assert_eq!(m.mass_kg(), 1.0);
    }

    #[test]
    fn never_lighter_than_told() {
        let mut m = MassEstimator::new(1.0);
        m.start_move(10.0);
        assert!(!speed_up(&mut m, 0.8, 2.0, 1.0e8));
        assert_eq!(m.mass_kg(), 1.0);
    }

    #[test]
    fn a_short_or_interrupted_speed_up_teaches_nothing() {
        // 2 N on 2 kg up to half of 2 mm/s: 1 ms, under two filter time constants (4 ms).
        let mut m = MassEstimator::new(1.0);
        m.start_move(10.0);
        speed_up(&mut m, 2.0, 2.0, 2.0e6);
        assert_eq!(m.mass_kg(), 1.0);
        // Braking (or anything else that ends the speed-up) ends the timing.
        m.start_move(10.0);
        let p = SpeedUpPeriod {
            speeding_up: false,
            sense: 1.0,
            thrust_x_n: 2.0,
            load_x_n: 0.0,
            speed_nm_s: 0.0,
            half_top_nm_s: 1.0,
            dt_s: DT_S,
            limits: None,
            preload_n: 10.0,
        };
        assert!(!m.update(&p));
        assert!(!m.timing());
    }

    #[test]
    fn a_new_told_mass_forgets() {
        let mut m = MassEstimator::new(1.0);
        m.start_move(10.0);
        speed_up(&mut m, 2.0, 2.0, 1.0e8);
        m.configure(3.0, false);
        assert!((m.mass_kg() - 2.0).abs() < 0.02);
        m.configure(3.0, true);
        assert_eq!(m.mass_kg(), 3.0);
    }
}
