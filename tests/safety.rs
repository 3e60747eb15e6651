//! Issue 16: the board-independent safety logic, against hand-calculated expectations.

mod common;

use common::TestBoard;
use piezo_drive::controller::{
    CommandError, ConfigChange, Controller, ControllerConfig, FaultCode, Inputs, State,
};
use piezo_drive::defaults;
use piezo_drive::fastmath::{clamp_f32, clamp_i32, clamp_sym_f32};
use piezo_drive::gcs::{error, Gcs, Pending, Reply, COMMANDS};
use piezo_drive::safety::fault_record::{self, FaultKind, FaultRecord, RECORD_WORDS};
use piezo_drive::safety::flash_ecc::{ecc_in_page, ecc_in_param_page};
use piezo_drive::safety::probe::{probe_says_floating, FloatDetector};
use piezo_drive::safety::soft_start::SoftStart;
use piezo_drive::safety::timing::{DeadlineMonitor, LeakyBucket};
use piezo_drive::safety::watchdog;

// ---------------------------------------------------------------- item 1: tick lateness

/// The firmware's numbers: 170 MHz, 10 kHz tick (17 000 counts), first update 2 samples
/// (2 × 850 counts) after the timers start, refill deadline 18 samples after the due time.
const PERIOD: u32 = 17_000;
const FIRST_DUE: u32 = 1_700;
const DEADLINE: u32 = 18 * 850;

#[test]
fn on_time_ticks_have_zero_latency_and_meet_the_deadline() {
    let mut m = DeadlineMonitor::new(FIRST_DUE, PERIOD, DEADLINE);
    for k in 0..5u32 {
        let now = FIRST_DUE + k * PERIOD + 40; // 40 counts of interrupt entry
        let t = m.begin(now);
        assert_eq!(t.due, FIRST_DUE + k * PERIOD);
        assert_eq!(t.latency, 40);
        assert_eq!(t.missed, 0);
        assert!(m.met(&t, now + 2_000)); // refill 2 000 counts later: 2 040 ≤ 15 300
    }
}

#[test]
fn a_refill_past_18_samples_is_late() {
    let mut m = DeadlineMonitor::new(FIRST_DUE, PERIOD, DEADLINE);
    let t = m.begin(FIRST_DUE + 15_000);
    assert_eq!(t.latency, 15_000);
    assert!(m.met(&t, FIRST_DUE + 15_300));
    assert!(!m.met(&t, FIRST_DUE + 15_301));
}

#[test]
fn a_tick_a_whole_lap_late_is_seen() {
    // The DMA buffer is two periods long: a tick 2 periods + 100 counts late finds the DMA in
    // the same half as an on-time tick would. The counter sees it.
    let mut m = DeadlineMonitor::new(FIRST_DUE, PERIOD, DEADLINE);
    let t0 = m.begin(FIRST_DUE + 10);
    assert_eq!(t0.missed, 0);
    let now = FIRST_DUE + 3 * PERIOD + 100; // ticks 1 and 2 never ran
    let t = m.begin(now);
    assert_eq!(t.missed, 2);
    assert_eq!(t.latency, 100);
    assert_eq!(t.due, FIRST_DUE + 3 * PERIOD);
    assert!(!m.met(&t, now + 10), "a missed period is never on time");
    // The schedule moved on: the next tick on time is on time again.
    let t = m.begin(FIRST_DUE + 4 * PERIOD + 5);
    assert_eq!((t.missed, t.latency), (0, 5));
    assert!(m.met(&t, FIRST_DUE + 4 * PERIOD + 500));
}

#[test]
fn the_schedule_survives_the_counter_wrapping() {
    // Due 100 counts before the 32-bit counter wraps.
    let first = u32::MAX - 99;
    let mut m = DeadlineMonitor::new(first, PERIOD, DEADLINE);
    let t = m.begin(first.wrapping_add(30));
    assert_eq!((t.latency, t.missed), (30, 0));
    // Next due at first + 17 000 = 16 900 after the wrap.
    let t = m.begin(16_900 + 7);
    assert_eq!((t.due, t.latency, t.missed), (16_900, 7, 0));
    assert!(m.met(&t, 16_900 + DEADLINE));
}

#[test]
fn an_early_reading_counts_as_on_time() {
    let mut m = DeadlineMonitor::new(FIRST_DUE, PERIOD, DEADLINE);
    let t = m.begin(FIRST_DUE - 3); // the two timers started 3 counts apart
    assert_eq!((t.due, t.latency, t.missed), (FIRST_DUE, 0, 0));
    assert!(m.met(&t, FIRST_DUE - 1));
}

/// The firmware's bucket: +10 per late tick, −1 per on-time tick, trips at 40.
fn bucket() -> LeakyBucket {
    LeakyBucket::new(10, 1, 40)
}

#[test]
fn four_late_ticks_in_a_row_trip() {
    let mut b = bucket();
    // 10, 20, 30, 40.
    assert!(!b.record(true));
    assert!(!b.record(true));
    assert!(!b.record(true));
    assert!(b.record(true));
    // Latched: on-time ticks do not clear it.
    for _ in 0..100 {
        assert!(b.record(false));
    }
    b.reset();
    assert!(!b.tripped());
    assert_eq!(b.level(), 0);
}

#[test]
fn alternating_late_and_on_time_trips_at_the_fifth_late_tick() {
    // late 10, ok 9, late 19, ok 18, late 28, ok 27, late 37, ok 36, late 46 ≥ 40.
    let mut b = bucket();
    let mut tripped_at = None;
    for i in 0..20 {
        let late = i % 2 == 0;
        if b.record(late) && tripped_at.is_none() {
            tripped_at = Some(i);
        }
    }
    assert_eq!(tripped_at, Some(8));
}

