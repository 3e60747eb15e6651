//! The supervisor's judgement of motion (following error, stall, an encoder that stopped
//! counting under a coarse drive, an open-loop drive that makes no progress) and the counts the
//! protocol watches (faults, limit-switch stops, failed referencing). The controller reads the
//! sensors and trips the fault it returns (`supervision.rs`). Its timers count control periods
//! in integers (a sum of f32 periods stops growing after about 2 000 s).

use super::FaultCode;

/// The coarse mode's encoder-loss watch ([`LossWatch`]) counts only while the drive is at least this share of the largest: near the foot's slip
/// threshold the model's crawl is least certain (a 0.3 kg carriage at 5 N stood 550 nm short of
/// a target at 13 V, where the model has it moving at 0.2 mm/s, until the approach push moved
/// it; `coarse.rs`).
pub(super) const LOSS_MIN_DRIVE_SHARE: f32 = 0.3;

/// Width of the encoder's hysteresis band ([`Band`]), in counts: a count flickering between two
/// neighbouring values stays inside it (after the first flick), a slider creeping on moves it a
/// count at a time and one turning round after a count (measured: two counts there put a 1 kg
/// carriage creeping against 70 % of its stall force into a false encoder loss).
const BAND_COUNTS: i64 = 1;

/// What an open-loop drive must gain along its direction in every window of the progress watch
/// ([`ProgressWatch`]), in counts: twice what a slider rattles against an end stop under the
/// referencing drive in the simulator (three to four counts, 150–200 nm).
pub(super) const PROGRESS_COUNTS: i64 = 8;
/// The window is the time the model's no-load speed, at the drive's amplitude, needs for
/// [`PROGRESS_COUNTS`] times this (a loaded or heavy carriage, or a drive at another frequency,
/// runs far below it), within [`PROGRESS_MIN_S`] and [`PROGRESS_MAX_S`].
pub(super) const PROGRESS_SLACK: f32 = 50.0;
/// Shortest window (s): a 50 kg carriage at the referencing drive gains the counts from rest in
/// well under it.
pub(super) const PROGRESS_MIN_S: f32 = 0.02;
/// Longest window (s): a drive the model has crawling still stops within this at an end stop.
pub(super) const PROGRESS_MAX_S: f32 = 0.05;

/// The limits the supervisor judges by.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct SupervisorConfig {
    pub(super) following_error_limit_nm: f32,
    /// Stall detection time in control periods.
    pub(super) stall_ticks: u32,
    pub(super) encoder_jump_counts: i32,
    /// Largest drive (V): "near full" and "full" drive are shares of it.
    pub(super) max_drive_v: f32,
    /// The encoder's resolution (nm per count).
    pub(super) nm_per_count: f32,
    /// How far the watch's model carriage may run unseen (counts; 0: not watched).
    pub(super) loss_counts: f32,
}

/// One closed-loop period as the supervisor sees it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct ClosedLoopPeriod {
    /// Reference − position (nm).
    pub(super) err_nm: f32,
    /// The sine's direction (±1) and the slider's filtered speed (nm/s, along +x).
    pub(super) dir: f32,
    pub(super) speed_nm_s: f32,
    /// Drive voltage (V) and whether the sine drives (coarse mode).
    pub(super) drive_v: f32,
    pub(super) coarse: bool,
    /// The model's no-load speed at full drive (nm/s; 0 before a table).
    pub(super) foot_speed_nm_s: f32,
    pub(super) dt_s: f32,
    /// The encoder's position left its hysteresis band this period ([`Band`]).
    pub(super) counted: bool,
    /// The count changed this period without the position leaving the band.
    pub(super) flicked: bool,
    /// The sine's peak-to-peak swing the amplifier gives the drive (V): what the model's thrust
    /// is taken at.
    pub(super) swing_v: f32,
    /// The moving mass the model's carriage has (kg).
    pub(super) mass_kg: f32,
}

/// The model's mean thrust along the drive at a swing (V) and a slider speed along the drive
/// (nm/s), in N; None without a model table. The supervisor asks only in the periods it needs it.
pub(super) trait ThrustAt: Fn(f32, f32) -> Option<f32> {}
impl<F: Fn(f32, f32) -> Option<f32>> ThrustAt for F {}

