//! Fixed-point copy of the steady-state thrust model (paper eqs. 13–22, physics.md §2 and §4).
//!
//! The same equations as host-sim's f64 model: contact angle from preload with the exact mean-force
//! relation, thrust at a slider speed as the period average of Coulomb + viscous friction, stall
//! force, no-load speed. Units: newtons, mm/s, radians, volts (peak-to-peak), kHz, all [`Fx`].
//! The motor's amplitudes come from [`MotorConstants`], a frequency table derived from the
//! physical parameters by host-sim (eqs. 5 and 7 with the amplifier's gain).

use crate::trig::{acos, cos, sin, taylor_sin};
use crate::Fx;

/// Number of frequency points in the motor table.
pub const FREQ_POINTS: usize = 21;

/// What the controller needs to know about the motor, per volt of drive.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotorConstants {
    /// Frequencies of the table, ascending (kHz).
    pub freq_khz: [Fx; FREQ_POINTS],
    /// Contact force amplitude `kc·Yc` per volt peak-to-peak (N/V), eq. (7).
    pub kc_yc_n_per_v: [Fx; FREQ_POINTS],
    /// Peak tangential foot speed `ω·Xc` per volt peak-to-peak ((mm/s)/V), eq. (1).
    pub foot_speed_mm_s_per_v: [Fx; FREQ_POINTS],
    /// Sliding friction coefficient μd.
    pub mu: Fx,
    /// Viscous friction εc in µN per mm/s (= mN·s/m).
    pub viscous_un_per_mm_s: Fx,
    /// Static foot displacement per volt of common offset on both stacks (nm/V).
    pub fine_nm_per_v: Fx,
    /// Moving mass (kg).
    pub moving_mass_kg: Fx,
}

/// Mean contact force over a period per unit `kc·Yc`, g(θ) = (2 sin(θ/2) − θ cos(θ/2))/2π, on
/// θ = 2πk/256, as Q16. Built at compile time from the exact relation (physics.md §2).
static MEAN_CONTACT_Q16: [i32; 257] = mean_contact_table();

// Runs at compile time: an index out of range fails the build, not the device.
#[allow(clippy::indexing_slicing)]
const fn mean_contact_table() -> [i32; 257] {
    let mut t = [0i32; 257];
    let mut k = 0;
    while k <= 256 {
        let theta = core::f64::consts::TAU * k as f64 / 256.0;
        let h = 0.5 * theta; // in [0, π]
        let s = if h <= core::f64::consts::FRAC_PI_2 {
            taylor_sin(h)
        } else {
            taylor_sin(core::f64::consts::PI - h)
        };
        let c = taylor_sin(core::f64::consts::FRAC_PI_2 - h);
        let g = (2.0 * s - theta * c) / core::f64::consts::TAU;
        t[k] = (g * 65536.0 + 0.5) as i32;
        k += 1;
    }
    t
}

