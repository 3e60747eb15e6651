//! Quadrature sine generator: a u32 phase accumulator and the sine table make the DAC words for
//! both stacks, a quarter period apart. Frequency changes keep the phase continuous; amplitude and
//! the static (DC) offsets slew at a bounded rate; a direction change ramps the amplitude to zero,
//! flips the quarter-period offset and ramps back, so no command makes a step in the output.

use crate::fastmath::{clamp_f32, clamp_i32};
use crate::trig::sin_turn_q30;

/// DAC and amplifier: volts at the amplifier output per DAC word, and the allowed output range.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct DacConfig {
    /// Amplifier output at DAC word 4095 (the DAC's full scale), volts.
    pub full_scale_v: f32,
    /// Output range no command can leave, volts.
    pub min_v: f32,
    pub max_v: f32,
    /// DAC sample rate (Hz).
    pub sample_rate_hz: u32,
    /// Allowed drive frequency range (Hz).
    pub min_freq_hz: f32,
    pub max_freq_hz: f32,
    /// Largest amplitude or offset change per sample, volts (slew limit).
    pub slew_v_per_sample: f32,
}

impl DacConfig {
    pub const DAC_MAX_WORD: u16 = 4095;

    /// Volts at the amplifier output → DAC word in 1/65536 of a word (Q16), clamped to the range
    /// and to the 12-bit word range (so every Q16 quantity fits an i32 with room for sums).
    fn volts_to_q16(&self, v: f32) -> i32 {
        let v = clamp_f32(v, self.min_v, self.max_v);
        let words = clamp_f32(v / self.full_scale_v * f32::from(Self::DAC_MAX_WORD), 0.0, 4095.0);
        (words * 65536.0) as i32
    }
    pub fn mid_v(&self) -> f32 {
        0.5 * (self.min_v + self.max_v)
    }
    /// Words to volts (for telemetry and tests).
    pub fn word_to_volts(&self, w: u16) -> f32 {
        f32::from(w) * self.full_scale_v / f32::from(Self::DAC_MAX_WORD)
    }
}

/// Output levels in Q16 words: mid-range and the clamps.
#[derive(Debug, Clone, Copy)]
struct Levels {
    mid: i32,
    min: i32,
    max: i32,
}

impl Levels {
    #[inline(always)]
    fn word(self, phase: u32, dc_q16: i32, amp_q16: i32) -> u16 {
        // amplitude (< 2²⁸) × sine (Q30): one 32×32→64 multiply.
        let ac = ((i64::from(amp_q16) * i64::from(sin_turn_q30(phase))) >> 30) as i32;
        let v = clamp_i32(self.mid + dc_q16 + ac, self.min, self.max);
        // min..max lie within the DAC's words (`volts_to_q16` clamps them), so the rounded word
        // is within 0..=4095 without a second clamp.
        ((v + 32768) >> 16) as u16
    }
}

/// Quadrature generator state. All internal quantities are DAC words in Q16, in i32: the whole
/// 12-bit range is below 2²⁸, so sums of mid, offset and amplitude cannot overflow, and the
/// per-sample arithmetic stays in single 32-bit instructions on the Cortex-M4.
#[derive(Debug, Clone)]
pub struct QuadratureGenerator {
    cfg: DacConfig,
    phase: u32,
    step: u32,
    freq_hz: f32,
    direction: i8,
    pending_direction: i8,
    amp_q16: i32,
    amp_target_q16: i32,
    mid_q16: i32,
    static_q16: [i32; 2],
    static_target_q16: [i32; 2],
    /// Per-sample step of a timed static ramp (0: use the slew limit).
    static_step_q16: [i32; 2],
    slew_q16: i32,
    min_q16: i32,
    max_q16: i32,
}

impl QuadratureGenerator {
    pub fn new(cfg: DacConfig) -> Self {
        let mid = cfg.volts_to_q16(cfg.mid_v());
        let mut g = QuadratureGenerator {
            cfg,
            phase: 0,
            step: 0,
            freq_hz: 0.0,
            direction: 1,
            pending_direction: 1,
            amp_q16: 0,
            amp_target_q16: 0,
            mid_q16: mid,
            static_q16: [0; 2],
            static_target_q16: [0; 2],
            static_step_q16: [0; 2],
            slew_q16: 1,
            min_q16: cfg.volts_to_q16(cfg.min_v),
            max_q16: cfg.volts_to_q16(cfg.max_v),
        };
        g.reset_slew();
        g.set_frequency_hz(cfg.min_freq_hz);
        g
    }

    pub fn config(&self) -> &DacConfig {
        &self.cfg
    }

