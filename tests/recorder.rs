//! The data recorder's core (`piezo_drive::recorder`) without the protocol: configuration and
//! its refusals, the triggers, the record rate, a recording that fills its table, the points each
//! option records and how they print. Hand-computed expectations; the protocol's side is in
//! `tests/gcs.rs`.

use piezo_drive::controller::{Controller, Inputs};
use piezo_drive::defaults;
use piezo_drive::gcs::datarec::write_point;
use piezo_drive::recorder::{option, trigger, Recorder, RecorderError, DEPTH, MAX_RATE, NO_VALUE, TABLES};
use proptest::prelude::*;

/// 16 N on the default force cell (1310 · 50 / 4095 = 15.995 N).
const PRELOAD_WORD: u16 = 1310;

fn controller() -> Controller {
    let mut ctl = Controller::new(defaults::controller_config()).unwrap();
    ctl.step(&Inputs { preload_word: PRELOAD_WORD, ..Default::default() });
    ctl
}

fn step(ctl: &mut Controller, rec: &Recorder, encoder: u16) {
    ctl.step(&Inputs { encoder_raw: encoder, preload_word: PRELOAD_WORD, ..Default::default() });
    rec.sample(ctl);
}

fn printed(opt: u32, v: i32) -> String {
    let mut b: heapless::Vec<u8, 32> = heapless::Vec::new();
    assert!(write_point(&mut b, opt, v));
    String::from_utf8(b.to_vec()).unwrap()
}

fn column(rec: &Recorder, id: usize) -> Vec<i32> {
    (0..rec.points(id).unwrap()).map(|i| rec.point(id, i).unwrap()).collect()
}

#[test]
fn the_recorder_fits_the_ram_budget() {
    // What a recorder costs in static RAM (the buffer plus its bookkeeping) against the 33 KiB
    // of the firmware's 64 KiB that it gets (PI's depth, 1 024 points, in 8 tables).
    assert!(core::mem::size_of::<Recorder>() <= 33 * 1024, "{}", core::mem::size_of::<Recorder>());
}

#[test]
fn power_up_state_and_refusals() {
    let rec = Recorder::new();
    let ctl = controller();
    assert_eq!(rec.rate(), 1);
    for id in 1..=TABLES {
        assert_eq!(rec.option(id), Ok(option::NOTHING));
        assert_eq!(rec.trigger(id), Ok(trigger::DEFAULT));
        assert_eq!(rec.points(id), Ok(0));
    }
    for bad in [0, TABLES + 1, usize::MAX] {
        assert_eq!(rec.configure(bad, option::ACTUAL_POSITION), Err(RecorderError::UnknownTable));
        assert_eq!(rec.points(bad), Err(RecorderError::UnknownTable));
        assert_eq!(rec.point(bad, 0), None);
    }
    assert_eq!(rec.set_trigger(TABLES + 1, trigger::IMMEDIATELY, &ctl), Err(RecorderError::UnknownTable));
    for bad in [4, 255, 260, u32::MAX] {
        assert_eq!(rec.configure(1, bad), Err(RecorderError::UnknownOption));
    }
    for bad in [3, 5, 7, u32::MAX] {
        assert_eq!(rec.set_trigger(1, bad, &ctl), Err(RecorderError::OutOfRange));
    }
    assert_eq!(rec.set_rate(0), Err(RecorderError::OutOfRange));
    assert_eq!(rec.set_rate(MAX_RATE + 1), Err(RecorderError::OutOfRange));
    assert_eq!(rec.set_rate(MAX_RATE), Ok(()));
    assert_eq!(rec.rate(), MAX_RATE);
    // Nothing refused changed anything.
    assert_eq!(rec.option(1), Ok(option::NOTHING));
    assert_eq!(rec.trigger(1), Ok(trigger::DEFAULT));
}

#[test]
fn the_rate_divides_the_ticks_from_the_trigger_on() {
    let rec = Recorder::new();
    let mut ctl = controller();
    rec.configure(1, option::ACTUAL_POSITION).unwrap();
    rec.set_rate(3).unwrap();
    rec.set_trigger(1, trigger::IMMEDIATELY, &ctl).unwrap();
    // Point 1 at the trigger (position 0), then after ticks 3, 6, 9 with the encoder at the
    // tick number (50 nm per count).
    assert_eq!(column(&rec, 1), [0]);
    for tick in 1..=9u16 {
        step(&mut ctl, &rec, tick);
        assert_eq!(rec.points(1), Ok(1 + usize::from(tick / 3)), "tick {tick}");
    }
    assert_eq!(column(&rec, 1), [0, 150, 300, 450]);
    // A new rate counts for recordings that start later; this one keeps its own.
    rec.set_rate(1).unwrap();
    assert_eq!(rec.table_rate(1), Ok(3));
    step(&mut ctl, &rec, 10);
    assert_eq!(rec.points(1), Ok(4));
    rec.set_trigger(1, trigger::IMMEDIATELY, &ctl).unwrap();
    assert_eq!(rec.table_rate(1), Ok(1));
    step(&mut ctl, &rec, 11);
    assert_eq!(column(&rec, 1), [500, 550]);
}

