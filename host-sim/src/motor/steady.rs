//! Steady-state thrust model of the shaking-beam motor (paper §2, eqs. 5, 7, 13–22; physics.md §2, §4).
//!
//! The slider is assumed to move at a constant speed `v` while the foot traces its ellipse; the
//! thrust is the period average of the friction force (19). Angles `φ` are measured from the top of
//! the ellipse, where the foot presses hardest and moves fastest in the drive direction.

use crate::motor::params::Params;
use std::f64::consts::{PI, TAU};

/// Operating condition of one steady run. `voltage_v` is the peak-to-peak swing of each stack
/// voltage (100 V = the full 0–100 V range, which gives the datasheet's 2.2 µm stroke).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OperatingPoint {
    pub preload_n: f64,
    pub voltage_v: f64,
    pub frequency_hz: f64,
}

/// Foot amplitudes at one drive condition.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Amplitudes {
    /// Normal force amplitude the two stacks put on the foot (eq. 3, both stacks).
    pub normal_force_n: f64,
    /// Non-contact normal amplitude `Yn` (eq. 5).
    pub yn_m: f64,
    /// Contact-stage normal amplitude `Yc` (eq. 7).
    pub yc_m: f64,
    /// Tangential amplitude `Xc` (eq. 1).
    pub xc_m: f64,
}

/// Gain of the DAC reconstruction filter + amplifier: two real poles, −3 dB at `bandwidth_hz`.
pub fn amplifier_gain(p: &Params, frequency_hz: f64) -> f64 {
    let wt = TAU * frequency_hz * amplifier_stage_tau_s(p);
    1.0 / (1.0 + wt * wt)
}

/// Time constant of each of the two identical amplifier poles.
pub fn amplifier_stage_tau_s(p: &Params) -> f64 {
    // Two equal poles are −3 dB where (ωτ)² = √2 − 1.
    (2f64.sqrt() - 1.0).sqrt() / (TAU * p.amplifier.bandwidth_hz)
}

pub fn amplitudes(p: &Params, voltage_v: f64, frequency_hz: f64) -> Amplitudes {
    let w2 = (TAU * frequency_hz).powi(2);
    let stroke_m = p.stack.stroke_m_per_v * 0.5 * voltage_v * amplifier_gain(p, frequency_hz);
    // F1 = ρ·Fmax·sin, F2 = ρ'·Fmax·cos (3) with ρ = ρ': the normal sum has amplitude √2·ρ·Fmax.
    let normal_force_n = 2f64.sqrt() * p.stator.normal_force_ratio * p.stack.stiffness_n_per_m * stroke_m;
    let (m1, m2) = (p.stator.foot_mass_kg, p.stator.counterweight_mass_kg);
    let (k1, k2, k3) = (p.k1_n_per_m(), p.stator.preload_spring_n_per_m, p.contact.stiffness_n_per_m);
    // Eq. (5): Ken = ((k1 − ω²m1)(k2 − ω²m2) − ω²m1k1) / (k2 − ω²m2).
    let ken = ((k1 - w2 * m1) * (k2 - w2 * m2) - w2 * m1 * k1) / (k2 - w2 * m2);
    // Eq. (7): Kec = ((k1 + k3 − ω²m1)(k1 + k2 − ω²m2) − k1²) / (k2 − ω²m2).
    let kec = ((k1 + k3 - w2 * m1) * (k1 + k2 - w2 * m2) - k1 * k1) / (k2 - w2 * m2);
    Amplitudes {
        normal_force_n,
        yn_m: (normal_force_n / ken).abs(),
        yc_m: (normal_force_n / kec).abs(),
        xc_m: 2f64.sqrt() * p.stator.tangential_scale * stroke_m,
    }
}

/// Mean contact force over a period for contact angle θ, per unit `kc·Yc` (physics.md §2, exact).
pub fn mean_contact_exact(theta_rad: f64) -> f64 {
    let h = 0.5 * theta_rad;
    (2.0 * h.sin() - theta_rad * h.cos()) / TAU
}

/// The paper's (14): `F0 = −kc·Yc·(θc/2π)·cos(θc/2)`, valid only for θc in [π, 2π].
pub fn mean_contact_paper(theta_rad: f64) -> f64 {
    -theta_rad / TAU * (0.5 * theta_rad).cos()
}

/// Contact angle θc from preload with the exact relation; 2π (full contact) when `F0 ≥ kc·Yc`.
pub fn contact_angle_exact(preload_n: f64, kc_yc_n: f64) -> f64 {
    // d/dθ of the mean contact force per kc·Yc: θ·sin(θ/2)/4π, positive on (0, 2π).
    let slope = |t: f64| kc_yc_n * t * (0.5 * t).sin() / (2.0 * TAU);
    solve_increasing_newton(|t| kc_yc_n * mean_contact_exact(t) - preload_n, slope, 0.0, TAU)
}