    /// Sets the drive frequency, clamped to the allowed range; the phase continues.
    pub fn set_frequency_hz(&mut self, f: f32) {
        let f = if f.is_finite() {
            clamp_f32(f, self.cfg.min_freq_hz, self.cfg.max_freq_hz)
        } else {
            self.cfg.min_freq_hz
        };
        if f == self.freq_hz && self.step != 0 {
            // The same frequency as now: the step is already right.
            return;
        }
        self.freq_hz = f;
        // Phase step per sample, f/rate of a turn in 2^32 units, in f32 on the FPU: this runs in
        // the control tick, where f64 and 64-bit division would be software routines
        // (`.ci/elf-gate`). f32's 24-bit mantissa puts the step within a few units of 2^-32 of
        // a turn: under 0.001 Hz at 200 kS/s.
        let per_hz = 4_294_967_296.0_f32 / self.cfg.sample_rate_hz.max(1) as f32;
        self.step = (f * per_hz) as u32;
    }

    pub fn frequency_hz(&self) -> f32 {
        self.freq_hz
    }

    /// Peak-to-peak sine amplitude (V) to ramp to, clamped so mid ± amplitude/2 stays in range.
    pub fn set_amplitude_v(&mut self, volts_pp: f32) {
        let half_v = if volts_pp.is_finite() { 0.5 * volts_pp.max(0.0) } else { 0.0 };
        let room = (self.cfg.mid_v() - self.cfg.min_v).min(self.cfg.max_v - self.cfg.mid_v());
        let half = half_v.min(room);
        let words = clamp_f32(half / self.cfg.full_scale_v * f32::from(DacConfig::DAC_MAX_WORD), 0.0, 4095.0);
        self.amp_target_q16 = (words * 65536.0) as i32;
    }

    /// Present peak-to-peak amplitude (V), after slewing.
    pub fn amplitude_v(&self) -> f32 {
        2.0 * self.amp_q16 as f32 / 65536.0 * self.cfg.full_scale_v / f32::from(DacConfig::DAC_MAX_WORD)
    }

    /// +1: channel 2 lags channel 1 by a quarter period (foot moves +x); −1: it leads.
    pub fn set_direction(&mut self, direction: i8) {
        self.pending_direction = if direction < 0 { -1 } else { 1 };
    }

    pub fn direction(&self) -> i8 {
        self.direction
    }

    /// Static offsets from mid-range on each stack (V), for fine positioning while the sine is
    /// off; clamped to the output range.
    pub fn set_static_offsets_v(&mut self, offsets: [f32; 2]) {
        self.static_step_q16 = [0; 2];
        let mid = self.cfg.mid_v();
        for (t, o) in self.static_target_q16.iter_mut().zip(offsets) {
            let o = if o.is_finite() { o } else { 0.0 };
            *t = self.cfg.volts_to_q16(mid + o) - self.mid_q16;
        }
    }

    /// Static offsets reached by a straight ramp spread evenly over the next `samples` samples,
    /// so the foot moves at a constant speed within a control period (fine positioning: a
    /// stuck foot must not jerk the slider).
    pub fn ramp_static_offsets_v(&mut self, offsets: [f32; 2], samples: u32) {
        if offsets == [0.0; 2] && self.static_target_q16 == [0; 2] && self.static_q16 == [0; 2] {
            // Already resting at mid-range (every coarse period once the offset is recentred):
            // a new ramp would change nothing the outputs show.
            return;
        }
        self.set_static_offsets_v(offsets);
        let n = samples.clamp(1, 1 << 16) as i32;
        for ((step, target), now) in
            self.static_step_q16.iter_mut().zip(self.static_target_q16).zip(self.static_q16)
        {
            *step = ((target - now).abs() + n - 1) / n;
        }
    }

    /// Both outputs at mid-range with no sine: where every ramp ends in the safe state.
    pub fn is_quiet(&self) -> bool {
        self.amp_q16 == 0 && self.static_q16 == [0, 0]
    }

    /// Sets every target to zero (sine off, no offsets); the outputs ramp there.
    pub fn ramp_to_quiet(&mut self) {
        self.amp_target_q16 = 0;
        self.static_target_q16 = [0, 0];
        self.static_step_q16 = [0; 2];
    }

    /// Ramps every output to mid-range within `samples` samples (the fault path): the slew rate
    /// is raised just enough, and restored by [`Self::reset_slew`].
    pub fn quiet_within(&mut self, samples: u32) {
        self.ramp_to_quiet();
        let largest = self.static_q16.iter().fold(self.amp_q16.abs(), |m, s| m.max(s.abs()));
        let needed = largest / samples.clamp(1, 1 << 16) as i32 + 1;
        self.slew_q16 = self.slew_q16.max(needed);
    }

    /// Back to the configured slew rate.
    pub fn reset_slew(&mut self) {
        let words = clamp_f32(
            self.cfg.slew_v_per_sample / self.cfg.full_scale_v * f32::from(DacConfig::DAC_MAX_WORD),
            0.0,
            4095.0,
        );
        self.slew_q16 = (words * 65536.0) as i32;
        self.slew_q16 = self.slew_q16.max(1);
    }