/// The coarse mode's encoder-loss watch: where the model's carriage would be had it started at
/// half the measured speed when the encoder last counted (the speed filter lags, and the model
/// may be 2× off), pushed by what the model's thrust has gained since. The load is taken as what
/// balanced the drive when the encoder last counted, the model's thrust then: a load the
/// controller has not learned (a 50 kg carriage starting against an unknown 70 % of its stall
/// force crept at a count per 3–6 ms, where the model with no load had it run 2 µm) is
/// counted, and so is none the load observer learns from the silence (it reads a silent
/// encoder's speed falling to zero as a load: on a 50 kg carriage the stall force within a
/// millisecond). A slider held by a load still counts as soon as the drive gains on it; a
/// stuck encoder never does.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
struct LossWatch {
    speed_nm_s: f32,
    travel_nm: f32,
    /// The swing (V) and the measured speed along the drive (nm/s) when the encoder last
    /// counted, and the model's thrust there once asked for (N): asked for only when the encoder
    /// falls silent, so a moving slider that counts every period costs no model evaluation.
    counted_at: (f32, f32),
    balance_n: Option<f32>,
    /// Count changes inside the band since it last moved.
    flicks: u8,
}

/// Count changes inside the encoder's band ([`Band`]) the loss watch takes as counts after the
/// band last moved: a slider that has just stopped against a load vibrates across a count a few
/// times (a 1 kg carriage at 5 N against 70 % of its stall force, before creeping on); a lost
/// channel whose partner still toggles flickers for ever.
const FLICKS_COUNTED: u8 = 8;

impl LossWatch {
    /// One period; true when the model's carriage ran `limit_nm` unseen.
    fn update(
        &mut self,
        p: &ClosedLoopPeriod,
        driven: bool,
        limit_nm: f32,
        thrust_at: impl ThrustAt,
    ) -> bool {
        if !p.coarse || p.mass_kg <= 0.0 {
            *self = LossWatch::default();
            return false;
        }
        let flick_counts = p.flicked && self.flicks < FLICKS_COUNTED;
        if p.counted || flick_counts {
            // A count changed inside the band: a slider vibrating across a count while held
            // near balance (stopping against a load it is about to creep on against), or one
            // channel lost. The first few count as before; a count that keeps flickering
            // without ever leaving the band is no progress.
            let flicks = if p.counted { 0 } else { self.flicks + 1 };
            let along = p.dir * p.speed_nm_s;
            let speed_nm_s = (0.5 * along).max(0.0);
            *self = LossWatch {
                speed_nm_s,
                travel_nm: 0.0,
                counted_at: (p.swing_v, along),
                balance_n: None,
                flicks,
            };
            return false;
        }
        if !driven {
            // Below the drive the model is trusted at: no push, and what it ran stays.
            self.speed_nm_s = 0.0;
            return false;
        }
        let balance = self.balance_n.or_else(|| thrust_at(self.counted_at.0, self.counted_at.1));
        let (Some(balance), Some(thrust)) = (balance, thrust_at(p.swing_v, self.speed_nm_s)) else {
            return false;
        };
        self.balance_n = Some(balance);
        let push = thrust - balance;
        self.speed_nm_s = (self.speed_nm_s + push / p.mass_kg * 1e9 * p.dt_s).max(0.0);
        self.travel_nm += self.speed_nm_s * p.dt_s;
        self.travel_nm >= limit_nm
    }
}

/// A hysteresis band on the encoder position, [`BAND_COUNTS`] wide: the slider has moved when
/// the position leaves the band, which then follows it. A lost quadrature channel whose partner
/// still toggles counts up and down between two neighbouring values: never out of the band, so
/// the watches below see no progress in it (any count change reset them before).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub(super) struct Band {
    lo_nm: i64,
    hi_nm: i64,
    started: bool,
}

impl Band {
    /// The position now (nm) and the band's width (nm); returns how far the band moved (nm,
    /// signed; 0 inside it).
    pub(super) fn update(&mut self, x_nm: i64, width_nm: i64) -> i64 {
        if !self.started {
            self.started = true;
            self.lo_nm = x_nm.saturating_sub(width_nm / 2);
            self.hi_nm = self.lo_nm.saturating_add(width_nm);
            return 0;
        }
        if x_nm > self.hi_nm {
            let d = x_nm.saturating_sub(self.hi_nm);
            self.hi_nm = x_nm;
            self.lo_nm = x_nm.saturating_sub(width_nm);
            d
        } else if x_nm < self.lo_nm {
            let d = x_nm.saturating_sub(self.lo_nm);
            self.lo_nm = x_nm;
            self.hi_nm = x_nm.saturating_add(width_nm);
            d
        } else {
            0
        }
    }
}

