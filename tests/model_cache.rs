//! The hand-over of the model table between the board's slow task and the tick
//! (`controller::model_cache`): what the controller asks for, what it takes, and what it does
//! without a table.

use piezo_drive::controller::model_cache::ModelTable;
use piezo_drive::controller::{Controller, Inputs, State};
use piezo_drive::defaults;

/// 16 N on the default force cell (50 N full scale on 4095 words).
const WORD_16_N: u16 = 1310;

fn controller_at(word: u16) -> Controller {
    let mut ctl = Controller::new(defaults::controller_config()).unwrap();
    ctl.step(&Inputs { preload_word: word, ..Default::default() });
    ctl
}

#[test]
fn a_table_is_asked_for_until_one_fits_the_measured_preload() {
    let mut ctl = Controller::new(defaults::controller_config()).unwrap();
    // No preload reading yet: nothing to build a table for.
    assert!(ctl.model_request().is_none());
    ctl.step(&Inputs { preload_word: WORD_16_N, ..Default::default() });
    let request = ctl.model_request().expect("a table is wanted once the preload is read");
    let preload = ctl.preload_n().unwrap();
    assert!((request.preload_n - preload).abs() < 1e-6);
    assert!(ctl.install_model(ModelTable::build(&request)));
    assert!(ctl.model_request().is_none(), "the installed table fits");
    // 10 words ≈ 0.12 N: more than the 0.05 N the table may be off by. The filter (α = 0.01)
    // needs a few hundred periods to move that far.
    for _ in 0..400 {
        ctl.step(&Inputs { preload_word: WORD_16_N + 10, ..Default::default() });
    }
    let moved = ctl.preload_n().unwrap();
    let resolve = piezo_drive::controller::model_cache::PRELOAD_RESOLVE_N;
    assert!(moved - preload > resolve, "preload moved {} N", moved - preload);
    let again = ctl.model_request().expect("a new table for the new preload");
    assert!((again.preload_n - moved).abs() < 1e-6);
}

#[test]
fn a_table_for_settings_that_changed_meanwhile_is_refused() {
    let mut ctl = controller_at(WORD_16_N);
    let request = ctl.model_request().unwrap();
    // The settings change while the slow task builds (a new drive frequency).
    let mut cfg = *ctl.config();
    cfg.drive_freq_hz = 1500.0;
    ctl.set_config(cfg).unwrap();
    assert!(!ctl.install_model(ModelTable::build(&request)), "built for the old frequency");
    let fresh = ctl.model_request().expect("still wanted");
    assert_ne!(fresh.per_volt, request.per_volt);
    assert!(ctl.install_model(ModelTable::build(&fresh)));
    // A change of what the table is built from drops it: the carriage's mass enters the grid.
    let mut cfg = *ctl.config();
    cfg.moving_mass_kg *= 2.0;
    ctl.set_config(cfg).unwrap();
    assert!(ctl.model_request().is_some());
}

#[test]
fn settings_outside_the_model_keep_the_table() {
    let mut ctl = controller_at(WORD_16_N);
    let request = ctl.model_request().unwrap();
    assert!(ctl.install_model(ModelTable::build(&request)));
    let before = ctl.thrust_limits().unwrap();
    // Speed, acceleration, deceleration, gains, limits, windows: none of them enters the table
    // (eqs. 19-22 and the carriage's motion read the motor, the drive and the carriage only).
    let changes: [fn(&mut piezo_drive::config::ControllerConfig); 6] = [
        |c| c.velocity_max_nm_s *= 0.5,
        |c| c.accel_max_nm_s2 *= 0.5,
        |c| c.decel_max_nm_s2 *= 0.5,
        |c| c.kp_per_s *= 2.0,
        |c| c.following_error_limit_nm *= 2.0,
        |c| c.fine_window_nm *= 2.0,
    ];
    for change in changes {
        let mut cfg = *ctl.config();
        change(&mut cfg);
        ctl.set_config(cfg).unwrap();
        assert!(ctl.model_request().is_none(), "the table stays");
        assert_eq!(ctl.thrust_limits().unwrap(), before);
    }
    // A build that was under way across such a change still installs.
    let mut ctl = controller_at(WORD_16_N);
    let request = ctl.model_request().unwrap();
    let mut cfg = *ctl.config();
    cfg.velocity_max_nm_s *= 0.5;
    ctl.set_config(cfg).unwrap();
    assert!(ctl.install_model(ModelTable::build(&request)));
}

