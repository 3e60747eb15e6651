//! Fine mode: no sine; both stacks hold a common static offset, the foot sticks to the slider
//! and carries it by a fraction of the stroke. Corrections step and settle, and the encoder must
//! see each one (encoder-loss check).

use super::{Controller, FaultCode, Mode, DAC_SAMPLES_PER_STEP};
use crate::fastmath::clamp_sym_f32;

/// Fine-mode encoder-loss check: a correction expected to move at least this many counts that
/// moves none counts as a miss; this many misses in a row trip [`FaultCode::EncoderLoss`].
const FINE_LOSS_MIN_COUNTS: i64 = 4;
const FINE_LOSS_MISSES: u32 = 3;
/// Periods at rest at the commanded offset before a correction is checked or a new one measured.
const SETTLE_PERIODS: u32 = 4;
/// Fastest the offset moves (V/s).
const RATE_MAX_V_S: f32 = 20_000.0;

/// Highest speed from which a stop at `accel` ends within `distance` (v = √(2·a·d)).
fn profile_speed(accel: f32, distance: f32) -> f32 {
    crate::fastmath::sqrt_f32(2.0 * accel * distance)
}

/// The fine mode's step in progress: the offset commanded, the offset's rate on its way there,
/// periods at rest since it arrived, and the encoder-loss check of the last correction (the
/// counts it should move, 0 = none pending, and the count when it was commanded).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct FineStep {
    cmd_v: f32,
    rate_v_s: f32,
    settle: u32,
    expect_counts: i64,
    start_counts: i64,
}

impl FineStep {
    /// At rest at the offset the coarse mode left.
    pub(super) fn at(offset_v: f32) -> Self {
        FineStep { cmd_v: offset_v, rate_v_s: 0.0, settle: 0, expect_counts: 0, start_counts: 0 }
    }

    /// No encoder-loss check pending (the servo came on anew).
    pub(super) fn forget_check(&mut self) {
        self.expect_counts = 0;
    }
}

/// The static stroke the amplifier leaves and the window the fine mode works in.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct FineModeConfig {
    /// Largest common static offset (V) that keeps both stacks in range.
    pub(super) room_v: f32,
    /// Hand-off to the fine mode within this distance of the target (nm).
    pub(super) window_nm: f32,
}

/// What one fine period needs to know.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct FinePeriod {
    /// Reference − position (nm).
    pub(super) err_nm: f32,
    /// The encoder's count and its resolution (nm per count).
    pub(super) counts: i64,
    pub(super) nm_per_count: i64,
    /// Static foot displacement per volt of offset (nm/V, > 0).
    pub(super) nm_per_v: f32,
    /// What the still foot's friction holds the carriage with (N), and its moving mass (kg).
    pub(super) grip_n: f32,
    pub(super) mass_kg: f32,
    pub(super) dt_s: f32,
}

/// What the fine mode decided for this period.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum FineDecision {
    /// Go on with this step; the offset to put on the stacks is [`FineMode::offset_v`].
    Step(FineStep),
    /// The correction is out of static stroke: take it with the sine, which recentres.
    Coarse,
    /// Corrections the encoder never saw: [`FaultCode::EncoderLoss`].
    Trip(FaultCode),
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct FineMode {
    cfg: FineModeConfig,
    /// Common static offset on both stacks (V).
    offset_v: f32,
    /// Corrections in a row the encoder missed (carried across fine-mode entries: a frozen
    /// encoder sends the fine mode out of stroke and back through the coarse mode).
    misses: u32,
}

impl FineMode {
    pub(super) fn new(cfg: FineModeConfig) -> Self {
        FineMode { cfg, offset_v: 0.0, misses: 0 }
    }

    pub(super) fn configure(&mut self, cfg: FineModeConfig) {
        self.cfg = cfg;
    }

    pub(super) fn offset_v(&self) -> f32 {
        self.offset_v
    }

    pub(super) fn room_v(&self) -> f32 {
        self.cfg.room_v
    }

