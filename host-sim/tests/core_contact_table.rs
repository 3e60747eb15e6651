//! The control core's model table built from its own contact model (`ModelTable::build` with
//! the contact model's inputs, `controller/contact_build.rs`: what the board builds) against
//! host-sim's f64 contact model (`steady_contact`), the reference it follows.
//!
//! The measure: at a drive V and a load L, the f64 model runs at v(L); the table's thrust at
//! (V, v(L)) should be L. Its error in % of the f64 model's stall force at that drive, over
//! loads 0-70 % of that stall force.

use host_sim::harness::sil::motor_constants;
use host_sim::motor::params::Params;
use host_sim::motor::steady::OperatingPoint;
use host_sim::motor::steady_contact::ContactModel;
use piezo_drive::contact_motor::Calibration;
use piezo_drive::controller::model_cache::{
    ContactInputs, FrequencyChoice, ModelRequest, ModelTable, VOLT_POINTS,
};
use piezo_drive::normal_motion::contact_force;
use piezo_drive::Fx;
use rayon::prelude::*;

/// The request a controller told the carriage's mass and pinned to `frequency_hz` makes, at the
/// static preload, for the contact model of `p`.
fn contact_request(p: &Params, mass_kg: f64, preload_n: f64, frequency_hz: f64) -> ModelRequest {
    let k = motor_constants(p);
    let per_volt = k.at_frequency(Fx::from_num(frequency_hz / 1000.0));
    ModelRequest {
        per_volt,
        preload_n: preload_n as f32,
        max_drive_v: 100.0,
        frequency_hz: frequency_hz as f32,
        choice: FrequencyChoice::fixed(frequency_hz as f32, per_volt, 0.0),
        moving_mass_kg: mass_kg as f32,
        rail_coulomb_n: 0.0,
        rail_viscous_n_s_per_m: 0.0,
        contact: Some(ContactInputs {
            motor: k.contact,
            calibration: Calibration {
                normal_force_ratio: p.stator.normal_force_ratio as f32,
                tangential_scale: p.stator.tangential_scale as f32,
                mu: p.friction.mu_dynamic as f32,
            },
        }),
        generation: 0,
    }
}

