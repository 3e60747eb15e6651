//! The firmware's fixed-point thrust model against host-sim's f64 model (the same equations):
//! within 1 % of the stall force over the operating grid, both directions.
//!
//! The grid's frequencies stay above 1.1 kHz. With the paper's 1 kg counterweight the foot-clamped
//! counterweight mode is at 857 Hz: there eq. (7)'s contact amplitude grows without bound (kc·Yc
//! per volt 0.13 N at 600 Hz, 1.4 N at 900 Hz, 0.23 N at 1.5 kHz), the model is not the plant
//! (`host-sim paper`, README) and the controller does not drive there.

use host_sim::harness::sil::motor_constants;
use host_sim::motor::params::Params;
use host_sim::motor::steady::{thrust_n, OperatingPoint, ThrustModel};
use piezo_drive::Fx;

#[test]
fn fixed_point_thrust_within_1_percent_of_stall_over_the_operating_grid() {
    let p = Params::prototype();
    let k = motor_constants(&p);
    let mut worst = 0.0f64;
    let mut points = 0;
    for preload_n in [3.0, 5.0, 8.0, 12.0, 16.0, 20.0] {
        for voltage_v in [30.0, 50.0, 75.0, 100.0] {
            for frequency_hz in [1150.0, 1250.0, 1500.0, 1750.0, 1900.0, 2200.0] {
                let op = OperatingPoint { preload_n, voltage_v, frequency_hz };
                let reference = ThrustModel::new(&p, op);
                let stall = reference.stall_force_n();
                let fx = k.point(
                    Fx::from_num(preload_n),
                    Fx::from_num(voltage_v),
                    Fx::from_num(frequency_hz / 1000.0),
                );
                for direction in [1i8, -1] {
                    for u in [-0.5, 0.0, 0.2, 0.5, 0.8, 0.95, 1.1] {
                        let v = u * reference.foot_speed_m_s;
                        let expected = thrust_n(&p, op, v, direction);
                        // Reverse drive in the core is the mirror image, as in the plant.
                        let d = f64::from(direction);
                        let got = d * fx.thrust_n(Fx::from_num(d * v * 1e3)).to_num::<f64>();
                        let err = (got - expected).abs() / stall;
                        worst = worst.max(err);
                        assert!(
                            err < 0.01,
                            "F0 {preload_n} V {voltage_v} f {frequency_hz} dir {direction} u {u}: fixed {got} f64 {expected} (stall {stall})"
                        );
                        points += 1;
                    }
                }
                let s = fx.stall_force_n().to_num::<f64>();
                assert!((s - stall).abs() < 0.01 * stall, "stall {s} vs {stall}");
                let v0 = fx.no_load_speed_mm_s().to_num::<f64>();
                let v0_ref = reference.no_load_speed_m_s() * 1e3;
                assert!((v0 - v0_ref).abs() < 0.01 * v0_ref + 2e-3, "no-load {v0} vs {v0_ref} mm/s");
            }
        }
    }
    assert!(points > 2000);
    eprintln!("worst fixed-point error: {:.3} % of stall", 100.0 * worst);
}

#[test]
fn inverse_model_returns_the_voltage_that_gives_the_wanted_speed() {
    let p = Params::prototype();
    let k = motor_constants(&p);
    for (preload_n, speed_mm_s, load_n) in
        [(16.0, 1.0, 0.0), (16.0, 1.5, 1.0), (10.0, 0.5, 2.0), (8.0, 2.0, 0.5)]
    {
        let v = k.voltage_for(
            Fx::from_num(preload_n),
            Fx::from_num(2.2),
            Fx::from_num(speed_mm_s),
            Fx::from_num(load_n),
            Fx::from_num(100),
        );
        assert!(v < Fx::from_num(100), "F0 {preload_n}: saturated");
        // The f64 model at that voltage runs at the wanted speed against that load.
        let m =
            ThrustModel::new(&p, OperatingPoint { preload_n, voltage_v: v.to_num(), frequency_hz: 2200.0 });
        let got = m.speed_at_load_m_s(load_n).unwrap() * 1e3;
        assert!(
            (got - speed_mm_s).abs() < 0.02 * speed_mm_s + 0.01,
            "F0 {preload_n}: {got} vs {speed_mm_s} mm/s"
        );
    }
}