#[test]
fn one_late_tick_in_ten_trips_after_31_late_ticks_one_in_eleven_never() {
    // One late then nine on time: the level after the n-th late tick is 10 + (n − 1) = n + 9,
    // which reaches 40 at n = 31, i.e. tick 30 · 10 = 300.
    let mut b = bucket();
    let mut tripped_at = None;
    for i in 0..1000 {
        if b.record(i % 10 == 0) && tripped_at.is_none() {
            tripped_at = Some(i);
        }
    }
    assert_eq!(tripped_at, Some(300));
    // One in eleven: +10 − 10 returns to 0 every time.
    let mut b = bucket();
    for i in 0..100_000 {
        assert!(!b.record(i % 11 == 0));
    }
}

#[test]
fn bucket_trip_now_latches() {
    let mut b = bucket();
    b.trip();
    assert!(b.tripped());
    assert!(b.record(false));
}

// ---------------------------------------------------------------- item 1: the fault and its error

const PRELOAD_WORD: u16 = 1310; // 16 N on the default 0–50 N cell

fn send(gcs: &mut Gcs, ctl: &mut Controller, bytes: &[u8]) -> Vec<u8> {
    let mut all = Vec::new();
    for &b in bytes {
        if let Some(p) = gcs.push_byte(b) {
            let mut reply = Reply::new();
            gcs.execute(&p, ctl, &mut TestBoard::default(), &mut reply);
            all.extend_from_slice(&reply);
        }
    }
    all
}

fn idle_controller() -> Controller {
    let mut ctl = Controller::new(defaults::controller_config()).unwrap();
    for _ in 0..10 {
        ctl.step(&Inputs { preload_word: PRELOAD_WORD, ..Default::default() });
        ctl.background();
    }
    ctl
}

#[test]
fn overrun_fault_disables_the_amplifier_and_has_its_own_error() {
    let mut ctl = idle_controller();
    let mut gcs = Gcs::new();
    assert_eq!(send(&mut gcs, &mut ctl, b"SVO 1 1\nERR?\n"), b"0\n");
    assert_eq!(ctl.state(), State::Holding);
    ctl.trip_external(FaultCode::Overrun);
    assert_eq!(ctl.state(), State::Fault(FaultCode::Overrun));
    assert!(!ctl.servo());
    let out = ctl.step(&Inputs { preload_word: PRELOAD_WORD, ..Default::default() });
    assert!(!out.amp_enable);
    assert_eq!(
        send(&mut gcs, &mut ctl, b"ERR?\nXFT?\n"),
        format!("{}\n1=6 control loop overrun: drive disabled\n", error::CONTROL_LOOP_OVERRUN).as_bytes()
    );
    // Cleared as any motion error: servo on again.
    assert_eq!(send(&mut gcs, &mut ctl, b"SVO 1 1\nERR?\n"), b"0\n");
    assert_eq!(ctl.state(), State::Holding);
}

#[test]
fn an_external_trip_keeps_the_first_fault() {
    let mut ctl = idle_controller();
    ctl.step(&Inputs { preload_word: PRELOAD_WORD, encoder_raw: 30_000, ..Default::default() });
    assert_eq!(ctl.state(), State::Fault(FaultCode::EncoderJump));
    ctl.trip_external(FaultCode::Overrun);
    assert_eq!(ctl.state(), State::Fault(FaultCode::EncoderJump));
}

// ---------------------------------------------------------------- item 2: queries on a copy

#[test]
fn exactly_the_queries_and_status_bytes_are_read_only() {
    for name in COMMANDS.iter().map(|c| c.name) {
        let pending = if let Some(n) = name.strip_prefix('#') {
            Pending::Byte(n.parse::<u8>().unwrap())
        } else {
            let mut line = heapless::Vec::new();
            line.extend_from_slice(name.as_bytes()).unwrap();
            line.extend_from_slice(b" 1").unwrap();
            Pending::Line(line)
        };
        let expect = matches!(name, "#4" | "#5" | "#7") || name.ends_with('?');
        assert_eq!(Gcs::is_read_only(&pending), expect, "{name}");
    }
    // Lower case and leading blanks as the executor accepts them.
    let mut line = heapless::Vec::new();
    line.extend_from_slice(b"  spa? 1 0x1").unwrap();
    assert!(Gcs::is_read_only(&Pending::Line(line)));
    let mut line = heapless::Vec::new();
    line.extend_from_slice(b"mov 1 1").unwrap();
    assert!(!Gcs::is_read_only(&Pending::Line(line)));
    assert!(!Gcs::is_read_only(&Pending::Byte(0x18)));
}

#[test]
fn every_query_gives_the_same_reply_on_a_copy_and_leaves_the_controller_alone() {
    // A controller in motion (referenced, holding, then a move) and its untouched twin.
    let mut ctl = idle_controller();
    let mut gcs = Gcs::new();
    send(&mut gcs, &mut ctl, b"FRF 1\n");
    ctl.step(&Inputs { preload_word: PRELOAD_WORD, index: true, ..Default::default() });
    assert_eq!(send(&mut gcs, &mut ctl, b"SVO 1 1\nMOV 1 0.5\nERR?\n"), b"0\n");
    for _ in 0..20 {
        ctl.step(&Inputs { preload_word: PRELOAD_WORD, ..Default::default() });
    }
    let twin = ctl.clone();
    let mut gcs_twin = Gcs::new();
    send(&mut gcs_twin, &mut ctl.clone(), b"RON 1 1\n");
    for name in COMMANDS.iter().map(|c| c.name).filter(|n| n.ends_with('?')) {
        let line = format!("{name}\n");
        let mut copy = ctl.clone();
        let on_copy = send(&mut gcs_twin, &mut copy, line.as_bytes());
        let on_real = send(&mut gcs, &mut ctl, line.as_bytes());
        assert_eq!(on_copy, on_real, "{name}");
    }
    // The real controller, queried every way, behaves exactly as its twin from here on.
    let mut twin = twin;
    for k in 0..200u16 {
        let inputs = Inputs { preload_word: PRELOAD_WORD, encoder_raw: k / 4, ..Default::default() };
        let a = ctl.step(&inputs);
        let b = twin.step(&inputs);
        assert_eq!(a, b, "step {k}");
        ctl.background();
        twin.background();
    }
    assert_eq!(ctl.state(), twin.state());
}

