//! The supervisor's judgement of closed-loop motion (following error, stall) and the counts the
//! protocol watches (faults, limit-switch stops, failed referencing). The controller reads the
//! sensors and trips the fault it returns (`supervision.rs`).

use super::FaultCode;

/// The limits the supervisor judges by.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct SupervisorConfig {
    pub(super) following_error_limit_nm: f32,
    pub(super) stall_time_s: f32,
    pub(super) encoder_jump_counts: i32,
    /// Largest drive (V): "near full" and "full" drive are shares of it.
    pub(super) max_drive_v: f32,
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
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Supervisor {
    cfg: SupervisorConfig,
    /// Time the slider has not followed a near-full drive (s; sliding back counts five times).
    stall_s: f32,
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
}

impl Supervisor {
    pub(super) fn new(cfg: SupervisorConfig) -> Self {
        Supervisor {
            cfg,
            stall_s: 0.0,
            max_following_error_nm: 0.0,
            faults: 0,
            limit_stops: 0,
            limit_stopped: false,
            reference_failures: 0,
        }
    }

    pub(super) fn configure(&mut self, cfg: SupervisorConfig) {
        self.cfg = cfg;
    }

    /// An encoder step of `delta_counts` in one period is a jump (a lost or noisy signal).
    pub(super) fn encoder_jumped(&self, delta_counts: i32) -> bool {
        delta_counts.abs() > self.cfg.encoder_jump_counts
    }

    /// One closed-loop period: the fault to trip, if any.
    pub(super) fn update(&mut self, p: &ClosedLoopPeriod) -> Option<FaultCode> {
        // Stall/slip: the foot is driven near full but the slider does not move the driven way
        // (commanded foot speed against encoder speed). Near full: below it the controller still
        // has thrust to give, and a heavy carriage creeping up to its target against an unknown
        // load at half the drive is no stall (50 kg against 2 N, half its stall force, tripped at
        // 54 V with the threshold at 50 %; now it settles).
        let max_v = self.cfg.max_drive_v;
        let driving = p.coarse && p.drive_v > 0.9 * max_v;
        let not_following = driving && p.dir * p.speed_nm_s < 0.1 * p.foot_speed_nm_s;
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
            self.stall_s += if backwards { 5.0 * p.dt_s } else { p.dt_s };
            if self.stall_s >= self.cfg.stall_time_s {
                return Some(FaultCode::Stall);
            }
        } else {
            self.stall_s = 0.0;
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
            stall_time_s: 0.01,
            encoder_jump_counts: 100,
            max_drive_v: 100.0,
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
        }
    }

    /// Periods until `p` repeated trips, at most `limit`.
    fn periods_to_trip(s: &mut Supervisor, p: &ClosedLoopPeriod, limit: u32) -> Option<(u32, FaultCode)> {
        (1..=limit).find_map(|n| s.update(p).map(|c| (n, c)))
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
        // 100 periods of 0.1 ms (float sums: within one period).
        let mut s = supervisor();
        let (n, code) = periods_to_trip(&mut s, &period(95.0, 1.0e5, 0.0), 1000).unwrap();
        assert_eq!(code, FaultCode::Stall);
        assert!((99..=101).contains(&n), "{n}");
    }

    #[test]
    fn sliding_back_at_full_drive_counts_five_times() {
        // −0.3 mm/s < −10 % of 2 mm/s at 95 V: 0.01 s / 0.5 ms = 20 periods.
        let mut s = supervisor();
        let (n, code) = periods_to_trip(&mut s, &period(95.0, -3.0e5, 0.0), 1000).unwrap();
        assert_eq!(code, FaultCode::Stall);
        assert!((19..=21).contains(&n), "{n}");
    }

    #[test]
    fn no_stall_below_near_full_drive_or_while_following() {
        let mut s = supervisor();
        assert_eq!(periods_to_trip(&mut s, &period(90.0, 0.0, 0.0), 1000), None);
        assert_eq!(periods_to_trip(&mut s, &period(95.0, 3.0e5, 0.0), 1000), None);
        // A following period resets the timer: 99 stuck periods, one moving, 99 stuck again.
        for _ in 0..99 {
            assert_eq!(s.update(&period(95.0, 0.0, 0.0)), None);
        }
        assert_eq!(s.update(&period(95.0, 3.0e5, 0.0)), None);
        for _ in 0..98 {
            assert_eq!(s.update(&period(95.0, 0.0, 0.0)), None);
        }
    }

    #[test]
    fn following_error_beyond_the_limit() {
        let mut s = supervisor();
        assert_eq!(s.update(&period(50.0, 1.0e6, 9_000.0)), None);
        assert_eq!(s.update(&period(50.0, 1.0e6, -10_001.0)), Some(FaultCode::FollowingError));
        assert_eq!(s.max_following_error_nm(), 10_001.0);
        // At full drive towards the reference with the slider not following: a stall.
        assert_eq!(s.update(&period(96.0, 0.0, 10_001.0)), Some(FaultCode::Stall));
        s.start_move();
        assert_eq!(s.max_following_error_nm(), 0.0);
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
