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
#[derive(Debug, Clone, Copy, PartialEq, Default)]
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
    /// The stator's normal force ratio ρ (eq. 3) and tangential scale λ (eq. 1) the table was
    /// computed with: `kc·Yc` is proportional to ρ and `ω·Xc` (and the fine stroke) to λ, so a
    /// motor calibrated to other values scales the table by their ratios
    /// ([`crate::controller::ControllerConfig::per_volt`]).
    pub normal_force_ratio: f32,
    pub tangential_scale: f32,
    /// Lowest drive frequency at which eq. (7) describes the stator (Hz): 1.4× its foot-clamped
    /// counterweight mode √((k1 + k2)/m2), where the contact amplitude grows without bound. The
    /// controller chooses its drive frequency from here up ([`crate::controller::model_cache`]).
    pub lowest_model_freq_hz: f32,
    /// The stator, the contact and its friction layer as the contact model takes them (the
    /// model table's contact build).
    pub contact: crate::contact_motor::ContactMotor,
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
    // Here 0 < preload < kc·Yc, so the ratio is in (0, 1). Divisions go through the FPU (one
    // instruction on the Cortex-M4F) instead of a 64-bit software divide.
    let r = ((preload_n.to_bits() as f32 / kc_yc_n.to_bits() as f32) * 65536.0) as i32;
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
    let frac = if g1 > g0 { ((i64::from(r) - g0) as f32 / (g1 - g0) as f32 * 65536.0) as i64 } else { 0 };
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

    /// Inverse model (the feedforward): the drive voltage (peak-to-peak, within `max_v`) at which
    /// the motor runs at `speed_mm_s` against `load_n` (opposing; negative = assisting). Returns
    /// `max_v` when even that is not enough. Thrust rises with voltage; the root is found to
    /// 0.01 V (a DAC word is 0.024 V at 100 V full scale), never below it.
    pub fn voltage_for(&self, preload_n: Fx, speed_mm_s: Fx, load_n: Fx, max_v: Fx) -> Fx {
        self.voltage_near(preload_n, speed_mm_s, load_n, max_v, max_v.to_num::<f32>() * 0.5)
    }

    /// [`Self::voltage_for`] searched first within 5 V of `hint_v` (e.g. the last period's
    /// answer): a control loop's feedforward moves little from one period to the next, and a
    /// narrow first bracket saves half the model evaluations.
    pub fn voltage_near(&self, preload_n: Fx, speed_mm_s: Fx, load_n: Fx, max_v: Fx, hint_v: f32) -> Fx {
        const SPAN_V: f32 = 5.0;
        let load: f32 = load_n.to_num();
        // Falling in voltage: load − thrust(v).
        let excess = |v: f32| {
            load - self.point(preload_n, crate::fastmath::fx_from_f32(v)).thrust_n(speed_mm_s).to_num::<f32>()
        };
        let top: f32 = max_v.max(Fx::ZERO).to_num();
        let h = if hint_v.is_finite() { crate::fastmath::clamp_f32(hint_v, 0.0, top) } else { 0.5 * top };
        let eh = excess(h);
        let bracket = if eh > 0.0 {
            let up = (h + SPAN_V).min(top);
            let eu = excess(up);
            if eu <= 0.0 {
                Bracket { a: h, fa: eh, b: up, fb: eu }
            } else {
                let et = if up < top { excess(top) } else { eu };
                if et > 0.0 {
                    return max_v;
                }
                Bracket { a: up, fa: eu, b: top, fb: et }
            }
        } else {
            let down = (h - SPAN_V).max(0.0);
            let ed = excess(down);
            if ed > 0.0 {
                Bracket { a: down, fa: ed, b: h, fb: eh }
            } else {
                let e0 = if down > 0.0 { excess(0.0) } else { ed };
                if e0 <= 0.0 {
                    return Fx::ZERO;
                }
                Bracket { a: 0.0, fa: e0, b: down, fb: ed }
            }
        };
        // The upper side of the final bracket: thrust reaches the load there. Eight steps bound
        // the worst period (a cold start over the whole range); warm starts need two or three.
        let k = falling_root(excess, bracket, 0.01, 1e-4, 8);
        crate::fastmath::fx_from_f32(k.b).min(max_v)
    }
}

/// A bracket of a decreasing function: f(a) > 0 ≥ f(b).
#[derive(Clone, Copy)]
struct Bracket {
    a: f32,
    fa: f32,
    b: f32,
    fb: f32,
}

