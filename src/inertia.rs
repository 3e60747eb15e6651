//! The steady-state model with the carriage's inertia, in the core (f32; host-sim's f64 model is
//! `host-sim/src/motor/steady_inertia.rs`, and the two are tested against each other).
//!
//! Eq. (19) averages the friction force for a slider whose speed does not change within a drive
//! period. A light carriage's speed does change: each contact arc accelerates it by about
//! μ·kc·Yc/(M·ω), comparable to the mean speed below a kilogram or so, and it sticks to the foot
//! and follows it backwards. So the slider's speed is solved over one period instead: the foot's
//! harmonic speed (eqs. 8–9), the contact force of eq. (15), Coulomb friction with εc (eq. 16),
//! `M·v̇ = F_friction − F_load`, sticking whenever the friction needed to move with the foot is
//! within μ·Fc. The periodic orbit `v(T) = v(0)` is found by regula falsi (Illinois) on `v(0)`:
//! the period map of this first-order flow is monotone, so `v(T) − v(0)` falls through zero once.
//!
//! Cost: [`STEPS`] steps per period and a handful of periods per orbit, a few tens of thousands
//! of instructions on the Cortex-M4: built off the tick, into the model table
//! ([`crate::controller::model_cache`]).

use crate::model::ThrustPoint;
use crate::trig::cos;
use crate::Fx;

/// Steps per drive period (2° each): against the f64 model's 720 the mean speed moves by at
/// most 1.4 % of the foot's peak speed (96 steps: 2.9 %), `host-sim/tests/fixed_model.rs`.
pub const STEPS: usize = 180;

/// Below this speed ripple per period, as a share of the foot's peak speed, the carriage is heavy
/// enough for the constant-speed model (eq. 19): at 1 % the two differ by well under 1 % of the
/// stall force, and the table is built without orbits.
pub const RIPPLE_SHARE_NEGLIGIBLE: f32 = 0.01;

/// One drive condition's contact force and foot speed over a period, ready for orbits.
#[derive(Debug, Clone, Copy)]
pub struct Orbits {
    /// Contact force at the middle of step i (N), φ from −π (the bottom of the ellipse).
    contact_n: [f32; STEPS],
    /// Foot speed at the end of step i (mm/s).
    foot_mm_s: [f32; STEPS],
    foot_peak_mm_s: f32,
    mu: f32,
    /// εc·h/M: the viscous term's share per step (implicit).
    viscous_per_step: f32,
    /// h/M in (mm/s) per N: speed change per step per newton.
    mm_s_per_n_step: f32,
    /// M/h in N per (mm/s): the force that changes the speed by 1 mm/s within a step.
    n_per_mm_s_step: f32,
}

impl Orbits {
    /// The drive condition of `point` at `frequency_hz` with a carriage of `mass_kg`.
    pub fn new(point: &ThrustPoint, frequency_hz: f32, mass_kg: f32) -> Self {
        let h_s = 1.0 / (frequency_hz.max(1.0) * STEPS as f32);
        let mass = mass_kg.max(1e-4);
        let kc_yc: f32 = point.kc_yc_n.to_num();
        let preload: f32 = point.preload_n.to_num();
        let full = point.full_contact();
        let cos_half: f32 = cos(point.contact_angle_rad / 2).to_num();
        let foot_peak: f32 = point.foot_speed_mm_s.to_num();
        let mut contact_n = [0.0f32; STEPS];
        let mut foot_mm_s = [0.0f32; STEPS];
        // φ of a step's middle and end as fractions of a turn from −π: cos(−π + x) = −cos(x).
        let step = Fx::from_num(core::f32::consts::TAU / STEPS as f32);
        for (i, (c, f)) in contact_n.iter_mut().zip(foot_mm_s.iter_mut()).enumerate() {
            let mid: f32 = -cos(step * i as i32 + step / 2).to_num::<f32>();
            let end: f32 = -cos(step * (i as i32 + 1)).to_num::<f32>();
            *c = if full { preload + kc_yc * mid } else { (kc_yc * (mid - cos_half)).max(0.0) };
            *f = foot_peak * end;
        }
        Orbits {
            contact_n,
            foot_mm_s,
            foot_peak_mm_s: foot_peak,
            mu: point.mu.to_num(),
            // εc in µN per mm/s = 1e-3 N·s/m; h/M in s/kg.
            viscous_per_step: point.viscous_un_per_mm_s.to_num::<f32>() * 1e-3 * h_s / mass,
            mm_s_per_n_step: h_s / mass * 1e3,
            n_per_mm_s_step: mass / h_s * 1e-3,
        }
    }

