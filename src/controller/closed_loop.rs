//! Closed-loop motion (Moving and Holding): the profile within the model's speed and
//! acceleration limits, on-target bookkeeping, and the hand-over between the coarse (sine) and
//! the fine (static) mode.

use super::fine::FineStep;
use super::model_cache::ModelTable;
use super::{Controller, ControllerConfig, Mode, State};

/// The foot pushes once per drive period, and a light carriage's speed ripples within one: a
/// stop squeezed into a few periods is over before the loop (one period late, speed measured
/// over periods) can follow it, and a 1 kg carriage braked at its full stall thrust overshot
/// 1 mm by 470 nm. Spread over this many periods it stops within a count; a heavy carriage's
/// stall-limited braking is gentler than this anyway.
const BRAKE_MIN_DRIVE_PERIODS: f32 = 20.0;
/// The profile's lowest speed limit, as a share of the approach speed (see `regulate`).
const PROFILE_CRAWL_SHARE: f32 = 0.1;
/// A moving carriage is handed to the fine mode early only while the stop its sine's end gives
/// it is at most this share of the fine window (0.5 and 1 were tried: no smaller overshoot, and
/// the 50 kg carriage's 1 and 10 µm steps took up to 40 % longer), and only within the fine window
/// and this share beyond it from the target.
const STOP_SHARE_OF_FINE_WINDOW: f32 = 0.25;
/// Floor of the braking limit (nm/s²) while the model has no speed yet.
const MIN_BRAKE_NM_S2: f32 = 1.0e6;

impl Controller {
    /// One closed-loop period (Moving and Holding): the profile, then the mode's control.
    pub(super) fn regulate(&mut self) {
        self.step_profile();
        if self.state() == State::Moving && self.motion.profile().done() {
            self.enter_hold();
        }
        self.judge_frequency_trial();
        let pos = self.position_nm();
        let err = (self.motion.profile().position_nm() - pos) as f32;
        let to_target = (self.motion.profile().target_nm() - pos) as f32;

        // On-target bookkeeping.
        let within = self.state() == State::Holding
            && (self.motion.profile().target_nm() - pos).abs() <= self.cfg.on_target_window_nm;
        self.motion.count_on_target(within);

        match self.status.mode {
            Mode::Coarse => {
                if !self.hand_to_fine(to_target) {
                    self.coarse(err);
                }
            }
            Mode::FineEntering => {
                self.drive.generator.set_amplitude_v(0.0);
                if self.drive.generator.amplitude_v() == 0.0 {
                    // No check pending; the misses carry over ([`super::fine::FineMode`]).
                    self.status.mode = Mode::Fine(FineStep::at(self.fine.offset_v()));
                }
            }
            Mode::Fine(_) => {
                let fine_room_nm = self.fine_room_v() * self.model.fine_nm_per_v;
                if to_target.abs() > fine_room_nm.max(self.cfg.fine_window_nm) * 1.5 {
                    self.status.mode = Mode::Coarse;
                    return;
                }
                self.fine(err);
            }
        }
    }

    /// The profile's period: its speed within the model's limits (and waiting for a lagging
    /// slider), its braking rate, and the acceleration the feedforward counts as M·a.
    fn step_profile(&mut self) {
        let (v_max, waiting) = self.profile_speed_limit_nm_s();
        if self.motion.decel_nm_s2() <= 0.0 {
            // A move commanded while the model table was being rebuilt (a setting changed just
            // before it: `VEL` then `MOV`) got no braking rate at its command, and a profile that
            // cannot brake crawls: it takes the rate from the first table (1 mm had not settled
            // after 3 s).
            let a = self.accel_limit_nm_s2();
            self.motion.set_decel_nm_s2(a);
        }
        // The speed-up limit at the profile's speed before this period's step.
        let v_nm_s = self.motion.profile().velocity_nm_s();
        let (mass_kg, load_x_n) = (self.moving_mass_kg(), self.load.estimate_n());
        let (table, cfg) = (self.model.table(), &self.cfg);
        self.motion
            .step(self.dt_s, v_max, waiting, || speedup_limit_nm_s2(table, mass_kg, load_x_n, v_nm_s, cfg));
    }