/// Root of a decreasing `f` inside a bracket, by false position with the Illinois modification:
/// superlinear, so a handful of model evaluations replace a 16–20 step bisection. Stops when the
/// bracket is narrower than `tol`, when |f| < `ftol` (then a = b = that point), or after
/// `max_evals`; returns the final bracket.
fn falling_root(
    mut f: impl FnMut(f32) -> f32,
    mut k: Bracket,
    tol: f32,
    ftol: f32,
    max_evals: u32,
) -> Bracket {
    let mut side = 0i8;
    for _ in 0..max_evals {
        if k.b - k.a <= tol {
            break;
        }
        let span = k.fa - k.fb;
        let mut c = if span > 0.0 { k.a + k.fa * (k.b - k.a) / span } else { 0.5 * (k.a + k.b) };
        // Keep strictly inside so the bracket always shrinks.
        let margin = 0.01 * (k.b - k.a);
        c = crate::fastmath::clamp_f32(c, k.a + margin, k.b - margin);
        let fc = f(c);
        if fc.abs() < ftol {
            return Bracket { a: c, fa: fc, b: c, fb: fc };
        }
        if fc > 0.0 {
            k.a = c;
            k.fa = fc;
            if side == 1 {
                k.fb *= 0.5;
            }
            side = 1;
        } else {
            k.b = c;
            k.fb = fc;
            if side == -1 {
                k.fa *= 0.5;
            }
            side = -1;
        }
    }
    k
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
        let t = (freq_khz.max(f0).min(f1) - f0).checked_div(f1 - f0).unwrap_or(Fx::ZERO);
        y0 + (y1 - y0) * t
    }

    /// `kc·Yc` per volt at a drive frequency. Interpolated as its reciprocal: `1/(kc·Yc)` is
    /// eq. (7)'s dynamic stiffness `Kec` over `kc`, smooth in frequency, while `kc·Yc` itself
    /// bends sharply towards the foot-clamped counterweight mode (with a 1 kg counterweight,
    /// 0.38 N/V at 1.1 kHz, 0.55 at 1 kHz, 1.4 at 0.9 kHz): straight lines between table points
    /// missed by 1 % of the stall force there, their reciprocals do not.
    fn kc_yc_per_volt(&self, freq_khz: Fx) -> Fx {
        let mut reciprocal = [Fx::ZERO; FREQ_POINTS];
        for (r, &y) in reciprocal.iter_mut().zip(self.kc_yc_n_per_v.iter()) {
            *r = Fx::ONE.checked_div(y).unwrap_or(Fx::MAX);
        }
        Fx::ONE.checked_div(self.per_volt(&reciprocal, freq_khz)).unwrap_or(Fx::ZERO)
    }

    /// The per-volt amplitudes at a drive frequency.
    pub fn at_frequency(&self, freq_khz: Fx) -> PerVolt {
        PerVolt {
            kc_yc_n_per_v: self.kc_yc_per_volt(freq_khz),
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
        self.kc_yc_per_volt(freq_khz).saturating_mul(voltage_v)
    }

    /// Inverse model at a drive frequency (see [`PerVolt::voltage_for`]).
    pub fn voltage_for(&self, preload_n: Fx, freq_khz: Fx, speed_mm_s: Fx, load_n: Fx, max_v: Fx) -> Fx {
        self.at_frequency(freq_khz).voltage_for(preload_n, speed_mm_s, load_n, max_v)
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
        let sin_half = sin(half);
        let w_bits = foot_speed_mm_s.to_bits();
        ThrustPoint {
            preload_n,
            kc_yc_n,
            contact_angle_rad,
            foot_speed_mm_s,
            mu,
            viscous_un_per_mm_s,
            // 2⁴⁸/w through the FPU: 24 significant bits are plenty for a speed ratio.
            inv_foot_speed_q32: if w_bits > 0 {
                (281_474_976_710_656.0f32 / w_bits as f32) as i64
            } else {
                0
            },
            half_angle_rad: half,
            cos_half,
            arc_half: sin_half - cos_half * half,
            viscous_sweep_mm_s: foot_speed_mm_s.saturating_mul(sin_half).saturating_mul_int(2),
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
        self.speed_at_load_near(load_n, f32::NAN)
    }

    /// [`Self::speed_at_load_mm_s`] searched first within 0.05 mm/s of `hint_mm_s` (the last
    /// answer, when the load estimate moved a little): two or three evaluations instead of eight.
    pub fn speed_at_load_near(&self, load_n: Fx, hint_mm_s: f32) -> Fx {
        const SPAN_MM_S: f32 = 0.05;
        let stall = self.stall_force_n();
        if stall <= load_n {
            return Fx::ZERO;
        }
        let load: f32 = load_n.to_num();
        let excess = |v: f32| self.thrust_n(crate::fastmath::fx_from_f32(v)).to_num::<f32>() - load;
        let top: f32 = self.foot_speed_mm_s.to_num();
        let f0 = (stall - load_n).to_num::<f32>();
        let mut bracket = None;
        if hint_mm_s.is_finite() && hint_mm_s > SPAN_MM_S && hint_mm_s + SPAN_MM_S < top {
            let (lo, hi) = (hint_mm_s - SPAN_MM_S, hint_mm_s + SPAN_MM_S);
            let (flo, fhi) = (excess(lo), excess(hi));
            if flo > 0.0 && fhi <= 0.0 {
                bracket = Some(Bracket { a: lo, fa: flo, b: hi, fb: fhi });
            }
        }
        let bracket = match bracket {
            Some(b) => b,
            None => {
                let ftop = excess(top);
                if ftop > 0.0 {
                    // An assisting load: faster than the foot itself.
                    return self.foot_speed_mm_s;
                }
                Bracket { a: 0.0, fa: f0, b: top, fb: ftop }
            }
        };
        let k = falling_root(excess, bracket, 0.001, 1e-4, 12);
        // The lower side: the motor surely makes this speed.
        crate::fastmath::fx_from_f32(k.a)
    }
}
