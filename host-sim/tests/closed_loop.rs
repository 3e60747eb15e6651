//! The firmware's controller in the loop with the plant (10 kHz control, 12-bit DAC, 16-bit
//! encoder counter, one-period output delay), against physical limits.

use host_sim::harness::moves::{ready_board, run_move, single_move, MoveSpec};
use host_sim::harness::sil::{controller_config, Sil};
use host_sim::motor::params::Params;
use host_sim::motor::plant::ExternalLoad;
use piezo_drive::controller::{CommandError, FaultCode, State};

fn board(preload_n: f64) -> (Params, Sil) {
    let p = Params::prototype();
    let sil = ready_board(&p, controller_config(&p), preload_n).unwrap();
    (p, sil)
}

/// Distance over the highest no-load speed the time-domain plant reaches within 100 V and
/// 0.5–2.2 kHz, plus the time to reach that speed at stall thrust (measured on the plant, no
/// controller involved: `host_sim::harness::sweep::physical_limit_s`).
fn physical_limit_s(p: &Params, distance_m: f64) -> f64 {
    host_sim::harness::sweep::physical_limit_s(p, distance_m, 16.0).0
}

fn assert_stays(sil: &mut Sil, target_nm: f64, seconds: f64) {
    let count_nm = 50.0;
    let end = sil.time_s() + seconds;
    while sil.time_s() < end {
        sil.period();
        let err = sil.plant.slider_position_m() * 1e9 - target_nm;
        assert!(err.abs() <= count_nm, "left the ±1 count window: {err:.1} nm at {:.4} s", sil.time_s());
    }
}

#[test]
fn one_millimetre_move_settles_within_one_count_near_the_physical_limit() {
    let (p, mut sil) = board(16.0);
    let r = run_move(&mut sil, 1_000_000, 3.0, 0.05);
    assert!(r.fault.is_none(), "{:?}", r.fault);
    let settle = r.settle_time_s.expect("settled");
    let limit = physical_limit_s(&p, 1e-3);
    eprintln!("1 mm: settle {settle:.4} s, physical limit {limit:.4} s, overshoot {:.1} nm", r.overshoot_nm);
    assert!(settle <= 1.25 * limit, "settle {settle} s > 1.25 × {limit} s");
    assert!(r.overshoot_nm < 200.0, "overshoot {} nm", r.overshoot_nm);
    assert!(r.final_error_nm.abs() <= 50.0);
    assert_stays(&mut sil, 1e6, 0.1);
    assert!(sil.controller.on_target());
}

#[test]
fn small_steps_of_100_nm_and_1_um_settle_within_one_count() {
    for step_nm in [100i64, 1_000, -100, -1_000] {
        let (_, mut sil) = board(16.0);
        let r = run_move(&mut sil, step_nm, 1.0, 0.05);
        assert!(r.fault.is_none() && r.settle_time_s.is_some(), "{step_nm} nm: {r:?}");
        assert_stays(&mut sil, step_nm as f64, 0.05);
    }
}

/// A step inside the fine window right after the servo comes on (the sine quiet) is the fine
/// mode's: the foot sticks to the slider and the stacks' static stroke carries it, on every
/// carriage of the sweep. It used to start in the coarse mode, where one drive period carries a
/// 0.1 kg carriage about 300 nm, and its 100 nm step overshot 268 nm (0.3 kg 160 nm).
#[test]
fn a_small_step_from_servo_on_is_taken_by_the_fine_mode() {
    for mass_kg in host_sim::harness::sweep::MASSES_KG {
        let mut p = Params::prototype();
        p.slider.mass_kg = mass_kg;
        let mut sil = ready_board(&p, controller_config(&p), 16.0).unwrap();
        sil.controller.move_to(100).unwrap();
        sil.period();
        assert!(sil.controller.fine_mode(), "{mass_kg} kg: the step starts in the coarse mode");
        let r = run_move(&mut sil, 100, 1.0, 0.05);
        assert!(r.fault.is_none() && r.settle_time_s.is_some(), "{mass_kg} kg: {:?}", r.fault);
        assert!(r.overshoot_nm < 50.0, "{mass_kg} kg: overshoot {:.1} nm", r.overshoot_nm);
        assert_eq!(sil.controller.drive_voltage_v(), 0.0, "{mass_kg} kg: the sine ran");
    }
}

#[test]
fn a_move_against_2_n_still_settles_within_one_count() {
    let (_, mut sil) = board(16.0);
    sil.set_load(ExternalLoad::opposing(2.0, 1));
    let r = run_move(&mut sil, 300_000, 3.0, 0.05);
    assert!(r.fault.is_none(), "{:?}", r.fault);
    assert!(r.settle_time_s.is_some() && r.final_error_nm.abs() <= 50.0, "{r:?}");
    assert_stays(&mut sil, 300_000.0, 0.05);
}

/// Runs until the controller faults; returns the outputs of that very period.
fn until_fault(sil: &mut Sil, max_s: f64) -> (FaultCode, piezo_drive::controller::Outputs) {
    let end = sil.time_s() + max_s;
    while sil.time_s() < end {
        let out = sil.period();
        if let State::Fault(code) = sil.controller.state() {
            return (code, out);
        }
    }
    panic!("no fault within {max_s} s");
}

fn assert_safe(out: &piezo_drive::controller::Outputs) {
    assert!(!out.amp_enable, "amplifier still enabled");
    let mid = (50.0f64 / 100.0 * 4095.0).round() as i32;
    let last = out.dac[out.dac.len() - 1];
    for w in last {
        assert!((i32::from(w) - mid).abs() <= 1, "DAC not at mid-range at the end of the period: {last:?}");
    }
}

#[test]
fn a_load_above_stall_trips_stall_detection_and_leaves_the_drive_safe() {
    let (_, mut sil) = board(16.0);
    // 6 N > the 4.3 N stall force at 16 N.
    sil.set_load(ExternalLoad::opposing(6.0, 1));
    sil.controller.move_to(300_000).unwrap();
    let (code, out) = until_fault(&mut sil, 1.0);
    assert_eq!(code, FaultCode::Stall);
    assert_safe(&out);
    // Cleared only deliberately; until then every command is refused.
    assert_eq!(sil.controller.move_to(0), Err(CommandError::Faulted(FaultCode::Stall)));
    sil.controller.clear_fault();
    assert_eq!(sil.controller.state(), State::Idle);
}

