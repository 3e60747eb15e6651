//! Effects the base model leaves out (physics.md §6), as modules of BOTH the time-domain plant and
//! the steady-state thrust model.
//!
//! Every effect has named parameters with their units in the name and reduces exactly to the base
//! model when its strength parameter is zero (or the section is absent). In a parameter file they
//! live in the optional `[effects.<name>]` sections; files without them load unchanged.
//!
//! | effect | plant | steady-state model |
//! |---|---|---|
//! | `rail_friction` | guide force `−c·sign(v) − b·v` on the slider | thrust balances `load + c·sign(v) + b·v` |
//! | `assembly_asymmetry` | tangential foot speed × `(1 + a·d)` for drive sense `d` | `ω·Xc` × `(1 + a·d)` |
//! | `preload_dependent_friction` | μ × `1/(1 + s·max(0, F0 − Fk))` | same factor on μ |
//! | `stribeck_friction` | μ(slip) = μ·(1 + r·exp(−(slip/vs)²)) in the Coulomb law | period average of the same law by Gauss–Legendre quadrature |
//! | `amplifier_rolloff` | one extra pole at `fc` on each stack voltage | voltage × `1/√(1 + (f/fc)²)` |
//! | `stator_resonance` | stroke + k·(resonator(stroke) − stroke), resonator at `fr`, ζ | voltage × `|1 + k·(H(jω) − 1)|` |
//! | `hertz_contact` | `kc × (F0/Fref)^n` | same `kc` in eq. (7) |
//! | `slider_inertia` | carriage mass `1/s` instead of `slider.mass_kg` | constant-speed speed + (mean speed of the periodic orbit of mass `1/s` − its `M → ∞` limit), [`inertia`] |
//!
//! `slider_inertia` and the file's `slider.mass_kg`: the base steady-state model has no mass (it
//! is the constant-speed model, `M = ∞`) while the base plant simulates `slider.mass_kg`; the
//! effect's mass `1/s` replaces it in the plant and enters the steady-state model, so with the
//! effect both sides simulate the same carriage, and at zero strength each is its own base.

pub mod config;
pub mod inertia;
pub use config::*;

use crate::motor::params::Params;
use crate::motor::roots::falling_root_from;
use crate::motor::steady::{OperatingPoint, ThrustModel};
use std::f64::consts::{PI, TAU};

/// One steady operating row: the drive, the load opposing the commanded motion, the drive sense.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Condition {
    pub preload_n: f64,
    pub voltage_v: f64,
    pub frequency_hz: f64,
    pub load_n: f64,
    pub direction: i8,
}

/// The steady-state model with effects at one condition.
#[derive(Debug, Clone, Copy)]
pub struct EffectModel {
    pub base: ThrustModel,
    pub stribeck_rise: f64,
    pub stribeck_speed_m_s: f64,
    pub rail_coulomb_n: f64,
    pub rail_viscous_n_s_per_m: f64,
    /// `slider_inertia`: 1/M (0: constant speed).
    pub inverse_mass_per_kg: f64,
    pub frequency_hz: f64,
}

impl EffectModel {
    pub fn new(p: &Params, c: &Condition) -> Self {
        let e = &p.effects;
        let hertz;
        let params = if e.hertz_contact.is_some_and(|h| h.hertz_exponent != 0.0) {
            let mut q = p.clone();
            q.contact.stiffness_n_per_m =
                e.contact_stiffness_n_per_m(p.contact.stiffness_n_per_m, c.preload_n);
            hertz = q;
            &hertz
        } else {
            p
        };
        let op = OperatingPoint {
            preload_n: c.preload_n,
            voltage_v: c.voltage_v * e.drive_gain(c.frequency_hz),
            frequency_hz: c.frequency_hz,
        };
        let mut base = ThrustModel::new(params, op);
        base.mu *= e.friction_factor(c.preload_n);
        base.foot_speed_m_s *= e.tangential_factor(c.direction);
        let (rise, vs) = match e.stribeck_friction {
            Some(s) => (s.stribeck_rise, s.stribeck_speed_m_s),
            None => (0.0, DEFAULT_STRIBECK_SPEED_M_S),
        };
        let (rc, rv) = match e.rail_friction {
            Some(r) => (r.rail_coulomb_n, r.rail_viscous_n_s_per_m),
            None => (0.0, 0.0),
        };
        EffectModel {
            base,
            stribeck_rise: rise,
            stribeck_speed_m_s: vs,
            rail_coulomb_n: rc,
            rail_viscous_n_s_per_m: rv,
            inverse_mass_per_kg: e.inverse_mass_per_kg(),
            frequency_hz: c.frequency_hz,
        }
    }

