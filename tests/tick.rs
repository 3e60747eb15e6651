//! The control tick's wiring (`piezo_drive::safety::tick`), the sequence the firmware's TIM7
//! handler runs, over a simulated board that logs every call: the refill comes before the step,
//! a late tick feeds no watchdog, an overrun trip and a controller fault drop the enable within
//! the same tick, parking ramps the drive down to rest before the enable drops (a fault cuts at
//! once), a silent preload ADC becomes an invalid reading.

use piezo_drive::controller::{Controller, ControllerConfig, FaultCode, LimitSwitches, State};
use piezo_drive::defaults::controller_config;
use piezo_drive::safety::soft_start::SoftStart;
use piezo_drive::safety::tick::{Samples, Tick, TickBoard, LIMIT_RELEASE_TICKS, PRELOAD_STALE_TICKS};
use piezo_drive::safety::timing::{DeadlineMonitor, LeakyBucket, OverrunSupervisor, TickTiming, Verdict};

/// Counts of the timebase per period and the refill's deadline after the due time (the board's
/// 17 000 counts at 170 MHz, refill within 17 of 20 samples).
const PERIOD: u32 = 17_000;
const DEADLINE: u32 = 14_450;
const REST: u16 = 0;
/// A preload word inside the default calibration's valid window (about 16 N).
const PRELOAD_WORD: u16 = 1_311;

#[derive(Debug, Clone, Copy, PartialEq)]
enum Call {
    Write { half: usize, first: [u16; 2], all_rest: bool },
    Enable(bool),
    Parked(bool),
    Timing { late: bool, tripped: bool },
    RecordOverrun,
    Encoder,
    Preload,
    Index(bool),
    AfterStep,
    Feed,
}

/// A board whose timebase reads what the test sets: `entry` at the tick's start is the test's,
/// `refill_after` counts later at the refill's end.
struct LogBoard {
    log: Vec<Call>,
    now: u32,
    refill_after: u32,
    dma_half: usize,
    park: bool,
    preload_seq: u16,
    /// The ADC delivers a new sample each tick (else its sequence number stands still).
    adc_alive: bool,
    /// The limit switch pins' levels (None: not wired).
    limit_pins: Option<[bool; 2]>,
    /// The encoder's count.
    encoder: u16,
}

impl LogBoard {
    fn new() -> Self {
        LogBoard {
            log: Vec::new(),
            now: 0,
            refill_after: 1_000,
            dma_half: 0,
            park: false,
            preload_seq: 0,
            adc_alive: true,
            limit_pins: None,
            encoder: 0,
        }
    }

    fn position(&self, call: impl Fn(&Call) -> bool) -> Option<usize> {
        self.log.iter().position(call)
    }
}

impl TickBoard for LogBoard {
    fn timebase(&mut self) -> u32 {
        self.now.wrapping_add(self.refill_after)
    }
    fn dma_half(&mut self) -> usize {
        self.dma_half
    }
    fn write_half(&mut self, half: usize, samples: &Samples) {
        let all_rest = samples.iter().all(|s| *s == [REST; 2]);
        self.log.push(Call::Write { half, first: samples[0], all_rest });
    }
    fn set_enable(&mut self, on: bool) {
        self.log.push(Call::Enable(on));
    }
    fn park_requested(&mut self) -> bool {
        self.park
    }
    fn parked(&mut self, parked: bool) {
        self.log.push(Call::Parked(parked));
    }
    fn note_timing(&mut self, _timing: &TickTiming, verdict: &Verdict) {
        self.log.push(Call::Timing { late: verdict.late, tripped: verdict.tripped_now });
    }
    fn record_overrun(&mut self, _detail: [u32; 8]) {
        self.log.push(Call::RecordOverrun);
    }
    fn encoder_raw(&mut self) -> u16 {
        self.log.push(Call::Encoder);
        self.encoder
    }
    fn preload_sample(&mut self) -> (u16, u16) {
        self.log.push(Call::Preload);
        if self.adc_alive {
            self.preload_seq = self.preload_seq.wrapping_add(1);
        }
        (self.preload_seq, PRELOAD_WORD)
    }
    fn index_latch(&mut self) -> (u16, u16) {
        (0, 0)
    }
    fn index_listening(&mut self, on: bool) {
        self.log.push(Call::Index(on));
    }
    fn limit_pins(&mut self) -> Option<[bool; 2]> {
        self.limit_pins
    }
    fn after_step(&mut self, _controller: Option<&Controller>) {
        self.log.push(Call::AfterStep);
    }
    fn feed_watchdogs(&mut self) {
        self.log.push(Call::Feed);
    }
}

