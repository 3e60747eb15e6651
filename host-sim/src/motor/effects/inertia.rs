//! `slider_inertia`: the steady-state side of a carriage of finite mass `M = 1/s`.
//!
//! The base model (eq. 19) is the constant-speed model, i.e. `M = ∞`. A finite carriage changes
//! speed within each drive period (physics.md §5; `motor::steady_inertia` solves that orbit for
//! the plots). Here the same periodic motion `M·v̇ = μ·Fc(φ)·sign(slip) − load`, sticking whenever
//! the friction needed to follow the foot is within `μ·Fc`, is solved cheaply enough to be fitted
//! row by row:
//!
//! - per step the contact force is held at its mid-step value and the foot speed is linear
//!   between the step's ends, and within the step the slip's zero crossing and a stick are
//!   located exactly (at most two events per step): 128 steps per period agree with 4096 within
//!   0.2 % of the no-load speed, and with the 720 fixed steps of `steady_inertia` within 0.7 %
//!   (tests/gap_effects.rs);
//! - the periodic `v(0)` is found by a secant iteration started at the same stepping's `M → ∞`
//!   speed (a handful of periods), with the bracketing regula falsi as the fallback;
//! - the model is the base model's speed plus the orbit's mean speed minus the same stepping's
//!   `M → ∞` limit (the root of its period-averaged force). The discretisation error is then an
//!   error of the inertial correction only, which vanishes with `1/M`: the effect is continuous
//!   at zero strength and exactly the base model there (no orbit is computed).
//!
//! Left out of the correction (kept in the constant-speed part): εc's viscous part (µN at these
//! speeds), the Stribeck rise; the guide friction enters it as a constant force at the
//! constant-speed speed.

use crate::motor::roots::{falling_root, falling_root_from};
use crate::motor::steady::ThrustModel;
use std::f64::consts::{PI, TAU};
use std::sync::OnceLock;

/// Steps per drive period of the orbit.
pub const ORBIT_STEPS: usize = 128;

/// cos φ at the step edges (φ from −π, the bottom of the ellipse, where the foot is slowest).
fn cos_edges() -> &'static [f64; ORBIT_STEPS + 1] {
    static TABLE: OnceLock<[f64; ORBIT_STEPS + 1]> = OnceLock::new();
    TABLE.get_or_init(|| std::array::from_fn(|i| (-PI + TAU * i as f64 / ORBIT_STEPS as f64).cos()))
}

/// cos φ at the step middles, where each step's contact force is taken: the same for every row,
/// and a row's 128 cosines were a seventh of a fit with the carriage on the constant-speed base.
fn cos_middles() -> &'static [f64; ORBIT_STEPS] {
    static TABLE: OnceLock<[f64; ORBIT_STEPS]> = OnceLock::new();
    TABLE.get_or_init(|| {
        let dphi = TAU / ORBIT_STEPS as f64;
        std::array::from_fn(|i| (-PI + (i as f64 + 0.5) * dphi).cos())
    })
}

/// The orbit problem at one row: per-step grip μ·Fc, foot speeds at the step edges, the step.
struct Orbit {
    grip_n: Vec<f64>,
    foot_m_s: Vec<f64>,
    inverse_mass_per_kg: f64,
    step_s: f64,
    load_n: f64,
}

impl Orbit {
    fn new(m: &ThrustModel, frequency_hz: f64, inverse_mass_per_kg: f64, load_n: f64, steps: usize) -> Self {
        let dphi = TAU / steps as f64;
        let foot_m_s = if steps == ORBIT_STEPS {
            cos_edges().iter().map(|c| m.foot_speed_m_s * c).collect()
        } else {
            (0..=steps).map(|i| m.foot_speed_m_s * (-PI + i as f64 * dphi).cos()).collect()
        };
        let grip_n = if steps == ORBIT_STEPS {
            cos_middles().iter().map(|c| m.mu * m.contact_force_at_cos_n(*c)).collect()
        } else {
            (0..steps).map(|i| m.mu * m.contact_force_n(-PI + (i as f64 + 0.5) * dphi)).collect()
        };
        Orbit { grip_n, foot_m_s, inverse_mass_per_kg, step_s: 1.0 / (frequency_hz * steps as f64), load_n }
    }

    fn steps(&self) -> usize {
        self.grip_n.len()
    }

    /// One period from `v0`: (end speed, mean speed).
    fn period(&self, v0: f64) -> (f64, f64) {
        let h = self.step_s;
        let k = self.inverse_mass_per_kg;
        let load = self.load_n;
        let mut v = v0;
        let mut area = 0.0;
        for i in 0..self.steps() {
            let (fa, fb) = (self.foot_m_s[i], self.foot_m_s[i + 1]);
            let af = (fb - fa) / h;
            let grip = self.grip_n[i];
            let mut t = 0.0;
            // Stick or slide, then at most one crossing: the slip then keeps its new sign (the
            // relative acceleration is the same on both sides), so two pieces end every step.
            for _ in 0..3 {
                let tau = h - t;
                if tau <= 0.0 {
                    break;
                }
                let slip = fa + af * t - v;
                let sigma = if slip != 0.0 {
                    slip.signum()
                } else if grip > 0.0 {
                    // With the foot: it sticks if the friction needed to follow is available.
                    let need = af / k + load;
                    if need.abs() <= grip {
                        area += 0.5 * tau * (v + fb);
                        v = fb;
                        break;
                    }
                    need.signum()
                } else {
                    0.0
                };
                let a = (sigma * grip - load) * k;
                let rel = af - a;
                if grip > 0.0 && slip * rel < 0.0 && slip.abs() < rel.abs() * tau {
                    // The slip reaches zero within the step: the slider meets the foot.
                    let tc = -slip / rel;
                    t += tc;
                    let meet = fa + af * t;
                    area += 0.5 * tc * (v + meet);
                    v = meet;
                } else {
                    let end = v + a * tau;
                    area += 0.5 * tau * (v + end);
                    v = end;
                    break;
                }
            }
        }
        (v, area / (h * self.steps() as f64))
    }