/// Root of an increasing function on [lo, hi] with its derivative, clamped to the ends: Newton
/// steps kept inside the shrinking bracket, bisection where a step would leave it. Six or so
/// evaluations where bisection to the same 1e-15 took 53 (each a sine and a cosine: the
/// closed form is built for every row of every fit in the gap workflow).
fn solve_increasing_newton(f: impl Fn(f64) -> f64, df: impl Fn(f64) -> f64, lo: f64, hi: f64) -> f64 {
    if f(lo) >= 0.0 {
        return lo;
    }
    if f(hi) <= 0.0 {
        return hi;
    }
    let (mut a, mut b) = (lo, hi);
    let mut t = 0.5 * (a + b);
    for _ in 0..100 {
        let y = f(t);
        if y < 0.0 {
            a = t;
        } else {
            b = t;
        }
        let d = df(t);
        let newton = t - y / d;
        let next = if d > 0.0 && newton > a && newton < b { newton } else { 0.5 * (a + b) };
        if (next - t).abs() < 1e-15 || b - a < 1e-15 {
            return next;
        }
        t = next;
    }
    t
}

/// Contact angle from the paper's approximate (14); it cannot go below π (the paper's conclusion).
pub fn contact_angle_paper(preload_n: f64, kc_yc_n: f64) -> f64 {
    solve_increasing(|t| kc_yc_n * mean_contact_paper(t) - preload_n, PI, TAU)
}

/// Root of an increasing function on [lo, hi], clamped to the ends.
fn solve_increasing(f: impl Fn(f64) -> f64, lo: f64, hi: f64) -> f64 {
    if f(lo) >= 0.0 {
        return lo;
    }
    if f(hi) <= 0.0 {
        return hi;
    }
    let (mut a, mut b) = (lo, hi);
    for _ in 0..100 {
        let m = 0.5 * (a + b);
        if f(m) < 0.0 {
            a = m;
        } else {
            b = m;
        }
        if b - a < 1e-15 {
            break;
        }
    }
    0.5 * (a + b)
}

/// Everything the thrust integral needs at one operating point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ThrustModel {
    pub preload_n: f64,
    /// `kc·Yc`: amplitude of the contact force law (eq. 15).
    pub kc_yc_n: f64,
    /// θc, exact relation. Read it; it is set by [`Self::new`] and
    /// [`Self::with_contact_force_amplitude`], which also set its half's cosine and sine.
    pub contact_angle_rad: f64,
    /// `ω·Xc`: peak tangential foot speed.
    pub foot_speed_m_s: f64,
    pub mu: f64,
    pub viscous_n_s_per_m: f64,
    /// cos and sin of θc/2: the thrust integral and the contact force read them at every speed
    /// and angle (the root of the speed at a load evaluates the thrust tens of times).
    half_cos: f64,
    half_sin: f64,
}

impl ThrustModel {
    pub fn new(p: &Params, op: OperatingPoint) -> Self {
        let a = amplitudes(p, op.voltage_v, op.frequency_hz);
        let kc_yc_n = p.contact.stiffness_n_per_m * a.yc_m;
        ThrustModel {
            preload_n: op.preload_n,
            kc_yc_n,
            contact_angle_rad: 0.0,
            foot_speed_m_s: TAU * op.frequency_hz * a.xc_m,
            mu: p.friction.mu_dynamic,
            viscous_n_s_per_m: p.friction.viscous_n_s_per_m,
            half_cos: 1.0,
            half_sin: 0.0,
        }
        .with_contact_force_amplitude(kc_yc_n)
    }

    /// The same point with the contact force amplitude `kc·Yc` replaced (contact angle re-solved).
    pub fn with_contact_force_amplitude(mut self, kc_yc_n: f64) -> Self {
        self.kc_yc_n = kc_yc_n;
        self.contact_angle_rad = contact_angle_exact(self.preload_n, kc_yc_n);
        let half = 0.5 * self.contact_angle_rad;
        (self.half_cos, self.half_sin) = (half.cos(), half.sin());
        self
    }

    pub fn full_contact(&self) -> bool {
        self.preload_n >= self.kc_yc_n
    }

    /// Contact force at angle φ from the top of the ellipse (eq. 15 in physics.md's form).
    pub fn contact_force_n(&self, phi: f64) -> f64 {
        self.contact_force_at_cos_n(phi.cos())
    }

    /// [`Self::contact_force_n`] from cos φ (for a caller that needs the cosine too).
    pub fn contact_force_at_cos_n(&self, cos_phi: f64) -> f64 {
        if self.full_contact() {
            self.preload_n + self.kc_yc_n * cos_phi
        } else {
            (self.kc_yc_n * (cos_phi - self.half_cos)).max(0.0)
        }
    }