fn tick() -> Tick {
    Tick::new(
        OverrunSupervisor::new(DeadlineMonitor::new(0, PERIOD, DEADLINE), LeakyBucket::new(10, 1, 40)),
        SoftStart::new(REST, 400),
        0,
    )
}

fn controller() -> Controller {
    Controller::new(controller_config()).expect("default settings")
}

/// Runs tick `k` (entered `late_by` counts after its due time) and returns its calls.
fn run(t: &mut Tick, b: &mut LogBoard, c: &mut Controller, k: u32, late_by: u32) -> Vec<Call> {
    b.log.clear();
    b.now = k.wrapping_mul(PERIOD).wrapping_add(late_by);
    t.run(b, Some(c), b.now);
    b.log.clone()
}

#[test]
fn an_on_time_tick_refills_the_free_half_before_it_steps_and_feeds_the_watchdogs_last() {
    let (mut t, mut b, mut c) = (tick(), LogBoard::new(), controller());
    for (k, dma) in [(0, 0), (1, 1), (2, 0)] {
        b.dma_half = dma;
        let log = run(&mut t, &mut b, &mut c, k, 100);
        let write = b.position(|c| matches!(c, Call::Write { .. })).expect("a refill");
        let Call::Write { half, .. } = log[write] else { unreachable!() };
        assert_eq!(half, 1 - dma, "tick {k}: the half the DMA does not read");
        let encoder = b.position(|c| *c == Call::Encoder).expect("the encoder is read");
        assert!(write < encoder, "tick {k}: refill before the step's inputs: {log:?}");
        assert!(b.position(|c| *c == Call::AfterStep).expect("after step") > encoder);
        assert_eq!(log.last(), Some(&Call::Feed), "tick {k}: watchdogs fed last: {log:?}");
        assert_eq!(log.iter().filter(|c| **c == Call::Feed).count(), 1);
    }
}

#[test]
fn a_late_tick_feeds_no_watchdog_and_a_missed_period_trips_at_once() {
    let (mut t, mut b, mut c) = (tick(), LogBoard::new(), controller());
    run(&mut t, &mut b, &mut c, 0, 100);
    // The refill ends past its deadline: late, no feed, but one late tick does not trip.
    b.refill_after = DEADLINE + 1;
    let log = run(&mut t, &mut b, &mut c, 1, 0);
    assert!(log.contains(&Call::Timing { late: true, tripped: false }), "{log:?}");
    assert!(!log.contains(&Call::Feed), "a late tick fed the watchdogs: {log:?}");
    assert_eq!(c.fault(), None);
    // On time again: fed.
    b.refill_after = 1_000;
    assert!(run(&mut t, &mut b, &mut c, 2, 0).contains(&Call::Feed));
    // Tick 3 never came: tick 4 finds a whole period missed and trips.
    let log = run(&mut t, &mut b, &mut c, 4, 10);
    assert!(log.contains(&Call::RecordOverrun), "{log:?}");
    assert_eq!(c.fault(), Some(FaultCode::Overrun));
    assert!(!log.contains(&Call::Feed));
}