// ---------------------------------------------------------------- item 5: soft start

#[test]
fn soft_start_ramps_from_rest_to_mid_scale_without_a_step() {
    // Rest word 0 (0 V), controller output 2048 (50 V), ramp of 4 000 samples (20 ms at 200 kS/s):
    // sample k is ⌊2048 · k / 4000⌋.
    let mut s = SoftStart::new(0, 4000);
    let mut all = Vec::new();
    for _ in 0..250 {
        let mut buf = [[2048u16; 2]; 20];
        s.apply(true, &mut buf);
        all.extend(buf.iter().map(|p| p[0]));
    }
    assert_eq!(all[0], 0);
    assert_eq!(all[1], 0); // 2048/4000 = 0.512
    assert_eq!(all[2], 1); // 1.024
    assert_eq!(all[2000], 1024);
    assert_eq!(all[3999], 2047); // 2047.488
    assert_eq!(all[4000], 2048);
    assert!(all[4000..].iter().all(|&w| w == 2048));
    let max_step = all.windows(2).map(|w| w[1].abs_diff(w[0])).max().unwrap();
    assert_eq!(max_step, 1);
    assert!(s.done());
}

/// An orderly disable runs the ramp backwards: rest + (word − rest)·k/n for k = n−1 … 0, then
/// rest, and reports rest only when there (hand values: rest 1000, word 3000, n = 4).
#[test]
fn soft_start_ramps_down_to_rest_before_it_reports_rest() {
    let mut s = SoftStart::new(1000, 4);
    let mut up = [[3000u16; 2]; 4];
    s.apply(true, &mut up);
    assert!(s.done() && !s.at_rest());
    let mut seen = Vec::new();
    for _ in 0..5 {
        let mut one = [[3000u16; 2]; 1];
        let at_rest = s.ramp_down(&mut one);
        seen.push((one[0][0], at_rest));
    }
    assert_eq!(seen, [(2500, false), (2000, false), (1500, false), (1000, true), (1000, true)]);
    // No ramp configured: rest at once.
    let mut none = SoftStart::new(1000, 0);
    let mut w = [[3000u16; 2]; 2];
    assert!(none.ramp_down(&mut w));
    assert_eq!(w, [[1000; 2]; 2]);
}

#[test]
fn soft_start_holds_rest_while_disabled_and_starts_over_after() {
    let mut s = SoftStart::new(100, 40);
    let mut buf = [[3000u16, 1000u16]; 20];
    s.apply(false, &mut buf);
    assert!(buf.iter().all(|p| *p == [100, 100]));
    let mut buf = [[3000u16, 1000u16]; 20];
    s.apply(true, &mut buf);
    // k = 0..19 of 40: 100 + 2900·k/40 and 100 + 900·k/40 (toward rest).
    assert_eq!(buf[0], [100, 100]);
    assert_eq!(buf[10], [825, 325]);
    assert_eq!(buf[19], [1477, 527]);
    let mut buf = [[3000u16, 1000u16]; 20];
    s.apply(true, &mut buf);
    assert_eq!(buf[0], [1550, 550]); // k = 20: half way
    assert!(s.done());
    // Enable drops (a fault): rest, and the next enable ramps again from the start.
    let mut buf = [[3000u16, 1000u16]; 20];
    s.apply(false, &mut buf);
    assert!(!s.done());
    let mut buf = [[3000u16, 1000u16]; 20];
    s.apply(true, &mut buf);
    assert_eq!(buf[0], [100, 100]);
}

#[test]
fn soft_start_passes_words_below_rest_and_zero_length() {
    let mut s = SoftStart::new(4095, 2);
    let mut buf = [[0u16; 2]; 3];
    s.apply(true, &mut buf);
    assert_eq!(buf, [[4095; 2], [2048, 2048], [0, 0]]); // 4095 − 4095·1/2 = 2047.5 → 2048 toward rest
    let mut s = SoftStart::new(0, 0);
    let mut buf = [[1234u16; 2]; 2];
    s.apply(true, &mut buf);
    assert_eq!(buf, [[1234; 2]; 2]);
}

// ---------------------------------------------------------------- item 6: watchdog and fault memory

#[test]
fn window_watchdog_reload_for_one_millisecond_at_170_mhz() {
    // One count: 4096 / 170 MHz = 24.094 µs. 1 000 µs / 24.094 µs = 41.50 → 42 counts: 0x40 + 42.
    assert_eq!(watchdog::count_ns(170_000_000, 0), 24_094);
    assert_eq!(watchdog::reload_for(170_000_000, 0, 1_000), Some(0x6A));
    // 63 counts fit (0x7F), 64 do not: 63 · 24.094 = 1 517.9 µs.
    assert_eq!(watchdog::reload_for(170_000_000, 0, 1_517), Some(0x7F));
    assert_eq!(watchdog::reload_for(170_000_000, 0, 1_600), None);
    // Prescaler 2³: 192.75 µs per count; 1 ms → 5.19 → 6 counts.
    assert_eq!(watchdog::reload_for(170_000_000, 3, 1_000), Some(0x46));
}