    /// The servo came on: no miss counts against the encoder.
    pub(super) fn forget_misses(&mut self) {
        self.misses = 0;
    }

    /// Whether the static stroke takes a move of `to_target_nm` from here: within the fine window
    /// and, with the offset already on the stacks, inside the stroke with margin (`model_nm_per_v`:
    /// the calibrated stroke per volt).
    pub(super) fn takes(&self, to_target_nm: f32, model_nm_per_v: f32) -> bool {
        let nm_per_v = model_nm_per_v.max(1e-3);
        let fine_room_nm = self.cfg.room_v * model_nm_per_v;
        let fits = (self.offset_v + to_target_nm / nm_per_v).abs() < 0.9 * self.cfg.room_v;
        fits && to_target_nm.abs() < self.cfg.window_nm.min(0.8 * fine_room_nm)
    }

    /// The sine's peak-to-peak swing at `amplitude_v` that the amplifier's range leaves it with
    /// the offset on the stacks (V): the offset clips the sine on one side until it is back to
    /// centre.
    pub(super) fn sine_swing_v(&self, amplitude_v: f32) -> f32 {
        let half = 0.5 * amplitude_v;
        let room = self.cfg.room_v;
        let up = half.min(room - self.offset_v);
        let down = half.min(room + self.offset_v);
        (up + down).max(0.0)
    }

    /// A coarse period: the offset on its way back to centre within a few milliseconds (the foot
    /// slides under the sine anyway). Returns the offset (V).
    pub(super) fn recentre(&mut self, dt_s: f32) -> f32 {
        let recentre = 100.0 * dt_s * self.cfg.room_v;
        self.offset_v -= clamp_sym_f32(self.offset_v, recentre);
        self.offset_v
    }

    /// One fine period with step `f` in progress. The offset moves along its own trapezoid
    /// (acceleration kept well below what static friction can give the moving mass); a new
    /// correction is measured only once the last one has been carried out and seen by the encoder
    /// (step and settle).
    pub(super) fn update(&mut self, mut f: FineStep, p: &FinePeriod) -> FineDecision {
        let at_rest = f.rate_v_s == 0.0 && (f.cmd_v - self.offset_v).abs() < 1e-3;
        if at_rest {
            f.settle = f.settle.saturating_add(1);
            if f.settle >= SETTLE_PERIODS && f.expect_counts != 0 && self.check_seen(&mut f, p.counts) {
                return FineDecision::Trip(FaultCode::EncoderLoss);
            }
            if f.settle >= SETTLE_PERIODS && !self.correct(&mut f, p) {
                return FineDecision::Coarse;
            }
        } else {
            f.settle = 0;
        }
        self.ramp(&mut f, p);
        FineDecision::Step(f)
    }

    /// The last correction has been carried out and settled: did the encoder see it? True when
    /// the misses in a row reach [`FINE_LOSS_MISSES`].
    fn check_seen(&mut self, f: &mut FineStep, counts: i64) -> bool {
        let moved = counts.saturating_sub(f.start_counts);
        if f.expect_counts.abs() >= FINE_LOSS_MIN_COUNTS && moved == 0 {
            self.misses = self.misses.saturating_add(1);
        } else if moved != 0 {
            self.misses = 0;
        }
        f.expect_counts = 0;
        self.misses >= FINE_LOSS_MISSES
    }

    /// A new correction when the error is over half a count; false when it is out of stroke.
    fn correct(&self, f: &mut FineStep, p: &FinePeriod) -> bool {
        let half_count = 0.5 * p.nm_per_count as f32;
        if p.err_nm.abs() <= half_count {
            return true;
        }
        // The count says only which bin the slider is in, and a slider that has just crossed
        // into the next bin sits at its edge: stepping a whole count carried it to the far edge
        // of the target's bin, where the step's own settling took it out again (5 kg: 50.9 nm).
        // Half a count short lands it inside, or one count low for another half-count step.
        let step_nm = p.err_nm - p.err_nm.signum() * half_count;
        let wanted = self.offset_v + step_nm / p.nm_per_v;
        if wanted.abs() > self.cfg.room_v {
            return false;
        }
        f.cmd_v = wanted;
        f.settle = 0;
        f.expect_counts = (p.err_nm / p.nm_per_count.max(1) as f32) as i64;
        f.start_counts = p.counts;
        true
    }