#[test]
fn a_request_within_the_preload_resolution_is_the_same_table() {
    let ctl = controller_at(WORD_16_N);
    let r = ctl.model_request().unwrap();
    let resolve = piezo_drive::controller::model_cache::PRELOAD_RESOLVE_N;
    let nudged =
        |df: f32| piezo_drive::controller::model_cache::ModelRequest { preload_n: r.preload_n + df, ..r };
    assert!(r.same_table_as(&nudged(0.5 * resolve)));
    assert!(r.same_table_as(&nudged(-0.9 * resolve)));
    assert!(!r.same_table_as(&nudged(1.5 * resolve)));
    let heavier =
        piezo_drive::controller::model_cache::ModelRequest { moving_mass_kg: r.moving_mass_kg * 2.0, ..r };
    assert!(!r.same_table_as(&heavier));
}

#[test]
fn without_a_table_a_move_is_accepted_but_the_drive_stays_quiet() {
    // The board's task has not delivered yet: the profile has no speed to move at, so the
    // controller holds where it is rather than drive without a model.
    let mut ctl = controller_at(WORD_16_N);
    ctl.set_servo(true).unwrap();
    ctl.move_to(100_000).unwrap();
    for _ in 0..100 {
        let out = ctl.step(&Inputs { preload_word: WORD_16_N, ..Default::default() });
        assert!(out.amp_enable);
    }
    assert_eq!(ctl.state(), State::Moving);
    assert_eq!(ctl.reference_nm(), 0, "the profile did not advance");
    assert_eq!(ctl.drive_voltage_v(), 0.0);
    // Once the table is in, it moves.
    ctl.background();
    for _ in 0..100 {
        ctl.step(&Inputs { preload_word: WORD_16_N, ..Default::default() });
    }
    assert!(ctl.reference_nm() > 0);
}

/// Issue 11: the drive frequency is chosen where the model has the carriage fastest against the
/// load; where the load is past the model's stall force at every candidate, the model has no
/// speed to rank them by, and the frequency in use stays (a 50 kg carriage at 5 N switched from
/// 2.2 to 1.8 kHz on such a non-ranking and faulted).
#[test]
fn past_the_models_stall_force_the_frequency_in_use_stays() {
    let ctl = controller_at(WORD_16_N);
    let request = ctl.model_request().unwrap();
    let c = request.choice;
    assert!(c.len > 3, "the default offers a choice of frequencies");
    let tables: Vec<ModelTable> = (0..c.len)
        .map(|k| {
            let mut r = request;
            r.frequency_hz = c.frequency_hz[k];
            r.per_volt = c.per_volt[k];
            r.choice.len = 1;
            r.choice.frequency_hz[0] = c.frequency_hz[k];
            r.choice.per_volt[0] = c.per_volt[k];
            ModelTable::build(&r)
        })
        .collect();
    // A middle candidate in use.
    let mut in_use = request;
    in_use.frequency_hz = c.frequency_hz[3];
    in_use.per_volt = c.per_volt[3];
    // Against no load the build goes where its table is fastest (within the table's 1 %).
    let fastest = tables.iter().map(|t| t.no_load_mm_s()).fold(0.0f32, f32::max);
    let free = in_use.chosen();
    let k = (0..c.len).find(|&k| c.frequency_hz[k] == free.frequency_hz).unwrap();
    assert!(tables[k].no_load_mm_s() >= 0.99 * fastest, "chose {} Hz", free.frequency_hz);
    // Against twice the highest stall force of any candidate, the one in use stays.
    let beyond = 2.0 * tables.iter().map(|t| t.stall_n()).fold(0.0f32, f32::max);
    in_use.choice.load_n = beyond;
    let stuck = in_use.chosen();
    assert_eq!(stuck.frequency_hz, c.frequency_hz[3], "against {beyond} N");
    assert_eq!(stuck.per_volt, c.per_volt[3]);
}

