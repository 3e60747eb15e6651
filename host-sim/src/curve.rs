//! Thrust–velocity characteristic: steady-state model and time-domain plant side by side.

use crate::check::ser;
use crate::motor::params::Params;
use crate::motor::plant::steady_speed_m_s;
use crate::motor::steady::{OperatingPoint, ThrustModel};
use crate::motor::steady_contact::ContactModel;
use crate::motor::steady_inertia::InertialModel;
use serde::Serialize;

/// JSON values are rounded to what they resolve: forces to 1e-4 N, speeds to 1 nm/s, angles to
/// 1 µrad.
#[derive(Debug, Clone, Serialize)]
pub struct CurvePoint {
    #[serde(serialize_with = "ser::newton")]
    pub load_n: f64,
    #[serde(serialize_with = "ser::mm_s")]
    pub speed_mm_s_model: f64,
    /// The model with the slider's inertia (`steady_inertia`); null where no periodic motion exists.
    #[serde(serialize_with = "ser::mm_s")]
    pub speed_mm_s_inertia: f64,
    /// The model with the contact's timing and the carriage's inertia (`steady_contact`): the
    /// steady-state model held to the plant (issue 28); null where no periodic motion exists.
    #[serde(serialize_with = "ser::mm_s")]
    pub speed_mm_s_contact: f64,
    #[serde(serialize_with = "ser::mm_s")]
    pub speed_mm_s_sim: f64,
}

#[derive(Debug, Clone, Serialize)]
pub struct Curve {
    #[serde(serialize_with = "ser::newton")]
    pub preload_n: f64,
    pub voltage_v: f64,
    pub frequency_hz: f64,
    pub direction: i8,
    #[serde(serialize_with = "ser::newton")]
    pub stall_force_n: f64,
    #[serde(serialize_with = "ser::mm_s")]
    pub no_load_speed_mm_s: f64,
    #[serde(serialize_with = "ser::rad")]
    pub contact_angle_rad: f64,
    pub full_contact: bool,
    #[serde(serialize_with = "ser::newton")]
    pub contact_force_amplitude_n: f64,
    #[serde(serialize_with = "ser::mm_s")]
    pub foot_peak_speed_mm_s: f64,
    /// Moving mass the plant and the inertial model ran with.
    pub slider_mass_kg: f64,
    /// Stall force and no-load speed of the model with the slider's inertia.
    #[serde(serialize_with = "ser::newton")]
    pub stall_force_inertia_n: f64,
    #[serde(serialize_with = "ser::mm_s")]
    pub no_load_speed_inertia_mm_s: f64,
    pub points: Vec<CurvePoint>,
    /// Dense model curve for plotting: (load N, speed mm/s).
    #[serde(skip)]
    pub model_line: Vec<(f64, f64)>,
    /// Dense curve of the model with inertia: (load N, speed mm/s).
    #[serde(skip)]
    pub inertia_line: Vec<(f64, f64)>,
}

/// Loads from 0 to `max_fraction` of stall in `points` steps; `progress` is told each finished point.
pub fn compute(
    p: &Params,
    op: OperatingPoint,
    direction: i8,
    points: usize,
    max_fraction: f64,
    mut progress: impl FnMut(usize, usize),
) -> Curve {
    let m = ThrustModel::new(p, op);
    let inertial = InertialModel::new(p, op);
    let contact = ContactModel::new(p, op);
    let stall = m.stall_force_n();
    let n = points.max(2);
    let mut pts = Vec::with_capacity(n);
    for i in 0..n {
        let load_n = stall * max_fraction * i as f64 / (n - 1) as f64;
        let model = m.speed_at_load_m_s(load_n).unwrap_or(f64::NAN) * 1e3;
        let inertia = inertial.speed_at_load_m_s(load_n).unwrap_or(f64::NAN) * 1e3;
        let with_contact = contact.speed_at_load_m_s(load_n).unwrap_or(f64::NAN) * 1e3;
        let sim = steady_speed_m_s(p, op.preload_n, op.voltage_v, op.frequency_hz, direction, load_n) * 1e3;
        pts.push(CurvePoint {
            load_n,
            speed_mm_s_model: model,
            speed_mm_s_inertia: inertia,
            speed_mm_s_contact: with_contact,
            speed_mm_s_sim: sim,
        });
        progress(i + 1, n);
    }
    let model_line = (0..=100)
        .map(|i| {
            let load = stall * i as f64 / 100.0;
            (load, m.speed_at_load_m_s(load).unwrap_or(0.0) * 1e3)
        })
        .collect();
    let inertia_line = (0..=40)
        .filter_map(|i| {
            let load = stall * i as f64 / 40.0;
            inertial.speed_at_load_m_s(load).map(|v| (load, v * 1e3))
        })
        .collect();
    Curve {
        preload_n: op.preload_n,
        voltage_v: op.voltage_v,
        frequency_hz: op.frequency_hz,
        direction,
        stall_force_n: stall,
        no_load_speed_mm_s: m.no_load_speed_m_s() * 1e3,
        contact_angle_rad: m.contact_angle_rad,
        full_contact: m.full_contact(),
        contact_force_amplitude_n: m.kc_yc_n,
        foot_peak_speed_mm_s: m.foot_speed_m_s * 1e3,
        slider_mass_kg: p.slider.mass_kg,
        stall_force_inertia_n: inertial.stall_force_n(),
        no_load_speed_inertia_mm_s: inertial.no_load_speed_m_s() * 1e3,
        points: pts,
        model_line,
        inertia_line,
    }
}