    /// The offset's trapezoid toward the commanded one.
    fn ramp(&mut self, f: &mut FineStep, p: &FinePeriod) {
        let accel_v_s2 = (0.25 * p.grip_n / p.mass_kg / (p.nm_per_v * 1e-9)).max(1.0);
        let d = f.cmd_v - self.offset_v;
        let dt = p.dt_s;
        let mut rate_des = d.signum() * RATE_MAX_V_S.min(profile_speed(accel_v_s2, d.abs()));
        if d.abs() < 1e-4 {
            rate_des = 0.0;
        }
        f.rate_v_s += clamp_sym_f32(rate_des - f.rate_v_s, accel_v_s2 * dt);
        let next = self.offset_v + f.rate_v_s * dt;
        if (f.cmd_v - next) * d <= 0.0 {
            self.offset_v = f.cmd_v;
            f.rate_v_s = 0.0;
        } else {
            self.offset_v = next;
        }
    }
}

impl Controller {
    /// Fine mode: the foot sticks to the slider and carries it by the static stroke
    /// ([`FineMode::update`]).
    pub(super) fn fine(&mut self, err_nm: f32) {
        let Mode::Fine(f) = self.status.mode else { return };
        let period = FinePeriod {
            err_nm,
            counts: self.feedback.encoder().map_or(0, |e| e.counts()),
            nm_per_count: self.feedback.encoder().map_or(50, |e| e.nm_per_count()),
            nm_per_v: self.model.fine_nm_per_v.max(1e-3),
            grip_n: self.grip_n(),
            mass_kg: self.moving_mass_kg(),
            dt_s: self.dt_s,
        };
        match self.fine.update(f, &period) {
            FineDecision::Step(f) => {
                self.status.mode = Mode::Fine(f);
                let offset = self.fine.offset_v();
                self.drive.generator.ramp_static_offsets_v([offset; 2], DAC_SAMPLES_PER_STEP as u32);
            }
            FineDecision::Coarse => self.status.mode = Mode::Coarse,
            FineDecision::Trip(code) => self.trip(code),
        }
    }

    /// Largest common static offset (V) that keeps both stacks in range.
    pub(super) fn fine_room_v(&self) -> f32 {
        self.fine.room_v()
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::panic)] // a test fails by panicking
mod tests {
    use super::*;

    const DT_S: f32 = 1e-4;

    /// ±10 V of stroke, a 500 nm window.
    fn fine() -> FineMode {
        FineMode::new(FineModeConfig { room_v: 10.0, window_nm: 500.0 })
    }

    /// 100 nm/V, 50 nm counts; 4 N grip on 1 kg: a = 0.25 · 4 / 1 / 1e-7 = 1e7 V/s².
    fn period(err_nm: f32, counts: i64) -> FinePeriod {
        FinePeriod {
            err_nm,
            counts,
            nm_per_count: 50,
            nm_per_v: 100.0,
            grip_n: 4.0,
            mass_kg: 1.0,
            dt_s: DT_S,
        }
    }