    /// Mean thrust of the foot on a slider at `v` (drive direction), with Stribeck if present.
    pub fn thrust_n(&self, speed_m_s: f64) -> f64 {
        if self.stribeck_rise == 0.0 {
            return self.base.thrust_n(speed_m_s);
        }
        // The drive half-angle once for both parts: its acos was a tenth of a Stribeck thrust.
        let phi_p = self.base.drive_half_angle(speed_m_s);
        let f = self.base.thrust_at_half_angle_n(speed_m_s, phi_p);
        f + self.stribeck_rise * self.base.mu * self.stribeck_integral(speed_m_s, phi_p)
    }

    /// (1/2π)∮ Fc(φ)·sign(slip)·exp(−(slip/vs)²) dφ over the contact arc, slip = ωX·cos φ − v;
    /// `phi_p` is the drive half-angle of `v`, where the slip changes sign.
    fn stribeck_integral(&self, v: f64, phi_p: f64) -> f64 {
        let m = &self.base;
        let wx = m.foot_speed_m_s;
        let half = if m.full_contact() { PI } else { 0.5 * m.contact_angle_rad };
        if half <= 0.0 {
            return 0.0;
        }
        let vs = self.stribeck_speed_m_s;
        let g = |phi: f64| {
            // One cosine per node for the slip and the contact force.
            let cos_phi = phi.cos();
            let slip = wx * cos_phi - v;
            let fc = m.contact_force_at_cos_n(cos_phi);
            fc * slip.signum() * (-(slip / vs).powi(2)).exp()
        };
        // Symmetric arc: twice the integral over [0, half], split where the slip changes sign.
        let total = if phi_p > 0.0 && phi_p < half {
            gauss_legendre(&g, 0.0, phi_p) + gauss_legendre(&g, phi_p, half)
        } else {
            gauss_legendre(&g, 0.0, half)
        };
        2.0 * total / TAU
    }

    /// Force the thrust must balance at `v`: the load plus the guide friction.
    fn resisting_n(&self, load_n: f64, v: f64, coulomb_sign: f64) -> f64 {
        load_n + self.rail_coulomb_n * coulomb_sign + self.rail_viscous_n_s_per_m * v
    }

    /// Steady (mean) speed along the commanded direction at `load_n`; 0 when stalled by the
    /// guide's Coulomb friction; negative when the load overruns the motor. With
    /// `slider_inertia`, the constant-speed speed plus the carriage's inertial correction.
    pub fn speed_at_load_m_s(&self, load_n: f64) -> f64 {
        self.speed_from_constant_m_s(load_n, self.constant_speed_at_load_m_s(load_n))
    }

    /// [`Self::speed_at_load_m_s`] from the constant-speed speed `v` at `load_n`.
    pub fn speed_from_constant_m_s(&self, load_n: f64, v: f64) -> f64 {
        if self.inverse_mass_per_kg == 0.0 || v == 0.0 {
            // v = 0: held by the guide's Coulomb friction (the orbit is not solved there).
            return v;
        }
        let resisting = self.resisting_n(load_n, v, v.signum());
        v + inertia::inertial_correction_m_s(
            &self.base,
            self.frequency_hz,
            self.inverse_mass_per_kg,
            resisting,
        )
    }

    /// [`Self::constant_speed_at_load_m_s`] found first within ±[`NEAR_SHARE`] of the foot's
    /// speed about `near` (the same load's speed at nearby parameters, e.g. a fit's Jacobian
    /// column): two thrusts bracket it and the root is refined to the same absolute tolerance as
    /// the full search, in a bracket ten thousand times narrower. Where they do not bracket it
    /// (or `near` is 0, the guide's stall band), the full search.
    pub fn constant_speed_near_m_s(&self, load_n: f64, near: f64) -> f64 {
        let wx = self.base.foot_speed_m_s.max(1e-12);
        let half = NEAR_SHARE * wx;
        let sense = near.signum();
        if near.abs() > half {
            let net = |v: f64| self.thrust_n(v) - self.resisting_n(load_n, v, sense);
            let (a, b) = (near - half, near + half);
            let net_a = net(a);
            if net_a > 0.0 {
                let net_b = net(b);
                if net_b < 0.0 {
                    // The full search's tolerance, 1e-11 of its first bracket (at least wx).
                    return falling_root_from(net, (a, net_a), (b, net_b), 1e-11 * wx / (b - a));
                }
            }
        }
        self.constant_speed_at_load_m_s(load_n)
    }

