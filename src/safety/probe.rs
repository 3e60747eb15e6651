//! A floating preload input: an unplugged or broken bridge-amplifier cable leaves the ADC pin
//! open, where it reads whatever charge sits on it, often mid-scale, which the preload window
//! cannot tell from a real force. The firmware probes the pin now and then: it pulls the pin
//! weakly down (the GPIO's ~40 kΩ pull-down, input mode) for a while, converts, then pulls it up
//! and converts again. A driven input (the amplifier's low output impedance) barely moves; an
//! open one follows the pulls. [`FloatDetector`] judges each probe and debounces the verdicts.

/// Whether one probe says "open": the reading after the pull-up exceeds the one after the
/// pull-down by at least `threshold` words.
pub fn probe_says_floating(after_pull_down: u16, after_pull_up: u16, threshold: u16) -> bool {
    after_pull_up.saturating_sub(after_pull_down) >= threshold
}

/// Debounced verdict over the last four probes: floating once three of them said so, driven
/// again once none of the last four did.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct FloatDetector {
    history: u8,
    floating: bool,
}

impl FloatDetector {
    pub const fn new() -> Self {
        FloatDetector { history: 0, floating: false }
    }

    /// Adds one probe's verdict; returns the debounced state.
    pub fn record(&mut self, probe_floating: bool) -> bool {
        self.history = ((self.history << 1) | u8::from(probe_floating)) & 0x0F;
        let n = self.history.count_ones();
        if n >= 3 {
            self.floating = true;
        } else if n == 0 {
            self.floating = false;
        }
        self.floating
    }

    pub fn floating(&self) -> bool {
        self.floating
    }
}
