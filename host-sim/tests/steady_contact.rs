//! The steady-state model with the contact's timing (`motor::steady_contact`, issue 28) against
//! the stator's linear response in closed form and against the time-domain plant of the sourced
//! parameter set over the carriages, preloads, frequencies and loads of issue 28.

use host_sim::model_grid;
use host_sim::motor::params::Params;
use host_sim::motor::plant::steady_speed_m_s;
use host_sim::motor::steady::{amplitudes, OperatingPoint};
use host_sim::motor::steady_contact::{ContactModel, ContactProfile, OrbitStart, FINE_STEPS};
use nalgebra::Complex;
use std::f64::consts::{PI, TAU};
use std::sync::Arc;

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
        let n = profile.fine_steps();
        let (mut a, mut b) = (0.0, 0.0);
        for (i, f) in profile.contact_n().iter().enumerate() {
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

/// Issue 28 item 2 at the two frequencies the paper measures (`model_grid`): every carriage
/// 0.1–50 kg and preload 5–18 N, loads 0, 35 and 70 % of the model's stall force, 100 V: the
/// model's speed within 5 % of the plant's no-load speed (the plant's steady speed as `host-sim
/// curve` measures it). On the same grid the constant-speed model misses by up to 983 % and the
/// inertial one by up to 71 % (`host-sim model-grid`).
#[test]
fn the_model_with_the_contacts_timing_follows_the_sourced_plant_within_5_percent() {
    let grid = model_grid::compute(&Params::prototype_sourced());
    assert_eq!(grid.len(), 5 * 4 * 2 * 3);
    let worst = grid
        .iter()
        .max_by(|a, b| {
            let e = |g: &&model_grid::GridPoint| {
                let e = g.error_percent(g.contact_mm_s).abs();
                if e.is_finite() {
                    e
                } else {
                    f64::INFINITY
                }
            };
            e(a).total_cmp(&e(b))
        })
        .expect("a grid");
    let err = worst.error_percent(worst.contact_mm_s).abs();
    eprintln!("worst: {err:.2} % at {worst:?}");
    assert!(err < 5.0, "{err:.1} % of the no-load speed at {worst:?}");
}

/// Issue 28 item 1, the band: at no load the model holds where light carriages are fastest
/// (0.7–1.2 kHz) as well as at 1.5–2.2 kHz, every carriage, 5–18 N, within 3 % of the plant's
/// speed. Left out, with the reason measured: 1.3 and 1.4 kHz, where at 5–10 N the bouncing foot
/// wanders between impact patterns over hundreds of periods and the plant's steady-speed measure
/// (two 10 ms windows that agree) stops early (50 kg, 1.4 kHz, 10 N: 2.40 mm/s from it, 1.67 over a
/// 0.5 s run); and 0.5–0.6 kHz, where the heavier carriages barely move at 16–18 N.
#[test]
fn the_model_with_the_contacts_timing_holds_over_the_band_at_no_load() {
    use host_sim::motor::plant::steady_speed_m_s;
    use host_sim::motor::steady_contact::ContactModel;
    use rayon::prelude::*;
    let p0 = Params::prototype_sourced();
    let mut cases = Vec::new();
    for f in [700.0, 900.0, 1100.0, 1200.0, 1500.0, 1800.0, 2200.0] {
        for m in [0.1, 0.3, 1.0, 5.0, 50.0] {
            for f0 in [5.0, 10.0, 16.0, 18.0] {
                cases.push((f, m, f0));
            }
        }
    }
    let worst = cases
        .par_iter()
        .map(|&(f, m, f0)| {
            let mut p = p0.clone();
            p.slider.mass_kg = m;
            let op = OperatingPoint { preload_n: f0, voltage_v: 100.0, frequency_hz: f };
            let model = ContactModel::new(&p, op).no_load_speed_m_s();
            let plant = steady_speed_m_s(&p, f0, 100.0, f, 1, 0.0);
            ((model - plant).abs() / plant.abs().max(1e-6), (f, m, f0, model, plant))
        })
        .reduce(|| (0.0, (0.0, 0.0, 0.0, 0.0, 0.0)), |a, b| if b.0 > a.0 { b } else { a });
    eprintln!("worst {:.2} % at {:?}", worst.0 * 100.0, worst.1);
    assert!(worst.0 < 0.03, "{:.1} % at (Hz, kg, N, model, plant) {:?}", worst.0 * 100.0, worst.1);
}

/// The contact model carries the parameter file's effects as the plant applies them (the plant,
/// run with each effect at a moderate size, is the reference): guide friction at the carriage's
/// own speed, the drive sense's asymmetry, μ by preload, Stribeck, and the drive gain of an
/// amplifier pole. 1 kg on the sourced plant at 16 and 10 N, no load and 40 % of stall, both
/// senses: within 5 % of the plant's no-load speed there, the bound the model-grid test holds
/// without effects.
#[test]
fn the_model_with_the_contacts_timing_carries_the_effects_as_the_plant_does() {
    use host_sim::motor::plant::steady_speed_m_s;
    use host_sim::motor::steady_contact::{ContactModel, ContactProfile};
    use rayon::prelude::*;
    use std::sync::Arc;
    let effects: [&[(&str, f64)]; 5] = [
        &[("rail_coulomb_n", 0.4)],
        &[("asymmetry_fraction", 0.07)],
        &[("mu_drop_per_n", 0.05), ("knee_preload_n", 10.0)],
        &[("stribeck_rise", 1.5)],
        &[("rolloff_corner_hz", 2500.0)],
    ];
    let mut cases = Vec::new();
    for (k, e) in effects.iter().enumerate() {
        for (f0, v, f) in [(16.0, 100.0, 1500.0), (10.0, 80.0, 2100.0)] {
            for direction in [1i8, -1] {
                for load_share in [0.0, 0.4] {
                    cases.push((k, e, f0, v, f, direction, load_share));
                }
            }
        }
    }
    let worst = cases
        .par_iter()
        .map(|&(k, e, f0, v, f, direction, load_share)| {
            let mut p = Params::prototype_sourced();
            for (name, value) in e.iter() {
                p.effects.set(name, *value).expect("a library parameter");
            }
            let op = OperatingPoint { preload_n: f0, voltage_v: v, frequency_hz: f };
            let model = ContactModel::with_profile(&p, Arc::new(ContactProfile::new(&p, op)), direction);
            let load_n = load_share * p.friction.mu_dynamic * f0;
            let plant_no_load = steady_speed_m_s(&p, f0, v, f, direction, 0.0);
            let plant = steady_speed_m_s(&p, f0, v, f, direction, load_n);
            let speed = model.speed_at_load_m_s(load_n).unwrap_or(f64::NAN);
            (
                (speed - plant).abs() / plant_no_load.abs().max(1e-6),
                (k, f0, f, direction, load_n, speed, plant),
            )
        })
        .reduce(
            || (0.0, (0, 0.0, 0.0, 0, 0.0, 0.0, 0.0)),
            |a, b| if b.0 > a.0 || b.0.is_nan() { b } else { a },
        );
    eprintln!("worst {:.2} % at {:?}", worst.0 * 100.0, worst.1);
    assert!(
        worst.0 < 0.05,
        "{:.1} % at (effect, N, Hz, sense, load, model, plant) {:?}",
        worst.0 * 100.0,
        worst.1
    );
}

/// A light carriage below the model's band: 0.3 kg on the sourced plant at 17 N, 60 V, 0.9 kHz
/// against 4.17 N (a row of `measure --grid compact`). The impacts push it about so hard that its
/// speed ripples from −5.5 to +1.5 mm/s within a period (`trace`), more than four times the
/// foot's peak speed of 1.1 mm/s either side, where the orbit search once gave up (and the gap
/// workflow fell back to the closed form, +0.69 mm/s). The orbit is there, and it is the plant's
/// (−1.78 mm/s: the impacts carry the carriage backwards).
#[test]
fn a_carriage_rippling_beyond_four_foot_speeds_has_its_orbit_and_it_is_the_plants() {
    use host_sim::motor::plant::steady_speed_m_s;
    use host_sim::motor::steady_contact::ContactModel;
    let mut p = Params::prototype_sourced();
    p.slider.mass_kg = 0.3;
    let op = OperatingPoint { preload_n: 17.0, voltage_v: 60.0, frequency_hz: 900.0 };
    let model = ContactModel::new(&p, op).speed_at_load_m_s(4.17).expect("an orbit");
    let plant = steady_speed_m_s(&p, 17.0, 60.0, 900.0, 1, 4.17);
    eprintln!("model {:.4} mm/s, plant {:.4} mm/s", model * 1e3, plant * 1e3);
    assert!(plant < -1.0e-3, "the plant runs backwards here: {plant} m/s");
    assert!((model - plant).abs() <= 0.05 * plant.abs(), "model {model} m/s, plant {plant} m/s");
}

#[test]
fn a_foot_whose_landing_repeats_only_to_its_rounding_is_solved_over_its_mean_period() {
    // On the sourced prototype these points' impulses alternate from period to period by 2e-5
    // to 2e-4 of the preload (the landing located to 1/1024 of a step), in patterns of 2 and 4
    // periods, and the one-period test (1e-5) never passed within 600 periods. The pattern is
    // found well before that cap, and its mean is one period: the orbit over it is the carriage's
    // periodic motion, so the no-load speed is the time-domain plant's (independent: it runs the
    // stator and carriage together from rest).
    let p = Params::prototype_sourced();
    for (preload_n, voltage_v, frequency_hz) in
        [(5.0, 60.0, 900.0), (5.0, 60.0, 2100.0), (8.0, 100.0, 1500.0)]
    {
        let op = OperatingPoint { preload_n, voltage_v, frequency_hz };
        let profile = ContactProfile::new(&p, op);
        assert!(profile.settled && profile.fine_steps() == FINE_STEPS, "{op:?}: settled {}", profile.settled);
        assert!(profile.periods <= 100, "{op:?}: {} periods", profile.periods);
        let model = ContactModel::with_profile(&p, Arc::new(profile), 1).no_load_speed_m_s();
        let plant = steady_speed_m_s(&p, preload_n, voltage_v, frequency_hz, 1, 0.0);
        assert!((model / plant - 1.0).abs() < 0.01, "{op:?}: model {model} m/s, plant {plant} m/s");
    }
}

/// `p` on a carriage of `mass_kg` at 100 V: the parameters, the normal motion and the model
/// along +x.
fn on_carriage(
    p: &Params,
    mass_kg: f64,
    preload_n: f64,
    frequency_hz: f64,
) -> (Params, Arc<ContactProfile>, ContactModel) {
    let mut q = p.clone();
    q.slider.mass_kg = mass_kg;
    let op = OperatingPoint { preload_n, voltage_v: 100.0, frequency_hz };
    let profile = Arc::new(ContactProfile::new(&q, op));
    let model = ContactModel::with_profile(&q, profile.clone(), 1);
    (q, profile, model)
}

#[test]
fn a_search_from_a_nearby_solution_finds_the_same_orbit_as_one_from_nothing() {
    // The hint (a nearby solution's start speed, layer state and slope) only shortens the
    // search: secant steps from it, or the bracket about it, end on the orbit the full bracket
    // finds, to the root's tolerance. Hints from μ 5 % higher and from 10 % more load, on light
    // and heavy carriages, at a settled and at a bouncing preload; each also with its slope
    // three times too steep and too shallow, so that the secant leaves its window of the
    // hint's slope and the bracket starts from the points the secant evaluated.
    let p = Params::prototype_sourced();
    for (mass_kg, preload_n, frequency_hz) in [(0.3, 16.0, 2200.0), (1.0, 5.0, 1500.0), (50.0, 10.0, 2200.0)]
    {
        let (q, profile, model) = on_carriage(&p, mass_kg, preload_n, frequency_hz);
        let stall_n = model.stall_force_n();
        let mut nearby_p = q.clone();
        nearby_p.friction.mu_dynamic *= 1.05;
        let nearby = ContactModel::with_profile(&nearby_p, profile, 1);
        for share in [0.0, 0.35, 0.7] {
            let load_n = share * stall_n;
            let (alone, _) = model.orbit_near(load_n, None).expect("an orbit");
            let hints = [nearby.orbit_near(load_n, None), model.orbit_near(1.1 * load_n, None)];
            for hint in hints.into_iter().flatten().flat_map(|(_, h)| {
                [h, OrbitStart { slope: 3.0 * h.slope, ..h }, OrbitStart { slope: h.slope / 3.0, ..h }]
            }) {
                let (hinted, start) = model.orbit_near(load_n, Some(hint)).expect("an orbit from the hint");
                let off = (hinted.mean_speed_m_s - alone.mean_speed_m_s).abs() / model.foot_peak_m_s;
                assert!(off < 1e-4, "{mass_kg} kg {preload_n} N at {load_n} N: {hinted:?} against {alone:?}");
                assert!(start.slope < 0.0, "the excess falls with the start speed: {start:?}");
            }
        }
    }
}

#[test]
fn one_secant_step_from_a_nearby_orbit_gives_its_speed_difference() {
    // The fits' slopes take a 5 % step of a parameter and the speed after one secant step from
    // the anchor's orbit (`speed_after_one_secant`). Held against the full search at the model's
    // own tolerance: the step's speed difference within 1 % of itself where the step is taken
    // (measured over 648 steps of the 0.3–5 kg carriages: 1.6 % at the 99th percentile, so a
    // few points are held here, each of which must take the step, not fall back).
    let p = Params::prototype_sourced();
    let mut taken = 0;
    for (mass_kg, preload_n, frequency_hz) in [(0.3, 16.0, 2200.0), (1.0, 16.0, 1500.0), (5.0, 10.0, 2200.0)]
    {
        let (q, profile, model) = on_carriage(&p, mass_kg, preload_n, frequency_hz);
        let stall_n = model.stall_force_n();
        for (k, share) in [0.0, 0.4, 0.7].into_iter().enumerate() {
            let load_n = share * stall_n;
            let (orbit, start) = model.orbit_near(load_n, None).expect("an orbit");
            let mut stepped = q.clone();
            match k {
                0 => stepped.friction.mu_dynamic *= 1.05,
                1 => stepped.stator.tangential_scale *= 1.05,
                _ => stepped.slider.mass_kg *= 1.05,
            }
            let nearby = ContactModel::with_profile(&stepped, profile.clone(), 1);
            let full = nearby.orbit(load_n).expect("an orbit").mean_speed_m_s;
            let Some(one) = nearby.speed_after_one_secant(load_n, start) else { continue };
            taken += 1;
            let step = full - orbit.mean_speed_m_s;
            assert!(step.abs() > 1e-4 * model.foot_peak_m_s, "the step moves the speed: {step}");
            assert!(
                (one - full).abs() < 0.01 * step.abs(),
                "{mass_kg} kg {preload_n} N at {load_n:.3} N: {one} against {full} (step {step})"
            );
        }
    }
    assert!(taken >= 7, "the secant step is taken at most of these points: {taken} of 9");
}

#[test]
fn the_orbits_halved_steps_give_the_speeds_of_uniform_fine_steps() {
    // The carriage's steps are the base steps, halved where the contact or the interface changes
    // (`ContactModel::period`). Held against the same model on uniform fine steps (4096 per
    // period, the contact's events then within 1/4096 of the period) over issue 28's grid: within
    // 1 % of the no-load speed (measured: 0.91 % at 0.1 kg, 18 N, 1.5 kHz; 0.24 % at 0.3 kg;
    // 0.15 % from 1 kg on). 1024 uniform steps, the model's steps before, were up to 1.34 % off.
    use rayon::prelude::*;
    let points = host_sim::model_grid::operating_points();
    let worst = points
        .par_iter()
        .map(|&(mass_kg, preload_n, frequency_hz)| {
            let (p, op) = host_sim::model_grid::at_point(
                &Params::prototype_sourced(),
                (mass_kg, preload_n, frequency_hz),
            );
            let model = ContactModel::new(&p, op);
            let fine = model.clone().on_fine_steps();
            let stall_n = fine.stall_force_n();
            let no_load = fine.no_load_speed_m_s();
            let off = host_sim::model_grid::worst_over_loads(
                stall_n,
                no_load,
                |load_n| model.speed_at_load_m_s(load_n).unwrap_or(f64::NAN),
                |load_n| fine.speed_at_load_m_s(load_n).unwrap_or(f64::NAN),
            );
            (off, (mass_kg, preload_n, frequency_hz))
        })
        .reduce(|| (0.0, (0.0, 0.0, 0.0)), |a, b| if b.0 > a.0 || b.0.is_nan() { b } else { a });
    eprintln!("worst {:.2} % at {:?}", worst.0 * 100.0, worst.1);
    assert!(worst.0 < 0.01, "{:.2} % at (kg, N, Hz) {:?}", worst.0 * 100.0, worst.1);
}