/// A load told to the controller above what the model has the motor push leaves the model no
/// speed for the profile. Under plain feedback the profile then never started and the move hung,
/// no fault, the drive at a fraction of full (0.1 kg at 16 N against a told 2 N, its plant
/// stalling at 0.9 N). The profile crawls on instead, and the full drive that builds up behind
/// it is judged a stall, with or without the feedforward.
#[test]
fn a_told_load_above_stall_faults_rather_than_hang_the_move() {
    for feedforward in [false, true] {
        let mut p = Params::prototype();
        p.slider.mass_kg = 0.1;
        let mut cfg = controller_config(&p);
        cfg.feedforward = feedforward;
        cfg.expected_load_n = 2.0;
        let mut sil = ready_board(&p, cfg, 16.0).unwrap();
        sil.set_load(ExternalLoad::opposing(2.0, 1));
        sil.controller.move_to(1_000_000).unwrap();
        let (code, out) = until_fault(&mut sil, 2.0);
        assert_eq!(code, FaultCode::Stall, "feedforward {feedforward}");
        assert_safe(&out);
    }
}

#[test]
fn an_encoder_jump_trips_its_fault_and_leaves_the_drive_safe() {
    let (_, mut sil) = board(16.0);
    sil.controller.move_to(200_000).unwrap();
    sil.run_until(0.02, |_| false);
    sil.encoder_offset_counts += 5_000;
    let (code, out) = until_fault(&mut sil, 0.01);
    assert_eq!(code, FaultCode::EncoderJump);
    assert_safe(&out);
}

#[test]
fn a_preload_below_the_window_is_refused() {
    let p = Params::prototype();
    let mut sil = Sil::new(&p, controller_config(&p), 2.0, 1).unwrap();
    sil.run_until(0.05, |_| false);
    assert_eq!(sil.controller.set_servo(true), Err(CommandError::PreloadOutOfWindow));
    assert_eq!(sil.controller.move_to(1000), Err(CommandError::ServoOff));
    // Dropping the preload while holding faults the drive into its safe state.
    let (_, mut sil) = board(16.0);
    sil.plant.set_preload_n(2.0);
    let (code, out) = until_fault(&mut sil, 0.5);
    assert_eq!(code, FaultCode::PreloadOutOfWindow);
    assert_safe(&out);
}

/// Feedforward from the inverse thrust model against plain PI feedback, both told the load (so
/// both plan the same feasible profile): the model supplies the drive the PI would otherwise have
/// to build from position error. On every carriage of the sweep (issue 11), against 2 N or, where
/// that is beyond the carriage, half its stall force (0.1 kg: 0.45 N). Measured peak following
/// error with / without: 0.1 kg 1.3 / 5.2 µm, 0.3 kg 2.5 / 7.4, 1 kg 0.78 / 9.3, 5 kg 0.71 / 7.7,
/// 50 kg 0.68 / 6.2.
#[test]
fn feedforward_halves_the_peak_following_error_against_a_known_load_on_every_carriage() {
    for mass_kg in host_sim::harness::sweep::MASSES_KG {
        let mut p = Params::prototype();
        p.slider.mass_kg = mass_kg;
        let load_n = 2.0f64.min(0.5 * host_sim::harness::sweep::plant_stall_n(&p, 16.0).0);
        let spec =
            |feedforward| MoveSpec { to_um: 1000.0, preload_n: 16.0, load_n, feedforward, load_known: true };
        let with = single_move(&p, spec(true)).expect("move with feedforward");
        let without = single_move(&p, spec(false)).expect("move without feedforward");
        let case = format!("{mass_kg} kg against {load_n:.2} N");
        eprintln!(
            "{case}: peak following error {:.3} µm with the feedforward, {:.3} without",
            with.max_following_error_um, without.max_following_error_um
        );
        assert!(with.fault.is_none() && with.final_error_nm.abs() <= 50.0, "{case}: {with:?}");
        assert!(with.settle_time_s.is_some(), "{case}: {with:?}");
        assert!(
            2.0 * with.max_following_error_um <= without.max_following_error_um,
            "{case}: peak following error with feedforward {} µm, without {} µm",
            with.max_following_error_um,
            without.max_following_error_um
        );
    }
}

/// The controller knows the moving mass only as a parameter (`SPA 1 0x101A`): told half or
/// twice the truth, the 1 mm move on every carriage of the sweep still settles within one count,
/// with no fault, within twice that plant's physical limit. Told twice the mass the default
/// carriage overshoots under 200 nm (9 nm measured at kp 400 /s). Told half, the 5 and 50 kg
/// carriages measure their mass in the speed-up (`controller/mass.rs`: the impulse over the speed
/// gained) and stop within 200 nm (15 and 26 nm; 0.9 and 8.4 µm before, at kp 100 /s). The lighter
/// ones speed up too fast to be timed against the speed filter and still overshoot (measured at
/// 400 /s: 0.1 kg 112 nm, 0.3 kg 374 nm, 1 kg 111 nm; issue 11 is open on this). Their table,
/// built from the periodic motion of a carriage of the told mass, is also slow or fast: told
/// half, the 0.3 kg carriage takes 1.28× its limit (1.68× while the profile counted an assisting
/// load estimate, the model's error, only up to half the stall force), and the 0.1 kg one 1.84×:
/// the model for 0.05 kg drives it at 1.2 kHz, where the plant makes 0.45 mm/s (0.66 at 2.2),
/// and at 1.2 kHz the model and the plant agree on the speed, so nothing in the move says so.
#[test]
fn a_moving_mass_parameter_off_by_two_either_way_still_settles() {
    for mass_kg in host_sim::harness::sweep::MASSES_KG {
        let mut p = Params::prototype();
        p.slider.mass_kg = mass_kg;
        let limit_s = physical_limit_s(&p, 1e-3);
        for factor in [2.0f32, 0.5] {
            let mut cfg = controller_config(&p);
            cfg.moving_mass_kg *= factor;
            let mut sil = ready_board(&p, cfg, 16.0).unwrap();
            let r = run_move(&mut sil, 1_000_000, 3.0 * limit_s, 0.05);
            let case = format!("{mass_kg} kg told × {factor}");
            eprintln!("{case}: settle {:?} s, overshoot {:.1} nm", r.settle_time_s, r.overshoot_nm);
            assert!(r.fault.is_none(), "{case}: {:?}", r.fault);
            let t = r.settle_time_s.unwrap_or(f64::INFINITY);
            assert!(t <= 2.0 * limit_s, "{case}: settled in {t} s, limit {limit_s:.3} s");
            assert!(r.final_error_nm.abs() <= 50.0, "{case}: {} nm", r.final_error_nm);
            if (mass_kg == 1.0 && factor > 1.0) || (mass_kg >= 5.0 && factor < 1.0) {
                assert!(r.overshoot_nm < 200.0, "{case}: overshoot {} nm", r.overshoot_nm);
            }
            if mass_kg >= 5.0 && factor < 1.0 {
                // The mass it measured in the speed-up: heavier than told, near the truth.
                let used = f64::from(sil.controller.moving_mass_kg());
                assert!((0.75 * mass_kg..=1.6 * mass_kg).contains(&used), "{case}: uses {used:.2} kg");
            }
        }
    }
}

