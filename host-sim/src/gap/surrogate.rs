//! The pieces of the gap workflow's contact base that the fits read (`fit.rs`) and the anchoring
//! writes (`base.rs`): the shared normal motions, an anchor's per-row differences and slopes,
//! and the closed form's view of a parameter set. Knows nothing of the fits.

use crate::motor::effects::{model_speed_m_s, Condition};
use crate::motor::params::{Params, SteadyModel};
use crate::motor::plant::contact_spring;
use crate::motor::steady::OperatingPoint;
use crate::motor::steady_contact::{ContactModel, ContactProfile, OrbitStart};
use std::collections::HashMap;
use std::sync::{Arc, Mutex};

/// The orbits' tolerance in the workflow (share of the foot's peak speed, see
/// `steady_contact::ROOT_TOLERANCE`): 1e-5, a hundredth of the lowest measurement noise seen
/// (0.2 % of the speed, the simulated board) and far below the 5 % steps of the fits' slopes.
/// Against the model's own 1e-6 a search takes about a seventh fewer periods. At 1e-4 (a
/// quarter fewer) the fits' paths on the 0.3 kg carriage's clean set named a 21 kHz amplifier
/// pole.
pub const ORBIT_TOLERANCE: f64 = 1e-5;

/// Normal motions already solved, by (preload, drive voltage after the drive gain, frequency,
/// normal force ratio, `kc`).
#[derive(Debug, Default)]
pub struct ProfileCache {
    map: Mutex<HashMap<[u64; 5], Arc<ContactProfile>>>,
}

impl ProfileCache {
    fn key(p: &Params, c: &Condition) -> [u64; 5] {
        let voltage_v = c.voltage_v * p.effects.drive_gain(c.frequency_hz);
        let (kc, _) = contact_spring(p, c.preload_n);
        [c.preload_n, voltage_v, c.frequency_hz, p.stator.normal_force_ratio, kc].map(f64::to_bits)
    }

    fn profile(&self, p: &Params, c: &Condition) -> Arc<ContactProfile> {
        let key = Self::key(p, c);
        if let Some(found) = self.map.lock().ok().and_then(|m| m.get(&key).cloned()) {
            return found;
        }
        let op =
            OperatingPoint { preload_n: c.preload_n, voltage_v: c.voltage_v, frequency_hz: c.frequency_hz };
        let solved = Arc::new(ContactProfile::new(p, op));
        match self.map.lock() {
            Ok(mut m) => m.entry(key).or_insert(solved).clone(),
            Err(_) => solved,
        }
    }

    fn model(&self, p: &Params, c: &Condition) -> ContactModel {
        ContactModel::with_profile(p, self.profile(p, c), c.direction).with_root_tolerance(ORBIT_TOLERANCE)
    }

    /// The speed after one secant step from `hint` (`ContactModel::speed_for_slope`: for the
    /// fits' slopes), else after the full search near it.
    pub fn speed_for_slope(&self, p: &Params, c: &Condition, hint: Option<OrbitStart>) -> f64 {
        self.model(p, c).speed_for_slope(c.load_n, hint).unwrap_or_else(|| closed_speed_m_s(p, c))
    }

    /// The contact model's steady speed along the commanded sense (m/s), the closed form's where
    /// the carriage has no periodic motion within reach (a load far past the stall), with the
    /// orbit searched first near `hint` (where the same row's orbit starts at nearby
    /// parameters); returns the speed and where the orbit starts. The hint only shortens the
    /// search: the orbit is the same to its tolerance.
    pub fn speed_near(
        &self,
        p: &Params,
        c: &Condition,
        hint: Option<OrbitStart>,
    ) -> (f64, Option<OrbitStart>) {
        match self.model(p, c).orbit_near(c.load_n, hint) {
            Some((orbit, start)) => (orbit.mean_speed_m_s, Some(start)),
            None => (closed_speed_m_s(p, c), None),
        }
    }
}

/// The contact base of a model: the shared normal motions and, at the anchor, the contact model's
/// difference from the closed form per row with its derivatives.
#[derive(Debug, Clone)]
pub struct Anchor {
    pub cache: Arc<ProfileCache>,
    /// The parameters the anchor was taken at (a prefix of the model's: a candidate effect's
    /// parameters are appended after them).
    pub x: Arc<Vec<f64>>,
    /// `v_contact − v_closed` at the anchor, per data row (m/s).
    pub delta_m_s: Arc<Vec<f64>>,
    /// `∂(v_contact − v_closed)/∂x_k` at the anchor, row-major per data row.
    pub slope: Arc<Vec<Vec<f64>>>,
    /// Where each row's orbit starts at the anchor (None: no orbit): where this model's next
    /// evaluations begin their search. Kept per anchor, not shared between models, so that a
    /// fit's path does not depend on what other fits ran at the same time.
    pub starts: Arc<Vec<Option<OrbitStart>>>,
}

impl Anchor {
    /// The surrogate's correction of row `i` at parameters `x`: first order about the anchor.
    pub fn correction_m_s(&self, i: usize, x: &[f64]) -> f64 {
        let d = self.delta_m_s.get(i).copied().unwrap_or(0.0);
        let Some(g) = self.slope.get(i) else { return d };
        d + g.iter().zip(x.iter().zip(self.x.iter())).map(|(g, (x, a))| g * (x - a)).sum::<f64>()
    }
}

/// A parameter set as the closed-form part of the surrogate sees it: without `slider_inertia`,
/// whose carriage the contact model already has.
pub fn closed_params(p: &Params) -> Params {
    let mut q = p.clone();
    q.effects.slider_inertia = None;
    q
}

fn closed_speed_m_s(p: &Params, c: &Condition) -> f64 {
    if p.effects.slider_inertia.is_some() {
        model_speed_m_s(&closed_params(p), c)
    } else {
        model_speed_m_s(p, c)
    }
}

/// Whether a parameter file asks for the contact model as its base.
pub fn wants_contact(p: &Params) -> bool {
    p.model.steady == SteadyModel::Contact
}

/// A new anchor (all differences zero) for `rows` measured rows on a base that selects the
/// contact model, else `None`.
pub fn new_anchor(p: &Params, rows: usize) -> Option<Anchor> {
    wants_contact(p).then(|| Anchor {
        cache: Arc::new(ProfileCache::default()),
        x: Arc::new(Vec::new()),
        delta_m_s: Arc::new(vec![0.0; rows]),
        slope: Arc::new(Vec::new()),
        starts: Arc::new(Vec::new()),
    })
}
