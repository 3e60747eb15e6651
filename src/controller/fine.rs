//! Fine mode: no sine; both stacks hold a common static offset, the foot sticks to the slider
//! and carries it by a fraction of the stroke. Corrections step and settle, and the encoder must
//! see each one (encoder-loss check).

use super::{Controller, FaultCode, Mode, DAC_SAMPLES_PER_STEP};

/// The fine mode's step in progress: the offset commanded, the offset's rate on its way there,
/// periods at rest since it arrived, and the encoder-loss check of the last correction (the
/// counts it should move, 0 = none pending, and the count when it was commanded).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct FineStep {
    cmd_v: f32,
    rate_v_s: f32,
    settle: u32,
    pub(super) expect_counts: i64,
    start_counts: i64,
}

impl FineStep {
    /// At rest at the offset the coarse mode left.
    pub(super) fn at(offset_v: f32) -> Self {
        FineStep { cmd_v: offset_v, rate_v_s: 0.0, settle: 0, expect_counts: 0, start_counts: 0 }
    }
}
use crate::fastmath::clamp_sym_f32;

/// Fine-mode encoder-loss check: a correction expected to move at least this many counts that
/// moves none counts as a miss; this many misses in a row trip [`FaultCode::EncoderLoss`].
const FINE_LOSS_MIN_COUNTS: i64 = 4;
const FINE_LOSS_MISSES: u32 = 3;

/// Highest speed from which a stop at `accel` ends within `distance` (v = √(2·a·d)).
fn profile_speed(accel: f32, distance: f32) -> f32 {
    crate::fastmath::sqrt_f32(2.0 * accel * distance)
}

impl Controller {
    /// Fine mode: the foot sticks to the slider and carries it by the static stroke. The offset
    /// moves along its own trapezoid (acceleration kept well below what static friction can
    /// give the moving mass); a new correction is measured only once the last one has been
    /// carried out and seen by the encoder (step and settle).
    pub(super) fn fine(&mut self, err_nm: f32) {
        let Mode::Fine(mut f) = self.mode else { return };
        let nm_per_v = self.model.fine_nm_per_v.max(1e-3);
        let room = self.fine_room_v();
        let at_rest = f.rate_v_s == 0.0 && (f.cmd_v - self.fine_offset_v).abs() < 1e-3;
        let counts = self.encoder.map_or(0, |e| e.counts());
        if at_rest {
            f.settle = f.settle.saturating_add(1);
            if f.settle >= 4 && f.expect_counts != 0 {
                // The last correction has been carried out and settled: did the encoder see it?
                let moved = counts.saturating_sub(f.start_counts);
                if f.expect_counts.abs() >= FINE_LOSS_MIN_COUNTS && moved == 0 {
                    self.fine_misses = self.fine_misses.saturating_add(1);
                } else if moved != 0 {
                    self.fine_misses = 0;
                }
                f.expect_counts = 0;
                if self.fine_misses >= FINE_LOSS_MISSES {
                    return self.trip(FaultCode::EncoderLoss);
                }
            }
            let nm_per_count = self.encoder.map_or(50, |e| e.nm_per_count());
            let half_count = 0.5 * nm_per_count as f32;
            if f.settle >= 4 && err_nm.abs() > half_count {
                // The count says only which bin the slider is in, and a slider that has just
                // crossed into the next bin sits at its edge: stepping a whole count carried it
                // to the far edge of the target's bin, where the step's own settling took it out
                // again (5 kg: 50.9 nm). Half a count short lands it inside, or one count low
                // for another half-count step.
                let step_nm = err_nm - err_nm.signum() * half_count;
                let wanted = self.fine_offset_v + step_nm / nm_per_v;
                if wanted.abs() > room {
                    // Out of static stroke: take the step with the sine, which recentres.
                    self.mode = Mode::Coarse;
                    return;
                }
                f.cmd_v = wanted;
                f.settle = 0;
                f.expect_counts = (err_nm / nm_per_count.max(1) as f32) as i64;
                f.start_counts = counts;
            }
        } else {
            f.settle = 0;
        }
        // Trapezoid toward the commanded offset.
        let mass = self.moving_mass_kg();
        let grip_n = self.grip_n();
        let accel_v_s2 = (0.25 * grip_n / mass / (nm_per_v * 1e-9)).max(1.0);
        let rate_max_v_s: f32 = 20_000.0;
        let d = f.cmd_v - self.fine_offset_v;
        let dt = self.dt_s;
        let mut rate_des = d.signum() * rate_max_v_s.min(profile_speed(accel_v_s2, d.abs()));
        if d.abs() < 1e-4 {
            rate_des = 0.0;
        }
        f.rate_v_s += clamp_sym_f32(rate_des - f.rate_v_s, accel_v_s2 * dt);
        let next = self.fine_offset_v + f.rate_v_s * dt;
        if (f.cmd_v - next) * d <= 0.0 {
            self.fine_offset_v = f.cmd_v;
            f.rate_v_s = 0.0;
        } else {
            self.fine_offset_v = next;
        }
        self.mode = Mode::Fine(f);
        self.generator.ramp_static_offsets_v([self.fine_offset_v; 2], DAC_SAMPLES_PER_STEP as u32);
    }

    /// Largest common static offset (V) that keeps both stacks in range.
    pub(super) fn fine_room_v(&self) -> f32 {
        let d = &self.cfg.dac;
        (d.mid_v() - d.min_v).min(d.max_v - d.mid_v())
    }
}