fn sample_record() -> FaultRecord {
    FaultRecord {
        kind: FaultKind::HardFault,
        boots_seen: 0,
        tick: 123_456,
        later_faults: 0,
        detail: [
            0x0800_1234,
            0xFFFF_FFF9,
            0x6100_0000,
            0x0000_8200,
            0x4000_0000,
            0,
            0x2000_0010,
            0x2001_FF00,
        ],
    }
}

#[test]
fn fault_record_round_trips() {
    let r = sample_record();
    let w = fault_record::encode(&r);
    assert_eq!(w[0], u32::from_le_bytes(*b"PZFR"));
    assert_eq!(w[1], 2);
    assert_eq!(w[3], 123_456);
    assert_eq!(fault_record::decode(&w), Some(r));
    for kind in [
        FaultKind::Overrun,
        FaultKind::Nmi,
        FaultKind::FlashEcc,
        FaultKind::WindowWatchdog,
        FaultKind::Panic,
        FaultKind::UnexpectedInterrupt,
        FaultKind::Controller,
    ] {
        let r = FaultRecord { kind, boots_seen: 3, ..sample_record() };
        assert_eq!(fault_record::decode(&fault_record::encode(&r)), Some(r));
    }
}

/// An overrun while a controller fault (or any earlier fault of this boot) is recorded: the
/// first stays and the later one is counted; before, the last writer won and the first cause
/// was lost. A record a boot has already seen gives way.
#[test]
fn the_fault_record_keeps_the_first_fault_of_a_boot_and_counts_the_rest() {
    let first =
        FaultRecord { kind: FaultKind::Controller, detail: [8, 0, 0, 0, 0, 0, 0, 0], ..sample_record() };
    let overrun = FaultRecord { kind: FaultKind::Overrun, tick: 200_000, ..sample_record() };
    let once = fault_record::merge(fault_record::decode(&fault_record::encode(&first)), overrun);
    assert_eq!(once, FaultRecord { later_faults: 1, ..first });
    let twice = fault_record::merge(fault_record::decode(&fault_record::encode(&once)), overrun);
    assert_eq!((twice.kind, twice.tick, twice.later_faults), (FaultKind::Controller, 123_456, 2));
    // Nothing (random RAM) before: the new one.
    assert_eq!(fault_record::merge(None, overrun), overrun);
    // A record from before the reset (a boot has seen it): the new one replaces it.
    let old = FaultRecord { boots_seen: 1, later_faults: 5, ..first };
    assert_eq!(fault_record::merge(Some(old), overrun), overrun);
    let w = fault_record::encode(&twice);
    assert_eq!(w[4], 2, "the count is the fifth word");
}

#[test]
fn fault_record_rejects_every_single_bit_flip_and_random_ram() {
    let w = fault_record::encode(&sample_record());
    for word in 0..RECORD_WORDS {
        for bit in 0..32 {
            let mut x = w;
            x[word] ^= 1 << bit;
            assert_eq!(fault_record::decode(&x), None, "word {word} bit {bit}");
        }
    }
    assert_eq!(fault_record::decode(&[0; RECORD_WORDS]), None);
    assert_eq!(fault_record::decode(&[u32::MAX; RECORD_WORDS]), None);
    // A valid CRC over an unknown kind is still refused.
    let mut x = w;
    x[1] = 99;
    let body: Vec<u8> = x[..RECORD_WORDS - 1].iter().flat_map(|v| v.to_le_bytes()).collect();
    x[RECORD_WORDS - 1] = piezo_drive::storage::crc32(&body);
    assert_eq!(fault_record::decode(&x), None);
}

// ---------------------------------------------------------------- item 4: flash ECC on the parameter page

#[test]
fn ecc_address_classification() {
    // The parameter page: bank 2, 0x0807_F800 − 0x0804_0000 = 0x3_F800, 2 KiB.
    let page = |bank2, addr| ecc_in_page(bank2, addr, true, 0x3_F800, 2048);
    assert!(page(true, 0x3_F800));
    assert!(page(true, 0x3_FFF8));
    assert!(!page(true, 0x4_0000));
    assert!(!page(true, 0x3_F7F8));
    assert!(!page(false, 0x3_F800), "the same offset in bank 1 is code");
    // Tolerant form: the page 0x7_F800 from the flash start, banks of 256 KiB.
    let param = |bk, addr| ecc_in_param_page(bk, addr, 0x7_F800, 0x4_0000, 2048);
    assert!(param(true, 0x3_F800)); // bank-relative, bank 2
    assert!(param(true, 0x7_FFF8)); // from the flash start, bank flag set
    assert!(param(false, 0x7_F800)); // from the flash start, bank flag clear
    assert!(!param(false, 0x3_F800)); // bank 1 code at the same bank offset
    assert!(!param(true, 0x3_F7F8));
    assert!(!param(true, 0x0_1000));
    assert!(!param(false, 0x7_F7F8));
}

// ---------------------------------------------------------------- item 7: sensing gaps

#[test]
fn floating_preload_probe() {
    // 1 024 words ≈ 0.8 V between the two pulled readings.
    assert!(probe_says_floating(12, 4080, 1024)); // open pin follows the pulls
    assert!(!probe_says_floating(2000, 2003, 1024)); // driven by the bridge amplifier
    assert!(!probe_says_floating(3000, 100, 1024)); // reversed: not the signature of an open pin
    assert!(probe_says_floating(1000, 2024, 1024));
    assert!(!probe_says_floating(1000, 2023, 1024));
}

#[test]
fn float_detector_needs_three_of_four_and_clears_on_four_clean() {
    let mut d = FloatDetector::new();
    assert!(!d.record(true));
    assert!(!d.record(true));
    assert!(!d.record(false));
    assert!(d.record(true)); // 3 of the last 4
    assert!(d.record(false)); // 2 of 4: still floating (hysteresis)
    assert!(d.record(false));
    assert!(d.record(false)); // 1 of 4
    assert!(!d.record(false)); // none of the last 4
}