#[test]
fn a_recording_that_overruns_stops_at_the_end() {
    let rec = Recorder::new();
    let mut ctl = controller();
    rec.configure(2, option::ACTUAL_POSITION).unwrap();
    rec.set_trigger(2, trigger::IMMEDIATELY, &ctl).unwrap();
    for tick in 1..(DEPTH as u16 + 100) {
        step(&mut ctl, &rec, tick);
    }
    assert_eq!(rec.points(2), Ok(DEPTH));
    // The first DEPTH points, the later ticks dropped: point k is tick k − 1.
    let col = column(&rec, 2);
    assert_eq!(col.len(), DEPTH);
    assert!(col.iter().enumerate().all(|(k, v)| *v == 50 * k as i32), "{col:?}");
    assert_eq!(rec.point(2, DEPTH), None);
    // The other tables recorded nothing.
    assert_eq!(rec.points(1), Ok(0));
    // A trigger starts it over.
    rec.set_trigger(2, trigger::IMMEDIATELY, &ctl).unwrap();
    assert_eq!(rec.points(2), Ok(1));
}

#[test]
fn triggers_by_moves() {
    let rec = Recorder::new();
    let mut ctl = controller();
    for (id, trig) in
        [(1, trigger::DEFAULT), (2, trigger::ANY_MOVE), (3, trigger::IMMEDIATELY), (4, trigger::NEXT_MOVE)]
    {
        rec.configure(id, option::ACTUAL_POSITION).unwrap();
        rec.set_trigger(id, trig, &ctl).unwrap();
    }
    // Table 5 has a move trigger but records nothing.
    rec.set_trigger(5, trigger::NEXT_MOVE, &ctl).unwrap();
    let points = |rec: &Recorder| (1..=5).map(|id| rec.points(id).unwrap()).collect::<Vec<_>>();
    assert_eq!(points(&rec), [0, 0, 1, 0, 0]);
    step(&mut ctl, &rec, 1);
    step(&mut ctl, &rec, 2);
    assert_eq!(points(&rec), [0, 0, 3, 0, 0]);
    rec.on_move(&ctl);
    assert_eq!(points(&rec), [1, 1, 3, 1, 0]);
    step(&mut ctl, &rec, 3);
    assert_eq!(points(&rec), [2, 2, 4, 2, 0]);
    // A second move restarts tables 1 and 2 (triggers 0 and 1), not 4 (next move only) nor 3.
    rec.on_move(&ctl);
    assert_eq!(points(&rec), [1, 1, 4, 2, 0]);
    assert_eq!(column(&rec, 1), [150]);
    assert_eq!(column(&rec, 4), [100, 150]);
    // DRT arms table 4 again: the next move starts it.
    rec.set_trigger(4, trigger::NEXT_MOVE, &ctl).unwrap();
    assert_eq!(rec.points(4), Ok(0));
    rec.on_move(&ctl);
    assert_eq!(rec.points(4), Ok(1));
    // Trigger 2: the next command of any kind, once.
    rec.set_trigger(4, trigger::NEXT_COMMAND, &ctl).unwrap();
    rec.on_move(&ctl);
    assert_eq!(rec.points(4), Ok(0));
    rec.on_command(&ctl);
    assert_eq!(rec.points(4), Ok(1));
    step(&mut ctl, &rec, 4);
    rec.on_command(&ctl);
    assert_eq!(rec.points(4), Ok(2));
    // DRC forgets a table's points and waits for its trigger.
    rec.configure(1, option::POSITION_ERROR).unwrap();
    assert_eq!(rec.points(1), Ok(0));
}

