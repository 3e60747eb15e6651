//! Lateness of the control tick, measured against an absolute clock.
//!
//! The firmware's tick (TIM7, 10 kHz) and a free-running 32-bit counter (TIM5) count the same
//! 170 MHz clock and start in the same critical section, so tick `k` is due at
//! `first_due + k · period` counter counts. [`DeadlineMonitor`] turns a counter reading at the
//! tick's entry into the due time it serves, how late it started and how many whole periods went
//! by without a tick (which the DMA position alone cannot see: the buffer is only two periods
//! long). [`LeakyBucket`] turns the stream of late/on-time ticks into a latched fault, so an
//! alternating late/on-time pattern trips too.

/// Counts of the counter at which one tick started, relative to its schedule.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TickTiming {
    /// The due time (counter value) this tick serves.
    pub due: u32,
    /// Counts between the due time and the tick's start (0 if it came early).
    pub latency: u32,
    /// Whole periods that passed without a tick before this one.
    pub missed: u32,
}

/// The tick's schedule on a wrapping 32-bit counter.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DeadlineMonitor {
    next_due: u32,
    period: u32,
    deadline: u32,
}

impl DeadlineMonitor {
    /// First tick due at counter value `first_due`, then every `period` counts (≥ 1); a tick
    /// must have finished its time-critical part (the buffer refill) `deadline` counts after
    /// its due time.
    pub const fn new(first_due: u32, period: u32, deadline: u32) -> Self {
        let period = if period == 0 { 1 } else { period };
        DeadlineMonitor { next_due: first_due, period, deadline }
    }

    /// Call at the tick's entry with the counter's value. Counter differences are taken
    /// modulo 2³²; a reading up to half the counter range *before* the due time counts as early
    /// (latency 0), anything else as late. The schedule moves on past every missed period, so
    /// one late tick does not make the following ones look late.
    pub fn begin(&mut self, now: u32) -> TickTiming {
        let since = now.wrapping_sub(self.next_due);
        let (latency, missed) = if since > u32::MAX / 2 {
            (0, 0)
        } else {
            // `period` is never 0 (see `new`); checked forms keep a panic path out of the tick.
            (since.checked_rem(self.period).unwrap_or(0), since.checked_div(self.period).unwrap_or(0))
        };
        let due = self.next_due.wrapping_add(missed.wrapping_mul(self.period));
        self.next_due = due.wrapping_add(self.period);
        TickTiming { due, latency, missed }
    }

    /// Whether a tick that finished its critical part at counter value `done` met its deadline:
    /// no whole period missed and `done` no more than `deadline` counts after the due time.
    pub fn met(&self, t: &TickTiming, done: u32) -> bool {
        let since = done.wrapping_sub(t.due);
        t.missed == 0 && (since <= self.deadline || since > u32::MAX / 2)
    }

    /// Re-anchors the schedule: the next tick is due at `next_due` (after a deliberate pause).
    pub fn resync(&mut self, next_due: u32) {
        self.next_due = next_due;
    }

    pub fn period(&self) -> u32 {
        self.period
    }
    pub fn deadline(&self) -> u32 {
        self.deadline
    }
}

/// A leaky bucket that latches: each bad event adds `add`, each good one takes `leak` out (not
/// below 0); the bucket trips once its level reaches `limit` and stays tripped until
/// [`Self::reset`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LeakyBucket {
    level: u32,
    add: u32,
    leak: u32,
    limit: u32,
    tripped: bool,
}

impl LeakyBucket {
    pub const fn new(add: u32, leak: u32, limit: u32) -> Self {
        LeakyBucket { level: 0, add, leak, limit, tripped: false }
    }

    /// One event; returns whether the bucket is tripped (now or before).
    pub fn record(&mut self, bad: bool) -> bool {
        self.level =
            if bad { self.level.saturating_add(self.add) } else { self.level.saturating_sub(self.leak) };
        if self.level >= self.limit {
            self.tripped = true;
        }
        self.tripped
    }

    /// Trips at once (an event bad enough on its own, e.g. a whole period missed).
    pub fn trip(&mut self) {
        self.level = self.level.max(self.limit);
        self.tripped = true;
    }

    pub fn tripped(&self) -> bool {
        self.tripped
    }
    pub fn level(&self) -> u32 {
        self.level
    }
    pub fn reset(&mut self) {
        self.level = 0;
        self.tripped = false;
    }
}

/// What one tick's lateness means for the board.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Verdict {
    /// The tick was late (deadline missed, a period missed, or the DMA already in the half it
    /// wrote).
    pub late: bool,
    /// The bucket tripped at this tick, the first time since the latch was last clear: drop the
    /// enable, latch the controller's overrun fault, record it.
    pub tripped_now: bool,
    /// The bucket tripped at this tick, the first time or again while the latch holds (the
    /// bucket starts afresh after each trip): every overrun is reported and counted, also
    /// during a fault.
    pub overrun_now: bool,
    /// Only an on-time tick feeds the watchdogs.
    pub feed_watchdogs: bool,
}

/// The control tick's overrun supervision as the firmware runs it: the schedule, the bucket and
/// the latch, in one place so the whole reaction is tested on the host.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct OverrunSupervisor {
    deadline: DeadlineMonitor,
    bucket: LeakyBucket,
    latched: bool,
    /// The bucket's level at its last trip (the fault record's detail).
    level_at_trip: u32,
}

impl OverrunSupervisor {
    pub const fn new(deadline: DeadlineMonitor, bucket: LeakyBucket) -> Self {
        OverrunSupervisor { deadline, bucket, latched: false, level_at_trip: 0 }
    }

    /// At the tick's entry (timebase reading `now`).
    pub fn begin(&mut self, now: u32) -> TickTiming {
        self.deadline.begin(now)
    }

    /// Whether the amplifier may be enabled for the samples being written: the controller wants
    /// it, no overrun is latched and the drive is not parked.
    pub fn enable(&self, controller_enable: bool, parked: bool) -> bool {
        controller_enable && !self.latched && !parked
    }

    /// After the refill, finished at timebase reading `refilled`; `dma_in_written_half`: the DMA
    /// had already entered the half just written.
    pub fn judge(&mut self, t: &TickTiming, refilled: u32, dma_in_written_half: bool) -> Verdict {
        let late = !self.deadline.met(t, refilled) || dma_in_written_half;
        if t.missed > 0 {
            self.bucket.trip();
        } else {
            self.bucket.record(late);
        }
        let overrun_now = self.bucket.tripped();
        let tripped_now = overrun_now && !self.latched;
        if overrun_now {
            // Latched until the host clears the fault; the bucket starts afresh so a further
            // overrun during the latch trips (and is reported) again.
            self.latched = true;
            self.level_at_trip = self.bucket.level();
            self.bucket.reset();
        }
        Verdict { late, tripped_now, overrun_now, feed_watchdogs: !late }
    }

    /// Once the controller has no fault any more (the host cleared it), the latch and the bucket
    /// start afresh. While any fault is active the latch stays.
    pub fn controller_fault_active(&mut self, active: bool) {
        if self.latched && !active {
            self.latched = false;
            self.bucket.reset();
        }
    }

    pub fn latched(&self) -> bool {
        self.latched
    }
    pub fn bucket_level(&self) -> u32 {
        self.bucket.level()
    }
    /// The bucket's level when it last tripped.
    pub fn level_at_trip(&self) -> u32 {
        self.level_at_trip
    }
}
