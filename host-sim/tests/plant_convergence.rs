//! The time-domain plant with the sourced prototype's Kelvin–Voigt friction layer converges in its
//! step, and its steady-speed measure waits for slow carriages.

use host_sim::motor::params::Params;
use host_sim::motor::plant::{steady_speed_m_s, Plant, QuadratureSine};
use host_sim::motor::steady::OperatingPoint;
use host_sim::motor::steady_contact::ContactModel;

fn sourced(mass_kg: f64) -> Params {
    let mut p = Params::from_toml(include_str!("../params/prototype-sourced.toml")).expect("valid file");
    p.slider.mass_kg = mass_kg;
    p
}

/// Steady speeds (m/s) at the production step and at its half and quarter.
fn halvings(p: &Params, preload_n: f64, voltage_v: f64, frequency_hz: f64, load_n: f64) -> [f64; 3] {
    [1.0, 0.5, 0.25].map(|share| {
        let mut q = p.clone();
        q.integrator.step_s *= share;
        steady_speed_m_s(&q, preload_n, voltage_v, frequency_hz, 1, load_n)
    })
}

/// The back-driven row near 70 % of stall where whole steps ran 50 % fast against an
/// independent solution of the same equations (−0.198 mm/s, scipy on fine steps; the contact
/// model −0.204): the speed converges as the step halves, the production step is within 0.5 %
/// of the no-load speed of the quarter step's, and within that of the contact model.
#[test]
fn back_driven_row_converges_in_the_step_and_meets_the_contact_model() {
    let p = sourced(0.5);
    let (preload_n, voltage_v, frequency_hz, load_n) = (9.0, 100.0, 2100.0, 2.075);
    let op = OperatingPoint { preload_n, voltage_v, frequency_hz };
    let model = ContactModel::new(&p, op);
    let no_load = model.no_load_speed_m_s();
    let contact = model.speed_at_load_m_s(load_n).expect("below stall");
    let [v1, v2, v4] = halvings(&p, preload_n, voltage_v, frequency_hz, load_n);
    eprintln!(
        "steps 1, 1/2, 1/4: {:.4} {:.4} {:.4} mm/s; contact model {:.4}",
        v1 * 1e3,
        v2 * 1e3,
        v4 * 1e3,
        contact * 1e3
    );
    assert!((v2 - v4).abs() < (v1 - v2).abs(), "not converging: {v1} {v2} {v4}");
    assert!((v1 - v4).abs() < 0.005 * no_load, "production step {v1} against {v4} (no load {no_load})");
    assert!((v1 - contact).abs() < 0.005 * no_load, "plant {v1} against the contact model {contact}");
    // Against the independent solution (−0.198 mm/s) to 0.5 % of the no-load speed.
    assert!((v1 + 0.198e-3).abs() < 0.005 * no_load, "plant {v1} against the independent −0.198 mm/s");

    // The same plant taking every step whole is the one that ran 50 % fast.
    let mut whole = Plant::new(&p, preload_n);
    whole.without_friction_switch_location();
    whole.load = host_sim::motor::plant::ExternalLoad::opposing(load_n, 1);
    let mut drive =
        QuadratureSine { voltage_v, frequency_hz, direction: 1, mid_v: p.amplifier_mid_v(), ramp_s: 0.01 };
    whole.run(&mut drive, 0.05);
    let x0 = whole.slider_position_m();
    whole.run(&mut drive, 0.1);
    let v_whole = (whole.slider_position_m() - x0) / 0.1;
    assert!(
        (v_whole - contact).abs() > 0.02 * no_load,
        "whole steps {v_whole} already met the model {contact}"
    );
}

/// No load on the compact grid's worst row (13 N, 60 V, 1.5 kHz) and a fast one: the step
/// halving converges (each difference under half the one before), and the production step
/// is within 1.5 % of the no-load speed of the quarter step's. (What remains at no load is not
/// the friction layer's switches: it is second order in the step and taking the stator and the
/// slider in 2 or 4 pieces per step does not move it; see docs/simulator.md.)
#[test]
fn no_load_speed_converges_in_the_step() {
    let p = sourced(0.5);
    for (preload_n, voltage_v, frequency_hz) in [(13.0, 60.0, 1500.0), (9.0, 100.0, 2100.0)] {
        let [v1, v2, v4] = halvings(&p, preload_n, voltage_v, frequency_hz, 0.0);
        eprintln!(
            "{preload_n} N {voltage_v} V {frequency_hz} Hz: {:.5} {:.5} {:.5} mm/s",
            v1 * 1e3,
            v2 * 1e3,
            v4 * 1e3
        );
        assert!((v2 - v4).abs() < 0.5 * (v1 - v2).abs(), "not converging: {v1} {v2} {v4}");
        assert!((v1 - v4).abs() < 0.015 * v4, "production step {v1} against {v4}");
    }
}

/// A 50 kg carriage settles with a time constant of about 0.1 s, ten of the measure's windows:
/// its steady speed agrees with the mean over 0.1 s after 1.2 s of running (over ten time
/// constants, e^−10 of the approach left) to 0.01 %. (Stopping at the first agreement of two
/// windows it read 0.06 % short at 5 N, 0.04 % at 16 N and 2.2 kHz.)
#[test]
fn settled_speed_of_a_heavy_carriage_matches_a_long_run() {
    let p = sourced(50.0);
    for (preload_n, voltage_v, frequency_hz) in [(5.0, 100.0, 1500.0), (16.0, 100.0, 2200.0)] {
        settled_against_long_run(&p, preload_n, voltage_v, frequency_hz);
    }
}

fn settled_against_long_run(p: &Params, preload_n: f64, voltage_v: f64, frequency_hz: f64) {
    let measured = steady_speed_m_s(p, preload_n, voltage_v, frequency_hz, 1, 0.0);
    let mut plant = Plant::new(p, preload_n);
    let mut drive =
        QuadratureSine { voltage_v, frequency_hz, direction: 1, mid_v: p.amplifier_mid_v(), ramp_s: 0.01 };
    plant.run(&mut drive, 1.2);
    let x0 = plant.slider_position_m();
    plant.run(&mut drive, 0.1);
    let long = (plant.slider_position_m() - x0) / 0.1;
    eprintln!(
        "50 kg {preload_n} N {frequency_hz} Hz: measure {:.5} mm/s, long run {:.5} mm/s",
        measured * 1e3,
        long * 1e3
    );
    assert!((measured - long).abs() < 1e-4 * long, "measure {measured} against the long run {long}");
}