    fn slew(value: &mut i32, target: i32, step: i32) {
        *value += clamp_i32(target - *value, -step, step);
    }

    /// The next sample for both channels.
    pub fn next_words(&mut self) -> [u16; 2] {
        // A direction change waits for the amplitude to reach zero, so ch2 never jumps.
        let target = if self.pending_direction != self.direction { 0 } else { self.amp_target_q16 };
        Self::slew(&mut self.amp_q16, target, self.slew_q16);
        if self.amp_q16 == 0 && self.pending_direction != self.direction {
            self.direction = self.pending_direction;
        }
        for ((s, t), step) in self.static_q16.iter_mut().zip(self.static_target_q16).zip(self.static_step_q16)
        {
            let limit = if step > 0 { step.min(self.slew_q16) } else { self.slew_q16 };
            Self::slew(s, t, limit);
        }
        let out = self.words_at(self.phase);
        self.phase = self.phase.wrapping_add(self.step);
        out
    }

    /// Both channels' words at a phase, with the present amplitude and offsets.
    #[inline(always)]
    fn words_at(&self, phase: u32) -> [u16; 2] {
        let [dc1, dc2] = self.static_q16;
        let l = self.levels();
        [l.word(phase, dc1, self.amp_q16), l.word(phase.wrapping_add(self.quadrature()), dc2, self.amp_q16)]
    }

    /// Phase of channel 2 relative to channel 1: a quarter turn behind (+1) or ahead (−1).
    #[inline(always)]
    fn quadrature(&self) -> u32 {
        let quarter: u32 = 1 << 30;
        if self.direction > 0 {
            quarter.wrapping_neg()
        } else {
            quarter
        }
    }

    fn levels(&self) -> Levels {
        Levels { mid: self.mid_q16, min: self.min_q16, max: self.max_q16 }
    }

    /// Fills a buffer of samples (e.g. one half of the circular DMA buffer). The loop works on
    /// local copies of the state so it runs in registers.
    pub fn fill(&mut self, buf: &mut [[u16; 2]]) {
        if self.pending_direction != self.direction {
            // A direction change in progress: the general per-sample path.
            for s in buf.iter_mut() {
                *s = self.next_words();
            }
            return;
        }
        let l = self.levels();
        let (step, slew, amp_t, offset) = (self.step, self.slew_q16, self.amp_target_q16, self.quadrature());
        let (mut phase, mut amp) = (self.phase, self.amp_q16);
        let [mut dc1, mut dc2] = self.static_q16;
        let [t1, t2] = self.static_target_q16;
        if amp == 0 && amp_t == 0 && [dc1, dc2] == [t1, t2] {
            // No sine (quiet, or the static fine mode): the same two words all period long; the
            // phase runs on as it would.
            let words = [l.word(phase, dc1, 0), l.word(phase, dc2, 0)];
            buf.fill(words);
            self.phase = phase.wrapping_add(step.wrapping_mul(buf.len() as u32));
            return;
        }
        if amp == amp_t && [dc1, dc2] == [t1, t2] {
            // Nothing slewing (the common case in a steady drive): only the phase advances.
            for s in buf.iter_mut() {
                *s = [l.word(phase, dc1, amp), l.word(phase.wrapping_add(offset), dc2, amp)];
                phase = phase.wrapping_add(step);
            }
            self.phase = phase;
            return;
        }
        if [dc1, dc2] == [t1, t2] {
            // Only the amplitude slews (the feedforward moved it, the usual case while moving):
            // the offsets stay where they are.
            for s in buf.iter_mut() {
                amp += clamp_i32(amp_t - amp, -slew, slew);
                *s = [l.word(phase, dc1, amp), l.word(phase.wrapping_add(offset), dc2, amp)];
                phase = phase.wrapping_add(step);
            }
            self.phase = phase;
            self.amp_q16 = amp;
            return;
        }
        let [l1, l2] = self.static_step_q16.map(|s| if s > 0 { s.min(slew) } else { slew });
        for s in buf.iter_mut() {
            amp += clamp_i32(amp_t - amp, -slew, slew);
            dc1 += clamp_i32(t1 - dc1, -l1, l1);
            dc2 += clamp_i32(t2 - dc2, -l2, l2);
            *s = [l.word(phase, dc1, amp), l.word(phase.wrapping_add(offset), dc2, amp)];
            phase = phase.wrapping_add(step);
        }
        self.phase = phase;
        self.amp_q16 = amp;
        self.static_q16 = [dc1, dc2];
    }

    /// Lowest and highest word the configured range allows (for tests and supervision).
    pub fn word_limits(&self) -> (u16, u16) {
        (((self.min_q16 + 32768) >> 16) as u16, ((self.max_q16 + 32768) >> 16) as u16)
    }
}