/// Contact angle θc from preload and `kc·Yc` with the exact relation; 2π at full contact.
pub fn contact_angle(preload_n: Fx, kc_yc_n: Fx) -> Fx {
    if preload_n <= Fx::ZERO {
        return Fx::ZERO;
    }
    if kc_yc_n <= preload_n {
        return Fx::TAU;
    }
    let ratio = preload_n.checked_div(kc_yc_n).unwrap_or(Fx::ONE);
    let r = ratio.to_bits();
    // Largest k with g(θk) ≤ ratio (the table rises from 0 to 1).
    let (mut lo, mut hi) = (0usize, 256usize);
    while hi - lo > 1 {
        let mid = (lo + hi) / 2;
        if MEAN_CONTACT_Q16.get(mid).copied().unwrap_or(i32::MAX) <= r {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let g0 = i64::from(MEAN_CONTACT_Q16.get(lo).copied().unwrap_or(0));
    let g1 = i64::from(MEAN_CONTACT_Q16.get(hi).copied().unwrap_or(65536));
    let step_q16 = i64::from(Fx::TAU.to_bits()) / 256;
    let frac = if g1 > g0 { ((i64::from(r) - g0) << 16) / (g1 - g0) } else { 0 };
    let theta = (lo as i64) * step_q16 + ((frac.clamp(0, 1 << 16) * step_q16) >> 16);
    Fx::from_bits(theta as i32)
}

/// The model at one drive condition.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ThrustPoint {
    pub preload_n: Fx,
    pub kc_yc_n: Fx,
    pub contact_angle_rad: Fx,
    pub foot_speed_mm_s: Fx,
    pub mu: Fx,
    pub viscous_un_per_mm_s: Fx,
}

impl MotorConstants {
    /// Table lookup with linear interpolation, clamped to the table's ends.
    fn per_volt(&self, table: &[Fx; FREQ_POINTS], freq_khz: Fx) -> Fx {
        let f = &self.freq_khz;
        let mut i = 0;
        while i + 2 < FREQ_POINTS && f.get(i + 1).is_some_and(|&x| freq_khz > x) {
            i += 1;
        }
        let (f0, f1) = (f.get(i).copied().unwrap_or(Fx::ZERO), f.get(i + 1).copied().unwrap_or(Fx::ONE));
        let (y0, y1) =
            (table.get(i).copied().unwrap_or(Fx::ZERO), table.get(i + 1).copied().unwrap_or(Fx::ZERO));
        let t = (freq_khz.clamp(f0, f1) - f0).checked_div(f1 - f0).unwrap_or(Fx::ZERO);
        y0 + (y1 - y0) * t
    }

    pub fn point(&self, preload_n: Fx, voltage_v: Fx, freq_khz: Fx) -> ThrustPoint {
        let kc_yc_n = self.per_volt(&self.kc_yc_n_per_v, freq_khz).saturating_mul(voltage_v);
        ThrustPoint {
            preload_n,
            kc_yc_n,
            contact_angle_rad: contact_angle(preload_n, kc_yc_n),
            foot_speed_mm_s: self.per_volt(&self.foot_speed_mm_s_per_v, freq_khz).saturating_mul(voltage_v),
            mu: self.mu,
            viscous_un_per_mm_s: self.viscous_un_per_mm_s,
        }
    }

    /// Preload at which contact becomes permanent at this drive (`kc·Yc`).
    pub fn full_contact_preload_n(&self, voltage_v: Fx, freq_khz: Fx) -> Fx {
        self.per_volt(&self.kc_yc_n_per_v, freq_khz).saturating_mul(voltage_v)
    }

    /// Inverse model (the feedforward): the drive voltage (peak-to-peak, within `max_v`) at which
    /// the motor runs at `speed_mm_s` against `load_n` (opposing; negative = assisting). Returns
    /// `max_v` when even that is not enough.
    pub fn voltage_for(&self, preload_n: Fx, freq_khz: Fx, speed_mm_s: Fx, load_n: Fx, max_v: Fx) -> Fx {
        let thrust = |v: Fx| self.point(preload_n, v, freq_khz).thrust_n(speed_mm_s);
        if thrust(max_v) <= load_n {
            return max_v;
        }
        let (mut lo, mut hi) = (Fx::ZERO, max_v);
        for _ in 0..16 {
            let mid = (lo + hi) / 2;
            if thrust(mid) < load_n {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        hi
    }
}

/// sin b − c·b: the integral of (cos φ − c) from 0 to b.
fn arc(b: Fx, c: Fx) -> Fx {
    sin(b) - c * b
}

impl ThrustPoint {
    pub fn full_contact(&self) -> bool {
        self.preload_n >= self.kc_yc_n
    }

    /// Mean thrust (N) on a slider moving at `speed_mm_s` along the drive direction (eqs. 19–22
    /// and the cases around them, as in host-sim's f64 model).
    pub fn thrust_n(&self, speed_mm_s: Fx) -> Fx {
        let w = self.foot_speed_mm_s;
        let phi_p = if w <= Fx::ZERO {
            if speed_mm_s < Fx::ZERO {
                Fx::PI
            } else {
                Fx::ZERO
            }
        } else {
            acos(speed_mm_s.checked_div(w).unwrap_or(Fx::ONE).clamp(-Fx::ONE, Fx::ONE))
        };
        let two_pi = Fx::TAU;
        let four = Fx::from_num(4);
        let visc_n = |x: Fx| x.saturating_mul(self.viscous_un_per_mm_s) / 1_000_000;
        if self.full_contact() {
            let f0 = self.preload_n;
            let coulomb =
                (four * f0 * phi_p - two_pi * f0 + four * self.kc_yc_n * sin(phi_p)) * self.mu / two_pi;
            return coulomb - visc_n(speed_mm_s);
        }
        let half = self.contact_angle_rad / 2;
        let c = cos(half);
        let m = phi_p.min(half);
        let r = self.mu * self.kc_yc_n;
        let coulomb = r * (four * arc(m, c) - arc(half, c) * 2) / two_pi;
        let viscous = visc_n(w * sin(half) * 2 - self.contact_angle_rad * speed_mm_s) / two_pi;
        coulomb + viscous
    }

    pub fn stall_force_n(&self) -> Fx {
        self.thrust_n(Fx::ZERO)
    }

    /// Speed at which the thrust falls to zero (bisection between standstill and the foot speed).
    pub fn no_load_speed_mm_s(&self) -> Fx {
        self.speed_at_load_mm_s(Fx::ZERO)
    }

    /// Forward speed at which the thrust equals an opposing `load_n` (0 when the load stalls it).
    pub fn speed_at_load_mm_s(&self, load_n: Fx) -> Fx {
        if self.stall_force_n() <= load_n {
            return Fx::ZERO;
        }
        let (mut lo, mut hi) = (Fx::ZERO, self.foot_speed_mm_s);
        for _ in 0..20 {
            let mid = (lo + hi) / 2;
            if self.thrust_n(mid) > load_n {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        lo
    }
}