#[test]
fn a_table_from_the_constant_speed_models_own_speed_law_is_the_cores_table() {
    // `ModelTable::from_speed_law` takes the carriage's speed from another model (host-sim feeds
    // it the contact model). Fed the constant-speed model's own speed law (eq. 19's root), it
    // must give back the core's table for a carriage heavy enough that the core builds from
    // that same model: each grid column's thrust, taken as a load, returns its own speed.
    let ctl = controller_at(WORD_16_N);
    let heavy = piezo_drive::controller::model_cache::ModelRequest {
        moving_mass_kg: 50.0,
        ..ctl.model_request().expect("a request once the preload is read")
    };
    let core = ModelTable::build(&heavy);
    let preload = piezo_drive::fastmath::fx_from_f32(heavy.preload_n);
    let law = ModelTable::from_speed_law(&heavy, |volts, load_n| {
        let point = heavy.per_volt.point(preload, piezo_drive::fastmath::fx_from_f32(volts));
        Some(point.speed_at_load_mm_s(piezo_drive::fastmath::fx_from_f32(load_n)).to_num())
    });
    let stall = core.stall_n();
    assert!((law.stall_n() - stall).abs() < 0.01 * stall, "stall {} against {stall}", law.stall_n());
    let v0 = core.no_load_mm_s();
    assert!((law.no_load_mm_s() - v0).abs() < 0.01 * v0, "no-load {} against {v0}", law.no_load_mm_s());
    // Where the thrust falls with the speed (between standstill and the foot's peak speed, where
    // the speed law is one-to-one), at part and full drive.
    let mut worst = 0.0f32;
    for volts in [40.0f32, 70.0, 100.0] {
        for share in [0.1f32, 0.3, 0.5, 0.7, 0.9] {
            let speed = share * core.speed_at_load_mm_s(0.0) * volts / 100.0;
            worst = worst.max((law.thrust_n(volts, speed) - core.thrust_n(volts, speed)).abs());
        }
    }
    assert!(worst < 0.01 * stall, "thrust off by {worst} N of a {stall} N stall force");
}

#[test]
fn a_choice_by_another_model_takes_that_models_fastest_candidate() {
    // `ModelRequest::chosen_with`: the candidate where the given speed law is highest, its
    // choice then fixed; where no candidate moves, the request's own frequency stays.
    let request = controller_at(WORD_16_N).model_request().expect("a request once the preload is read");
    assert!(request.choice.len > 1, "the default configuration offers a choice");
    let lowest = request.choice.frequency_hz[request.choice.len - 1];
    let slow_high = request.chosen_with(|c| 3.0 - c.frequency_hz / 1000.0);
    assert_eq!(slow_high.frequency_hz, lowest);
    assert_eq!(slow_high.choice.len, 1);
    let none = request.chosen_with(|_| 0.0);
    assert_eq!(none.frequency_hz, request.frequency_hz);
}

#[test]
fn a_contact_table_follows_the_inertial_bootstrap_and_replaces_it() {
    use piezo_drive::controller::model_cache::TableModelKind;
    let mut cfg = defaults::controller_config();
    cfg.contact_table = true;
    let mut ctl = Controller::new(cfg).unwrap();
    ctl.step(&Inputs { preload_word: WORD_16_N, ..Default::default() });
    // First the cheap table: the board moves on it while the contact table builds.
    let first = ctl.model_request().expect("a table is wanted");
    assert!(first.contact.is_none(), "the bootstrap table is the inertial model's");
    assert!(ctl.install_model(ModelTable::build(&first)));
    assert_eq!(ctl.table_model(), Some(TableModelKind::Inertial));
    // Then the contact model's, asked for although the inertial table fits the preload.
    let second = ctl.model_request().expect("the contact table is wanted next");
    assert!(second.contact.is_some());
    assert!(ctl.install_model(ModelTable::build(&second)));
    assert_eq!(ctl.table_model(), Some(TableModelKind::Contact));
    assert!(ctl.model_request().is_none(), "the contact table fits");
    // Switching the setting off drops it for an inertial one.
    let mut cfg = *ctl.config();
    cfg.contact_table = false;
    ctl.set_config(cfg).unwrap();
    let third = ctl.model_request().expect("a table for the new setting");
    assert!(third.contact.is_none());
}

