//! One drive period of the time-domain plant, sample by sample: what the foot does, what the
//! contact carries and how the slider answers. The evidence for what a light carriage does
//! differently from a heavy one (README, "Light carriages").

use crate::motor::params::Params;
use crate::motor::plant::{ExternalLoad, Plant, QuadratureSine};
use crate::motor::steady::OperatingPoint;
use serde::Serialize;

/// One sample of the period.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct PeriodSample {
    /// Drive phase of channel 1 (deg, 0–360).
    pub phase_deg: f64,
    /// Foot normal position relative to the slider surface (µm, + = pressed in).
    pub foot_normal_um: f64,
    /// Foot tangential position relative to its period mean (µm, + = drive direction).
    pub foot_tangential_um: f64,
    pub foot_speed_mm_s: f64,
    pub contact_force_n: f64,
    /// Friction force on the slider (N, + = drive direction).
    pub friction_force_n: f64,
    pub slider_speed_mm_s: f64,
    /// Slider position relative to the start of the period (µm).
    pub slider_position_um: f64,
}

#[derive(Debug, Clone, Serialize)]
pub struct PeriodTrace {
    pub slider_mass_kg: f64,
    pub preload_n: f64,
    pub voltage_v: f64,
    pub frequency_hz: f64,
    pub load_n: f64,
    /// Mean slider speed over the settled periods before the traced one (mm/s).
    pub mean_speed_mm_s: f64,
    /// Share of the period with the foot in contact.
    pub contact_fraction: f64,
    /// Share of the contact time in which the slider moves with the foot (stick).
    pub stick_fraction_of_contact: f64,
    /// Slider displacement over the traced period (µm).
    pub advance_per_period_um: f64,
    /// Phase of the contact force's centroid (deg): where in the period the foot presses.
    pub contact_centre_deg: f64,
    /// Phase of the foot's peak forward speed (deg): where the model centres the contact.
    pub foot_peak_speed_deg: f64,
    pub samples: Vec<PeriodSample>,
}

/// Runs the plant at one drive point until it has settled (≥ 60 ms and ≥ 40 periods), then
/// records one period, `samples` points evenly spread.
pub fn one_period(p: &Params, op: OperatingPoint, load_n: f64, samples: usize) -> PeriodTrace {
    let mut plant = Plant::new(p, op.preload_n);
    plant.load = ExternalLoad::opposing(load_n, 1);
    let mut drive = QuadratureSine {
        voltage_v: op.voltage_v,
        frequency_hz: op.frequency_hz,
        direction: 1,
        mid_v: p.amplifier_mid_v(),
        ramp_s: 0.01,
    };
    let period_s = 1.0 / op.frequency_hz;
    // Settle on a whole number of periods so the trace starts at phase 0.
    let settle_periods = (0.06 / period_s).ceil().max(40.0);
    let measure_periods = (0.02 / period_s).ceil().max(10.0);
    plant.run(&mut drive, (settle_periods - measure_periods) * period_s);
    let x0 = plant.slider_position_m();
    let t0 = plant.time_s();
    plant.run(&mut drive, measure_periods * period_s);
    let mean_speed_mm_s = (plant.slider_position_m() - x0) / (plant.time_s() - t0) * 1e3;

    let dt = plant.step_s();
    let steps = (period_s / dt).round() as usize;
    let every = (steps / samples.max(2)).max(1);
    let start_x = plant.slider_position_m();
    let mut foot_x = 0.0;
    let mut raw = Vec::with_capacity(steps / every + 1);
    let (mut contact_steps, mut stick_steps) = (0usize, 0usize);
    // Stick: slider and foot move together to within 1 % of the foot's peak speed.
    let stick_band_m_s = 0.01
        * crate::motor::steady::amplitudes(p, op.voltage_v, op.frequency_hz).xc_m
        * std::f64::consts::TAU
        * op.frequency_hz;
    for i in 0..steps {
        plant.step(&mut drive);
        foot_x += plant.foot_speed_m_s() * dt;
        let in_contact = plant.contact_force_n() > 0.0;
        if in_contact {
            contact_steps += 1;
            if (plant.slider_velocity_m_s() - plant.foot_speed_m_s()).abs() <= stick_band_m_s {
                stick_steps += 1;
            }
        }
        if i % every == 0 {
            // Phase at the end of this step, exact in whole steps.
            let phase = (i + 1) as f64 / steps as f64 * 360.0;
            raw.push(PeriodSample {
                phase_deg: phase,
                foot_normal_um: plant.foot_normal_m() * 1e6,
                foot_tangential_um: foot_x * 1e6,
                foot_speed_mm_s: plant.foot_speed_m_s() * 1e3,
                contact_force_n: plant.contact_force_n(),
                friction_force_n: plant.friction_force_n(),
                slider_speed_mm_s: plant.slider_velocity_m_s() * 1e3,
                slider_position_um: (plant.slider_position_m() - start_x) * 1e6,
            });
        }
    }
    // Tangential position about its mean, so the ellipse is centred.
    let mean_x = raw.iter().map(|s| s.foot_tangential_um).sum::<f64>() / raw.len().max(1) as f64;
    for s in &mut raw {
        s.foot_tangential_um -= mean_x;
    }
    // Circular means, so a contact arc across 0° is not split.
    let circular = |weight: &dyn Fn(&PeriodSample) -> f64| {
        let (mut c, mut s) = (0.0, 0.0);
        for x in &raw {
            let (sin, cos) = x.phase_deg.to_radians().sin_cos();
            c += weight(x) * cos;
            s += weight(x) * sin;
        }
        s.atan2(c).to_degrees().rem_euclid(360.0)
    };
    let contact_centre_deg = circular(&|x| x.contact_force_n);
    let foot_peak_speed_deg = circular(&|x| x.foot_speed_mm_s.max(0.0).powi(4));
    PeriodTrace {
        contact_centre_deg,
        foot_peak_speed_deg,
        slider_mass_kg: p.slider.mass_kg,
        preload_n: op.preload_n,
        voltage_v: op.voltage_v,
        frequency_hz: op.frequency_hz,
        load_n,
        mean_speed_mm_s,
        contact_fraction: contact_steps as f64 / steps.max(1) as f64,
        stick_fraction_of_contact: stick_steps as f64 / contact_steps.max(1) as f64,
        advance_per_period_um: (plant.slider_position_m() - start_x) * 1e6,
        samples: raw,
    }
}