/// Referencing on the index with the count latched at the edge: the reference lands on the
/// edge, wherever the slider is by the time the tick reads it.
#[test]
fn index_latched_count_places_the_reference_at_the_edge() {
    let mut ctl = idle_controller();
    let mut gcs = Gcs::new();
    assert_eq!(send(&mut gcs, &mut ctl, b"FRF 1\nERR?\n"), b"0\n");
    ctl.step(&Inputs { preload_word: PRELOAD_WORD, encoder_raw: 65_530, ..Default::default() });
    // The edge came at raw 65 533; by the tick the slider (moving −x) has reached 65 521:
    // 12 counts (600 nm) past the mark, across no wrap. The position is then −600 nm.
    ctl.step(&Inputs {
        preload_word: PRELOAD_WORD,
        encoder_raw: 65_521,
        index: true,
        index_raw: Some(65_533),
        ..Default::default()
    });
    assert!(ctl.referenced());
    assert_eq!(ctl.position_nm(), -600);
    // Across the 16-bit wrap: edge at 3, read at 65 530 (9 counts further −x): −450 nm.
    let mut ctl = idle_controller();
    send(&mut gcs, &mut ctl, b"FRF 1\n");
    ctl.step(&Inputs { preload_word: PRELOAD_WORD, encoder_raw: 5, ..Default::default() });
    ctl.step(&Inputs {
        preload_word: PRELOAD_WORD,
        encoder_raw: 65_530,
        index: true,
        index_raw: Some(3),
        ..Default::default()
    });
    assert_eq!(ctl.position_nm(), -450);
    // Without a latched count: the reference is where the tick reads the slider (as before).
    let mut ctl = idle_controller();
    send(&mut gcs, &mut ctl, b"FRF 1\n");
    ctl.step(&Inputs { preload_word: PRELOAD_WORD, encoder_raw: 65_521, index: true, ..Default::default() });
    assert_eq!(ctl.position_nm(), 0);
}

/// Drives a referenced, holding controller into fine mode toward +250 nm (5 counts), with the
/// encoder either frozen or following the fine offset as the foot would carry the slider.
fn fine_mode_run(encoder_follows: bool) -> Controller {
    let mut ctl = idle_controller();
    let mut gcs = Gcs::new();
    send(&mut gcs, &mut ctl, b"FRF 1\n");
    ctl.step(&Inputs { preload_word: PRELOAD_WORD, index: true, ..Default::default() });
    assert_eq!(send(&mut gcs, &mut ctl, b"SVO 1 1\nMOV 1 0.00025\nERR?\n"), b"0\n");
    let nm_per_v: f32 = ctl.config().motor.fine_nm_per_v.to_num();
    let mut counts: i64 = 0;
    for _ in 0..20_000 {
        if matches!(ctl.state(), State::Fault(_)) {
            break;
        }
        if encoder_follows && ctl.fine_mode() {
            counts = (ctl.fine_offset_v() * nm_per_v / 50.0).round() as i64;
        }
        ctl.step(&Inputs { preload_word: PRELOAD_WORD, encoder_raw: counts as u16, ..Default::default() });
        // The board's lower-rate task (the model table), between ticks.
        ctl.background();
    }
    ctl
}

#[test]
fn encoder_loss_in_fine_mode_trips() {
    let ctl = fine_mode_run(false);
    assert_eq!(ctl.state(), State::Fault(FaultCode::EncoderLoss));
}

#[test]
fn fine_mode_with_a_live_encoder_does_not_trip() {
    let ctl = fine_mode_run(true);
    assert!(!matches!(ctl.state(), State::Fault(_)), "{:?}", ctl.state());
    assert_eq!(ctl.position_nm(), 250);
}

// ---------------------------------------------------------------- item 8: no panic paths

#[test]
fn clamps_never_panic_and_match_std_for_ordered_bounds() {
    for &(x, lo, hi) in &[(5.0f32, 0.0, 1.0), (-5.0, 0.0, 1.0), (0.5, 0.0, 1.0), (1.0, 1.0, 1.0)] {
        assert_eq!(clamp_f32(x, lo, hi), x.clamp(lo, hi));
    }
    // Where f32::clamp would panic: NaN or crossed bounds.
    assert_eq!(clamp_f32(0.5, f32::NAN, 1.0), 0.5);
    assert_eq!(clamp_f32(2.0, f32::NAN, 1.0), 1.0);
    assert_eq!(clamp_f32(0.5, 1.0, 0.0), 1.0);
    assert_eq!(clamp_sym_f32(3.0, f32::NAN), 3.0);
    assert_eq!(clamp_sym_f32(3.0, -1.0), -1.0); // lo = 1, hi = −1: 3 is not below lo, above hi → hi
    assert!(clamp_f32(f32::NAN, 0.0, 1.0).is_nan());
    assert_eq!(clamp_i32(7, 0, 5), 5);
    assert_eq!(clamp_i32(3, 5, 0), 5);
    assert_eq!(clamp_i32(-3, -1, 1), -1);
}

