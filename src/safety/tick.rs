//! The control tick's order of operations, over the board's peripherals ([`TickBoard`]), so that
//! the host tests run the very sequence the firmware's TIM7 handler runs (`tests/tick.rs`):
//!
//! 1. **Refill first**: the samples the previous step computed go into the ring half the DMA is
//!    not reading, through the soft start; the enable is set for them (low at once when the
//!    controller or a latched overrun wants it low; parking ramps the drive down to rest first).
//! 2. **Lateness**: the overrun supervisor judges the tick (deadline, missed periods, the DMA
//!    already in the half just written); a trip drops the enable at once, latches the
//!    controller's `Overrun` fault and records it.
//! 3. **Step**: encoder count, preload word (an invalid word once the ADC has gone quiet for
//!    [`PRELOAD_STALE_TICKS`]), index latch, limit switches (when wired and enabled: active at
//!    the set level from the first such reading, released after [`LIMIT_RELEASE_TICKS`] quiet
//!    ones) → `Controller::step`; its samples wait for the next tick; a dropped enable in its
//!    outputs drops the pin at once. The index interrupt is enabled only while the controller
//!    references.
//! 4. **Watchdogs**: fed only by a tick that was on time.
//!
//! The firmware's handler (`src/firmware/control.rs`) only binds the registers to
//! [`TickBoard`] and calls [`Tick::run`].

use super::soft_start::SoftStart;
use super::timing::{OverrunSupervisor, TickTiming, Verdict};
use crate::controller::{Controller, FaultCode, Inputs, DAC_SAMPLES_PER_STEP};

/// One period's DAC words, both channels.
pub type Samples = [[u16; 2]; DAC_SAMPLES_PER_STEP];

/// Ticks without a new preload sample after which the tick hands the core an invalid word (20 ms
/// at 10 kHz, twenty missed 1 kHz samples): a stuck ADC task becomes the core's preload-sensor
/// fault instead of a frozen force reading, while the watchdogs only watch the tick.
pub const PRELOAD_STALE_TICKS: u32 = 200;

/// Readings in a row at the inactive level before a limit switch counts as released (2 ms at
/// 10 kHz): a bouncing contact does not let a stopped drive start again. A switch counts as
/// active from its first active reading, so a hit stops the drive in the tick that reads it.
pub const LIMIT_RELEASE_TICKS: u16 = 20;

/// The preload word the controller gets for a stale reading: outside the 12-bit ADC's range, so
/// outside any calibration window that matches the ADC.
pub const STALE_PRELOAD_WORD: u16 = u16::MAX;

/// What the tick needs of the board, in the order it asks.
pub trait TickBoard {
    /// The free-running timebase (core clock counts, wraps).
    fn timebase(&mut self) -> u32;
    /// The ring half (0 or 1) the DMA reads now.
    fn dma_half(&mut self) -> usize;
    fn write_half(&mut self, half: usize, samples: &Samples);
    /// The amplifier enable pin.
    fn set_enable(&mut self, on: bool);
    /// The flash store asks for the drive parked (enable low, rest words).
    fn park_requested(&mut self) -> bool;
    /// This tick ran parked, the drive at rest and the enable low (or not).
    fn parked(&mut self, parked: bool);
    /// Lateness figures for the statistics (every tick).
    fn note_timing(&mut self, timing: &TickTiming, verdict: &Verdict);
    /// The overrun bucket tripped: record the fault with these detail words.
    fn record_overrun(&mut self, detail: [u32; 8]);
    fn encoder_raw(&mut self) -> u16;
    /// The preload ADC's last sample: (sequence number, word).
    fn preload_sample(&mut self) -> (u16, u16);
    /// The index latch: (sequence number of the last edge, count at it).
    fn index_latch(&mut self) -> (u16, u16);
    /// Whether the index edge interrupt is enabled (called every tick; act on changes).
    fn index_listening(&mut self, on: bool);
    /// The limit switch pins' levels now, [negative, positive] (true: high; a board whose EXTI
    /// caught a pulse since the last tick reports that pin at the level of the pulse), or None
    /// on a board without them wired.
    fn limit_pins(&mut self) -> Option<[bool; 2]> {
        None
    }
    /// After the step: the data recorder's point and the step's cost.
    fn after_step(&mut self, controller: Option<&Controller>);
    fn feed_watchdogs(&mut self);
}

/// The tick's own state between periods.
#[derive(Debug, Clone, Copy)]
pub struct Tick {
    overrun: OverrunSupervisor,
    soft: SoftStart,
    /// The samples and enable the last step computed, for this tick's refill.
    pending: Samples,
    pending_enable: bool,
    preload_seq: u16,
    preload_age_ticks: u32,
    index_seq: u16,
    limits: LimitDebounce,
}

/// The limit switches' debounce: active at once, released after [`LIMIT_RELEASE_TICKS`] quiet
/// readings.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct LimitDebounce {
    active: [bool; 2],
    quiet_ticks: [u16; 2],
}

impl LimitDebounce {
    /// One reading of both pins (true: high); the switches' states, [negative, positive].
    pub fn update(&mut self, levels: [bool; 2], active_high: bool) -> [bool; 2] {
        for ((active, quiet), level) in self.active.iter_mut().zip(self.quiet_ticks.iter_mut()).zip(levels) {
            if level == active_high {
                *active = true;
                *quiet = 0;
            } else if *active {
                *quiet = quiet.saturating_add(1);
                if *quiet >= LIMIT_RELEASE_TICKS {
                    *active = false;
                    *quiet = 0;
                }
            }
        }
        self.active
    }
}