/// A host that changes a setting and moves at once (`VEL` then `MOV`, as a script does): every
/// accepted setting asks for a new model table, and the move's braking rate, fixed at its command,
/// was taken while there was none: 0, and a profile that cannot brake crawled (1 mm back had not
/// settled after 3 s). It now takes the rate from the first table: the move settles within 1.25×
/// the plant's limit, as the same move does without the setting change.
#[test]
fn a_move_commanded_right_after_a_setting_change_runs_at_full_speed() {
    let (p, mut sil) = board(16.0);
    let limit_s = physical_limit_s(&p, 1e-3);
    let out = run_move(&mut sil, 1_000_000, 3.0, 0.05);
    assert!(out.fault.is_none() && out.settle_time_s.is_some(), "out: {out:?}");
    let mut slower = *sil.controller.config();
    slower.velocity_max_nm_s *= 0.9;
    sil.controller.set_config(slower).unwrap();
    let back = run_move(&mut sil, 0, 3.0, 0.05);
    let t = back.settle_time_s.unwrap_or(f64::INFINITY);
    eprintln!("back right after the setting change: settle {t:.4} s, limit {limit_s:.4} s");
    assert!(back.fault.is_none() && t <= 1.25 * limit_s, "settled in {t} s, limit {limit_s:.3} s");
}

/// `STP` and `HLT` in the period after a setting change (no model table yet: the model's
/// braking rate is 0) planned the stop kilometres away, and the slider ran on past its target.
/// Now they brake at the move's own rate, the profile's braking spread over 20 drive periods:
/// from 2.5 mm/s at 2.2 kHz that is 20 · 2.5 mm/s / (2 · 2200 Hz) = 11 µm (with a table `STP`
/// brakes at the stall force, about 1 µm).
#[test]
fn a_stop_right_after_a_setting_change_stops_the_slider() {
    for halt in [false, true] {
        let (_, mut sil) = board(16.0);
        sil.controller.move_to(1_000_000).unwrap();
        sil.run_until(0.2, |_| false);
        let at_nm = sil.plant.slider_position_m() * 1e9;
        let mut slower = *sil.controller.config();
        slower.velocity_max_nm_s *= 0.9;
        sil.controller.set_config(slower).unwrap();
        if halt {
            sil.controller.halt();
        } else {
            sil.controller.stop();
        }
        sil.run_until(0.5, |_| false);
        let ran_nm = sil.plant.slider_position_m() * 1e9 - at_nm;
        let case = if halt { "HLT" } else { "STP" };
        eprintln!("{case} right after a setting change: the slider ran on {ran_nm:.0} nm");
        assert!(ran_nm.abs() < 15_000.0, "{case}: ran on {ran_nm:.0} nm");
        assert_eq!(sil.controller.state(), State::Holding, "{case}");
    }
}

/// A payload the speed-up measured stays in use: the next move measures it again from the mass
/// it learned, not from the payload (a second 5 kg measurement against 1.5× the 5 kg in use would
/// not count as a payload and fell back to the told 2.5 kg), and a speed or acceleration setting
/// (`VEL`, `ACC`: a new configuration with the same mass and calibration) keeps it.
#[test]
fn a_measured_payload_stays_through_the_next_move_and_a_speed_setting() {
    for mass_kg in [5.0, 50.0] {
        let mut p = Params::prototype();
        p.slider.mass_kg = mass_kg;
        let mut cfg = controller_config(&p);
        cfg.moving_mass_kg *= 0.5;
        let mut sil = ready_board(&p, cfg, 16.0).unwrap();
        for (i, to_nm) in [1_000_000, 0, 1_000_000].into_iter().enumerate() {
            let r = run_move(&mut sil, to_nm, 3.0, 0.05);
            assert!(r.fault.is_none() && r.settle_time_s.is_some(), "{mass_kg} kg, move {i}: {r:?}");
            let used = f64::from(sil.controller.moving_mass_kg());
            eprintln!("{mass_kg} kg told half, move {i}: uses {used:.2} kg");
            assert!(
                (0.75 * mass_kg..=1.6 * mass_kg).contains(&used),
                "{mass_kg} kg, move {i}: uses {used:.2} kg"
            );
            if i == 1 {
                let mut faster = *sil.controller.config();
                faster.velocity_max_nm_s *= 0.9;
                sil.controller.set_config(faster).unwrap();
                let kept = f64::from(sil.controller.moving_mass_kg());
                assert_eq!(kept, used, "{mass_kg} kg: a speed setting dropped the measured mass");
            }
        }
    }
}

/// Ten 1 mm moves out and back, `load` on the slider, on a plant whose truth is `truth` and a
/// controller built for the prototype with the truth's carriage mass: each move's peak following
/// error (µm).
fn back_and_forth(truth: &Params, load: ExternalLoad) -> Vec<f64> {
    let mut sil = board_for(truth);
    sil.set_load(load);
    ten_moves(&mut sil)
}

fn board_for(truth: &Params) -> Sil {
    let mut p = Params::prototype();
    p.slider.mass_kg = truth.slider.mass_kg;
    ready_board(truth, controller_config(&p), 16.0).unwrap()
}

fn ten_moves(sil: &mut Sil) -> Vec<f64> {
    let fe: Vec<f64> = (0..10)
        .map(|i| {
            let r = run_move(sil, if i % 2 == 0 { 1_000_000 } else { 0 }, 3.0, 0.05);
            assert!(r.fault.is_none() && r.settle_time_s.is_some(), "move {i}: {r:?}");
            r.max_following_error_um
        })
        .collect();
    eprintln!("peak following error per move, µm: {fe:.2?}");
    fe
}