#[test]
fn fx_from_f32_matches_fixed_without_its_nan_panic() {
    use piezo_drive::fastmath::fx_from_f32;
    use piezo_drive::Fx;
    let edge = [
        0.0f32,
        -0.0,
        1.0,
        -1.0,
        0.5 / 65536.0,
        1.5 / 65536.0,
        2.5 / 65536.0,
        -0.5 / 65536.0,
        -1.5 / 65536.0,
        127.99998,
        32767.99998,
        32768.0,
        -32768.0,
        -32769.0,
        1e9,
        -1e9,
        f32::INFINITY,
        f32::NEG_INFINITY,
        f32::MIN_POSITIVE,
        1e-40,
        3.25159,
        -2.61828,
        128.0 + 0.5 / 65536.0,
        16.0,
        50.0,
    ];
    for x in edge {
        assert_eq!(fx_from_f32(x), Fx::saturating_from_num(x), "{x:e}");
    }
    // Every bit pattern step through the whole f32 range (NaNs excluded).
    let mut bits: u32 = 0;
    loop {
        let x = f32::from_bits(bits);
        if !x.is_nan() {
            assert_eq!(fx_from_f32(x), Fx::saturating_from_num(x), "{x:e} ({bits:08x})");
        }
        match bits.checked_add(4_099) {
            Some(b) => bits = b,
            None => break,
        }
    }
    assert_eq!(fx_from_f32(f32::NAN), Fx::ZERO);
}

/// A settings change is prepared off the lock from a snapshot of the settings: if another change
/// was applied meanwhile, applying the stale one would undo it, so it is refused whole.
#[test]
fn a_settings_change_prepared_from_older_settings_is_refused() {
    let cfg = defaults::controller_config();
    let mut ctl = Controller::new(cfg).unwrap();
    let before = ctl.config_generation();
    let slower = ControllerConfig { velocity_max_nm_s: cfg.velocity_max_nm_s * 0.5, ..cfg };
    let stale = ConfigChange::prepare(ctl.config(), before, slower).unwrap();
    let faster = ControllerConfig { velocity_max_nm_s: cfg.velocity_max_nm_s * 0.9, ..cfg };
    ctl.set_config(faster).unwrap();
    assert_ne!(ctl.config_generation(), before);
    assert_eq!(ctl.apply_config(&stale), Err(CommandError::Busy));
    assert_eq!(*ctl.config(), faster);
    // Prepared from the current settings it applies.
    let fresh = ConfigChange::prepare(ctl.config(), ctl.config_generation(), slower).unwrap();
    assert_eq!(ctl.apply_config(&fresh), Ok(()));
    assert_eq!(*ctl.config(), slower);
    // What the board fixes cannot change; a value out of range is refused before any lock.
    let other_loop = ControllerConfig { loop_hz: cfg.loop_hz / 2, ..cfg };
    assert_eq!(ConfigChange::prepare(ctl.config(), 0, other_loop), Err(CommandError::InvalidValue));
    let negative = ControllerConfig { velocity_max_nm_s: -1.0, ..cfg };
    assert!(ConfigChange::prepare(ctl.config(), 0, negative).is_err());
}

/// What a settings change forgets: a new motor calibration restarts the load estimate from the
/// told load; a new told load, a limit or a new mass alone leaves the estimate; a new mass is
/// taken at once (the learned one forgotten).
#[test]
fn a_new_calibration_forgets_the_learned_load_and_a_new_mass_the_learned_mass() {
    let cfg = defaults::controller_config();
    let mut ctl = Controller::new(cfg).unwrap();
    assert_eq!(ctl.load_estimate_n(), 0.0);
    let calibrations: [fn(&mut ControllerConfig); 5] = [
        |c| c.mu_dynamic *= 1.1,
        |c| c.tangential_scale *= 1.1,
        |c| c.normal_force_ratio *= 1.1,
        |c| c.rail_coulomb_n += 0.5,
        |c| c.rail_viscous_n_s_per_m += 1.0,
    ];
    let mut estimate_n = 0.0;
    for (i, recalibrate) in calibrations.iter().enumerate() {
        let told_n = 1.0 + i as f32;
        // Told load, limit, mass: what was learned stays.
        let mut c = *ctl.config();
        c.expected_load_n = told_n;
        c.velocity_max_nm_s *= 0.9;
        c.moving_mass_kg *= 1.1;
        ctl.set_config(c).unwrap();
        assert_eq!(ctl.load_estimate_n(), estimate_n, "calibration {i}: kept");
        assert_eq!(ctl.moving_mass_kg(), c.moving_mass_kg, "calibration {i}: the new mass");
        // The calibration: from the told load again.
        recalibrate(&mut c);
        ctl.set_config(c).unwrap();
        assert_eq!(ctl.load_estimate_n(), told_n, "calibration {i}: forgotten");
        estimate_n = told_n;
    }
}

#[test]
fn settings_commands_on_a_copy_then_set_config_equal_running_them_directly() {
    let lines: [&[u8]; 7] = [
        b"SPA 1 0xA 0.01\n",
        b"VEL 1 2.5\n",
        b"ACC 1 100\n",
        b"DEC 1 50\n",
        b"SPA 1 0x1 20 1 0x1002 80\n",
        b"SPA 1 0x1 -5\n",   // refused: nothing changes
        b"SPA 1 0xFFFF 1\n", // unknown parameter
    ];
    for line in lines {
        let mut p = None;
        let mut g = Gcs::new();
        for &b in line {
            if let Some(x) = g.push_byte(b) {
                p = Some(x);
            }
        }
        let p = p.unwrap();
        assert!(Gcs::is_settings_only(&p));
        // Directly.
        let mut direct = idle_controller();
        let mut gcs_a = Gcs::new();
        send(&mut gcs_a, &mut direct, b"SVO 1 1\n");
        let mut board = TestBoard::default();
        let mut reply_a = Reply::new();
        gcs_a.execute(&p, &mut direct, &mut board, &mut reply_a);
        // On a copy, then the settings only.
        let mut real = idle_controller();
        let mut gcs_b = Gcs::new();
        send(&mut gcs_b, &mut real, b"SVO 1 1\n");
        let mut copy = real.clone();
        let mut reply_b = Reply::new();
        gcs_b.execute(&p, &mut copy, &mut board, &mut reply_b);
        if *real.config() != *copy.config() {
            real.set_config(*copy.config()).unwrap();
        }
        assert_eq!(reply_a, reply_b);
        assert_eq!(gcs_a.latched_error(), gcs_b.latched_error(), "{}", String::from_utf8_lossy(line));
        assert!(*real.config() == *direct.config());
        for k in 0..100u16 {
            let inputs = Inputs { preload_word: PRELOAD_WORD, encoder_raw: k / 8, ..Default::default() };
            assert_eq!(real.step(&inputs), direct.step(&inputs));
            real.background();
            direct.background();
        }
    }
    // Not settings-only: motion, servo, queries, stores.
    for l in [&b"MOV 1 1"[..], b"SVO 1 0", b"SPA? 1 0xA", b"WPA 100", b"VEL? 1"] {
        let mut line = heapless::Vec::new();
        line.extend_from_slice(l).unwrap();
        assert!(!Gcs::is_settings_only(&Pending::Line(line)), "{}", String::from_utf8_lossy(l));
    }
}

