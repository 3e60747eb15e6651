//! The steady-state models against the time-domain plant over issue 28's grid: carriages ×
//! preloads × drive frequencies × loads, each model's speed against the plant's, in % of the
//! plant's no-load speed at that point. Beside the f64 models, the firmware's: the full-drive
//! speed table the control core builds (fixed point and f32) for a controller told the carriage's
//! mass, pinned to the point's frequency, at the preload its force cell reads. `host-sim model-grid` prints it; the docs' table and
//! figure (`readme-figures`) and the tests hold it.

use crate::harness::sil::hardware;
use crate::motor::params::Params;
use crate::motor::plant::steady_speed_m_s;
use crate::motor::steady::{OperatingPoint, ThrustModel};
use crate::motor::steady_contact::ContactModel;
use crate::motor::steady_inertia::InertialModel;
use piezo_drive::controller::model_cache::ModelTable;
use piezo_drive::controller::{Controller, Inputs};
use piezo_drive::defaults::controller_config_for;
use rayon::prelude::*;
use serde::Serialize;

pub const MASSES_KG: [f64; 5] = [0.1, 0.3, 1.0, 5.0, 50.0];
pub const PRELOADS_N: [f64; 4] = [5.0, 10.0, 16.0, 18.0];
pub const FREQUENCIES_HZ: [f64; 2] = [1500.0, 2200.0];
/// Loads as shares of the stall force of the model with the contact's timing.
pub const LOAD_SHARES: [f64; 3] = [0.0, 0.35, 0.7];

/// One grid point: speeds in mm/s (NaN where a model has no periodic motion).
#[derive(Debug, Clone, Copy, Serialize)]
pub struct GridPoint {
    pub slider_mass_kg: f64,
    pub preload_n: f64,
    pub frequency_hz: f64,
    pub load_n: f64,
    pub plant_mm_s: f64,
    pub plant_no_load_mm_s: f64,
    pub constant_speed_mm_s: f64,
    pub inertia_mm_s: f64,
    pub contact_mm_s: f64,
    /// The firmware's model table (what its feedforward uses), NaN without one.
    pub firmware_mm_s: f64,
}

impl GridPoint {
    /// A model's error in % of the plant's no-load speed here.
    pub fn error_percent(&self, model_mm_s: f64) -> f64 {
        100.0 * (model_mm_s - self.plant_mm_s) / self.plant_no_load_mm_s.abs().max(1e-9)
    }
}

/// The grid's operating points: (carriage kg, preload N, frequency Hz), every combination.
pub fn operating_points() -> Vec<(f64, f64, f64)> {
    MASSES_KG
        .iter()
        .flat_map(|&m| {
            PRELOADS_N.iter().flat_map(move |&f0| FREQUENCIES_HZ.iter().map(move |&hz| (m, f0, hz)))
        })
        .collect()
}

/// The file `p` with its carriage mass replaced by the point's, and the point's operating point
/// at the grid's 100 V: a grid point as every comparison over it builds its models.
pub fn at_point(p: &Params, (mass_kg, preload_n, frequency_hz): (f64, f64, f64)) -> (Params, OperatingPoint) {
    let mut q = p.clone();
    q.slider.mass_kg = mass_kg;
    (q, OperatingPoint { preload_n, voltage_v: 100.0, frequency_hz })
}

/// The largest difference between two speed laws (m/s against load N) over [`LOAD_SHARES`] of
/// `stall_n`, as a share of `no_load_m_s` (NaN where either has no speed).
pub fn worst_over_loads(
    stall_n: f64,
    no_load_m_s: f64,
    a: impl Fn(f64) -> f64,
    b: impl Fn(f64) -> f64,
) -> f64 {
    LOAD_SHARES
        .iter()
        .map(|share| {
            let load_n = share * stall_n;
            (a(load_n) - b(load_n)).abs() / no_load_m_s.abs()
        })
        .fold(0.0, |w, d| if d.is_nan() || w.is_nan() { f64::NAN } else { w.max(d) })
}

