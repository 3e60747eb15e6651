//! Soft start of the amplifier: while its enable is low the amplifier's output sits at its rest
//! level (0 V for a 0–100 V amplifier), but the controller's quiet output is mid-scale (50 V).
//! Enabling it there would step the stacks by 50 V. [`SoftStart`] sits between the controller's
//! DAC words and the drive buffer: while the enable is low it holds every sample at the rest word;
//! once the enable goes high it blends from the rest word to the controller's words over a fixed
//! number of samples, linearly, and then passes them through unchanged. Every time the enable
//! drops it starts over. An orderly disable ramps down the same way before the enable drops
//! ([`SoftStart::ramp_down`]); only a fault cuts at once.

/// The blend from the amplifier's rest word to the controller's output.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SoftStart {
    rest: u16,
    ramp_samples: u32,
    done_samples: u32,
}

impl SoftStart {
    /// `rest`: DAC word equal to the amplifier's output while disabled; `ramp_samples`: length of
    /// the ramp (0 = no ramp).
    pub const fn new(rest: u16, ramp_samples: u32) -> Self {
        SoftStart { rest, ramp_samples, done_samples: 0 }
    }

    /// Applies the enable state of this period to its samples (in place).
    pub fn apply(&mut self, enable: bool, samples: &mut [[u16; 2]]) {
        if !enable {
            self.done_samples = 0;
            for s in samples.iter_mut() {
                *s = [self.rest; 2];
            }
            return;
        }
        for s in samples.iter_mut() {
            if self.done_samples >= self.ramp_samples {
                return;
            }
            for w in s.iter_mut() {
                *w = blend(self.rest, *w, self.done_samples, self.ramp_samples);
            }
            self.done_samples += 1;
        }
    }

    /// An orderly disable (parking for a flash store, not a fault): the same blend run backwards,
    /// from the controller's words down to the rest word, one sample at a time; true once the
    /// drive has reached rest (all of `samples` at the rest word), when the enable may drop
    /// without a step. A fault does not wait for it: [`Self::apply`] with the enable low.
    pub fn ramp_down(&mut self, samples: &mut [[u16; 2]]) -> bool {
        if self.ramp_samples == 0 {
            self.apply(false, samples);
            return true;
        }
        for s in samples.iter_mut() {
            self.done_samples = self.done_samples.saturating_sub(1);
            for w in s.iter_mut() {
                *w = blend(self.rest, *w, self.done_samples, self.ramp_samples);
            }
        }
        self.done_samples == 0
    }

    /// The drive is at the rest word (the enable may drop without a step).
    pub fn at_rest(&self) -> bool {
        self.done_samples == 0
    }

    /// The ramp is over: samples pass unchanged.
    pub fn done(&self) -> bool {
        self.done_samples >= self.ramp_samples
    }

    pub const fn rest(&self) -> u16 {
        self.rest
    }
}

/// `rest + (word − rest) · k / n`, rounded toward `rest`, in 32-bit integer arithmetic (it runs
/// in the control tick, where a 64-bit division is a software routine, `.ci/elf-gate`):
/// `|word − rest| · k` fits in a u32 for `k < n ≤ 65 536`; a longer ramp is scaled down to that
/// (the blend then moves in steps of `n / 65 536` samples).
fn blend(rest: u16, word: u16, k: u32, n: u32) -> u16 {
    if n == 0 || k >= n {
        return word;
    }
    let shift = (32 - (n - 1).leading_zeros()).saturating_sub(16);
    let (k, n) = (k >> shift, n >> shift);
    let magnitude = u32::from(word.abs_diff(rest));
    let step = magnitude.saturating_mul(k) / n.max(1);
    let step = u16::try_from(step).unwrap_or(u16::MAX);
    if word >= rest {
        rest.saturating_add(step)
    } else {
        rest.saturating_sub(step)
    }
}