#[test]
fn overrun_supervisor_reaction() {
    use piezo_drive::safety::timing::OverrunSupervisor;
    let mut s = OverrunSupervisor::new(DeadlineMonitor::new(FIRST_DUE, PERIOD, DEADLINE), bucket());
    let due = |k: u32| FIRST_DUE + k * PERIOD;
    // On time: enable allowed, watchdogs fed.
    let t = s.begin(due(0) + 50);
    let v = s.judge(&t, due(0) + 3_000, false);
    assert_eq!((v.late, v.tripped_now, v.feed_watchdogs), (false, false, true));
    assert!(s.enable(true, false));
    assert!(!s.enable(true, true), "parked");
    assert!(!s.enable(false, false));
    // Ticks 1–4 refill 16 000 counts after their due time (past 15 300): late, not fed; the
    // fourth trips (10, 20, 30, 40).
    for k in 1..=4 {
        let t = s.begin(due(k) + 14_000);
        let v = s.judge(&t, due(k) + 16_000, false);
        assert!(v.late && !v.feed_watchdogs);
        assert_eq!(v.tripped_now, k == 4, "tick {k}");
    }
    assert!(s.latched());
    assert!(!s.enable(true, false), "latched: the amplifier stays off");
    // On time again: fed, but the latch holds while the controller's fault is active.
    let t = s.begin(due(5) + 10);
    let v = s.judge(&t, due(5) + 1_000, false);
    assert_eq!((v.late, v.tripped_now, v.feed_watchdogs), (false, false, true));
    s.controller_fault_active(true);
    assert!(s.latched());
    // The host clears the fault: afresh.
    s.controller_fault_active(false);
    assert!(!s.latched());
    assert_eq!(s.bucket_level(), 0);
    assert!(s.enable(true, false));
    // A tick a whole period late trips at once, even though it starts early in its own period.
    let t = s.begin(due(7) + 20);
    let v = s.judge(&t, due(7) + 500, false);
    assert!(v.late && v.tripped_now);
    // The DMA found in the half just written is late whatever the clock says.
    s.controller_fault_active(false);
    let t = s.begin(due(8) + 20);
    let v = s.judge(&t, due(8) + 500, true);
    assert!(v.late && !v.tripped_now);
}

/// The soft start's blend in 32-bit arithmetic (no 64-bit division in the tick) is exactly
/// `rest + (word − rest)·k/n` truncated toward `rest`, the closed form in i64, for every word,
/// rest and ramp length up to 65 536 samples.
#[test]
fn the_soft_start_blend_is_the_closed_form_exactly() {
    let mut seed = 0x2545_f491_4f6c_dd1du64;
    let mut next = move || {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        seed
    };
    for _ in 0..2000 {
        let rest = (next() & 0xFFFF) as u16;
        let word = (next() & 0xFFFF) as u16;
        let n = 1 + (next() % 65_536) as u32;
        let k = (next() % u64::from(n)) as u32;
        let mut s = SoftStart::new(rest, n);
        // Run the ramp to sample k with the word held, then read sample k's blend.
        let mut skip = vec![[word; 2]; k as usize];
        s.apply(true, &mut skip);
        let mut one = [[word; 2]];
        s.apply(true, &mut one);
        let d = i64::from(word) - i64::from(rest);
        let expected = i64::from(rest) + d * i64::from(k) / i64::from(n);
        assert_eq!(i64::from(one[0][0]), expected, "rest {rest} word {word} k {k} n {n}");
    }
}

// ---------------------------------------------------------------- a board that cannot hurt its motor

/// Steps `ctl` with the encoder at `count(k)` in period `k` until it faults or `limit` periods
/// passed; the period of the fault (1 = the first) and its code.
fn periods_to_fault(
    ctl: &mut Controller,
    limit: u32,
    count: impl Fn(u32) -> u16,
) -> Option<(u32, FaultCode)> {
    (1..=limit).find_map(|k| {
        let out =
            ctl.step(&Inputs { preload_word: PRELOAD_WORD, encoder_raw: count(k), ..Default::default() });
        ctl.background();
        ctl.fault().map(|code| {
            assert!(!out.amp_enable, "the fault's own period disables the amplifier");
            (k, code)
        })
    })
}

