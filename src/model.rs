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

/// The model at one drive condition. The speed-independent parts of eq. (22) are computed once
/// here, so each thrust evaluation is one acos, one sine and a few multiplies.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ThrustPoint {
    pub preload_n: Fx,
    pub kc_yc_n: Fx,
    pub contact_angle_rad: Fx,
    pub foot_speed_mm_s: Fx,
    pub mu: Fx,
    pub viscous_un_per_mm_s: Fx,
    /// 2⁴⁸ / foot-speed bits: speed/foot-speed as a multiply (0 when the foot does not move).
    inv_foot_speed_q32: i64,
    half_angle_rad: Fx,
    cos_half: Fx,
    /// arc(θc/2, cos θc/2), the contact arc's share that does not depend on speed.
    arc_half: Fx,
    /// 2·w·sin(θc/2), the viscous term's speed-independent part (mm/s).
    viscous_sweep_mm_s: Fx,
}

/// 1/2π in Q32: dividing by 2π as a multiply (no 64-bit software divide on the Cortex-M4).
const INV_TAU_Q32: i64 = 683_565_276;

fn div_tau(x: Fx) -> Fx {
    Fx::from_bits(((i64::from(x.to_bits()) * INV_TAU_Q32) >> 32) as i32)
}

/// The motor's per-volt amplitudes at one frequency (table lookups done once).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PerVolt {
    pub kc_yc_n_per_v: Fx,
    pub foot_speed_mm_s_per_v: Fx,
    pub mu: Fx,
    pub viscous_un_per_mm_s: Fx,
}

impl PerVolt {
    pub fn point(&self, preload_n: Fx, voltage_v: Fx) -> ThrustPoint {
        ThrustPoint::new(
            preload_n,
            self.kc_yc_n_per_v.saturating_mul(voltage_v),
            self.foot_speed_mm_s_per_v.saturating_mul(voltage_v),
            self.mu,
            self.viscous_un_per_mm_s,
        )
    }
}

/// Root of a decreasing `f` on [lo, hi] with f(lo) > 0 ≥ f(hi), by false position with the
/// Illinois modification: superlinear, so a handful of model evaluations replace a 16–20 step
/// bisection. Stops when the bracket is below `tol`, when |f| < `ftol`, or after `max_evals`;
/// returns the end of the bracket on the positive side (never past the root, up to `ftol`).
fn falling_root(mut f: impl FnMut(f32) -> f32, lo: f32, hi: f32, tol: f32, ftol: f32, max_evals: u32) -> f32 {
    let (mut a, mut fa) = (lo, f(lo));
    let (mut b, mut fb) = (hi, f(hi));
    if fa <= 0.0 {
        return lo;
    }
    if fb > 0.0 {
        return hi;
    }
    let mut side = 0i8;
    for _ in 0..max_evals {
        if b - a <= tol {
            break;
        }
        let span = fa - fb;
        let mut c = if span > 0.0 { a + fa * (b - a) / span } else { 0.5 * (a + b) };
        // Keep strictly inside so the bracket always shrinks.
        let margin = 0.01 * (b - a);
        c = c.clamp(a + margin, b - margin);
        let fc = f(c);
        if fc.abs() < ftol {
            return c;
        }
        if fc > 0.0 {
            a = c;
            fa = fc;
            if side == 1 {
                fb *= 0.5;
            }
            side = 1;
        } else {
            b = c;
            fb = fc;
            if side == -1 {
                fa *= 0.5;
            }
            side = -1;
        }
    }
    a
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

    /// The per-volt amplitudes at a drive frequency.
    pub fn at_frequency(&self, freq_khz: Fx) -> PerVolt {
        PerVolt {
            kc_yc_n_per_v: self.per_volt(&self.kc_yc_n_per_v, freq_khz),
            foot_speed_mm_s_per_v: self.per_volt(&self.foot_speed_mm_s_per_v, freq_khz),
            mu: self.mu,
            viscous_un_per_mm_s: self.viscous_un_per_mm_s,
        }
    }

    pub fn point(&self, preload_n: Fx, voltage_v: Fx, freq_khz: Fx) -> ThrustPoint {
        self.at_frequency(freq_khz).point(preload_n, voltage_v)
    }

    /// Preload at which contact becomes permanent at this drive (`kc·Yc`).
    pub fn full_contact_preload_n(&self, voltage_v: Fx, freq_khz: Fx) -> Fx {
        self.per_volt(&self.kc_yc_n_per_v, freq_khz).saturating_mul(voltage_v)
    }

    /// Inverse model (the feedforward): the drive voltage (peak-to-peak, within `max_v`) at which
    /// the motor runs at `speed_mm_s` against `load_n` (opposing; negative = assisting). Returns
    /// `max_v` when even that is not enough. Thrust rises with voltage; the root is found to
    /// 0.01 V (a hundredth of a DAC word's worth at 100 V full scale is 0.0024 V per word).
    pub fn voltage_for(&self, preload_n: Fx, freq_khz: Fx, speed_mm_s: Fx, load_n: Fx, max_v: Fx) -> Fx {
        let per_volt = self.at_frequency(freq_khz);
        let load: f32 = load_n.to_num();
        // Falling in voltage: load − thrust(v).
        let excess = |v: f32| {
            load - per_volt.point(preload_n, Fx::saturating_from_num(v)).thrust_n(speed_mm_s).to_num::<f32>()
        };
        let top: f32 = max_v.max(Fx::ZERO).to_num();
        if excess(top) >= 0.0 {
            return max_v;
        }
        // The smallest voltage whose thrust reaches the load: the root's upper side.
        let below = falling_root(excess, 0.0, top, 0.01, 1e-4, 12);
        let v = Fx::saturating_from_num(below + 0.01).min(max_v);
        if excess(v.to_num()) < 0.0 {
            v
        } else {
            Fx::saturating_from_num(below + 0.02).min(max_v)
        }
    }
}