/// The mass measured in a speed-up (`mass.rs`) does not depend on where the move started. A
/// move from a fine-mode hold starts with the hold's static offset on the stacks, and until the
/// coarse mode has brought it back to centre the sine is clipped on one side: it pushes less than
/// the model says at the set amplitude, and the difference read as mass. The observer and the
/// speed-up timing now take the model's thrust at the swing the range leaves (`coarse.rs`).
/// 5 kg carriage, told its true mass, on a plant with μ 15 % below the controller's table (the
/// model's thrust error reads as mass too: the first move, from rest, measures 7.72 kg, 1.54×,
/// just over the 1.5× at which a measurement is used). Ten moves out and back, each commanded as
/// soon as the last is on target (as a host polling `ONT?` would): from the holds the mass used
/// to climb to 8.5–9.1 kg (1.10–1.17× the reading from rest); now within 5 % of it (the limit
/// here is 10 %), and the peak following error of the later moves fell from 1.1–1.5 to
/// 0.8–1.1 µm.
#[test]
fn a_move_from_a_hold_measures_the_mass_a_move_from_rest_does() {
    let mut p = Params::prototype();
    p.slider.mass_kg = 5.0;
    let mut truth = p.clone();
    truth.friction.mu_dynamic *= 0.85;
    truth.friction.mu_static *= 0.85;
    let mut sil = ready_board(&truth, controller_config(&p), 16.0).unwrap();
    let mut from_rest = None;
    for i in 0..10 {
        sil.controller.move_to(if i % 2 == 0 { 1_000_000 } else { 0 }).unwrap();
        let arrived =
            sil.run_until(3.0, |s| s.controller.state() == State::Holding && s.controller.on_target());
        assert!(arrived, "move {i}: {:?}", sil.controller.state());
        let used = f64::from(sil.controller.moving_mass_kg());
        eprintln!("move {i}: mass in use {used:.2} kg");
        let first = *from_rest.get_or_insert(used);
        assert!(used <= 1.1 * first, "move {i}: uses {used:.2} kg, {first:.2} kg from rest");
    }
}

/// Issue 11 item 3, in part: repeated moves out and back. Two things made every later move worse
/// than the first, and both are fixed:
/// - What the load observer learns in a move is the load plus the model's thrust error along the
///   drive; carried into a move the other way the error has the wrong sign. A move now starts
///   from the mean of the end estimates of the last move each way (the load, which both share).
/// - A move that starts from a fine-mode hold has the hold's static offset on both stacks (up to
///   ±23 V): until the coarse mode has brought it back to centre, the sine has less room in the
///   amplifier's range. The recentring took 45 ms, the whole speed-up; now 4.5 ms.
///
/// Measured before (μ right / μ 15 % low / μ 15 % low and 0.8 N unknown): first move 0.55 /
/// 0.71 / 4.57 µm peak following error, later ones 0.9–2.8 / 2.0–2.2 / —; at kp 100 /s first
/// 0.48 / 0.57 / 2.42, later ones 0.40–0.53 / 0.55–0.67 / 0.57–0.98; now (kp 400 /s, braking
/// counting only the known load, the stuck-approach push, thrust at the sine's swing) first
/// 0.36 / 0.35 / 1.71, later ones 0.21–0.36 / 0.32–0.45 / 0.33–0.72 (the second move, the first
/// reversal, still carries its estimate: 0.4–0.65 µm). The
/// issue's goal, the tenth at most half the first with μ 15 % low, is not reached there (the
/// first move, from rest with no estimate, is already near the best); it is with the unknown
/// load, which the later moves start from.
#[test]
fn repeated_moves_out_and_back_get_no_worse_and_learn_an_unknown_load() {
    let right = back_and_forth(&Params::prototype(), ExternalLoad::default());
    assert!(
        right[2..].iter().all(|&fe| fe <= 1.5 * right[0]),
        "μ right: first {:.3} µm, later {right:?}",
        right[0]
    );
    let mut truth = Params::prototype();
    truth.friction.mu_dynamic *= 0.85;
    truth.friction.mu_static *= 0.85;
    let low = back_and_forth(&truth, ExternalLoad::default());
    let later = low[2..].iter().sum::<f64>() / 8.0;
    assert!(
        later <= 1.3 * low[0],
        "μ 15 % low: first {:.3} µm, later {later:.3} on average: {low:?}",
        low[0]
    );
    // An unknown constant load is what both senses share: the later moves start from it.
    let loaded = back_and_forth(&truth, ExternalLoad::opposing(0.8, 1));
    let later = loaded[2..].iter().sum::<f64>() / 8.0;
    assert!(
        later <= 0.5 * loaded[0],
        "0.8 N unknown: first {:.3} µm, later {later:.3} on average: {loaded:?}",
        loaded[0]
    );
}

/// Issue 11 item 3: the feedforward learns the model's thrust error over repeated moves. A
/// speed-up long enough to time well (ten speed-filter time constants, `mass.rs`) measures the
/// carriage by momentum with the model's thrust; on a plant with μ 15 % below the table's the
/// plant pushes 0.85× what the model says, which reads as a carriage 1/0.85 = 1.18× heavier. That
/// effective mass, taken in half a measurement at a time and kept across moves, makes the
/// profile's speed-up, its braking and the feedforward's M·a what the plant can do. The 50 kg
/// carriage (its speed-up takes 25–30 ms): peak following error 1.27 µm on the first move, 0.57
/// on the tenth (1.35 without the learning). Two independent checks that it is the thrust error
/// that is learned: a right model teaches nothing (50.4 kg), and the masses learned with μ 15 %
/// low and with μ right are in the thrust ratio (measured 1.184 against 1.176).
/// A preload change of more than 1 N forgets it (the error depends on the preload). The lighter
/// carriages speed up in a few filter time constants and learn nothing: their first move is
/// already at the loop's floor (1 kg: 0.35 µm with μ low, 0.36 with μ right).
#[test]
fn a_heavy_carriage_learns_the_models_thrust_error_over_repeated_moves() {
    let mut right = Params::prototype();
    right.slider.mass_kg = 50.0;
    let mut sil = board_for(&right);
    ten_moves(&mut sil);
    let learned_right = f64::from(sil.controller.moving_mass_kg());
    // A right model has nothing to teach.
    assert!((50.0..=52.5).contains(&learned_right), "μ right: learned {learned_right:.2} kg");
    let mut low = right.clone();
    low.friction.mu_dynamic *= 0.85;
    low.friction.mu_static *= 0.85;
    let mut sil = board_for(&low);
    let fe = ten_moves(&mut sil);
    assert!(fe[9] <= 0.5 * fe[0], "μ 15 % low: first {:.3} µm, tenth {:.3}: {fe:.2?}", fe[0], fe[9]);
    let learned_low = f64::from(sil.controller.moving_mass_kg());
    let ratio = learned_low / learned_right;
    eprintln!("learned {learned_right:.2} kg (μ right), {learned_low:.2} kg (μ low): {ratio:.3}");
    assert!((ratio - 1.0 / 0.85).abs() < 0.05, "learned mass ratio {ratio:.3}, thrust ratio 1/0.85");
    // The same preload: the next command keeps it.
    sil.controller.move_to(0).unwrap();
    assert_eq!(f64::from(sil.controller.moving_mass_kg()), learned_low, "forgotten at the same preload");
    sil.run_until(3.0, |s| s.controller.on_target());
    // Another preload: what was learned is forgotten at the next command.
    sil.plant.set_preload_n(14.0);
    sil.run_until(0.2, |_| false);
    sil.controller.move_to(500_000).unwrap();
    assert_eq!(sil.controller.moving_mass_kg(), 50.0, "learned at 16 N, kept at 14 N");
}