/// Open-loop stepping (`XOS`) against an end stop: the encoder never moves. Before, the run went
/// on for all its cycles (here 10 s at 80 V) whatever the encoder said; now the progress watch
/// stops it after one window of the model's foot speed at that drive (clamped to 20–50 ms: the
/// 4 counts it asks are 200 nm, 1/50 of what the foot covers in the window at the least).
#[test]
fn open_loop_stepping_into_a_stop_faults_no_progress_within_a_window() {
    let mut ctl = idle_controller();
    ctl.open_loop_step(15_000, 80.0, 1500.0).unwrap();
    let window = ctl.progress_window_ticks(80.0);
    assert!((200..=500).contains(&window), "window {window} periods");
    let (n, code) = periods_to_fault(&mut ctl, 100_000, |_| 0).expect("a fault");
    assert_eq!(code, FaultCode::NoProgress);
    assert_eq!(n, window);
    // A slider gaining a count every 10 periods (far slower than the model's) runs on.
    let mut ctl = idle_controller();
    ctl.open_loop_step(1_500, 80.0, 1500.0).unwrap();
    assert_eq!(periods_to_fault(&mut ctl, 10_001, |k| (k / 10) as u16), None);
    assert_eq!(ctl.state(), State::Idle, "the run ended after its cycles");
}

/// A lost quadrature channel whose partner still toggles makes the count flicker between two
/// values: before, any change reset the watches; now the flicker is no progress.
#[test]
fn a_flickering_encoder_is_no_progress() {
    let mut ctl = idle_controller();
    ctl.open_loop_step(-15_000, 80.0, 1500.0).unwrap();
    let window = ctl.progress_window_ticks(80.0);
    let (n, code) = periods_to_fault(&mut ctl, 100_000, |k| (k / 3 % 2) as u16).expect("a fault");
    assert_eq!((n, code), (window, FaultCode::NoProgress));
}

/// Referencing (`FRF`) with the index on the far side and no limit switches: the search toward
/// −x meets the stop. Before: 50 V against the stop until the 200 s timeout; now the progress
/// watch's window at the referencing drive.
#[test]
fn referencing_into_a_stop_faults_no_progress() {
    let mut ctl = idle_controller();
    ctl.start_referencing().unwrap();
    let cfg = *ctl.config();
    let window = ctl.progress_window_ticks(cfg.reference_drive_v);
    // Moving toward −x for 1000 periods (a count every 5), then against the stop.
    let (n, code) =
        periods_to_fault(&mut ctl, 100_000, |k| 0u16.wrapping_sub(k.min(1000) as u16 / 5)).expect("a fault");
    assert_eq!(code, FaultCode::NoProgress);
    // The last gain ended a window at or before period 1000: the fault one window later at most.
    assert!(n > 1000 && n <= 1000 + window, "fault at {n}, window {window}");
    assert!(!ctl.referenced());
}

/// The timeouts have upper bounds (an hour), and the timers count periods: the reference
/// search times out after exactly its setting's periods.
#[test]
fn timeouts_are_bounded_and_counted_in_periods() {
    use piezo_drive::controller::validate_settings;
    let d = defaults::controller_config();
    for (s, ok) in [(3600.0, true), (3600.5, false), (1e6, false)] {
        assert_eq!(validate_settings(&ControllerConfig { reference_timeout_s: s, ..d }).is_ok(), ok, "{s}");
        assert_eq!(validate_settings(&ControllerConfig { stall_time_s: s, ..d }).is_ok(), ok, "{s}");
        assert_eq!(validate_settings(&ControllerConfig { settle_time_s: s, ..d }).is_ok(), ok, "{s}");
    }
    assert_eq!(d.ticks_for_s(3600.0), 36_000_000);
    assert_eq!(d.ticks_for_s(0.0123), 123);
    // A search at 20 V (below the progress watch's share) that finds nothing: it fails after
    // 0.0123 s = 123 periods, the 124th period ends it.
    let mut ctl =
        Controller::new(ControllerConfig { reference_timeout_s: 0.0123, reference_drive_v: 20.0, ..d })
            .unwrap();
    for _ in 0..10 {
        ctl.step(&Inputs { preload_word: PRELOAD_WORD, ..Default::default() });
    }
    ctl.start_referencing().unwrap();
    let n = (1..=1000u32)
        .find(|_| {
            ctl.step(&Inputs { preload_word: PRELOAD_WORD, ..Default::default() });
            !ctl.referencing()
        })
        .unwrap();
    assert_eq!(n, 124);
    assert_eq!(ctl.reference_failure_count(), 1);
}

/// An overrun during another fault: the controller keeps the first fault's code and counts the
/// overrun (before, it was dropped without a trace).
#[test]
fn an_overrun_during_a_fault_is_counted() {
    let mut ctl = idle_controller();
    ctl.step(&Inputs { preload_word: PRELOAD_WORD, encoder_raw: 30_000, ..Default::default() });
    assert_eq!(ctl.fault(), Some(FaultCode::EncoderJump));
    assert_eq!(ctl.overrun_count(), 0);
    ctl.trip_external(FaultCode::Overrun);
    ctl.trip_external(FaultCode::Overrun);
    assert_eq!(ctl.fault(), Some(FaultCode::EncoderJump));
    assert_eq!(ctl.overrun_count(), 2);
}

#[test]
fn the_independent_watchdog_is_fed_only_while_the_communication_executor_beats() {
    use piezo_drive::safety::watchdog::Heartbeat;
    let mut h = Heartbeat::default();
    // A beat every 100 ticks (the monitor's 10 ms at 10 kHz): alive throughout.
    let mut beat = 0u32;
    for t in 0..10_000u32 {
        if t % 100 == 0 {
            beat += 1;
        }
        assert!(h.alive(beat), "tick {t}");
    }
    // Its last beat, then it hangs: alive for 299 more ticks, dead from the 300th (30 ms) on
    // and until it beats again.
    beat += 1;
    assert!(h.alive(beat));
    let dead_from = (1..=1_000u32).find(|_| !h.alive(beat)).expect("goes stale");
    assert_eq!(dead_from, Heartbeat::STALE_TICKS);
    assert!(!h.alive(beat));
    assert!(h.alive(beat + 1), "a new beat revives it");
}
