//! Figures measured on the time-domain plant the way one would on the bench: free amplitude,
//! share of the period in contact, stall force. `paper` prints them beside the steady-state
//! model's values.

use crate::motor::params::Params;
use crate::motor::plant::{steady_speed_m_s, Plant, QuadratureSine};
use crate::motor::steady::OperatingPoint;

fn drive(p: &Params, voltage_v: f64, frequency_hz: f64) -> QuadratureSine {
    QuadratureSine { voltage_v, frequency_hz, direction: 1, mid_v: p.amplifier_mid_v(), ramp_s: 0.005 }
}

/// Whole drive periods covering at least `seconds`.
fn periods_s(frequency_hz: f64, seconds: f64) -> f64 {
    (seconds * frequency_hz).ceil() / frequency_hz
}

/// Non-contact normal amplitude of the foot (m): the slider pulled 20 µm away, half the foot's
/// peak-to-peak normal excursion over the last 10 ms after 60 ms of settling (paper Fig. 8).
pub fn free_amplitude_m(p: &Params, voltage_v: f64, frequency_hz: f64) -> f64 {
    let mut plant = Plant::new(p, 1.0);
    plant.lift_off(20e-6);
    let mut d = drive(p, voltage_v, frequency_hz);
    plant.run(&mut d, periods_s(frequency_hz, 0.06));
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    let steps = (periods_s(frequency_hz, 0.01) / plant.step_s()).round() as usize;
    for _ in 0..steps {
        plant.step(&mut d);
        lo = lo.min(plant.foot_normal_m());
        hi = hi.max(plant.foot_normal_m());
    }
    0.5 * (hi - lo)
}

/// Share of the drive period in which the foot touches the slider (0–1), slider held still,
/// over 20 ms after 60 ms of settling.
pub fn contact_fraction(p: &Params, op: OperatingPoint) -> f64 {
    let mut held = p.clone();
    // The normal dynamics do not depend on the slider; a heavy one keeps the run short.
    held.slider.mass_kg = 1e6;
    let mut plant = Plant::new(&held, op.preload_n);
    let mut d = drive(p, op.voltage_v, op.frequency_hz);
    plant.run(&mut d, periods_s(op.frequency_hz, 0.06));
    let steps = (periods_s(op.frequency_hz, 0.02) / plant.step_s()).round() as usize;
    let mut touching = 0usize;
    for _ in 0..steps {
        plant.step(&mut d);
        if plant.contact_force_n() > 0.0 {
            touching += 1;
        }
    }
    touching as f64 / steps.max(1) as f64
}

/// Lowest preload (N) at which the foot never leaves the slider (contact ≥ 99.9 % of the
/// period), searched between 1 and 60 N; `None` when contact stays intermittent up to 60 N.
pub fn full_contact_preload_n(p: &Params, voltage_v: f64, frequency_hz: f64) -> Option<f64> {
    let full =
        |f0: f64| contact_fraction(p, OperatingPoint { preload_n: f0, voltage_v, frequency_hz }) >= 0.999;
    let (mut lo, mut hi) = (1.0, 60.0);
    if !full(hi) {
        return None;
    }
    while hi - lo > 0.1 {
        let mid = 0.5 * (lo + hi);
        if full(mid) {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    Some(hi)
}

/// Stall force (N): the opposing load at which the plant's steady speed crosses zero, by
/// bisection to 1 % of `guess_n` between 0 and 2 × `guess_n` (the model's stall force).
pub fn stall_force_n(p: &Params, op: OperatingPoint, guess_n: f64) -> f64 {
    let speed = |load_n: f64| steady_speed_m_s(p, op.preload_n, op.voltage_v, op.frequency_hz, 1, load_n);
    let (mut lo, mut hi) = (0.0, 2.0 * guess_n);
    if speed(lo) <= 0.0 {
        return 0.0;
    }
    while hi - lo > 0.01 * guess_n {
        let mid = 0.5 * (lo + hi);
        if speed(mid) > 0.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}