#[test]
fn four_late_ticks_trip_the_overrun_drop_the_enable_at_once_and_latch_it() {
    let (mut t, mut b, mut c) = (tick(), LogBoard::new(), controller());
    // On time: the controller's quiet output is enabled.
    run(&mut t, &mut b, &mut c, 0, 100);
    assert!(run(&mut t, &mut b, &mut c, 1, 100).contains(&Call::Enable(true)));
    b.refill_after = DEADLINE + 1;
    // +10 per late tick, the limit 40: the fourth trips (tests/safety.rs counts it by hand).
    for k in 2..5 {
        let log = run(&mut t, &mut b, &mut c, k, 0);
        assert!(!log.contains(&Call::RecordOverrun), "tick {k} tripped early: {log:?}");
    }
    let log = run(&mut t, &mut b, &mut c, 5, 0);
    let tripped = b.position(|c| *c == Call::RecordOverrun).expect("the fourth late tick trips");
    let timing = b.position(|c| matches!(c, Call::Timing { tripped: true, .. })).expect("verdict");
    let encoder = b.position(|c| *c == Call::Encoder).expect("step");
    // The enable drops between the verdict and the step, in this very tick.
    assert!(log[timing..encoder].contains(&Call::Enable(false)), "enable not dropped at the trip: {log:?}");
    assert!(tripped < encoder);
    assert_eq!(c.fault(), Some(FaultCode::Overrun));
    assert!(t.overrun_latched());
    // On time again, the fault still set: the enable stays low, every refill at rest.
    b.refill_after = 1_000;
    for k in 6..10 {
        let log = run(&mut t, &mut b, &mut c, k, 0);
        assert!(!log.contains(&Call::Enable(true)), "tick {k} re-enabled a latched overrun: {log:?}");
        assert!(log.iter().any(|c| matches!(c, Call::Write { all_rest: true, .. })));
    }
    // The host clears the fault (SVO): the latch opens and the drive ramps in again.
    c.clear_fault();
    run(&mut t, &mut b, &mut c, 10, 0);
    run(&mut t, &mut b, &mut c, 11, 0);
    assert!(!t.overrun_latched());
    assert!(run(&mut t, &mut b, &mut c, 12, 0).contains(&Call::Enable(true)));
}

#[test]
fn a_controller_fault_drops_the_enable_in_the_same_tick() {
    let (mut t, mut b, mut c) = (tick(), LogBoard::new(), controller());
    run(&mut t, &mut b, &mut c, 0, 100);
    // The last step asked for the enable: this refill sets it high ...
    c.trip_external(FaultCode::EncoderJump);
    let log = run(&mut t, &mut b, &mut c, 1, 100);
    let high = b.position(|c| *c == Call::Enable(true)).expect("refill with the enable");
    let step = b.position(|c| *c == Call::AfterStep).expect("step");
    // ... and the faulted step drops it before the tick ends, not at the next refill.
    let low = log.iter().rposition(|c| *c == Call::Enable(false)).expect("dropped");
    assert!(high < low && low < step, "{log:?}");
}

/// Ticks of the soft start's ramp (400 samples, 20 per tick).
const RAMP_TICKS: u32 = 400 / 20;

#[test]
fn parking_ramps_the_drive_down_to_rest_before_the_enable_drops() {
    let (mut t, mut b, mut c) = (tick(), LogBoard::new(), controller());
    for k in 0..30 {
        run(&mut t, &mut b, &mut c, k, 100);
    }
    // The idle controller's quiet output (mid-scale), ramped up in full.
    let Call::Write { first: [quiet, _], .. } =
        *b.log.iter().find(|c| matches!(c, Call::Write { .. })).expect("refill")
    else {
        unreachable!()
    };
    assert!(quiet > REST + 1000, "quiet output {quiet}");
    b.park = true;
    let mut last = quiet;
    let mut k = 30;
    // While the ramp runs the enable stays high, the halves step down toward rest, and the
    // tick does not count as parked.
    for _ in 0..RAMP_TICKS {
        let log = run(&mut t, &mut b, &mut c, k, 100);
        let Some(&Call::Write { first: [w, _], .. }) = log.iter().find(|c| matches!(c, Call::Write { .. }))
        else {
            panic!("no refill: {log:?}")
        };
        assert!(w < last, "tick {k}: {w} not below {last}");
        assert!(
            !log.contains(&Call::Enable(false)) && log.contains(&Call::Parked(false)),
            "tick {k}: {log:?}"
        );
        last = w;
        k += 1;
    }
    // A whole half at rest, then the enable drops and the board may store.
    let log = run(&mut t, &mut b, &mut c, k, 100);
    assert!(log.iter().any(|c| matches!(c, Call::Write { all_rest: true, .. })), "{log:?}");
    assert!(log.contains(&Call::Enable(false)) && !log.contains(&Call::Enable(true)), "{log:?}");
    assert!(log.contains(&Call::Parked(true)));
    // Unparked: the soft start ramps up again from rest.
    b.park = false;
    let log = run(&mut t, &mut b, &mut c, k + 1, 100);
    assert!(log.contains(&Call::Enable(true)));
    let Some(&Call::Write { first: [w, _], .. }) = log.iter().find(|c| matches!(c, Call::Write { .. }))
    else {
        panic!("no refill")
    };
    assert!(w < quiet, "ramps up from rest: {w}");
}