/// The open-loop drive's progress watch (referencing, open-loop stepping, where no reference is
/// followed): in every window of `window_ticks` the slider must gain [`PROGRESS_COUNTS`] along
/// the drive, net, from where the window started (a flicker or a slider rattling against a stop
/// gains nothing, however often its count changes). An end stop, a stalled slider and a lost
/// encoder all fail it, whatever the limit switches say. The first window after the drive turns
/// round is [`TURN_WINDOWS`] long: the slider first has to stop.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub(super) struct ProgressWatch {
    /// The drive this window judges: direction, and its window (periods; 0 before the first).
    dir: i8,
    window_ticks: u32,
    /// This window: where it started (nm), its length and the periods it has run.
    anchor_nm: i64,
    limit_ticks: u32,
    ticks: u32,
}

/// The first window after the drive turns round, in windows: a 50 kg carriage at 3 mm/s takes
/// 0.1 s to stop under 1.5 N.
pub(super) const TURN_WINDOWS: u32 = 4;

impl ProgressWatch {
    /// Whether the watch has a window for a drive in `dir`; if not, the controller computes one
    /// and calls [`Self::start`] (once per run or turn, not every period).
    pub(super) fn judging(&self, dir: i8) -> bool {
        self.window_ticks > 0 && self.dir == dir
    }

    /// A drive in `dir` starts (or turns round) with the slider at `x_nm`.
    pub(super) fn start(&mut self, dir: i8, window_ticks: u32, x_nm: i64) {
        let turn = self.window_ticks > 0 && self.dir == -dir;
        let window_ticks = window_ticks.max(1);
        let limit_ticks = if turn { window_ticks.saturating_mul(TURN_WINDOWS) } else { window_ticks };
        *self = ProgressWatch { dir, window_ticks, anchor_nm: x_nm, limit_ticks, ticks: 0 };
    }

    /// One period under drive with the slider at `x_nm`; `need_nm`: the gain a window needs.
    /// True when a window ended without it.
    pub(super) fn update(&mut self, x_nm: i64, need_nm: i64) -> bool {
        let gained = x_nm.saturating_sub(self.anchor_nm).saturating_mul(i64::from(self.dir));
        if gained >= need_nm {
            self.anchor_nm = x_nm;
            self.ticks = 0;
            self.limit_ticks = self.window_ticks;
            return false;
        }
        self.ticks = self.ticks.saturating_add(1);
        self.ticks >= self.limit_ticks
    }