/// Issue 11: against a load it is not told about, a heavy carriage settles without a fault. The
/// 50 kg carriage against 2 N (half its stall force) used to trip the stall fault at the end of
/// the move: the load pushed it back while the drive came up from the braking, and 54 V with the
/// slider creeping forward counted as a stall (the threshold was half the drive; it is now 90 %,
/// where the controller has no thrust left to give).
#[test]
fn a_heavy_carriage_against_an_unknown_load_at_half_its_stall_settles_without_a_fault() {
    let mut p = Params::prototype();
    p.slider.mass_kg = 50.0;
    let mut cfg = controller_config(&p);
    cfg.moving_mass_kg = 50.0;
    let mut sil = ready_board(&p, cfg, 16.0).unwrap();
    sil.set_load(ExternalLoad::opposing(2.0, 1));
    let r = run_move(&mut sil, 1_000_000, 3.0, 0.2);
    assert!(r.fault.is_none(), "{:?}", r.fault);
    assert!(r.settle_time_s.is_some(), "did not settle: {r:?}");
    assert!(r.overshoot_nm < 200.0, "overshoot {} nm", r.overshoot_nm);
}

/// One 1 mm move out on a fresh board with the frequency chosen (from the motor table's lowest
/// valid frequency, 1.2 kHz, up to 2.2 kHz) or fixed at 2.2 kHz: (settle s, the frequency it
/// ended at, Hz).
fn out_move(p: &Params, load_n: f64, chosen: bool) -> (f64, f32) {
    let mut cfg = controller_config(p);
    if !chosen {
        cfg.drive_freq_min_hz = cfg.drive_freq_hz;
    }
    let mut sil = ready_board(p, cfg, 16.0).unwrap();
    sil.set_load(ExternalLoad::opposing(load_n, 1));
    let r = run_move(&mut sil, 1_000_000, 8.0, 0.05);
    assert!(r.fault.is_none(), "{r:?}");
    (r.settle_time_s.expect("settles"), sil.controller.coarse_frequency_hz())
}

/// Issue 11 item 2: the drive frequency is chosen from the model with the moving mass. A 0.05 kg
/// carriage rides the foot, and its model says it runs fastest at 1.2 kHz; the plant agrees
/// (its own no-load speeds, no controller involved), and the move is faster than at the fixed
/// 2.2 kHz. The default 1 kg carriage stays at 2.2 kHz, where its plant is fastest too.
/// Measured: 0.05 kg settles 1 mm in 2.61 s at 1.2 kHz against 3.72 s at 2.2 kHz.
#[test]
fn a_light_carriage_drives_at_the_frequency_where_its_model_and_the_plant_run_fastest() {
    use host_sim::motor::plant::steady_speed_m_s;
    let mut light = Params::prototype();
    light.slider.mass_kg = 0.05;
    let (t_chosen, f) = out_move(&light, 0.0, true);
    let (t_fixed, f_fixed) = out_move(&light, 0.0, false);
    assert_eq!(f_fixed, 2200.0);
    assert!(f < 1600.0, "0.05 kg drove at {f} Hz");
    let plant_at = |p: &Params, hz: f64| steady_speed_m_s(p, 16.0, 100.0, hz, 1, 0.0);
    assert!(
        plant_at(&light, f64::from(f)) > 1.3 * plant_at(&light, 2200.0),
        "the plant is not faster at {f} Hz than at 2.2 kHz"
    );
    assert!(t_fixed > 1.25 * t_chosen, "1 mm: {t_chosen:.3} s at {f} Hz, {t_fixed:.3} s at 2.2 kHz");
    let default = Params::prototype();
    let (_, f_default) = out_move(&default, 0.0, true);
    assert_eq!(f_default, 2200.0);
    let best = (12..=22).map(|k| plant_at(&default, 100.0 * f64::from(k))).fold(0.0, f64::max);
    assert_eq!(plant_at(&default, 2200.0), best, "the 1 kg plant is faster elsewhere in the band");
}

/// Issue 11 item 2: against a load above the top frequency's stall force, the observer learns it
/// and the drive moves to a frequency with more thrust. A 5 kg carriage against an unknown 4 N
/// (78 % of the highest stall force the plant reaches in the band, 5.1 N at 0.9 kHz; above its
/// 3.95 N at 2.2 kHz): at the fixed 2.2 kHz it stalls (the stall fault, drive safe); with the
/// frequency chosen it settles (measured 3.8 s at 1.2 kHz, where the plant makes 0.28 mm/s under
/// 4 N). The way back, with the load, goes at 2.2 kHz again.
#[test]
fn against_an_unknown_load_above_the_top_frequencys_stall_the_drive_moves_to_one_with_more_thrust() {
    use host_sim::motor::plant::steady_speed_m_s;
    let mut p = Params::prototype();
    p.slider.mass_kg = 5.0;
    let plant_at = |hz: f64| steady_speed_m_s(&p, 16.0, 100.0, hz, 1, 4.0);
    assert!(plant_at(2200.0) <= 0.0, "the plant moves under 4 N at 2.2 kHz");
    let mut fixed = controller_config(&p);
    fixed.drive_freq_min_hz = fixed.drive_freq_hz;
    let mut sil = ready_board(&p, fixed, 16.0).unwrap();
    sil.set_load(ExternalLoad::opposing(4.0, 1));
    let r = run_move(&mut sil, 1_000_000, 8.0, 0.05);
    assert_eq!(r.fault.as_ref().map(|f| f.code), Some(FaultCode::Stall as u8), "{r:?}");

    let mut sil = ready_board(&p, controller_config(&p), 16.0).unwrap();
    sil.set_load(ExternalLoad::opposing(4.0, 1));
    let out = run_move(&mut sil, 1_000_000, 8.0, 0.05);
    assert!(out.fault.is_none() && out.settle_time_s.is_some(), "{out:?}");
    let f = out.drive_frequency_hz;
    assert!(f < 2200.0 && plant_at(f) > 0.1e-3, "drove at {f} Hz: plant {:.3} mm/s", plant_at(f) * 1e3);
    let back = run_move(&mut sil, 0, 8.0, 0.05);
    assert!(back.fault.is_none() && back.drive_frequency_hz == 2200.0, "{back:?}");
}