/// The firmware's baked motor table is what host-sim derives from the shipped parameter file
/// (regenerate with `host-sim firmware-table > src/motor_table.rs`).
#[test]
fn the_baked_motor_table_matches_the_prototype_parameter_file() {
    let committed = include_str!("../../src/motor_table.rs");
    let generated =
        host_sim::harness::sil::motor_table_source(&Params::prototype(), "host-sim/params/prototype.toml");
    assert!(
        committed == generated,
        "src/motor_table.rs is stale: run `cargo run -p host-sim -- firmware-table > src/motor_table.rs`"
    );
    assert_eq!(
        piezo_drive::motor_table::PROTOTYPE_MOTOR,
        host_sim::harness::sil::motor_constants(&Params::prototype())
    );
}

/// The firmware's defaults and the simulated board agree for the prototype file, so what the
/// simulator proves is what the board runs.
#[test]
fn firmware_defaults_equal_the_simulated_board() {
    assert_eq!(
        piezo_drive::defaults::controller_config(),
        host_sim::harness::sil::controller_config(&Params::prototype())
    );
}

/// The tick's model table (`controller::model_cache`, built off the tick) against the f64 model:
/// thrust between table voltages, the speed table, and the inverse, over the operating grid.
#[test]
fn model_table_within_1_percent_of_stall_of_the_f64_model() {
    use piezo_drive::controller::model_cache::{FrequencyChoice, ModelRequest, ModelTable};
    let p = Params::prototype();
    let k = motor_constants(&p);
    let (mut worst_thrust, mut worst_inverse, mut worst_speed) = (0.0f64, 0.0f64, 0.0f64);
    for preload_n in [5.0f64, 10.0, 16.0, 20.0] {
        for frequency_hz in [1200.0f64, 1500.0, 2200.0] {
            let per_volt = k.at_frequency(Fx::from_num(frequency_hz / 1000.0));
            let request = ModelRequest {
                per_volt,
                preload_n: preload_n as f32,
                max_drive_v: 100.0,
                frequency_hz: frequency_hz as f32,
                choice: FrequencyChoice::fixed(frequency_hz as f32, per_volt, 0.0),
                // Heavy enough for the constant-speed model (no orbits): the interpolation
                // is what this test measures.
                moving_mass_kg: 50.0,
                rail_coulomb_n: 0.0,
                rail_viscous_n_s_per_m: 0.0,
                contact: None,
                generation: 0,
            };
            let table = ModelTable::build(&request);
            let full_op = OperatingPoint { preload_n, voltage_v: 100.0, frequency_hz };
            let full = ThrustModel::new(&p, full_op);
            let stall = full.stall_force_n();
            assert!((f64::from(table.stall_n()) - stall).abs() < 0.01 * stall);
            // Voltages between the table's points (3.125 V apart), speeds over the foot's range.
            for voltage_v in [2.2f64, 4.7, 7.0, 12.9, 21.5, 38.9, 50.0, 64.2, 81.7, 99.0] {
                let op = OperatingPoint { preload_n, voltage_v, frequency_hz };
                let m = ThrustModel::new(&p, op);
                for u in [-0.9, -0.4, 0.0, 0.2, 0.5, 0.8, 0.95, 0.995] {
                    let v = u * m.foot_speed_m_s;
                    let expected = thrust_n(&p, op, v, 1);
                    let got = f64::from(table.thrust_n(voltage_v as f32, (v * 1e3) as f32));
                    let err = (got - expected).abs() / stall;
                    worst_thrust = worst_thrust.max(err);
                    assert!(
                        err < 0.01,
                        "F0 {preload_n} f {frequency_hz} V {voltage_v} u {u}: table {got} f64 {expected}"
                    );
                }
            }
            // Speed at full drive against loads between the speed table's points.
            for share in [0.0, 0.13, 0.31, 0.52, 0.77, 0.93] {
                let load = share * stall;
                let expected = full.speed_at_load_m_s(load).unwrap_or(0.0) * 1e3;
                let got = f64::from(table.speed_at_load_mm_s(load as f32));
                // As a thrust error: the speed error times the slope of the characteristic.
                let slope = (thrust_n(&p, full_op, (expected + 0.01) * 1e-3, 1)
                    - thrust_n(&p, full_op, expected * 1e-3, 1))
                .abs()
                    / 0.01;
                let err = (got - expected).abs() * slope / stall;
                worst_speed = worst_speed.max(err);
                // 1 % held on the heavy stator; with the paper's masses the characteristic at
                // 1.2 kHz is so steep near no-load (kc·Yc ≈ 36 N against 5–10 N) that the
                // table's 0.3 % speed error is up to 2.41 % of the stall force (measured, 5 N):
                // regression bound.
                assert!(err < 0.025, "F0 {preload_n} f {frequency_hz} load {load}: {got} vs {expected} mm/s");
            }
            // The inverse: the f64 model at the voltage found gives the wanted thrust.
            for (speed_mm_s, share) in [(0.3, 0.1), (0.8, 0.0), (1.2, 0.3), (0.5, 0.6), (1.0, -0.2)] {
                let load = share * stall;
                let mut hint = 50.0;
                for start in [0.0f32, 50.0, 100.0] {
                    let v = table.voltage_for(speed_mm_s as f32, load as f32, start);
                    if start == 50.0 {
                        hint = v;
                    }
                    let op = OperatingPoint { preload_n, voltage_v: f64::from(v), frequency_hz };
                    let thrust = thrust_n(&p, op, speed_mm_s * 1e-3, 1);
                    if v > 0.0 && v < 100.0 {
                        let err = (thrust - load).abs() / stall;
                        worst_inverse = worst_inverse.max(err);
                        assert!(err < 0.01, "F0 {preload_n} f {frequency_hz} {speed_mm_s} mm/s {load} N: {v} V gives {thrust} N");
                    } else if v >= 100.0 {
                        assert!(thrust <= load + 0.01 * stall, "saturated high but {thrust} N > {load} N");
                    } else {
                        assert!(thrust >= load - 0.01 * stall, "zero drive but {thrust} N < {load} N");
                    }
                }
                // The same answer from every starting hint.
                assert!((table.voltage_for(speed_mm_s as f32, load as f32, 3.0) - hint).abs() < 1e-3);
            }
        }
    }
    eprintln!(
        "model table vs f64, worst share of stall: thrust {:.3} %, speed table {:.3} %, inverse {:.3} %",
        100.0 * worst_thrust,
        100.0 * worst_speed,
        100.0 * worst_inverse
    );
}