#[test]
fn the_contact_table_is_solved_at_the_quiet_preload_and_kept_through_a_move() {
    let mut cfg = defaults::controller_config();
    cfg.contact_table = true;
    let mut ctl = Controller::new(cfg).unwrap();
    // The drive quiet for a second: the reading settles at 16 N.
    for _ in 0..10_000 {
        ctl.step(&Inputs { preload_word: WORD_16_N, ..Default::default() });
        ctl.background();
    }
    let quiet_n = ctl.preload_n().unwrap();
    assert_eq!(ctl.table_model(), Some(piezo_drive::controller::model_cache::TableModelKind::Contact));
    assert!(ctl.model_request().is_none());
    // A move: under drive the force cell reads the mean contact force, here 0.6 N more (40
    // words), which would ask an inertial table anew (its resolution is 0.05 N).
    ctl.set_servo(true).unwrap();
    ctl.move_to(1_000_000).unwrap();
    let (mut asked, mut driven) = (0, 0);
    for k in 0..2_000u16 {
        // The slider follows at about 1 mm/s (2 counts of 50 nm a period), as on the motor.
        let encoder_raw = k.wrapping_mul(2);
        ctl.step(&Inputs { preload_word: WORD_16_N + 40, encoder_raw, ..Default::default() });
        if ctl.drive_voltage_v() > 0.0 {
            driven += 1;
            if let Some(r) = ctl.model_request() {
                asked += 1;
                assert!(
                    (r.preload_n - quiet_n).abs() < 1e-3,
                    "solved at the quiet {quiet_n} N, not {}",
                    r.preload_n
                );
            }
        }
    }
    let moving_n = ctl.preload_n().unwrap();
    assert!(moving_n - quiet_n > 0.4, "the reading moved {} N", moving_n - quiet_n);
    assert!(driven > 1_000, "the drive ran {driven} periods");
    assert_eq!(asked, 0, "no contact table asked for while the drive runs");
}

#[test]
fn a_table_goes_in_part_by_part_and_only_the_last_part_swaps_it() {
    use piezo_drive::controller::model_cache::{Staged, TABLE_PARTS};
    let mut ctl = controller_at(WORD_16_N);
    let first = ctl.model_request().unwrap();
    assert!(ctl.install_model(ModelTable::build(&first)));
    let before = ctl.thrust_limits().unwrap();
    // A new table for another preload (400 periods at 0.5 N more).
    for _ in 0..400 {
        ctl.step(&Inputs { preload_word: WORD_16_N + 40, ..Default::default() });
    }
    let next = ModelTable::build(&ctl.model_request().expect("a new preload"));
    for part in 0..TABLE_PARTS - 1 {
        assert_eq!(ctl.stage_model(&next, part), Staged::More);
        // The old table serves until the swap.
        assert_eq!(ctl.coarse_frequency_hz(), first.chosen().frequency_hz);
        assert!(ctl.model_request().is_some(), "still the old table in use");
    }
    assert_eq!(ctl.stage_model(&next, TABLE_PARTS - 1), Staged::Installed);
    assert!(ctl.model_request().is_none(), "the new table fits");
    assert_ne!(ctl.thrust_limits().unwrap(), before);
    // Out of order: refused, and the staging starts over.
    assert_eq!(ctl.stage_model(&next, 2), Staged::Refused);
    // A change of what the table is built from between parts: refused at the check.
    for part in 0..3 {
        assert_eq!(ctl.stage_model(&next, part), Staged::More);
    }
    let mut cfg = *ctl.config();
    cfg.moving_mass_kg *= 2.0;
    ctl.set_config(cfg).unwrap();
    assert_eq!(ctl.stage_model(&next, 3), Staged::Refused);
}
