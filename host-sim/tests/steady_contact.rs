//! The steady-state model with the contact's timing (`motor::steady_contact`, issue 28) against
//! the stator's linear response in closed form and against the time-domain plant of the sourced
//! parameter set over the carriages, preloads, frequencies and loads of issue 28.

use host_sim::motor::params::Params;
use host_sim::motor::plant::steady_speed_m_s;
use host_sim::motor::steady::{amplitudes, OperatingPoint};
use host_sim::motor::steady_contact::{ContactModel, ContactProfile};
use nalgebra::Complex;
use std::f64::consts::{PI, TAU};

type C = Complex<f64>;

/// Complex amplitude of the contact force in permanent contact, by hand: the two masses on
/// `K − ω²M + iωC` under the stacks' normal force `F̂` on the foot and its reaction on the
/// counterweight, each spring with the dashpot of its own mode (the structural ratio across k1,
/// the preload mode's across k2, the contact's from its restitution across kc), solved by
/// Cramer's rule; the contact force is `(kc + iω·c3)·Y1`.
fn permanent_contact_force(p: &Params, op: OperatingPoint) -> C {
    let w = TAU * op.frequency_hz;
    let (m1, m2) = (p.stator.foot_mass_kg, p.stator.counterweight_mass_kg);
    let (k1, k2, kc) = (p.k1_n_per_m(), p.stator.preload_spring_n_per_m, p.contact.stiffness_n_per_m);
    let c1 = 2.0 * p.stator.damping_ratio * (k1 * m1 * m2 / (m1 + m2)).sqrt();
    let c2 = 2.0 * p.stator.preload_mode_damping_ratio() * (k2 * (m1 + m2)).sqrt();
    let c3 = 2.0 * p.contact.damping_ratio() * (kc * m1).sqrt();
    let z = |k: f64, c: f64| C::new(k, w * c);
    let a11 = z(k1 + kc, c1 + c3) - C::new(w * w * m1, 0.0);
    let a12 = -z(k1, c1);
    let a22 = z(k1 + k2, c1 + c2) - C::new(w * w * m2, 0.0);
    let f = amplitudes(p, op.voltage_v, op.frequency_hz).normal_force_n;
    // [a11 a12; a12 a22]·[Y1; Y2] = [F; −F]
    let det = a11 * a22 - a12 * a12;
    let y1 = (C::new(f, 0.0) * a22 + C::new(f, 0.0) * a12) / det;
    z(kc, c3) * y1
}

#[test]
fn in_permanent_contact_the_contact_force_is_the_stators_linear_response() {
    // Above the permanent-contact preload the stator is linear: the contact force is F0 plus
    // one harmonic whose amplitude and phase (against the drive's cos φ) the closed form gives.
    let p = Params::prototype_sourced();
    // (Near the foot-clamped counterweight mode, ≈ 0.86 kHz, the response grows past the
    // preload and the foot lifts off again: 1.5 and 2.2 kHz.)
    for frequency_hz in [1500.0, 2200.0] {
        let op = OperatingPoint { preload_n: 35.0, voltage_v: 100.0, frequency_hz };
        let profile = ContactProfile::new(&p, op);
        let share = profile.contact_fraction();
        assert!(profile.settled && share == 1.0, "{frequency_hz} Hz: in contact {share}");
        let n = profile.contact_n.len();
        let (mut a, mut b) = (0.0, 0.0);
        for (i, f) in profile.contact_n.iter().enumerate() {
            let phi = -PI + TAU * (i as f64 + 0.5) / n as f64;
            a += 2.0 / n as f64 * f * phi.cos();
            b += 2.0 / n as f64 * f * phi.sin();
        }
        let measured = C::new(a, -b);
        let expected = permanent_contact_force(&p, op);
        let amp_err = (measured.norm() / expected.norm() - 1.0).abs();
        let phase_err = (measured / expected).arg().abs();
        assert!(
            amp_err < 0.005,
            "{frequency_hz} Hz: amplitude {} N vs {} N",
            measured.norm(),
            expected.norm()
        );
        assert!(phase_err < 0.005, "{frequency_hz} Hz: phase off by {phase_err} rad");
        assert!((profile.mean_contact_n() / 35.0 - 1.0).abs() < 1e-3, "mean {}", profile.mean_contact_n());
    }
}

/// Issue 28 item 2 at the two frequencies the paper measures: every carriage and preload, loads
/// 0, 35 and 70 % of the model's stall force: the model's mean speed within 5 % of the plant's
/// no-load speed (the plant's steady speed from `steady_speed_m_s`, the measure `host-sim curve`
/// prints). The constant-speed model misses this grid by up to 48–76 % and the inertial model by
/// up to 180 % (`docs/simulator.md`).
#[test]
fn the_model_with_the_contacts_timing_follows_the_sourced_plant_within_5_percent() {
    use rayon::prelude::*;
    let p0 = Params::prototype_sourced();
    let mut cases = Vec::new();
    for mass_kg in [0.1, 0.3, 1.0, 5.0, 50.0] {
        for preload_n in [5.0, 10.0, 16.0, 18.0] {
            for frequency_hz in [1500.0, 2200.0] {
                cases.push((mass_kg, preload_n, frequency_hz));
            }
        }
    }
    let worst: Vec<(f64, String)> = cases
        .par_iter()
        .map(|&(mass_kg, preload_n, frequency_hz)| {
            let mut p = p0.clone();
            p.slider.mass_kg = mass_kg;
            let op = OperatingPoint { preload_n, voltage_v: 100.0, frequency_hz };
            let model = ContactModel::new(&p, op);
            let stall = model.stall_force_n();
            let plant_no_load = steady_speed_m_s(&p, preload_n, 100.0, frequency_hz, 1, 0.0);
            let mut worst = (0.0f64, String::new());
            for share in [0.0, 0.35, 0.7] {
                let load_n = share * stall;
                let plant = steady_speed_m_s(&p, preload_n, 100.0, frequency_hz, 1, load_n);
                let m = model.speed_at_load_m_s(load_n).unwrap_or(f64::NAN);
                let err = (m - plant).abs() / plant_no_load;
                if err.is_nan() || err > worst.0 {
                    worst = (
                        err,
                        format!(
                            "{mass_kg} kg {preload_n} N {frequency_hz} Hz at {load_n:.2} N: model {:.3} plant {:.3} mm/s",
                            m * 1e3,
                            plant * 1e3
                        ),
                    );
                }
            }
            worst
        })
        .collect();
    let (err, case) =
        worst.into_iter().fold((0.0, String::new()), |a, b| if b.0 > a.0 || b.0.is_nan() { b } else { a });
    eprintln!("worst: {:.2} % ({case})", err * 100.0);
    assert!(err < 0.05, "{:.1} % of the no-load speed: {case}", err * 100.0);
}