/// The core's periodic-motion model (`piezo_drive::inertia`, f32, 96 steps per period) against
/// host-sim's (`steady_inertia`, f64, 720 steps): the same equations, so the mean speeds agree
/// to the step's resolution over light to heavy carriages, preloads, drives and loads.
#[test]
fn core_orbit_model_follows_the_f64_inertial_model() {
    use host_sim::motor::steady_inertia::InertialModel;
    use piezo_drive::inertia::Orbits;
    let p0 = Params::prototype();
    let k = motor_constants(&p0);
    let mut worst = 0.0f64;
    let mut points = 0;
    for mass in [0.1, 0.3, 1.0, 5.0] {
        let mut p = p0.clone();
        p.slider.mass_kg = mass;
        for (preload_n, voltage_v) in [(5.0, 100.0), (16.0, 100.0), (16.0, 50.0), (20.0, 70.0)] {
            for frequency_hz in [1500.0, 2200.0] {
                let op = OperatingPoint { preload_n, voltage_v, frequency_hz };
                let reference = InertialModel::new(&p, op);
                let stall = ThrustModel::new(&p, op).stall_force_n();
                let point = k.point(
                    Fx::from_num(preload_n),
                    Fx::from_num(voltage_v),
                    Fx::from_num(frequency_hz / 1000.0),
                );
                let orbits = Orbits::new(&point, frequency_hz as f32, mass as f32);
                let foot_mm_s = reference.base.foot_speed_m_s * 1e3;
                for fraction in [0.0, 0.35, 0.7] {
                    let load = fraction * stall;
                    let (Some(want), Some(got)) =
                        (reference.speed_at_load_m_s(load), orbits.mean_speed_mm_s(load as f32))
                    else {
                        panic!("no orbit at {mass} kg, {preload_n} N, {voltage_v} V, {frequency_hz} Hz, {load} N");
                    };
                    let err = (f64::from(got) - want * 1e3).abs() / foot_mm_s;
                    worst = worst.max(err);
                    assert!(
                        err < 0.02,
                        "{mass} kg, {preload_n} N, {voltage_v} V, {frequency_hz} Hz, load {load:.2} N: core {got} f64 {} mm/s",
                        want * 1e3
                    );
                    points += 1;
                }
            }
        }
    }
    assert_eq!(points, 96);
    eprintln!("worst core orbit error: {:.2} % of the foot's peak speed", 100.0 * worst);
}