#[test]
fn a_fault_while_parking_cuts_at_once() {
    let (mut t, mut b, mut c) = (tick(), LogBoard::new(), controller());
    for k in 0..30 {
        run(&mut t, &mut b, &mut c, k, 100);
    }
    b.park = true;
    run(&mut t, &mut b, &mut c, 30, 100);
    c.trip_external(FaultCode::EncoderJump);
    // The faulted step drops the enable in its own tick; the next refill is all rest, enable low
    // before it, with the ramp-down far from done.
    run(&mut t, &mut b, &mut c, 31, 100);
    let log = run(&mut t, &mut b, &mut c, 32, 100);
    assert_eq!(log.first(), Some(&Call::Enable(false)), "{log:?}");
    assert!(log.iter().any(|c| matches!(c, Call::Write { all_rest: true, .. })), "{log:?}");
}

#[test]
fn a_silent_preload_adc_becomes_an_invalid_reading_after_the_stale_limit() {
    let (mut t, mut b, mut c) = (tick(), LogBoard::new(), controller());
    for k in 0..10 {
        run(&mut t, &mut b, &mut c, k, 100);
    }
    assert!(c.preload_n().is_some(), "a live ADC gives a reading");
    b.adc_alive = false;
    let mut k = 10;
    // The same sample for PRELOAD_STALE_TICKS more ticks still counts ...
    for _ in 0..PRELOAD_STALE_TICKS {
        run(&mut t, &mut b, &mut c, k, 100);
        k += 1;
    }
    assert!(c.preload_n().is_some(), "stale too early");
    // ... one more, and the controller sees an invalid word.
    run(&mut t, &mut b, &mut c, k, 100);
    assert_eq!(c.preload_n(), None);
    // A new sample makes it valid again.
    b.adc_alive = true;
    run(&mut t, &mut b, &mut c, k + 1, 100);
    assert!(c.preload_n().is_some());
}

#[test]
fn the_index_interrupt_listens_only_while_referencing() {
    let (mut t, mut b, mut c) = (tick(), LogBoard::new(), controller());
    for k in 0..30 {
        assert!(run(&mut t, &mut b, &mut c, k, 100).contains(&Call::Index(false)), "tick {k}");
    }
    c.set_servo(true).expect("servo on");
    c.start_referencing().expect("referencing starts");
    let log = run(&mut t, &mut b, &mut c, 30, 100);
    // Listening before the step reads the latch.
    let on = b.position(|c| *c == Call::Index(true)).expect("listening");
    assert!(on < b.position(|c| *c == Call::Encoder).expect("step"), "{log:?}");
    c.stop();
    run(&mut t, &mut b, &mut c, 31, 100);
    assert!(run(&mut t, &mut b, &mut c, 32, 100).contains(&Call::Index(false)));
}

/// A controller with the limit switches read, active low (normally closed switches to ground
/// with pull-ups: a broken wire reads active).
fn controller_with_switches() -> Controller {
    let cfg = ControllerConfig {
        limit_switches_enabled: true,
        limit_switch_active_high: false,
        ..controller_config()
    };
    Controller::new(cfg).expect("settings in range")
}