    /// The profile's speed limit this period (nm/s), and whether it waits for the slider.
    fn profile_speed_limit_nm_s(&self) -> (f32, bool) {
        // Never below a crawl: a load estimate at or past the model's stall force (told, or
        // learned) leaves the model no speed at all, and a profile that cannot start hangs the
        // move with the drive short of full, where no stall is judged (plain feedback against a
        // told 2 N on 0.1 kg sat still for good). Crawling on, either the slider follows or the
        // full drive it gets is judged a stall. Without a table there is no model to move by:
        // the profile stays.
        let crawl = if self.model.table().is_some() {
            PROFILE_CRAWL_SHARE * self.cfg.approach_speed_nm_s
        } else {
            0.0
        };
        let mut v_max = self.speed_limit_nm_s().max(crawl);
        // A reference running away from a slider that cannot follow (an unknown load, a preload
        // change) only builds following error: past some lag the profile waits for the slider.
        let lag = (self.motion.profile().position_nm() - self.position_nm()) as f32
            * self.motion.profile().velocity_nm_s().signum();
        let waiting = lag > self.cfg.profile_wait_lag_nm;
        if waiting {
            v_max = v_max
                .min((self.feedback.speed_nm_s() * self.motion.profile().velocity_nm_s().signum()).max(0.0));
        }
        (v_max, waiting)
    }

    /// In the coarse mode: hands the move to the fine mode when the static stroke takes what is
    /// left (true: the sine ramps out this period). A light carriage rides the foot and swings
    /// with it within each drive period (up to ~300 nm at full drive): finishing in the coarse
    /// mode, its 1 and 10 µm steps overshot by the swing (180–440 nm). It goes to the fine mode
    /// while it still moves, once the sine's end stops it where the fine stroke reaches the
    /// target whichever way the swing leaves it (1–60 nm).
    fn hand_to_fine(&mut self, to_target: f32) -> bool {
        let early = !self.motion.profile().done()
            && self.stop_with_sine_quiet_nm(to_target).is_some_and(|stop| {
                let swing = self.model.table().map_or(0.0, |t| t.swing_nm(self.drive.commanded_v));
                let rest = to_target - stop;
                self.fine_takes(rest + swing) && self.fine_takes(rest - swing)
            });
        if early {
            // The coarse part is over: the reference waits at the target instead of the fine
            // mode chasing its last few hundred nm (a carriage ahead of it stepped back first;
            // 10 µm steps of 0.1 and 0.3 kg took up to 5 ms longer).
            let target = self.motion.profile().target_nm();
            self.motion.profile_mut().reset(target);
        }
        if early || (self.motion.profile().done() && self.fine_takes(to_target)) {
            self.status.mode = Mode::FineEntering;
            self.drive.generator.set_amplitude_v(0.0);
            self.drive.commanded_v = 0.0;
            return true;
        }
        false
    }

    /// Where the slider stops if its sine stops now (nm from here, along its speed): the still
    /// foot's friction μ·F0 brakes the moving mass over M·v²/(2·μ·F0). Only while moving and near
    /// enough the target for the fine mode to take what is left, and only while that stop is short
    /// enough to trust.
    fn stop_with_sine_quiet_nm(&self, to_target_nm: f32) -> Option<f32> {
        let window = self.cfg.fine_window_nm;
        if self.state() != State::Moving || to_target_nm.abs() > (1.0 + STOP_SHARE_OF_FINE_WINDOW) * window {
            return None;
        }
        // The measured speed lags the slider by a few periods: the faster of it and the
        // reference's, with its sign.
        let (measured, reference) = (self.feedback.speed_nm_s(), self.motion.profile().velocity_nm_s());
        let v_m_s = (if measured.abs() >= reference.abs() { measured } else { reference }) * 1e-9;
        let grip_n = self.grip_n();
        if grip_n <= 0.0 {
            return None;
        }
        let stop_nm = self.moving_mass_kg() * v_m_s * v_m_s * 1e9 / (2.0 * grip_n);
        (stop_nm < STOP_SHARE_OF_FINE_WINDOW * window).then_some(stop_nm * v_m_s.signum())
    }