    /// [`Self::speed_at_load_m_s`] of a slider that cannot change speed within a period.
    pub fn constant_speed_at_load_m_s(&self, load_n: f64) -> f64 {
        let wx = self.base.foot_speed_m_s.max(1e-12);
        let net = |v: f64, s: f64| self.thrust_n(v) - self.resisting_n(load_n, v, s);
        let at0 = self.thrust_n(0.0);
        // The thrust at rest and at the widened end are known here: the root finder is given
        // them, not the thrust's closed form twice more.
        if at0 - load_n > self.rail_coulomb_n {
            // Forward: root of net(v, +1) on (0, hi].
            let mut hi = wx;
            let mut net_hi = net(hi, 1.0);
            while net_hi > 0.0 && hi < 1.0 {
                hi *= 2.0;
                net_hi = net(hi, 1.0);
            }
            let net_0 = at0 - self.resisting_n(load_n, 0.0, 1.0);
            falling_root_from(|v| net(v, 1.0), (0.0, net_0), (hi, net_hi), 1e-11)
        } else if at0 - load_n >= -self.rail_coulomb_n {
            0.0
        } else {
            let mut lo = -wx;
            let mut net_lo = net(lo, -1.0);
            while net_lo < 0.0 && lo > -1.0 {
                lo *= 2.0;
                net_lo = net(lo, -1.0);
            }
            let net_0 = at0 - self.resisting_n(load_n, 0.0, -1.0);
            falling_root_from(|v| net(v, -1.0), (lo, net_lo), (0.0, net_0), 1e-11)
        }
    }
}

/// Half-width of [`EffectModel::constant_speed_near_m_s`]'s first bracket, in foot speeds: a
/// Jacobian column's 1e-6 step moves a speed by far less.
pub const NEAR_SHARE: f64 = 1e-4;

/// 20-point Gauss–Legendre quadrature on [a, b].
fn gauss_legendre(f: &impl Fn(f64) -> f64, a: f64, b: f64) -> f64 {
    const X: [f64; 10] = [
        0.076_526_521_133_497_33,
        0.227_785_851_141_645_08,
        0.373_706_088_715_419_56,
        0.510_867_001_950_827_1,
        0.636_053_680_726_515,
        0.746_331_906_460_150_8,
        0.839_116_971_822_218_8,
        0.912_234_428_251_326,
        0.963_971_927_277_913_8,
        0.993_128_599_185_094_9,
    ];
    const W: [f64; 10] = [
        0.152_753_387_130_725_85,
        0.149_172_986_472_603_75,
        0.142_096_109_318_382_05,
        0.131_688_638_449_176_63,
        0.118_194_531_961_518_42,
        0.101_930_119_817_240_44,
        0.083_276_741_576_704_75,
        0.062_672_048_334_109_06,
        0.040_601_429_800_386_94,
        0.017_614_007_139_152_12,
    ];
    let (c, h) = (0.5 * (a + b), 0.5 * (b - a));
    let mut s = 0.0;
    for i in 0..10 {
        s += W[i] * (f(c + h * X[i]) + f(c - h * X[i]));
    }
    s * h
}

/// Steady speed (m/s along the commanded direction) of the steady-state model with effects.
pub fn model_speed_m_s(p: &Params, c: &Condition) -> f64 {
    EffectModel::new(p, c).speed_at_load_m_s(c.load_n)
}

/// Plant-side hooks, evaluated once per step.
impl Effects {
    /// Guide force on the slider (along +x) at velocity `v`.
    pub fn rail_force_on_slider_n(&self, v: f64) -> f64 {
        match self.rail_friction {
            Some(r) => {
                let coulomb = if v > 0.0 {
                    r.rail_coulomb_n
                } else if v < 0.0 {
                    -r.rail_coulomb_n
                } else {
                    0.0
                };
                -coulomb - r.rail_viscous_n_s_per_m * v
            }
            None => 0.0,
        }
    }

    /// μ multiplier at slip speed `slip` (Stribeck).
    pub fn stribeck_factor(&self, slip_m_s: f64) -> f64 {
        match self.stribeck_friction {
            Some(s) if s.stribeck_rise != 0.0 => {
                1.0 + s.stribeck_rise * (-(slip_m_s / s.stribeck_speed_m_s).powi(2)).exp()
            }
            _ => 1.0,
        }
    }

    /// `stribeck_friction` peak factor (at zero slip), for the sticking limit.
    pub fn stribeck_peak(&self) -> f64 {
        self.stribeck_factor(0.0)
    }
}