/// The grid at 100 V for the file `p` (its carriage mass replaced by each of [`MASSES_KG`]).
pub fn compute(p: &Params) -> Vec<GridPoint> {
    operating_points()
        .par_iter()
        .flat_map_iter(|&(mass_kg, preload_n, frequency_hz)| {
            let (q, op) = at_point(p, (mass_kg, preload_n, frequency_hz));
            let contact = ContactModel::new(&q, op);
            let inertial = InertialModel::new(&q, op);
            let constant = ThrustModel::new(&q, op);
            let stall = contact.stall_force_n();
            let firmware = firmware_table(&q, preload_n, frequency_hz);
            let plant = |load: f64| steady_speed_m_s(&q, preload_n, 100.0, frequency_hz, 1, load) * 1e3;
            let no_load = plant(0.0);
            LOAD_SHARES
                .iter()
                .map(|share| {
                    let load_n = share * stall;
                    let mm_s = |v: Option<f64>| v.map_or(f64::NAN, |v| v * 1e3);
                    GridPoint {
                        slider_mass_kg: mass_kg,
                        preload_n,
                        frequency_hz,
                        load_n,
                        plant_mm_s: if load_n == 0.0 { no_load } else { plant(load_n) },
                        plant_no_load_mm_s: no_load,
                        constant_speed_mm_s: mm_s(constant.speed_at_load_m_s(load_n)),
                        inertia_mm_s: mm_s(inertial.speed_at_load_m_s(load_n)),
                        contact_mm_s: mm_s(contact.speed_at_load_m_s(load_n)),
                        firmware_mm_s: firmware
                            .as_ref()
                            .map_or(f64::NAN, |t| f64::from(t.speed_at_load_mm_s(load_n as f32))),
                    }
                })
                .collect::<Vec<_>>()
        })
        .collect()
}

/// The model table the firmware's control core builds for the file `p` (its carriage told as the
/// moving mass, the drive frequency pinned at `frequency_hz`) once its force cell reads
/// `preload_n`; None when the controller asks for none.
fn firmware_table(p: &Params, preload_n: f64, frequency_hz: f64) -> Option<ModelTable> {
    let hw = hardware(p);
    let mut cfg = controller_config_for(&hw);
    cfg.moving_mass_kg = p.slider.mass_kg as f32;
    (cfg.drive_freq_hz, cfg.drive_freq_min_hz) = (frequency_hz as f32, frequency_hz as f32);
    let mut ctl = Controller::new(cfg).ok()?;
    let word =
        (preload_n / f64::from(cfg.preload.newton_per_word)).round() + f64::from(cfg.preload.zero_word);
    ctl.step(&Inputs { preload_word: word as u16, ..Default::default() });
    Some(ModelTable::build(&ctl.model_request()?))
}

/// Worst absolute error (% of the plant's no-load speed) of each model per carriage:
/// `(mass, constant-speed, inertial, contact, firmware)`; a model with no periodic motion where the plant
/// has one counts as 100 %.
pub fn worst_per_mass(grid: &[GridPoint]) -> Vec<(f64, f64, f64, f64, f64)> {
    MASSES_KG
        .iter()
        .map(|&m| {
            let worst = |pick: fn(&GridPoint) -> f64| {
                grid.iter()
                    .filter(|g| g.slider_mass_kg == m)
                    .map(|g| {
                        let e = g.error_percent(pick(g)).abs();
                        if e.is_finite() {
                            e
                        } else {
                            100.0
                        }
                    })
                    .fold(0.0, f64::max)
            };
            (
                m,
                worst(|g| g.constant_speed_mm_s),
                worst(|g| g.inertia_mm_s),
                worst(|g| g.contact_mm_s),
                worst(|g| g.firmware_mm_s),
            )
        })
        .collect()
}