    /// What the still foot's friction holds or brakes the carriage with (N): μ·F0.
    pub(super) fn grip_n(&self) -> f32 {
        self.feedback.preload_force_n().max(0.0) * self.cfg.mu_dynamic
    }

    /// Whether the fine mode's static stroke takes a move of `to_target_nm` from here.
    pub(super) fn fine_takes(&self, to_target_nm: f32) -> bool {
        self.fine.takes(to_target_nm, self.model.fine_nm_per_v)
    }

    /// Highest profile speed: the model's speed at full drive against the estimated load in the
    /// direction of travel, with margin. An assisting estimate counts up to the whole stall force
    /// (the estimate's own bound): a model that runs slow shows as one, and a 0.3 kg carriage
    /// told half its mass (its table from a 0.15 kg carriage's periodic motion) cruised at 1.20
    /// mm/s against the 2 the plant makes while it counted only half (1 mm 1.68 → 1.28× the limit).
    pub(super) fn speed_limit_nm_s(&self) -> f32 {
        let Some(t) = self.model.table() else { return 0.0 };
        let dir =
            if self.motion.profile().target_nm() >= self.motion.profile().position_nm() { 1.0 } else { -1.0 };
        let load = (dir * self.load.estimate_n()).max(-t.stall_n());
        (t.speed_at_load_mm_s(load) * 1e6 * self.cfg.speed_fraction).min(self.cfg.velocity_max_nm_s)
    }

    /// Braking limit: the model's (below) within the user's deceleration limit, and spread over
    /// at least [`BRAKE_MIN_DRIVE_PERIODS`] drive periods from the profile's top speed.
    pub(super) fn accel_limit_nm_s2(&self) -> f32 {
        let spread = self.speed_limit_nm_s() * self.coarse_frequency_hz() / BRAKE_MIN_DRIVE_PERIODS;
        self.model_brake_nm_s2().min(self.cfg.decel_max_nm_s2).min(spread.max(MIN_BRAKE_NM_S2))
    }

    /// The model's braking: reverse drive at full voltage brakes with at least the stall force.
    pub(super) fn model_brake_nm_s2(&self) -> f32 {
        let mass = self.moving_mass_kg();
        let stall = self.cached_limits().map_or(0.0, |(f, _)| f);
        // Leave the load estimate's share of the thrust for the load.
        let usable = (stall - self.load.estimate_n().abs()).max(0.3 * stall);
        usable / mass * 1e9 * self.cfg.accel_fraction
    }
}

/// Speeding-up limit at the profile's present speed: the model's thrust at that speed and
/// full drive, less the load estimate, over the moving mass. No acceleration the motor
/// cannot deliver at the measured preload.
fn speedup_limit_nm_s2(
    table: Option<&ModelTable>,
    mass_kg: f32,
    load_x_n: f32,
    v_nm_s: f32,
    cfg: &ControllerConfig,
) -> f32 {
    let Some(t) = table else { return 0.0 };
    let thrust = t.full_thrust_n(v_nm_s.abs() * 1e-6);
    let load = v_nm_s.signum() * load_x_n;
    let stall = t.stall_n();
    let usable = (thrust - load.max(0.0)).max(0.05 * stall);
    (usable / mass_kg * 1e9 * cfg.accel_fraction).min(cfg.accel_max_nm_s2)
}
