//! Steady-state thrust model that knows the moving mass (physics.md §5: "the model must then
//! include the carriage's inertia").
//!
//! The constant-speed model (eq. 19) averages the friction force for a slider whose speed does not
//! change within a drive period. A light carriage does change speed: each contact arc accelerates
//! it by ≈ μ·kc·Yc/(M·ω), comparable to the mean speed below about a kilogram, and it may stick to
//! the foot and follow it backwards. Here the slider's motion over one period is solved instead:
//! the same harmonic foot (eqs. 8–9), contact force (eq. 15) and Coulomb friction with εc (eq. 16),
//! with `M·v̇ = F_friction − F_load`, sticking whenever the friction needed to move with the foot
//! is within μ·Fc. The periodic solution `v(T) = v(0)` is found by regula falsi on `v(0)`: the
//! period map of a first-order flow is monotone, so `v(T) − v(0)` falls through zero once. Its
//! mean speed tends to the constant-speed model's as `M → ∞` (tested).

use crate::motor::params::Params;
use crate::motor::roots::{falling_root, stall_load_n};
use crate::motor::steady::{OperatingPoint, ThrustModel};
use std::f64::consts::{PI, TAU};

/// Steps per drive period of the orbit integration (0.5° each).
const STEPS: usize = 720;

/// The slider's periodic motion at one load.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Orbit {
    /// Mean slider speed over the period (m/s, along the drive direction).
    pub mean_speed_m_s: f64,
    /// Peak-to-peak speed ripple within the period (m/s).
    pub ripple_m_s: f64,
    /// Share of the period in which the slider sticks to the foot.
    pub stick_fraction: f64,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct InertialModel {
    pub base: ThrustModel,
    pub mass_kg: f64,
    pub frequency_hz: f64,
}

impl InertialModel {
    /// The model at an operating point with the file's moving mass (`slider.mass_kg`).
    pub fn new(p: &Params, op: OperatingPoint) -> Self {
        InertialModel {
            base: ThrustModel::new(p, op),
            mass_kg: p.slider.mass_kg,
            frequency_hz: op.frequency_hz,
        }
    }

    /// Integrates one period from `v0` (φ from −π, the bottom of the ellipse); returns the end
    /// speed, the mean speed, the speed range and the stick count.
    fn run_period(&self, v0: f64, load_n: f64) -> (f64, f64, f64, usize) {
        let m = &self.base;
        let h = 1.0 / (self.frequency_hz * STEPS as f64);
        let dphi = TAU / STEPS as f64;
        let mass = self.mass_kg;
        let mut v = v0;
        let (mut sum, mut lo, mut hi, mut stuck) = (0.0, v0, v0, 0usize);
        for i in 0..STEPS {
            // Contact force at the middle of the step, foot speed at its end (velocity-level law,
            // as in the plant: the friction needed to move with the foot at the end of the step).
            let phi_mid = -PI + (i as f64 + 0.5) * dphi;
            let phi_end = -PI + (i as f64 + 1.0) * dphi;
            let fc = m.contact_force_n(phi_mid);
            let foot = m.foot_speed_m_s * phi_end.cos();
            let v_old = v;
            if fc > 0.0 {
                let need = mass * (foot - v_old) / h + load_n;
                if need.abs() <= m.mu * fc {
                    v = foot;
                    stuck += 1;
                } else {
                    // Sliding: μ·Fc in the direction of the need, εc's part implicit.
                    let k = m.viscous_n_s_per_m * h / mass;
                    v = (v_old + h * (m.mu * fc * need.signum() - load_n) / mass + k * foot) / (1.0 + k);
                }
            } else {
                v = v_old - h * load_n / mass;
            }
            sum += 0.5 * (v_old + v);
            lo = lo.min(v);
            hi = hi.max(v);
        }
        (v, sum / STEPS as f64, hi - lo, stuck)
    }

    /// The periodic motion under a constant load opposing the drive direction; `None` when no
    /// periodic motion exists (the load overruns even the braking of a slider pushed backwards).
    pub fn orbit(&self, load_n: f64) -> Option<Orbit> {
        let w = self.base.foot_speed_m_s.max(1e-9);
        let excess = |v0: f64| self.run_period(v0, load_n).0 - v0;
        let (mut lo, mut hi) = (-2.0 * w, 2.0 * w);
        // Widen until v(T) − v(0) changes sign: positive below the orbit, negative above.
        let mut tries = 0;
        while excess(lo) <= 0.0 {
            lo *= 2.0;
            tries += 1;
            if tries > 12 {
                return None;
            }
        }
        while excess(hi) >= 0.0 {
            hi *= 2.0;
            tries += 1;
            if tries > 24 {
                return None;
            }
        }
        // Regula falsi on the decreasing excess, to 1e-7 of the bracket (≈ 1e-7 of the foot's
        // peak speed): far below any speed the plant resolves. The excess is nearly linear in
        // v(0) for a heavy slider, so this takes a handful of periods where bisection takes forty.
        let root = falling_root(excess, lo, hi, 1e-7);
        let (_, mean, ripple, stuck) = self.run_period(root, load_n);
        Some(Orbit { mean_speed_m_s: mean, ripple_m_s: ripple, stick_fraction: stuck as f64 / STEPS as f64 })
    }

    /// Mean speed at a load; `None` as in [`Self::orbit`].
    pub fn speed_at_load_m_s(&self, load_n: f64) -> Option<f64> {
        self.orbit(load_n).map(|o| o.mean_speed_m_s)
    }

    pub fn no_load_speed_m_s(&self) -> f64 {
        self.speed_at_load_m_s(0.0).unwrap_or(0.0)
    }

    /// The load at which the mean speed falls to zero, by bisection between 0 and twice the
    /// constant-speed model's stall force, to 1e-4 of it.
    pub fn stall_force_n(&self) -> f64 {
        let guess = self.base.stall_force_n().max(1e-9);
        let forward = |load: f64| self.speed_at_load_m_s(load).is_some_and(|v| v > 0.0);
        stall_load_n(forward, 2.0 * guess, 1e-4 * guess)
    }
}