/// A limit switch read by the board stops open-loop stepping toward it in the tick that reads
/// it (before, the tick handed the controller no switch at all); the switch counts as active
/// from its first reading and is released only after the debounce's quiet readings; with the
/// setting off, or no pins, the switches are ignored. The controller says what it saw.
#[test]
fn a_limit_switch_read_by_the_tick_stops_the_drive_in_that_tick() {
    let (mut t, mut b, mut c) = (tick(), LogBoard::new(), controller_with_switches());
    b.limit_pins = Some([true, true]); // pulled up: inactive
    for k in 0..20 {
        run(&mut t, &mut b, &mut c, k, 0);
    }
    assert_eq!(
        c.limit_switches(),
        LimitSwitches { wired: true, enabled: true, negative: false, positive: false }
    );
    // Stepping toward +x, the slider moving (a count a tick).
    c.open_loop_step(10_000, 80.0, 1500.0).expect("servo off, preload fine");
    for k in 20..40 {
        b.encoder = b.encoder.wrapping_add(1);
        run(&mut t, &mut b, &mut c, k, 0);
        assert_eq!(c.state(), State::OpenLoop);
    }
    // The positive switch closes: this tick's step ends the run.
    b.limit_pins = Some([true, false]);
    run(&mut t, &mut b, &mut c, 40, 0);
    assert_ne!(c.state(), State::OpenLoop, "the run went on past the switch");
    assert_eq!(c.limit_stop_count(), 1);
    assert!(c.limit_switches().positive);
    // Bouncing: open for fewer than the release readings, then closed again: never released.
    for k in 41..(41 + u32::from(LIMIT_RELEASE_TICKS) - 1) {
        b.limit_pins = Some([true, true]);
        run(&mut t, &mut b, &mut c, k, 0);
        assert!(c.limit_switches().positive, "released after {} quiet readings", k - 40);
    }
    let k = 41 + u32::from(LIMIT_RELEASE_TICKS) - 1;
    run(&mut t, &mut b, &mut c, k, 0);
    assert!(!c.limit_switches().positive, "released after {} quiet readings", LIMIT_RELEASE_TICKS);
    // The setting off: the same pin level is no switch.
    let mut cfg = *c.config();
    cfg.limit_switches_enabled = false;
    c.set_config(cfg).expect("settings in range");
    b.limit_pins = Some([false, false]);
    run(&mut t, &mut b, &mut c, k + 1, 0);
    assert_eq!(
        c.limit_switches(),
        LimitSwitches { wired: true, enabled: false, negative: false, positive: false }
    );
    // Not wired: nothing either.
    b.limit_pins = None;
    run(&mut t, &mut b, &mut c, k + 2, 0);
    assert!(!c.limit_switches().wired);
}

/// An overrun while the controller already has a fault (here an encoder jump): reported to the
/// board's record and counted by the controller, which keeps the first fault; a second overrun
/// during the same latch is reported again (before: neither counted, nor a second one seen).
#[test]
fn overruns_during_a_fault_are_reported_each_time() {
    let (mut t, mut b, mut c) = (tick(), LogBoard::new(), controller());
    run(&mut t, &mut b, &mut c, 0, 100);
    b.encoder = 30_000;
    run(&mut t, &mut b, &mut c, 1, 100);
    assert_eq!(c.fault(), Some(FaultCode::EncoderJump));
    b.refill_after = DEADLINE + 1;
    let mut reported = 0;
    for k in 2..10 {
        if run(&mut t, &mut b, &mut c, k, 0).contains(&Call::RecordOverrun) {
            reported += 1;
        }
    }
    // +10 a late tick, trips at 40 and starts afresh: ticks 5 and 9.
    assert_eq!(reported, 2);
    assert_eq!(c.overrun_count(), 2);
    assert_eq!(c.fault(), Some(FaultCode::EncoderJump), "the first fault stays");
}