    /// Whether the carriage is light enough for its inertia to matter at this drive condition:
    /// the speed gain of one contact arc, μ·max(Fc)·T/M, against the foot's peak speed.
    pub fn inertia_matters(&self) -> bool {
        let peak = self.contact_n.iter().fold(0.0f32, |a, &b| a.max(b));
        let gain_mm_s = self.mu * peak * self.mm_s_per_n_step * STEPS as f32;
        gain_mm_s > RIPPLE_SHARE_NEGLIGIBLE * self.foot_peak_mm_s
    }

    /// One period from `v0_mm_s` under `load_n` (opposing the drive): the end speed and the
    /// mean speed (mm/s).
    fn period(&self, v0_mm_s: f32, load_n: f32) -> (f32, f32) {
        let mut v = v0_mm_s;
        let mut sum = 0.0f32;
        let k = self.viscous_per_step;
        for (&fc, &foot) in self.contact_n.iter().zip(self.foot_mm_s.iter()) {
            let before = v;
            if fc > 0.0 {
                let need = self.n_per_mm_s_step * (foot - before) + load_n;
                let grip = self.mu * fc;
                if need.abs() <= grip {
                    v = foot;
                } else {
                    let push = if need > 0.0 { grip } else { -grip };
                    v = (before + self.mm_s_per_n_step * (push - load_n) + k * foot) / (1.0 + k);
                }
            } else {
                v = before - self.mm_s_per_n_step * load_n;
            }
            sum += 0.5 * (before + v);
        }
        (v, sum / STEPS as f32)
    }

    /// Mean speed of the periodic motion under `load_n` opposing the drive (mm/s, along the
    /// drive); `None` when there is none within reach (a load far beyond what friction holds).
    pub fn mean_speed_mm_s(&self, load_n: f32) -> Option<f32> {
        let w = self.foot_peak_mm_s.max(1e-6);
        let excess = |v0: f32| self.period(v0, load_n).0 - v0;
        let (mut lo, mut hi) = (-2.0 * w, 2.0 * w);
        let (mut e_lo, mut e_hi) = (excess(lo), excess(hi));
        let mut widen = 0;
        while e_lo <= 0.0 || e_hi >= 0.0 {
            widen += 1;
            if widen > 8 || !(e_lo.is_finite() && e_hi.is_finite()) {
                return None;
            }
            if e_lo <= 0.0 {
                lo *= 2.0;
                e_lo = excess(lo);
            }
            if e_hi >= 0.0 {
                hi *= 2.0;
                e_hi = excess(hi);
            }
        }
        // Illinois: the excess is nearly linear in v(0) for a heavy carriage, so a few periods
        // do; 1e-4 of the foot's peak speed is far below what the encoder resolves.
        let tol = 1e-4 * w;
        let mut side = 0i8;
        let mut root = lo;
        for _ in 0..40 {
            let d = e_lo - e_hi;
            root = if d > 0.0 { lo + (hi - lo) * e_lo / d } else { 0.5 * (lo + hi) };
            let e = excess(root);
            if e > 0.0 {
                lo = root;
                e_lo = e;
                if side == 1 {
                    e_hi *= 0.5;
                }
                side = 1;
            } else {
                hi = root;
                e_hi = e;
                if side == -1 {
                    e_lo *= 0.5;
                }
                side = -1;
            }
            if hi - lo < tol || e.abs() < 1e-7 * w {
                break;
            }
        }
        Some(self.period(root, load_n).1)
    }
}