/// Issue 11: loads up to 70 % of the plant's stall force, not told to the controller, at every
/// preload of the window (5, 10, 16, 18 N). The load is 70 % of the highest stall force each
/// plant has over 0.5–2.2 kHz at that preload (measured on the plant, `sweep::plant_stall_n`; at
/// 16 N 0.63 / 2.50 / 2.95 / 3.58 / 3.37 N for 0.1 / 0.3 / 1 / 5 / 50 kg). Every carriage
/// settles with no fault, given three times the plant's own limit against that load
/// (`sweep::loaded_limit_s`: 0.1 kg at 18 N crawls at 0.12 mm/s and takes 8.7 s against a
/// limit of 7.9). Before the frequency trial (`frequency.rs`) the 50 kg carriage faulted at 5
/// and 10 N: its observer read the model's thrust error as load past the model's stall force,
/// and the model, ranking frequencies where it cannot, switched to 1.2 kHz, where the plant
/// barely moves. The 0.1–1 kg carriages overshoot under 200 nm, except the 0.1 kg one at 5 N,
/// 360 nm (its load is near what the foot holds when the drive stops; bound 450). The 5 and
/// 50 kg ones overshoot erratically, 20–995 nm over loads of 3.30–3.60 N at 16 N: they cruise
/// up to 0.9 µm ahead of the reference at full drive and brake from there. Held as a
/// regression bound of 1.5 µm; issue 11 is open on it.
#[test]
fn unknown_loads_at_70_percent_of_each_plants_stall_settle_without_a_fault() {
    for preload_n in [5.0, 10.0, 16.0, 18.0] {
        for mass_kg in host_sim::harness::sweep::MASSES_KG {
            let mut p = Params::prototype();
            p.slider.mass_kg = mass_kg;
            let (stall_n, _) = host_sim::harness::sweep::plant_stall_n(&p, preload_n);
            let load_n = 0.7 * stall_n;
            let limit_s = host_sim::harness::sweep::loaded_limit_s(&p, 1e-3, preload_n, load_n, stall_n)
                .expect("the plant moves against 70 % of its stall force");
            let mut sil = ready_board(&p, controller_config(&p), preload_n).unwrap();
            sil.set_load(ExternalLoad::opposing(load_n, 1));
            let r = run_move(&mut sil, 1_000_000, 3.0 * limit_s, 0.05);
            let case = format!("{mass_kg} kg at {preload_n} N against {load_n:.2} N");
            eprintln!(
                "{case}: settle {:?} s (limit {limit_s:.3} s), overshoot {:.1} nm, {} Hz",
                r.settle_time_s, r.overshoot_nm, r.drive_frequency_hz
            );
            let outcome = (r.fault.as_ref().map(|f| f.text.clone()), r.settle_time_s, r.final_error_nm);
            assert!(r.fault.is_none() && r.settle_time_s.is_some(), "{case}: {outcome:?}");
            let bound = match (preload_n as u32, mass_kg) {
                (5, 0.1) => 450.0,
                (_, m) if m <= 1.0 => 200.0,
                _ => 1500.0,
            };
            assert!(r.overshoot_nm < bound, "{case}: overshoot {:.1} nm", r.overshoot_nm);
        }
    }
}

/// Issue 11: holding ±1 count for 1 s under a 1 N load step applied while holding, on every
/// carriage of the sweep and both ways. In the fine mode the foot sticks to the slider: static
/// friction (μs·F0 ≈ 6 N at 16 N) carries the step, and the friction layer's shear stiffness
/// (7.7e8 N/m) gives way by about 1 nm, well inside the count (expected from the plant's
/// parameters, before running it). The 0.1 kg carriage holds it too, though 1 N is above what
/// its drive can push at speed (0.9 N).
#[test]
fn holding_stays_within_one_count_for_a_second_under_a_1_n_load_step() {
    for mass_kg in host_sim::harness::sweep::MASSES_KG {
        for sense in [1i8, -1] {
            let mut p = Params::prototype();
            p.slider.mass_kg = mass_kg;
            let mut sil = ready_board(&p, controller_config(&p), 16.0).unwrap();
            let r = run_move(&mut sil, 100_000, 3.0, 0.05);
            assert!(r.fault.is_none() && r.settle_time_s.is_some(), "{mass_kg} kg: {r:?}");
            sil.set_load(ExternalLoad::opposing(1.0, sense));
            eprintln!("{mass_kg} kg, load along {sense}: holding from {:.4} s", sil.time_s());
            assert_stays(&mut sil, 100_000.0, 1.0);
            assert_eq!(sil.controller.state(), State::Holding, "{mass_kg} kg, load along {sense}");
        }
    }
}