    fn step(d: FineDecision) -> FineStep {
        match d {
            FineDecision::Step(f) => f,
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn takes_what_the_window_and_the_stroke_allow() {
        let mut m = fine();
        // 400 nm: 4 V of 9 usable, inside min(500, 0.8 · 1000) nm.
        assert!(m.takes(400.0, 100.0));
        assert!(!m.takes(600.0, 100.0), "outside the window");
        m.offset_v = 8.0;
        assert!(!m.takes(200.0, 100.0), "8 + 2 V is past 90 % of the stroke");
        assert!(m.takes(-200.0, 100.0));
    }

    #[test]
    fn a_correction_steps_half_a_count_short_and_arrives_on_a_trapezoid() {
        let mut m = fine();
        let mut f = FineStep::at(0.0);
        // Three periods settling, the fourth measures: 200 nm − 25 nm = 175 nm = 1.75 V.
        for _ in 0..3 {
            f = step(m.update(f, &period(200.0, 0)));
            assert_eq!(f.cmd_v, 0.0);
        }
        f = step(m.update(f, &period(200.0, 0)));
        assert!((f.cmd_v - 1.75).abs() < 1e-6);
        assert_eq!(f.expect_counts, 4);
        // Triangle at 1e7 V/s² over 1.75 V: 2·√(1.75 / 1e7) = 0.84 ms, 8.4 periods; the
        // discrete ramp (rate first, then offset) and the snap onto the command save up to one
        // and a half, the last slow approach costs a few. The rate never passes the triangle's
        // peak √(a·D) = 4183 V/s by more than one period's a·dt = 1000 V/s.
        let mut periods = 1;
        while m.offset_v() != f.cmd_v {
            f = step(m.update(f, &period(200.0, 0)));
            assert!(f.rate_v_s <= 4183.0 + 1000.0, "{}", f.rate_v_s);
            periods += 1;
            assert!(periods < 20, "not there after {periods} periods: {}", m.offset_v());
        }
        assert!(periods >= 7, "{periods}");
        assert_eq!(f.rate_v_s, 0.0);
    }

    #[test]
    fn no_correction_within_half_a_count() {
        let mut m = fine();
        let mut f = FineStep::at(1.0);
        m.offset_v = 1.0;
        for _ in 0..10 {
            f = step(m.update(f, &period(25.0, 0)));
        }
        assert_eq!((f.cmd_v, m.offset_v()), (1.0, 1.0));
    }

    #[test]
    fn out_of_stroke_goes_coarse() {
        let mut m = fine();
        let mut f = FineStep::at(9.0);
        m.offset_v = 9.0;
        for _ in 0..3 {
            f = step(m.update(f, &period(200.0, 0)));
        }
        // 9 + 1.75 V > 10 V.
        assert_eq!(m.update(f, &period(200.0, 0)), FineDecision::Coarse);
    }

    #[test]
    fn three_unseen_corrections_are_encoder_loss() {
        let mut m = fine();
        let mut f = FineStep::at(0.0);
        let mut err = 200.0;
        let mut decisions = 0;
        loop {
            match m.update(f, &period(err, 0)) {
                FineDecision::Step(next) => f = next,
                FineDecision::Trip(code) => {
                    assert_eq!(code, FaultCode::EncoderLoss);
                    break;
                }
                FineDecision::Coarse => panic!("out of stroke"),
            }
            // The encoder never moves; the error stays and alternates so the offset stays small.
            if f.settle == 0 && f.expect_counts != 0 {
                err = -err;
            }
            decisions += 1;
            assert!(decisions < 200);
        }
        assert_eq!(m.misses, 3);
        // Seen corrections clear the count.
        let mut m = fine();
        m.misses = 2;
        let mut f = FineStep::at(0.0);
        f.expect_counts = 4;
        f.start_counts = 0;
        for _ in 0..4 {
            f = step(m.update(f, &period(0.0, 3)));
        }
        assert_eq!(m.misses, 0);
    }

    #[test]
    fn recentres_at_a_hundred_strokes_a_second() {
        // 100 · 1e-4 s · 10 V = 0.1 V a period: 5 V back to 0 in 50 periods.
        let mut m = fine();
        m.offset_v = 5.0;
        let periods = (1..=100).find(|_| m.recentre(DT_S) == 0.0).unwrap();
        assert!((50..=51).contains(&periods), "{periods}");
    }

    #[test]
    fn the_offset_clips_the_sine() {
        let mut m = fine();
        assert_eq!(m.sine_swing_v(16.0), 16.0);
        // 4 V offset leaves 6 V above: 6 + 8.
        m.offset_v = 4.0;
        assert_eq!(m.sine_swing_v(16.0), 14.0);
    }
}