    /// The same stepping's `M → ∞` limit: the mean force on a slider at constant `v` (the step's
    /// linear foot speed crossing `v` splits its grip), minus the load. Decreasing in `v`.
    fn heavy_excess_n(&self, v: f64) -> f64 {
        let mut sum = 0.0;
        for i in 0..self.steps() {
            let (sa, sb) = (self.foot_m_s[i] - v, self.foot_m_s[i + 1] - v);
            let w = if sa >= 0.0 && sb >= 0.0 {
                1.0
            } else if sa <= 0.0 && sb <= 0.0 {
                -1.0
            } else {
                let alpha = sa / (sa - sb);
                sa.signum() * alpha + sb.signum() * (1.0 - alpha)
            };
            sum += self.grip_n[i] * w;
        }
        sum / self.steps() as f64 - self.load_n
    }

    /// Speed bracket scale: the foot's peak speed.
    fn scale_m_s(&self) -> f64 {
        self.foot_m_s[0].abs().max(1e-9)
    }

    /// The `M → ∞` speed, `None` when the load overruns even a slider pushed backwards.
    fn heavy_speed_m_s(&self) -> Option<f64> {
        let w = self.scale_m_s();
        let (mut lo, mut hi) = (-w, w);
        let mut tries = 0;
        // The ends' excesses as tested are the root finder's too.
        let mut at_lo = self.heavy_excess_n(lo);
        while at_lo < 0.0 {
            lo *= 2.0;
            at_lo = self.heavy_excess_n(lo);
            tries += 1;
            if tries > 8 {
                return None;
            }
        }
        let mut at_hi = self.heavy_excess_n(hi);
        while at_hi > 0.0 {
            hi *= 2.0;
            at_hi = self.heavy_excess_n(hi);
            tries += 1;
            if tries > 16 {
                return None;
            }
        }
        Some(falling_root_from(|v| self.heavy_excess_n(v), (lo, at_lo), (hi, at_hi), 1e-13))
    }

    /// Mean speed of the periodic motion, starting the search at `guess`; `None` if there is none.
    fn mean_speed_m_s(&self, guess: f64) -> Option<f64> {
        let w = self.scale_m_s();
        let excess = |v0: f64| {
            let (end, mean) = self.period(v0);
            (end - v0, mean)
        };
        // Secant on v(T) − v(0): nearly linear for a heavy slider, flat where the slider sticks.
        let (mut x0, (mut g0, _)) = (guess, excess(guess));
        let mut x1 = guess + 1e-3 * w;
        let (mut g1, mut mean1) = excess(x1);
        for _ in 0..30 {
            if g1 == 0.0 {
                return Some(mean1);
            }
            let slope = (g1 - g0) / (x1 - x0);
            if !(slope < 0.0 && slope.is_finite()) {
                break;
            }
            let x2 = x1 - g1 / slope;
            if !x2.is_finite() || (x2 - x1).abs() > 8.0 * w {
                break;
            }
            (x0, g0) = (x1, g1);
            x1 = x2;
            (g1, mean1) = excess(x1);
            if (x1 - x0).abs() <= 1e-11 * w {
                return Some(mean1);
            }
        }
        // Fallback: bracket and regula falsi, as `steady_inertia` does.
        let (mut lo, mut hi) = (-2.0 * w, 2.0 * w);
        let mut tries = 0;
        while excess(lo).0 <= 0.0 {
            lo *= 2.0;
            tries += 1;
            if tries > 12 {
                return None;
            }
        }
        while excess(hi).0 >= 0.0 {
            hi *= 2.0;
            tries += 1;
            if tries > 24 {
                return None;
            }
        }
        let root = falling_root(|v| excess(v).0, lo, hi, 1e-12);
        Some(excess(root).1)
    }
}

/// The inertial correction to add to the constant-speed speed at a row: the mean speed of a
/// carriage of mass `1/inverse_mass_per_kg` minus the `M → ∞` limit of the same stepping, under
/// the opposing force `load_n` (load plus guide friction). 0 at zero strength or when no periodic
/// motion exists (the load overruns the motor).
pub fn inertial_correction_m_s(
    m: &ThrustModel,
    frequency_hz: f64,
    inverse_mass_per_kg: f64,
    load_n: f64,
) -> f64 {
    if inverse_mass_per_kg <= 0.0 {
        return 0.0;
    }
    let orbit = Orbit::new(m, frequency_hz, inverse_mass_per_kg, load_n, ORBIT_STEPS);
    let Some(heavy) = orbit.heavy_speed_m_s() else { return 0.0 };
    match orbit.mean_speed_m_s(heavy) {
        Some(mean) => mean - heavy,
        None => 0.0,
    }
}

/// The orbit's mean speed itself (no `M → ∞` subtraction) with `steps` per period, to check the
/// stepping's error; `None` when there is no periodic motion.
pub fn orbit_mean_speed_m_s(
    m: &ThrustModel,
    frequency_hz: f64,
    inverse_mass_per_kg: f64,
    load_n: f64,
    steps: usize,
) -> Option<f64> {
    let orbit = Orbit::new(m, frequency_hz, inverse_mass_per_kg, load_n, steps);
    let guess = orbit.heavy_speed_m_s()?;
    orbit.mean_speed_m_s(guess)
}