/// The table's speed (mm/s) at drive `volts` against `load_n`: where its thrust falls to the
/// load, by bisection over the foot's speed range (the thrust falls as the speed rises).
fn table_speed_mm_s(table: &ModelTable, foot_mm_s: f64, volts: f64, load_n: f64) -> f64 {
    let (mut lo, mut hi) = (-foot_mm_s, foot_mm_s);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if f64::from(table.thrust_n(volts as f32, mid as f32)) > load_n {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// Per drive in `volts`: the worst thrust error of the table in shares of the f64 model's stall
/// force at full drive (where the f64 carriage slides: on a sticking plateau many loads share one
/// speed and the thrust at that speed is not one number), and the worst speed error in shares of
/// the f64 no-load speed at full drive, over loads 0, 35, 70 % of the stall force at that drive.
fn errors(p: &Params, table: &ModelTable, op: OperatingPoint, volts: &[f64]) -> Vec<(f64, f64, f64, bool)> {
    let full = ContactModel::new(p, op);
    let (full_stall, no_load_mm_s) = (full.stall_force_n(), full.no_load_speed_m_s() * 1e3);
    let foot_mm_s_per_v = f64::from(table.request().per_volt.foot_speed_mm_s_per_v.to_num::<f32>());
    volts
        .iter()
        .map(|&v| {
            let model = ContactModel::new(p, OperatingPoint { voltage_v: v, ..op });
            let stall = model.stall_force_n().max(0.0);
            let (mut thrust_err, mut speed_err) = (0.0f64, 0.0f64);
            for share in [0.0, 0.35, 0.7] {
                let load = share * stall;
                let speed_mm_s = model.speed_at_load_m_s(load).unwrap_or(f64::NAN) * 1e3;
                // Where the f64 carriage sticks, many loads share the speed 0: neither the thrust
                // at that speed nor a speed off the table's (V, φp) grid, which cannot hold a
                // vertical step at v = 0, is one number to compare.
                if speed_mm_s.abs() > 0.01 * no_load_mm_s || speed_mm_s.is_nan() {
                    let thrust = f64::from(table.thrust_n(v as f32, speed_mm_s as f32));
                    thrust_err = thrust_err.max((thrust - load).abs() / full_stall);
                    let table_speed = table_speed_mm_s(table, foot_mm_s_per_v * v, v, load);
                    speed_err = speed_err.max((table_speed - speed_mm_s).abs() / no_load_mm_s);
                }
            }
            (v, thrust_err, speed_err, unsettled_between(p, table, op, v))
        })
        .collect()
}

/// Whether a grid row either side of `volts` is one whose normal motion the core refuses to
/// settle (a bouncing foot's subharmonic or chaos): the table bridges such rows.
fn unsettled_between(p: &Params, table: &ModelTable, op: OperatingPoint, volts: f64) -> bool {
    let r = table.request();
    let Some(c) = r.contact else { return false };
    let step = 100.0 / (VOLT_POINTS - 1) as f64;
    let rows = [(volts / step).floor(), (volts / step).ceil()];
    rows.iter().any(|&j| {
        let v = (j * step) as f32;
        let pt = c.motor.point(&c.calibration, op.preload_n as f32, v, r.frequency_hz, r.moving_mass_kg);
        j > 0.0 && contact_force(&pt.stator, &pt.drive).is_err()
    }) && p.slider.mass_kg > 0.0
}

#[test]
fn the_cores_contact_table_follows_the_f64_contact_model() {
    let base = Params::prototype_sourced();
    let points: Vec<(f64, f64, f64)> = [0.1, 1.0, 50.0]
        .iter()
        .flat_map(|&m| {
            [5.0, 16.0].iter().flat_map(move |&f0| [1500.0, 2200.0].iter().map(move |&hz| (m, f0, hz)))
        })
        .collect();
    let results: Vec<_> = points
        .par_iter()
        .map(|&(mass_kg, preload_n, frequency_hz)| {
            let mut p = base.clone();
            p.slider.mass_kg = mass_kg;
            let table = ModelTable::build(&contact_request(&p, mass_kg, preload_n, frequency_hz));
            let op = OperatingPoint { preload_n, voltage_v: 100.0, frequency_hz };
            ((mass_kg, preload_n, frequency_hz), errors(&p, &table, op, &[40.0, 70.0, 100.0]))
        })
        .collect();
    // Rows that settle: the table's interpolation of the core's own model. Rows the core
    // refuses: bridged by the rows either side, against the f64 model's average over the chaos.
    let mut worst = [(0.0f64, (0.0, 0.0, 0.0), 0.0); 4];
    for (at, errs) in &results {
        for &(v, t, s, bridged) in errs {
            eprintln!(
                "{at:?} {v} V: thrust {:.2} % of stall, speed {:.2} % of no-load{}",
                t * 100.0,
                s * 100.0,
                if bridged { " (bridged rows)" } else { "" }
            );
            let base = if bridged { 2 } else { 0 };
            for (k, e) in [(base, t), (base + 1, s)] {
                if e > worst[k].0 || e.is_nan() {
                    worst[k] = (e, *at, v);
                }
            }
        }
    }
    for (k, name) in
        ["thrust, settled", "speed, settled", "thrust, bridged", "speed, bridged"].iter().enumerate()
    {
        eprintln!("worst {name}: {:.2} % at {:?}, {} V", worst[k].0 * 100.0, worst[k].1, worst[k].2);
    }
    // Measured when written: settled rows 6.15 % of stall (0.1 kg, 16 N, 1.5 kHz, 70 V, a
    // carriage just past sticking: its speed within 1.85 %) and 3.10 % of the no-load speed
    // (0.1 kg, 16 N, 2.2 kHz, 100 V); bridged rows 17.6 % and 12.6 %. The goal is 1 %
    // everywhere (docs/simulator.md says where it is not met and why).
    assert!(
        worst[0].0 <= 0.065,
        "settled thrust {:.2} % at {:?} {} V",
        worst[0].0 * 100.0,
        worst[0].1,
        worst[0].2
    );
    assert!(
        worst[1].0 <= 0.035,
        "settled speed {:.2} % at {:?} {} V",
        worst[1].0 * 100.0,
        worst[1].1,
        worst[1].2
    );
    assert!(
        worst[2].0 <= 0.2,
        "bridged thrust {:.2} % at {:?} {} V",
        worst[2].0 * 100.0,
        worst[2].1,
        worst[2].2
    );
    assert!(
        worst[3].0 <= 0.15,
        "bridged speed {:.2} % at {:?} {} V",
        worst[3].0 * 100.0,
        worst[3].1,
        worst[3].2
    );
}