    /// No drive to judge (closed loop, idle, a run ended).
    pub(super) fn stop(&mut self) {
        *self = ProgressWatch::default();
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Supervisor {
    cfg: SupervisorConfig,
    /// Periods the slider has not followed a near-full drive (sliding back counts five).
    stall_ticks: u32,
    /// Largest |reference − position| since the last move command (nm).
    max_following_error_nm: f32,
    /// Faults since power-up (wraps).
    faults: u32,
    /// Moves and open-loop runs a limit switch stopped (wraps), and whether the move or run in
    /// progress has been stopped by one already (counted once; cleared when one starts).
    limit_stops: u32,
    limit_stopped: bool,
    /// Referencing searches that ended without finding the mark (wraps).
    reference_failures: u32,
    /// Control-loop overruns the board reported, during a fault too (wraps).
    overruns: u32,
    loss_watch: LossWatch,
    /// The encoder position's hysteresis band; the open-loop drive's progress watch.
    band: Band,
    pub(super) progress: ProgressWatch,
}

impl Supervisor {
    pub(super) fn new(cfg: SupervisorConfig) -> Self {
        Supervisor {
            cfg,
            stall_ticks: 0,
            max_following_error_nm: 0.0,
            faults: 0,
            limit_stops: 0,
            limit_stopped: false,
            reference_failures: 0,
            overruns: 0,
            loss_watch: LossWatch::default(),
            band: Band::default(),
            progress: ProgressWatch::default(),
        }
    }

    pub(super) fn configure(&mut self, cfg: SupervisorConfig) {
        self.cfg = cfg;
    }

    /// The position this period (nm): how far the hysteresis band moved (nm, 0 within it).
    pub(super) fn track(&mut self, position_nm: i64) -> i64 {
        let width = BAND_COUNTS.saturating_mul(self.cfg.nm_per_count as i64);
        self.band.update(position_nm, width)
    }

    /// The gain an open-loop window needs (nm).
    pub(super) fn progress_need_nm(&self) -> i64 {
        PROGRESS_COUNTS.saturating_mul(self.cfg.nm_per_count as i64)
    }

    /// An encoder step of `delta_counts` in one period is a jump (a lost or noisy signal).
    pub(super) fn encoder_jumped(&self, delta_counts: i32) -> bool {
        delta_counts.abs() > self.cfg.encoder_jump_counts
    }

    /// One closed-loop period: the fault to trip, if any (`thrust_at`: the model, for the
    /// encoder-loss watch).
    pub(super) fn update(&mut self, p: &ClosedLoopPeriod, thrust_at: impl ThrustAt) -> Option<FaultCode> {
        // Stall/slip: the foot is driven near full but the slider does not move the driven way
        // (commanded foot speed against encoder speed). Near full: below it the controller still
        // has thrust to give, and a heavy carriage creeping up to its target against an unknown
        // load at half the drive is no stall (50 kg against 2 N, half its stall force, tripped at
        // 54 V with the threshold at 50 %; now it settles).
        let max_v = self.cfg.max_drive_v;
        let driving = p.coarse && p.drive_v > 0.9 * max_v;
        let not_following = driving && p.dir * p.speed_nm_s < 0.1 * p.foot_speed_nm_s;
        let watched = p.drive_v >= LOSS_MIN_DRIVE_SHARE * max_v;
        let limit_nm = self.cfg.loss_counts * self.cfg.nm_per_count;
        if limit_nm > 0.0 && self.loss_watch.update(p, watched, limit_nm, thrust_at) {
            return Some(FaultCode::EncoderLoss);
        }
        let err = p.err_nm;
        self.max_following_error_nm = self.max_following_error_nm.max(err.abs());
        if err.abs() > self.cfg.following_error_limit_nm {
            // A light carriage under a load above the stall force is dragged back fast enough
            // to exceed the following error before the stall timer runs out: with the full
            // drive pushing towards the reference and the slider not going that way, the cause
            // is a stall.
            let full_drive_towards = p.drive_v >= 0.95 * max_v && p.dir * err > 0.0;
            let code = if not_following && full_drive_towards {
                FaultCode::Stall
            } else {
                FaultCode::FollowingError
            };
            return Some(code);
        }
        if not_following {
            // Sliding backwards under full drive is the clearest sign: count it five times faster.
            // (only at full drive: below it the controller may still be finding the load).
            let backwards = p.dir * p.speed_nm_s < -0.1 * p.foot_speed_nm_s && p.drive_v >= 0.95 * max_v;
            self.stall_ticks = self.stall_ticks.saturating_add(if backwards { 5 } else { 1 });
            if self.stall_ticks >= self.cfg.stall_ticks {
                return Some(FaultCode::Stall);
            }
        } else {
            self.stall_ticks = 0;
        }
        None
    }

    /// A move starts: its own peak following error, and a limit switch may stop it anew.
    pub(super) fn start_move(&mut self) {
        self.max_following_error_nm = 0.0;
        self.limit_stopped = false;
    }

    /// An open-loop run starts: a limit switch may stop it anew.
    pub(super) fn start_run(&mut self) {
        self.limit_stopped = false;
    }

    /// Counts a limit switch's stop (once per move or run).
    pub(super) fn note_limit_stop(&mut self) {
        if !self.limit_stopped {
            self.limit_stopped = true;
            self.limit_stops = self.limit_stops.wrapping_add(1);
        }
    }

    pub(super) fn note_fault(&mut self) {
        self.faults = self.faults.wrapping_add(1);
    }

    pub(super) fn note_overrun(&mut self) {
        self.overruns = self.overruns.wrapping_add(1);
    }

    pub(super) fn overruns(&self) -> u32 {
        self.overruns
    }

    pub(super) fn note_reference_failure(&mut self) {
        self.reference_failures = self.reference_failures.wrapping_add(1);
    }

    pub(super) fn max_following_error_nm(&self) -> f32 {
        self.max_following_error_nm
    }

    pub(super) fn faults(&self) -> u32 {
        self.faults
    }

    pub(super) fn limit_stops(&self) -> u32 {
        self.limit_stops
    }

    pub(super) fn reference_failures(&self) -> u32 {
        self.reference_failures
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::panic)] // a test fails by panicking
mod tests {
    use super::*;

    const DT_S: f32 = 1e-4;

    fn supervisor() -> Supervisor {
        Supervisor::new(SupervisorConfig {
            following_error_limit_nm: 10_000.0,
            stall_ticks: 100,
            encoder_jump_counts: 100,
            max_drive_v: 100.0,
            nm_per_count: 50.0,
            loss_counts: 40.0,
        })
    }

    /// Driving +x at `drive_v` with the slider at `speed_nm_s`, `err_nm` behind; foot 2 mm/s.
    fn period(drive_v: f32, speed_nm_s: f32, err_nm: f32) -> ClosedLoopPeriod {
        ClosedLoopPeriod {
            err_nm,
            dir: 1.0,
            speed_nm_s,
            drive_v,
            coarse: true,
            foot_speed_nm_s: 2.0e6,
            dt_s: DT_S,
            counted: true,
            flicked: false,
            swing_v: drive_v,
            mass_kg: 1.0,
        }
    }

    /// No model table.
    fn no_model(_swing_v: f32, _speed_nm_s: f32) -> Option<f32> {
        None
    }

    /// A model whose thrust is a hundredth of the swing (N per V), whatever the speed.
    fn hundredth_of_the_swing(swing_v: f32, _speed_nm_s: f32) -> Option<f32> {
        Some(swing_v / 100.0)
    }

    /// Periods until `p` repeated trips, at most `limit`.
    fn periods_to_trip(s: &mut Supervisor, p: &ClosedLoopPeriod, limit: u32) -> Option<(u32, FaultCode)> {
        periods_to_trip_with(s, p, limit, hundredth_of_the_swing)
    }

    fn periods_to_trip_with(
        s: &mut Supervisor,
        p: &ClosedLoopPeriod,
        limit: u32,
        model: impl ThrustAt + Copy,
    ) -> Option<(u32, FaultCode)> {
        (1..=limit).find_map(|n| s.update(p, model).map(|c| (n, c)))
    }

    #[test]
    fn encoder_jump_is_beyond_the_limit_either_way() {
        let s = supervisor();
        assert!(!s.encoder_jumped(100) && !s.encoder_jumped(-100));
        assert!(s.encoder_jumped(101) && s.encoder_jumped(-101));
    }

    #[test]
    fn stall_after_the_stall_time_near_full_drive() {
        // 95 V > 90 % of 100 V, the slider at 0.1 mm/s < 10 % of the foot's 2 mm/s: 0.01 s is
        // 100 periods of 0.1 ms, counted exactly.
        let mut s = supervisor();
        let (n, code) = periods_to_trip(&mut s, &period(95.0, 1.0e5, 0.0), 1000).unwrap();
        assert_eq!(code, FaultCode::Stall);
        assert_eq!(n, 100);
    }

    #[test]
    fn sliding_back_at_full_drive_counts_five_times() {
        // −0.3 mm/s < −10 % of 2 mm/s at 95 V: 0.01 s / 0.5 ms = 20 periods.
        let mut s = supervisor();
        let (n, code) = periods_to_trip(&mut s, &period(95.0, -3.0e5, 0.0), 1000).unwrap();
        assert_eq!(code, FaultCode::Stall);
        assert_eq!(n, 20);
    }

    #[test]
    fn no_stall_below_near_full_drive_or_while_following() {
        let mut s = supervisor();
        assert_eq!(periods_to_trip(&mut s, &period(90.0, 0.0, 0.0), 1000), None);
        assert_eq!(periods_to_trip(&mut s, &period(95.0, 3.0e5, 0.0), 1000), None);
        // A following period resets the timer: 99 stuck periods, one moving, 99 stuck again.
        for _ in 0..99 {
            assert_eq!(s.update_no_model(&period(95.0, 0.0, 0.0)), None);
        }
        assert_eq!(s.update_no_model(&period(95.0, 3.0e5, 0.0)), None);
        for _ in 0..98 {
            assert_eq!(s.update_no_model(&period(95.0, 0.0, 0.0)), None);
        }
    }

    #[test]
    fn following_error_beyond_the_limit() {
        let mut s = supervisor();
        assert_eq!(s.update_no_model(&period(50.0, 1.0e6, 9_000.0)), None);
        assert_eq!(s.update_no_model(&period(50.0, 1.0e6, -10_001.0)), Some(FaultCode::FollowingError));
        assert_eq!(s.max_following_error_nm(), 10_001.0);
        // At full drive towards the reference with the slider not following: a stall.
        assert_eq!(s.update_no_model(&period(96.0, 0.0, 10_001.0)), Some(FaultCode::Stall));
        s.start_move();
        assert_eq!(s.max_following_error_nm(), 0.0);
    }

    impl Supervisor {
        fn update_no_model(&mut self, p: &ClosedLoopPeriod) -> Option<FaultCode> {
            self.update(p, no_model)
        }
    }

    /// A coarse period at 50 V of drive (above the watched 30 %) with the sine's swing at
    /// `swing_v`, the encoder counting or not, the slider standing.
    fn watched(swing_v: f32, counted: bool) -> ClosedLoopPeriod {
        ClosedLoopPeriod { counted, swing_v, ..period(50.0, 0.0, 0.0) }
    }

    #[test]
    fn a_silent_encoder_trips_when_the_models_carriage_ran_40_counts() {
        // Balanced at 0.5 N (50 V of swing) when the encoder last counted, then 1.5 N: 1 N on
        // 1 kg from rest (semi-implicit Euler, 0.1 ms): after n periods n(n+1)/2·a·dt² =
        // 5·n(n+1) nm, which first reaches 40 counts (2 000 nm) at n = 20.
        let mut s = supervisor();
        assert_eq!(s.update(&watched(50.0, true), hundredth_of_the_swing), None);
        let (n, code) = periods_to_trip(&mut s, &watched(150.0, false), 1000).unwrap();
        assert_eq!(code, FaultCode::EncoderLoss);
        assert_eq!(n, 20);
    }

    #[test]
    fn a_count_no_gain_over_the_balance_a_low_drive_or_no_model_is_no_encoder_loss() {
        let mut s = supervisor();
        assert_eq!(s.update(&watched(50.0, true), hundredth_of_the_swing), None);
        // 19 silent periods, then a count: the watch starts over, and 19 more do not trip.
        for _ in 0..19 {
            assert_eq!(s.update(&watched(150.0, false), hundredth_of_the_swing), None);
        }
        assert_eq!(s.update(&watched(150.0, true), hundredth_of_the_swing), None);
        assert_eq!(s.update(&watched(50.0, true), hundredth_of_the_swing), None);
        for _ in 0..19 {
            assert_eq!(s.update(&watched(150.0, false), hundredth_of_the_swing), None);
        }
        // The drive no stronger than when it last counted (a load the model does not know
        // holds the slider): never.
        let mut s = supervisor();
        assert_eq!(s.update(&watched(150.0, true), hundredth_of_the_swing), None);
        assert_eq!(periods_to_trip(&mut s, &watched(150.0, false), 10_000), None);
        // Below 30 % of the largest drive, or without a model table: never.
        let mut s = supervisor();
        let low = |counted| ClosedLoopPeriod { counted, swing_v: 150.0, ..period(29.0, 0.0, 0.0) };
        assert_eq!(s.update(&ClosedLoopPeriod { swing_v: 50.0, ..low(true) }, hundredth_of_the_swing), None);
        assert_eq!(periods_to_trip(&mut s, &low(false), 10_000), None);
        let mut s = supervisor();
        assert_eq!(s.update(&watched(50.0, true), no_model), None);
        assert_eq!(periods_to_trip_with(&mut s, &watched(150.0, false), 10_000, no_model), None);
    }

    #[test]
    fn a_silent_encoder_at_cruise_trips_from_half_the_measured_speed() {
        // Last counted at 2 mm/s, the drive unchanged: the model's carriage starts at 1 mm/s
        // and, with nothing gained over the balance, runs 2 000 nm in 2 ms = 20 periods.
        let mut s = supervisor();
        let cruise = |counted| ClosedLoopPeriod { counted, ..period(80.0, 2.0e6, 0.0) };
        assert_eq!(s.update(&cruise(true), hundredth_of_the_swing), None);
        let (n, code) = periods_to_trip(&mut s, &cruise(false), 1000).unwrap();
        assert_eq!(code, FaultCode::EncoderLoss);
        assert!((19..=21).contains(&n), "{n}");
    }

    #[test]
    fn a_count_flickering_in_the_band_counts_only_eight_times() {
        // At cruise as above (trips 19–21 periods after the last count), the count flickering
        // inside the band every period from there: the first eight flicks count, the watch
        // then trips 19–21 periods after the eighth.
        let mut s = supervisor();
        let cruise = |counted, flicked| ClosedLoopPeriod { counted, flicked, ..period(80.0, 2.0e6, 0.0) };
        assert_eq!(s.update(&cruise(true, false), hundredth_of_the_swing), None);
        let (n, code) = periods_to_trip(&mut s, &cruise(false, true), 1000).unwrap();
        assert_eq!(code, FaultCode::EncoderLoss);
        assert!((8 + 19..=8 + 21).contains(&n), "{n}");
    }

    #[test]
    fn a_counting_slider_costs_no_model_evaluation() {
        let calls = core::cell::Cell::new(0u32);
        let counting = |swing_v: f32, speed: f32| {
            calls.set(calls.get() + 1);
            hundredth_of_the_swing(swing_v, speed)
        };
        let mut s = supervisor();
        for _ in 0..100 {
            assert_eq!(s.update(&watched(80.0, true), counting), None);
        }
        assert_eq!(calls.get(), 0);
        // The first silent period asks for the balance and the thrust, each later one the thrust.
        s.update(&watched(80.0, false), counting);
        s.update(&watched(80.0, false), counting);
        assert_eq!(calls.get(), 3);
    }

    #[test]
    fn the_band_ignores_a_one_count_flicker_and_follows_motion() {
        // 50 nm counts, 2 counts wide. A count flickering between 10 and 11 (a lost channel, its
        // partner toggling) never moves the band; a slider stepping a count a period moves it a
        // count a period once past the edge, either way.
        let mut b = Band::default();
        assert_eq!(b.update(500, 100), 0);
        for k in 0..100 {
            assert_eq!(b.update(500 + 50 * (k % 2), 100), 0, "{k}");
        }
        assert_eq!(b.update(600, 100), 50);
        assert_eq!(b.update(650, 100), 50);
        // Turning round: two counts back inside the band, the third moves it.
        assert_eq!(b.update(600, 100), 0);
        assert_eq!(b.update(550, 100), 0);
        assert_eq!(b.update(500, 100), -50);
    }

    #[test]
    fn progress_watch_asks_a_net_gain_every_window() {
        // 400 nm a window of 200 periods.
        let mut w = ProgressWatch::default();
        assert!(!w.judging(1));
        w.start(1, 200, 0);
        assert!(w.judging(1) && !w.judging(-1));
        // Gaining 50 nm every 20 periods: 400 nm in 160 periods, never trips; period 9 600 ends
        // a window (the 480th gain, 60 windows).
        let mut x = 0;
        for k in 1..=9_600u32 {
            if k % 20 == 0 {
                x += 50;
            }
            assert!(!w.update(x, 400), "{k}");
        }
        // Rattling from there: 150 nm up and down every period is no net gain; trips at the
        // 200th period exactly.
        let n = (1..=1000u32).find(|k| w.update(x - 150 * i64::from(k % 2), 400)).unwrap();
        assert_eq!(n, 200);
        // Turning round (now −x, from +x): the first window is four long, later ones one.
        w.start(-1, 200, x);
        let n = (1..=10_000u32).find(|_| w.update(x, 400)).unwrap();
        assert_eq!(n, 800);
        w.start(-1, 200, x);
        assert!(!w.update(x - 400, 400));
        let n = (1..=10_000u32).find(|_| w.update(x - 400, 400)).unwrap();
        assert_eq!(n, 200);
    }

    #[test]
    fn a_limit_stop_counts_once_per_move() {
        let mut s = supervisor();
        s.note_limit_stop();
        s.note_limit_stop();
        assert_eq!(s.limit_stops(), 1);
        s.start_run();
        s.note_limit_stop();
        assert_eq!(s.limit_stops(), 2);
        s.faults = u32::MAX;
        s.note_fault();
        assert_eq!(s.faults(), 0, "wraps");
    }
}
