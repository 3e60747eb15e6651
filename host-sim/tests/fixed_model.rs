//! The firmware's fixed-point thrust model against host-sim's f64 model (the same equations):
//! within 1 % of the stall force over the operating grid, both directions.

use host_sim::params::Params;
use host_sim::sil::motor_constants;
use host_sim::steady::{thrust_n, OperatingPoint, ThrustModel};
use piezo_drive::Fx;

#[test]
fn fixed_point_thrust_within_1_percent_of_stall_over_the_operating_grid() {
    let p = Params::prototype();
    let k = motor_constants(&p);
    let mut worst = 0.0f64;
    let mut points = 0;
    for preload_n in [3.0, 5.0, 8.0, 12.0, 16.0, 20.0] {
        for voltage_v in [30.0, 50.0, 75.0, 100.0] {
            for frequency_hz in [500.0, 800.0, 1250.0, 1500.0, 1900.0, 2200.0] {
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
    let generated = host_sim::sil::motor_table_source(&Params::prototype(), "host-sim/params/prototype.toml");
    assert!(
        committed == generated,
        "src/motor_table.rs is stale: run `cargo run -p host-sim -- firmware-table > src/motor_table.rs`"
    );
    assert_eq!(
        piezo_drive::motor_table::PROTOTYPE_MOTOR,
        host_sim::sil::motor_constants(&Params::prototype())
    );
}

/// The firmware's defaults and the simulated board agree for the prototype file, so what the
/// simulator proves is what the board runs.
#[test]
fn firmware_defaults_equal_the_simulated_board() {
    assert_eq!(
        piezo_drive::defaults::controller_config(),
        host_sim::sil::controller_config(&Params::prototype())
    );
}