/// The calibrated motor (issue 13: μ, λ, ρ and the guide's friction uploaded with `SPA`) against
/// the f64 model of the same motor written as a parameter file: the table scaled by the ratios,
/// with the guide friction taken off, agrees with `EffectModel` (rail friction as a resisting
/// force in the speed balance, the other values in the file) as the plain table does.
#[test]
fn calibrated_table_with_guide_friction_matches_the_f64_model_of_that_motor() {
    use host_sim::harness::sil::controller_config;
    use host_sim::motor::effects::{model_speed_m_s, Condition};
    use piezo_drive::controller::model_cache::ModelTable;
    use piezo_drive::controller::Controller;
    let base = Params::heavy_slider();
    // The fitted motor: μ 20 % lower, λ 5 % lower, ρ 10 % higher, 0.4 N + 30 N·s/m in the guide.
    let mut truth = base.clone();
    truth.friction.mu_dynamic *= 0.8;
    truth.stator.tangential_scale *= 0.95;
    truth.stator.normal_force_ratio *= 1.1;
    truth.effects.set("rail_coulomb_n", 0.4).unwrap();
    truth.effects.set("rail_viscous_n_s_per_m", 30.0).unwrap();
    let mut cfg = controller_config(&base);
    cfg.mu_dynamic = truth.friction.mu_dynamic as f32;
    cfg.tangential_scale = truth.stator.tangential_scale as f32;
    cfg.normal_force_ratio = truth.stator.normal_force_ratio as f32;
    (cfg.rail_coulomb_n, cfg.rail_viscous_n_s_per_m) = (0.4, 30.0);
    let mut c = Controller::new(cfg).expect("the calibration is accepted");
    // A 16 N reading of the force cell (zero word 0).
    let word = (16.0 / cfg.preload.newton_per_word).round() as u16;
    c.step(&piezo_drive::controller::Inputs { preload_word: word, ..Default::default() });
    let request = c.model_request().expect("a table is wanted");
    assert_eq!((request.rail_coulomb_n, request.rail_viscous_n_s_per_m), (0.4, 30.0));
    let table = ModelTable::build(&request);
    let cond = |load_n: f64| Condition {
        preload_n: f64::from(request.preload_n),
        voltage_v: 100.0,
        frequency_hz: f64::from(cfg.drive_freq_hz),
        load_n,
        direction: 1,
    };
    // Stall: the load at which the f64 model's speed reaches zero, by bisection.
    let (mut lo, mut hi) = (0.0f64, 20.0f64);
    for _ in 0..50 {
        let mid = 0.5 * (lo + hi);
        if model_speed_m_s(&truth, &cond(mid)) > 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let stall = lo;
    let plain_stall = f64::from(
        ModelTable::build(&{
            let mut r = request;
            (r.rail_coulomb_n, r.rail_viscous_n_s_per_m) = (0.0, 0.0);
            r
        })
        .stall_n(),
    );
    // The guide's 0.4 N is off the stall exactly (at standstill its viscous part is nil).
    assert!(
        (plain_stall - f64::from(table.stall_n()) - 0.4).abs() < 1e-3,
        "{plain_stall} vs {}",
        table.stall_n()
    );
    assert!(
        (f64::from(table.stall_n()) - stall).abs() < 0.01 * stall,
        "stall {} vs f64 {stall}",
        table.stall_n()
    );
    // Speeds within 1.5 % of the no-load speed: the speed column is interpolated between 17
    // loads, as in the plain table (1 % of the stall force as a thrust error there).
    let no_load = model_speed_m_s(&truth, &cond(0.0)) * 1e3;
    for share in [0.0, 0.2, 0.5, 0.8, 0.95] {
        let load = share * stall;
        let want = model_speed_m_s(&truth, &cond(load)) * 1e3;
        let got = f64::from(table.speed_at_load_mm_s(load as f32));
        assert!((got - want).abs() < 0.015 * no_load, "load {load:.3} N: table {got:.4} mm/s, f64 {want:.4}");
    }
}