/// Issue 11 item 1: preloads 5–20 N. The window ends at the preload where full drive still lifts
/// the foot off (18.4 N on the prototype, `0x1010`; above it the controller refuses to move, as
/// `a_preload_below_the_window_is_refused` shows at the other end). At 5, 10, 16 and 18 N, on
/// every carriage of the sweep, a 1 mm move settles within 1.25× that plant's physical limit at
/// that preload, overshooting under 200 nm, except (measured, kept as bounds): at 5 N the 5 kg
/// carriage overshoots 212 nm (682 nm while the braking still counted on an opposing load
/// estimate, `coarse.rs`); the 0.1 kg carriage's plant is fastest below the lowest frequency
/// where the controller's model holds (1.2 kHz, `0x1022`; the stator's foot-clamped
/// counterweight mode is at 857 Hz): at 16 N it makes 0.78 mm/s at 0.7 kHz against 0.66 at
/// 2.2 kHz, where the best the drive can do is 1.18× and the controller, cruising at 0.63 mm/s
/// with the drive at 97 V, takes 1.26× (199 nm overshoot); at 18 N 0.73 mm/s at 0.8 kHz
/// against 0.38 at 1.2 kHz: 2.17× (1.12× against that speed).
#[test]
fn a_one_millimetre_move_settles_at_every_preload_of_the_window() {
    let exceptions = |preload_n: f64, mass_kg: f64| match (preload_n as u32, mass_kg) {
        (5, 5.0) => (1.25, 300.0),
        (16, 0.1) => (1.3, 210.0),
        (18, 0.1) => (2.3, 200.0),
        _ => (1.25, 200.0),
    };
    for preload_n in [5.0, 10.0, 16.0, 18.0] {
        for mass_kg in host_sim::harness::sweep::MASSES_KG {
            let mut p = Params::prototype();
            p.slider.mass_kg = mass_kg;
            let limit_s = host_sim::harness::sweep::physical_limit_s(&p, 1e-3, preload_n).0;
            let mut sil = ready_board(&p, controller_config(&p), preload_n).unwrap();
            let r = run_move(&mut sil, 1_000_000, 4.0 * limit_s, 0.05);
            let case = format!("{mass_kg} kg at {preload_n} N");
            let t = r.settle_time_s.unwrap_or(f64::INFINITY);
            eprintln!("{case}: {:.2}× the limit, overshoot {:.1} nm", t / limit_s, r.overshoot_nm);
            assert!(r.fault.is_none(), "{case}: {:?}", r.fault);
            let (times, overshoot_nm) = exceptions(preload_n, mass_kg);
            assert!(t <= times * limit_s, "{case}: settled in {t:.4} s, limit {limit_s:.4} s");
            assert!(r.overshoot_nm < overshoot_nm, "{case}: overshoot {:.1} nm", r.overshoot_nm);
        }
    }
}

/// Issue 11: 100 nm, 1 µm and 10 µm steps settle to ±1 count within 20 ms, on every carriage at
/// 5, 10, 16 and 18 N. At 5 N the 0.3 kg carriage stopped 550 nm short of a 10 µm step with
/// 13 V on the drive, where the model has it moving at the approach speed, and the integral
/// alone took 89 ms (1 µm: 36 ms) to find the missing thrust; a stuck final approach now pushes
/// harder (`coarse.rs`): 18 and 9 ms. Two kinds of case are out of reach, kept as bounds:
/// - the 50 kg carriage's 10 µm: speeding up and braking at the plant's highest stall force
///   over the band (`plant_stall_n`) alone take 2·√(d·M/F), 20 ms at 16 N (4.8 N) and 32 ms
///   at 5 N (2.0 N); it takes 1.05× (5 N) to 1.35× (18 N) that, at 2.2 kHz, where the stall
///   force is lower (3.9 N at 16 N);
/// - the 0.1 kg carriage's 10 µm at 16 and 18 N: its model runs slow against the plant (0.51
///   against 0.66 mm/s at 2.2 kHz, 16 N), and the move is over before the observer learns it
///   (23.4 and 36.6 ms, measured; 26 and 41 before the hand-over below).
///
/// Light carriages (0.1 and 0.3 kg) also overshoot no step by more than two counts. In the
/// coarse mode such a carriage rides the foot and swings with it within each drive period by up
/// to the foot's stroke (about 300 nm at full drive): its 1 and 10 µm steps overshot 180–440 nm.
/// It is now handed to the fine mode while still moving, as soon as the sine's end stops it
/// where the fine stroke reaches the target even with the swing either way (`closed_loop.rs`):
/// 1–60 nm, and settle as fast or faster.
#[test]
fn small_steps_settle_within_20_ms_on_every_carriage_at_every_preload() {
    for preload_n in [5.0, 10.0, 16.0, 18.0] {
        for mass_kg in host_sim::harness::sweep::MASSES_KG {
            let mut p = Params::prototype();
            p.slider.mass_kg = mass_kg;
            let stall_n = host_sim::harness::sweep::plant_stall_n(&p, preload_n).0;
            for step_nm in [100i64, 1_000, 10_000] {
                let mut sil = ready_board(&p, controller_config(&p), preload_n).unwrap();
                let r = run_move(&mut sil, step_nm, 0.5, 0.02);
                let case = format!("{mass_kg} kg at {preload_n} N, {step_nm} nm");
                let t = r.settle_time_s.unwrap_or(f64::INFINITY);
                eprintln!("{case}: {:.1} ms", t * 1e3);
                assert!(r.fault.is_none(), "{case}: {:?}", r.fault);
                let bang_bang_s = 2.0 * (step_nm as f64 * 1e-9 * mass_kg / stall_n).sqrt();
                let bound_s = match (mass_kg, step_nm, preload_n as u32) {
                    (50.0, 10_000, _) => 1.4 * bang_bang_s,
                    (0.1, 10_000, 16) => 0.026,
                    (0.1, 10_000, 18) => 0.040,
                    _ => 0.020,
                };
                assert!(t <= bound_s, "{case}: settled in {:.1} ms, bound {:.1} ms", t * 1e3, bound_s * 1e3);
                if mass_kg <= 0.3 {
                    assert!(r.overshoot_nm < 100.0, "{case}: overshoot {:.0} nm", r.overshoot_nm);
                }
            }
        }
    }
}

/// Issue 30 item 9: a limit switch while moving. A 1 mm move toward a switch at 0.3 mm stops
/// there, past it by no more than the braking distance at full speed (v²/2a: 2.9 mm/s at the
/// 1000 mm/s² the profile brakes at most, 4.2 µm; bound 10 µm), holds without a fault and counts
/// one limit stop (the protocol latches error 7); a move further into the switch goes nowhere
/// (under 1 µm) and counts another; a move away settles where it was sent.
#[test]
fn a_limit_switch_stops_a_move_into_it_and_lets_the_slider_move_away() {
    let p = Params::prototype();
    let mut sil = ready_board(&p, controller_config(&p), 16.0).unwrap();
    let switch_m = 0.3e-3;
    sil.limits_m = Some((-1.0, switch_m));
    let r = run_move(&mut sil, 1_000_000, 3.0, 0.05);
    let x = sil.plant.slider_position_m();
    assert!(r.fault.is_none(), "{r:?}");
    assert!(x >= switch_m && x < switch_m + 10e-6, "stopped at {:.2} µm", x * 1e6);
    assert_eq!(sil.controller.state(), State::Holding);
    assert_eq!(sil.controller.limit_stop_count(), 1);

    let r = run_move(&mut sil, 800_000, 1.0, 0.05);
    let x2 = sil.plant.slider_position_m();
    assert!(r.fault.is_none() && (x2 - x).abs() < 1e-6, "moved {:.3} µm into the switch", (x2 - x) * 1e6);
    assert_eq!(sil.controller.limit_stop_count(), 2);

    let r = run_move(&mut sil, 100_000, 3.0, 0.05);
    assert!(r.settle_time_s.is_some() && r.final_error_nm.abs() <= 50.0, "{r:?}");
    assert_eq!(sil.controller.limit_stop_count(), 2);
}