/// sin b − c·b: the integral of (cos φ − c) from 0 to b.
fn arc(b: Fx, c: Fx) -> Fx {
    sin(b) - c * b
}

impl ThrustPoint {
    fn new(preload_n: Fx, kc_yc_n: Fx, foot_speed_mm_s: Fx, mu: Fx, viscous_un_per_mm_s: Fx) -> Self {
        let contact_angle_rad = contact_angle(preload_n, kc_yc_n);
        let half = contact_angle_rad / 2;
        let cos_half = cos(half);
        let w_bits = i64::from(foot_speed_mm_s.to_bits());
        ThrustPoint {
            preload_n,
            kc_yc_n,
            contact_angle_rad,
            foot_speed_mm_s,
            mu,
            viscous_un_per_mm_s,
            inv_foot_speed_q32: if w_bits > 0 { (1i64 << 48) / w_bits } else { 0 },
            half_angle_rad: half,
            cos_half,
            arc_half: arc(half, cos_half),
            viscous_sweep_mm_s: foot_speed_mm_s.saturating_mul(sin(half)).saturating_mul_int(2),
        }
    }

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
            // speed / w, saturated to ±1 (beyond the foot's speed the angle is 0 or π).
            let ratio = (i64::from(speed_mm_s.to_bits()).saturating_mul(self.inv_foot_speed_q32) >> 32)
                .clamp(-65536, 65536);
            acos(Fx::from_bits(ratio as i32))
        };
        let four = Fx::from_num(4);
        let visc_n = |x: Fx| x.saturating_mul(self.viscous_un_per_mm_s) / 1_000_000;
        if self.full_contact() {
            let f0 = self.preload_n;
            let coulomb =
                div_tau((four * f0 * phi_p - Fx::TAU * f0 + four * self.kc_yc_n * sin(phi_p)) * self.mu);
            return coulomb - visc_n(speed_mm_s);
        }
        let m = phi_p.min(self.half_angle_rad);
        let r = self.mu * self.kc_yc_n;
        let coulomb = div_tau(r * (four * arc(m, self.cos_half) - self.arc_half * 2));
        let viscous =
            div_tau(visc_n(self.viscous_sweep_mm_s - self.contact_angle_rad.saturating_mul(speed_mm_s)));
        coulomb + viscous
    }

    pub fn stall_force_n(&self) -> Fx {
        self.thrust_n(Fx::ZERO)
    }

    /// Speed at which the thrust falls to zero.
    pub fn no_load_speed_mm_s(&self) -> Fx {
        self.speed_at_load_mm_s(Fx::ZERO)
    }

    /// Forward speed at which the thrust equals an opposing `load_n` (0 when the load stalls it),
    /// to 0.001 mm/s. Thrust falls with speed between standstill and the foot's peak speed.
    pub fn speed_at_load_mm_s(&self, load_n: Fx) -> Fx {
        if self.stall_force_n() <= load_n {
            return Fx::ZERO;
        }
        let load: f32 = load_n.to_num();
        let excess = |v: f32| self.thrust_n(Fx::saturating_from_num(v)).to_num::<f32>() - load;
        let top: f32 = self.foot_speed_mm_s.to_num();
        Fx::saturating_from_num(falling_root(excess, 0.0, top, 0.001, 1e-4, 12))
    }
}