#[test]
fn each_option_records_its_quantity_in_integer_units() {
    let rec = Recorder::new();
    let mut ctl = controller();
    let opts = [
        option::COMMANDED_POSITION,
        option::ACTUAL_POSITION,
        option::POSITION_ERROR,
        option::DRIVE_AMPLITUDE,
        option::DRIVE_FREQUENCY,
        option::PRELOAD_FORCE,
        option::CONTROLLER_STATE,
    ];
    for (i, o) in opts.iter().enumerate() {
        rec.configure(i + 1, *o).unwrap();
    }
    // Servo off at rest: the commanded position is 0 and the encoder reads 40 counts (2 µm).
    step(&mut ctl, &rec, 40);
    rec.set_trigger(0, trigger::IMMEDIATELY, &ctl).unwrap();
    let row: Vec<i32> = (1..=opts.len()).map(|id| rec.point(id, 0).unwrap()).collect();
    let f = defaults::controller_config().drive_freq_hz;
    assert_eq!(row, [0, 2000, -2000, 0, (f * 1000.0) as i32, 15995, 0]);
    assert_eq!(rec.point(8, 0), None);
    // A preload word outside the valid window: no value.
    let mut ctl = controller();
    for _ in 0..5 {
        ctl.step(&Inputs { preload_word: u16::MAX, ..Default::default() });
    }
    assert!(ctl.preload_n().is_none());
    rec.set_trigger(0, trigger::IMMEDIATELY, &ctl).unwrap();
    assert_eq!(rec.point(6, 0), Some(NO_VALUE));
    // Servo off, the sensor's fault does not count: idle. A fault's state code is 10 + its code.
    assert_eq!(rec.point(7, 0), Some(0));
    use piezo_drive::controller::{FaultCode, State};
    assert_eq!(piezo_drive::recorder::state_code(State::Fault(FaultCode::PreloadSensor)), 14);
    assert_eq!(piezo_drive::recorder::state_code(State::OpenLoop), 4);
}

#[test]
fn points_print_in_the_protocols_units() {
    assert_eq!(printed(option::ACTUAL_POSITION, 1_000_050), "1.000050");
    assert_eq!(printed(option::COMMANDED_POSITION, 0), "0.000000");
    assert_eq!(printed(option::POSITION_ERROR, -50), "-0.000050");
    assert_eq!(printed(option::DRIVE_AMPLITUDE, 98_250), "98.250");
    assert_eq!(printed(option::DRIVE_FREQUENCY, 2_200_000), "2200.000");
    assert_eq!(printed(option::PRELOAD_FORCE, 15_995), "15.995");
    assert_eq!(printed(option::PRELOAD_FORCE, NO_VALUE), "nan");
    assert_eq!(printed(option::CONTROLLER_STATE, 11), "11");
    assert_eq!(printed(option::ACTUAL_POSITION, i32::MAX), "2147.483647");
    assert_eq!(printed(option::ACTUAL_POSITION, i32::MIN + 1), "-2147.483647");
}

#[derive(Debug, Clone)]
enum Op {
    Configure(usize, u32),
    Trigger(usize, u32),
    Rate(u32),
    Move,
    Command,
    Ticks(u16),
}

fn op() -> impl Strategy<Value = Op> {
    prop_oneof![
        (0usize..10, prop::sample::select(vec![0u32, 1, 2, 3, 4, 256, 257, 258, 259, 260]))
            .prop_map(|(t, o)| Op::Configure(t, o)),
        (0usize..10, 0u32..8).prop_map(|(t, g)| Op::Trigger(t, g)),
        (0u32..70_000).prop_map(Op::Rate),
        Just(Op::Move),
        Just(Op::Command),
        (0u16..800).prop_map(Op::Ticks),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Whatever the commands, nothing panics, no table holds more than DEPTH points, every
    /// point below the count reads, none above does.
    #[test]
    fn any_sequence_of_operations_keeps_the_tables_consistent(ops in proptest::collection::vec(op(), 1..40)) {
        let rec = Recorder::new();
        let mut ctl = controller();
        let mut encoder = 0u16;
        for op in ops {
            match op {
                Op::Configure(t, o) => { let _ = rec.configure(t, o); }
                Op::Trigger(t, g) => { let _ = rec.set_trigger(t, g, &ctl); }
                Op::Rate(r) => { let _ = rec.set_rate(r); }
                Op::Move => rec.on_move(&ctl),
                Op::Command => rec.on_command(&ctl),
                Op::Ticks(n) => for _ in 0..n {
                    encoder = encoder.wrapping_add(1);
                    step(&mut ctl, &rec, encoder);
                },
            }
            for id in 1..=TABLES {
                let n = rec.points(id).unwrap();
                prop_assert!(n <= DEPTH);
                prop_assert!(n == 0 || rec.point(id, n - 1).is_some());
                prop_assert!(rec.point(id, n).is_none());
                prop_assert!(rec.option(id).unwrap() != option::NOTHING || n == 0);
            }
            prop_assert!((1..=MAX_RATE).contains(&rec.rate()));
        }
    }
}