/// Issue 30 item 9: open-loop stepping (servo off, `XOS`) toward a switch ends at the switch and
/// counts a limit stop; stepping away from it runs.
#[test]
fn open_loop_stepping_ends_at_a_limit_switch_and_runs_away_from_it() {
    let p = Params::prototype();
    let mut sil = Sil::new(&p, controller_config(&p), 16.0, 7).unwrap();
    sil.run_until(0.05, |_| false);
    let switch_m = 20e-6;
    sil.limits_m = Some((-1.0, switch_m));
    // 2000 cycles at 2.2 kHz and full drive would carry the slider about 2.6 mm.
    sil.controller.open_loop_step(2000, 100.0, 2200.0).unwrap();
    sil.run_until(1.0, |s| s.controller.state() == State::Idle);
    let x = sil.plant.slider_position_m();
    assert_eq!(sil.controller.state(), State::Idle);
    assert!(x >= switch_m && x < switch_m + 5e-6, "ended at {:.2} µm", x * 1e6);
    assert_eq!(sil.controller.limit_stop_count(), 1);
    sil.controller.open_loop_step(-200, 100.0, 2200.0).unwrap();
    sil.run_until(1.0, |s| s.controller.state() == State::Idle);
    assert!(
        sil.plant.slider_position_m() < x - 100e-6,
        "did not step away: {:e}",
        sil.plant.slider_position_m()
    );
    assert_eq!(sil.controller.limit_stop_count(), 1);
}

/// The encoder stops counting once `now` holds (None: it never did within 3 s); then the fault
/// (within 0.2 s, [`until_fault`]), how long until it and how far the slider ran in that time (s,
/// nm).
fn lose_encoder_when(sil: &mut Sil, now: impl FnMut(&Sil) -> bool) -> Option<(FaultCode, f64, f64)> {
    if !sil.run_until(3.0, now) {
        return None;
    }
    sil.frozen_encoder_counts = Some(sil.plant.encoder_counts());
    let (t0, x0) = (sil.time_s(), sil.plant.slider_position_m());
    let (code, _) = until_fault(sil, 0.2);
    Some((code, sil.time_s() - t0, (sil.plant.slider_position_m() - x0).abs() * 1e9))
}

/// Issue 30 item 6: an encoder that stops counting (cable off, dirty scale) under the coarse
/// mode's sine is caught within milliseconds, not by the stall check's 50 ms (before: a stall
/// after 25–72 ms, the slider run 36–173 µm unseen). The watch trips once the model's carriage,
/// started at half the last measured speed and pushed by what the drive gained since, has run
/// 40 counts (2 µm): the slider itself runs that far and a little more while the model lags it
/// (measured: 1.6–4.4 µm, 0.8–2.9 ms while moving; 1.0–3.0 µm, 12–14 ms in a hold's final
/// approach, where the drive first has to rise above the watched 30 %).
#[test]
fn a_lost_encoder_under_the_coarse_drive_trips_within_milliseconds() {
    let mut holds = 0;
    for preload_n in [5.0, 16.0] {
        for mass_kg in host_sim::harness::sweep::MASSES_KG {
            let mut p = Params::prototype();
            p.slider.mass_kg = mass_kg;
            let case = format!("{mass_kg} kg at {preload_n} N");
            let mut sil = ready_board(&p, controller_config(&p), preload_n).unwrap();
            sil.controller.move_to(1_000_000).unwrap();
            let lost = lose_encoder_when(&mut sil, |s| s.plant.slider_position_m() > 0.5e-3);
            let (code, after_s, ran_nm) = lost.unwrap_or_else(|| panic!("{case}: never half way"));
            assert_eq!(code, FaultCode::EncoderLoss, "{case} moving");
            assert!(after_s <= 0.005 && ran_nm <= 5_000.0, "{case} moving: {after_s} s, {ran_nm} nm");
            // The final approach of a hold in the coarse mode, where a move ends in one.
            let mut sil = ready_board(&p, controller_config(&p), preload_n).unwrap();
            sil.controller.move_to(1_000_000).unwrap();
            let hold_coarse = |s: &Sil| s.controller.state() == State::Holding && !s.controller.fine_mode();
            if let Some((code, after_s, ran_nm)) = lose_encoder_when(&mut sil, hold_coarse) {
                holds += 1;
                assert_eq!(code, FaultCode::EncoderLoss, "{case} holding");
                assert!(after_s <= 0.02 && ran_nm <= 5_000.0, "{case} holding: {after_s} s, {ran_nm} nm");
            }
        }
    }
    assert!(holds >= 2, "only {holds} moves ended in a coarse hold");
}

/// The watch's limit is a setting (`0x1023`): ten times the default trips later and after a
/// longer run unseen, and 0 leaves the stall check (50 ms) to catch the lost encoder.
#[test]
fn the_encoder_loss_limit_setting_moves_the_trip_and_zero_turns_the_watch_off() {
    let p = Params::prototype();
    let lose = |loss_counts: i32| {
        let mut cfg = controller_config(&p);
        cfg.encoder_loss_counts = loss_counts;
        let mut sil = ready_board(&p, cfg, 16.0).unwrap();
        sil.controller.move_to(1_000_000).unwrap();
        let lost = lose_encoder_when(&mut sil, |s| s.plant.slider_position_m() > 0.5e-3);
        lost.unwrap_or_else(|| panic!("limit {loss_counts}: never half way"))
    };
    let (code_40, after_40_s, ran_40_nm) = lose(40);
    let (code_400, after_400_s, ran_400_nm) = lose(400);
    let (code_off, after_off_s, _) = lose(0);
    assert_eq!(
        (code_40, code_400, code_off),
        (FaultCode::EncoderLoss, FaultCode::EncoderLoss, FaultCode::Stall)
    );
    assert!(after_400_s > after_40_s && ran_400_nm > 5.0 * ran_40_nm, "{ran_40_nm} nm, {ran_400_nm} nm");
    assert!(after_off_s > 0.02, "{after_off_s} s");
}
