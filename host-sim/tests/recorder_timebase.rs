//! The data recorder's time base on the simulated board: a 1 mm move recorded from the move
//! command on (`MOV` with trigger 6), the way the board and `host-sim serve` record it (a point
//! after each `RTR`-th step), against the same move watched every period. Deterministic: same
//! plant, same seed, no wall clock.

use host_sim::harness::moves::{ready_board, run_move};
use host_sim::harness::sil::controller_config;
use host_sim::motor::params::Params;
use piezo_drive::recorder::{option, trigger, Recorder, DEPTH};

const TARGET_NM: i64 = 1_000_000;
const COUNT_NM: i64 = 50;

/// First index from which every value stays within one count of the target.
fn settle_index(values: &[i64]) -> Option<usize> {
    let mut idx = None;
    for (i, v) in values.iter().enumerate() {
        if (v - TARGET_NM).abs() <= COUNT_NM {
            idx.get_or_insert(i);
        } else {
            idx = None;
        }
    }
    idx
}

#[test]
fn recorded_settle_time_is_the_watched_one_on_the_record_grid() {
    let p = Params::prototype();
    let rate = 20usize;
    let dt = 1.0 / f64::from(controller_config(&p).loop_hz);
    let mut sil = ready_board(&p, controller_config(&p), 16.0).unwrap();
    let rec = Recorder::new();
    rec.configure(1, option::ACTUAL_POSITION).unwrap();
    rec.configure(2, option::COMMANDED_POSITION).unwrap();
    rec.set_rate(rate as u32).unwrap();
    rec.set_trigger(0, trigger::NEXT_MOVE, &sil.controller).unwrap();
    sil.controller.move_to(TARGET_NM).unwrap();
    rec.on_move(&sil.controller);
    // Watched: the encoder position at the command and after every period.
    let mut watched = vec![sil.controller.position_nm()];
    for _ in 0..DEPTH * rate {
        sil.period();
        rec.sample(&sil.controller);
        watched.push(sil.controller.position_nm());
    }
    assert_eq!(rec.points(1), Ok(DEPTH));
    let recorded: Vec<i64> = (0..DEPTH).map(|i| i64::from(rec.point(1, i).unwrap())).collect();
    // Point k is the state k · RTR periods after the command, exactly.
    for (k, v) in recorded.iter().enumerate() {
        assert_eq!(*v, watched[k * rate], "point {k}");
    }
    assert_eq!(rec.point(2, DEPTH - 1), Some(TARGET_NM as i32));
    // The recorded settle time is the watched one rounded up to the record grid.
    let tick = settle_index(&watched).expect("settles within the recording");
    let point = settle_index(&recorded).expect("settles within the recording");
    let (t_watched, t_recorded, period) = (tick as f64 * dt, (point * rate) as f64 * dt, rate as f64 * dt);
    assert!(
        t_recorded >= t_watched - 1e-12 && t_recorded < t_watched + period,
        "{t_recorded} vs {t_watched}"
    );
    // And agrees with `host-sim move`'s (on the plant's true position) within one period.
    let mut fresh = ready_board(&p, controller_config(&p), 16.0).unwrap();
    let r = run_move(&mut fresh, TARGET_NM, 2.0, 0.05);
    let t_move = r.settle_time_s.expect("host-sim move settles");
    // (1e-9 s: the simulator's clock sums 1e-4 s steps, a few ulps off the exact grid.)
    assert!((t_recorded - t_move).abs() <= period + 1e-9, "recorded {t_recorded} s, move {t_move} s");
    println!(
        "settle: watched {t_watched:.4} s, recorded {t_recorded:.4} s, move {t_move:.4} s, period {period} s"
    );
}