    /// Half-width φp of the arc where the foot outruns a slider moving at `v` (eq. 17).
    pub fn drive_half_angle(&self, speed_m_s: f64) -> f64 {
        if self.foot_speed_m_s <= 0.0 {
            return if speed_m_s < 0.0 { PI } else { 0.0 };
        }
        (speed_m_s / self.foot_speed_m_s).clamp(-1.0, 1.0).acos()
    }

    /// Mean thrust on a slider moving at `speed_m_s` along the drive direction: closed form.
    ///
    /// Partial contact with φp < θc/2 is eq. (22); φp ≥ θc/2 (the whole contact arc drives),
    /// full contact, and reverse motion or `v > ω·Xc` follow from the same integral (19).
    pub fn thrust_n(&self, speed_m_s: f64) -> f64 {
        self.thrust_at_half_angle_n(speed_m_s, self.drive_half_angle(speed_m_s))
    }

    /// [`Self::thrust_n`] with the drive half-angle `phi_p` of `speed_m_s` already known.
    pub fn thrust_at_half_angle_n(&self, speed_m_s: f64, phi_p: f64) -> f64 {
        let r = self.mu * self.kc_yc_n; // ℜ = μ·kc·Yc
        let wx = self.foot_speed_m_s;
        if self.full_contact() {
            let f0 = self.preload_n;
            let coulomb = self.mu / TAU * (4.0 * f0 * phi_p - TAU * f0 + 4.0 * self.kc_yc_n * phi_p.sin());
            return coulomb - self.viscous_n_s_per_m * speed_m_s;
        }
        let half = 0.5 * self.contact_angle_rad;
        let c = self.half_cos;
        // I(b) = ∫₀ᵇ (cos φ − c) dφ: the drive arc is |φ| < min(φp, θc/2), the rest of the arc brakes.
        let arc_half = self.half_sin - c * half;
        let arc_drive = if phi_p < half { phi_p.sin() - c * phi_p } else { arc_half };
        let coulomb = r / TAU * (4.0 * arc_drive - 2.0 * arc_half);
        let viscous =
            self.viscous_n_s_per_m / TAU * (2.0 * wx * self.half_sin - self.contact_angle_rad * speed_m_s);
        coulomb + viscous
    }

    /// Reference: direct midpoint average of the friction force of eq. (16) over one period.
    pub fn thrust_numeric_n(&self, speed_m_s: f64, samples: usize) -> f64 {
        let n = samples.max(1);
        let mut sum = 0.0;
        for i in 0..n {
            let phi = -PI + TAU * (i as f64 + 0.5) / n as f64;
            let fc = self.contact_force_n(phi);
            if fc <= 0.0 {
                continue;
            }
            let slip = self.foot_speed_m_s * phi.cos() - speed_m_s;
            let dir = if slip > 0.0 {
                1.0
            } else if slip < 0.0 {
                -1.0
            } else {
                0.0
            };
            sum += self.mu * fc * dir + self.viscous_n_s_per_m * slip;
        }
        sum / n as f64
    }

    pub fn stall_force_n(&self) -> f64 {
        self.thrust_n(0.0)
    }

    /// Speed at which the thrust balances `load_n`; `None` when the load overruns the motor even
    /// when the slider is pushed backwards faster than the foot moves.
    pub fn speed_at_load_m_s(&self, load_n: f64) -> Option<f64> {
        let wx = self.foot_speed_m_s.max(1e-12);
        let (mut lo, mut hi) = (-wx, wx);
        if self.thrust_n(lo) < load_n {
            return None;
        }
        // Above ω·Xc only braking remains, so F(hi) ≤ 0 for any load ≥ 0; extend for negative loads.
        while self.thrust_n(hi) > load_n {
            hi *= 2.0;
            if hi > 1e3 {
                return None;
            }
        }
        for _ in 0..200 {
            let m = 0.5 * (lo + hi);
            if self.thrust_n(m) > load_n {
                lo = m;
            } else {
                hi = m;
            }
        }
        Some(0.5 * (lo + hi))
    }

    pub fn no_load_speed_m_s(&self) -> f64 {
        self.speed_at_load_m_s(0.0).unwrap_or(0.0)
    }
}

/// Convenience: the model at a point, in the drive direction. Reverse drive is the mirror image:
/// `F_reverse(v) = −F(−v)`.
pub fn thrust_n(p: &Params, op: OperatingPoint, speed_m_s: f64, direction: i8) -> f64 {
    let m = ThrustModel::new(p, op);
    if direction >= 0 {
        m.thrust_n(speed_m_s)
    } else {
        -m.thrust_n(-speed_m_s)
    }
}
