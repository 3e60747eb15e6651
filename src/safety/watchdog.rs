//! Window watchdog (WWDG) settings. Its 7-bit counter counts down at PCLK / 4096 / 2^WDGTB; the
//! early-warning interrupt comes when it reaches 0x40 and the reset one count later (0x3F).
//! Reloading it with `T` gives the early warning `T − 0x40` counts after the reload.

/// Counter value at which the early-warning interrupt fires.
pub const EWI_COUNT: u8 = 0x40;
/// Largest counter value.
pub const MAX_COUNT: u8 = 0x7F;

/// Duration of one counter step in ns for a given bus clock and prescaler exponent (0..=7).
pub fn count_ns(pclk_hz: u32, wdgtb: u8) -> u64 {
    let div = 4096u64 << u64::from(wdgtb.min(7));
    div * 1_000_000_000 / u64::from(pclk_hz.max(1))
}

/// Reload value `T` so the early warning comes no earlier than `ewi_after_us` after a reload
/// (rounded up to whole counts); `None` when that does not fit the 7-bit counter.
pub fn reload_for(pclk_hz: u32, wdgtb: u8, ewi_after_us: u32) -> Option<u8> {
    let div = 4096u64 << u64::from(wdgtb.min(7));
    // counts = ceil(t · pclk / div)
    let num = u64::from(ewi_after_us) * u64::from(pclk_hz);
    let den = 1_000_000 * div;
    let counts = num.div_ceil(den).max(1);
    let t = u64::from(EWI_COUNT) + counts;
    (t <= u64::from(MAX_COUNT)).then_some(t as u8)
}

/// The communication executor's heartbeat as the tick sees it. The tick feeds the window
/// watchdog on every period it runs on time (that one watches the tick), but the independent
/// watchdog only while this says the executor that runs the UART, the preload reading and the
/// flash store is alive too: a hung executor then ends in the independent watchdog's reset, with
/// every pin at its reset state (the amplifier's enable pulled low), instead of an idle
/// controller holding the enable high with nobody listening.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Heartbeat {
    last_beat: u32,
    quiet_ticks: u32,
}

impl Heartbeat {
    /// Ticks without a new beat before the executor counts as dead: 30 ms at 10 kHz, three of
    /// the monitor task's 10 ms beats.
    pub const STALE_TICKS: u32 = 300;

    /// One tick that reads the executor's beat counter `beat`: whether it is alive (a beat came
    /// within [`Self::STALE_TICKS`]).
    pub fn alive(&mut self, beat: u32) -> bool {
        if beat != self.last_beat {
            self.last_beat = beat;
            self.quiet_ticks = 0;
        } else {
            self.quiet_ticks = self.quiet_ticks.saturating_add(1);
        }
        self.quiet_ticks < Self::STALE_TICKS
    }
}