impl Tick {
    /// `index_seq`: the index latch's sequence number now (edges before the start are old).
    pub const fn new(overrun: OverrunSupervisor, soft: SoftStart, index_seq: u16) -> Self {
        let rest = soft.rest();
        Tick {
            overrun,
            soft,
            pending: [[rest; 2]; DAC_SAMPLES_PER_STEP],
            pending_enable: false,
            preload_seq: 0,
            preload_age_ticks: 0,
            index_seq,
            limits: LimitDebounce { active: [false; 2], quiet_ticks: [0; 2] },
        }
    }

    /// One tick, entered at timebase reading `entry`.
    pub fn run(&mut self, board: &mut impl TickBoard, mut controller: Option<&mut Controller>, entry: u32) {
        let timing = self.overrun.begin(entry);

        // 1. Refill first, with what the last step computed. A fault (the controller's enable
        // low, a latched overrun) cuts the enable at once; parking alone ramps the drive down to
        // the rest word first (a whole half at rest), then drops it.
        let parked = board.park_requested();
        let wanted = self.overrun.enable(self.pending_enable, parked);
        let orderly = !wanted && parked && self.pending_enable && !self.overrun.latched();
        if !wanted && !orderly {
            board.set_enable(false);
        }
        let half = 1 - (board.dma_half() & 1);
        let enable = if orderly {
            let was_at_rest = self.soft.at_rest();
            self.soft.ramp_down(&mut self.pending);
            !was_at_rest
        } else {
            self.soft.apply(wanted, &mut self.pending);
            wanted
        };
        board.write_half(half, &self.pending);
        board.set_enable(enable);
        let refilled = board.timebase();
        let verdict = self.overrun.judge(&timing, refilled, board.dma_half() == half);
        board.parked(parked && !enable);

        // 2. Lateness: the bucket's verdict, and its latched fault.
        board.note_timing(&timing, &verdict);
        if verdict.overrun_now {
            // The first overrun latches the controller's fault; one during a fault (of any kind)
            // is counted by the controller and in the fault record, the first fault kept.
            board.set_enable(false);
            if let Some(c) = controller.as_deref_mut() {
                c.trip_external(FaultCode::Overrun);
            }
            let detail = [
                timing.latency,
                timing.missed,
                self.overrun.level_at_trip(),
                refilled.wrapping_sub(timing.due),
                0,
                0,
                0,
                0,
            ];
            board.record_overrun(detail);
        } else if let Some(c) = controller.as_deref() {
            // The latch clears once the host has cleared every fault (SVO).
            self.overrun.controller_fault_active(c.fault().is_some());
        }

        // 3. The step, for the next tick's refill. The index interrupt listens only while the
        // controller searches the reference (as the commands left it): a noisy index line at
        // any other time would take the CPU from the tick at a higher priority.
        board.index_listening(controller.as_deref().is_some_and(Controller::referencing));
        let index_raw = self.index_edge(board.index_latch());
        let preload_word = self.fresh_preload_word(board.preload_sample());
        let switches = controller.as_deref().map(|c| {
            let cfg = c.config();
            (cfg.limit_switches_enabled, cfg.limit_switch_active_high)
        });
        let pins = board.limit_pins();
        let [negative_limit, positive_limit] = match (pins, switches) {
            (Some(levels), Some((true, active_high))) => self.limits.update(levels, active_high),
            _ => {
                self.limits = LimitDebounce::default();
                [false; 2]
            }
        };
        let inputs = Inputs {
            encoder_raw: board.encoder_raw(),
            preload_word,
            index: index_raw.is_some(),
            index_raw,
            negative_limit,
            positive_limit,
            limits_wired: pins.is_some(),
        };
        match controller.as_deref_mut().map(|c| c.step(&inputs)) {
            Some(out) => {
                self.pending = out.dac;
                self.pending_enable = out.amp_enable;
            }
            None => {
                self.pending = [[self.soft.rest(); 2]; DAC_SAMPLES_PER_STEP];
                self.pending_enable = false;
            }
        }
        if !self.pending_enable {
            // A fault drops the enable now, not at the next refill.
            board.set_enable(false);
        }
        board.after_step(controller.as_deref());

        // 4. Watchdogs: only an on-time tick feeds them.
        if verdict.feed_watchdogs {
            board.feed_watchdogs();
        }
    }

    /// The latest preload word, or [`STALE_PRELOAD_WORD`] once the ADC has delivered nothing new
    /// for [`PRELOAD_STALE_TICKS`].
    fn fresh_preload_word(&mut self, (seq, word): (u16, u16)) -> u16 {
        if seq != self.preload_seq {
            self.preload_seq = seq;
            self.preload_age_ticks = 0;
        } else {
            self.preload_age_ticks = self.preload_age_ticks.saturating_add(1);
        }
        if self.preload_age_ticks > PRELOAD_STALE_TICKS {
            STALE_PRELOAD_WORD
        } else {
            word
        }
    }

    /// The count latched at an index edge since the last tick, if any.
    fn index_edge(&mut self, (seq, count): (u16, u16)) -> Option<u16> {
        if seq == self.index_seq {
            return None;
        }
        self.index_seq = seq;
        Some(count)
    }

    /// The overrun latch (for the board's statistics and tests).
    pub fn overrun_latched(&self) -> bool {
        self.overrun.latched()
    }
}
