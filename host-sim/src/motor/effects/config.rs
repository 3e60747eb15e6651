//! The effects' configuration: what a parameter file's optional `[effects.<name>]` sections say,
//! the names, parameters and signatures of the library. No physics here (that is the parent
//! module, `effects`), so the parameter file can hold it without importing the models.

use anyhow::{anyhow, bail, Result};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// The optional `[effects]` section of a parameter file.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Effects {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rail_friction: Option<RailFriction>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub assembly_asymmetry: Option<AssemblyAsymmetry>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub preload_dependent_friction: Option<PreloadDependentFriction>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stribeck_friction: Option<StribeckFriction>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub amplifier_rolloff: Option<AmplifierRolloff>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stator_resonance: Option<StatorResonance>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub hertz_contact: Option<HertzContact>,
    /// One-sigma uncertainty of fitted effect parameters, by parameter name (written by `gap`).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub std_dev: BTreeMap<String, f64>,
}

/// Coulomb + viscous drag in the slider guide (the paper's "inner friction").
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RailFriction {
    pub rail_coulomb_n: f64,
    #[serde(default)]
    pub rail_viscous_n_s_per_m: f64,
}

/// Forward and backward strokes differ: the tangential amplitude is `Xc·(1 + a·d)` for sense `d`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AssemblyAsymmetry {
    pub asymmetry_fraction: f64,
}

/// μ falls above a knee preload: `μ/(1 + s·max(0, F0 − Fk))`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PreloadDependentFriction {
    pub mu_drop_per_n: f64,
    pub knee_preload_n: f64,
}

/// μ rises at low sliding (slip) speed: `μ·(1 + r·exp(−(slip/vs)²))`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StribeckFriction {
    pub stribeck_rise: f64,
    #[serde(default = "default_stribeck_speed")]
    pub stribeck_speed_m_s: f64,
}

/// The drive amplitude falls with frequency: one pole at `rolloff_corner_hz` (0 = none).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AmplifierRolloff {
    pub rolloff_corner_hz: f64,
}

/// The stroke rises toward a stator mode: stroke + k·(resonator − stroke).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StatorResonance {
    pub resonance_strength: f64,
    #[serde(default = "default_resonance_hz")]
    pub resonance_hz: f64,
    #[serde(default = "default_resonance_damping")]
    pub resonance_damping_ratio: f64,
}

/// Contact stiffness grows with preload: `kc·(F0/Fref)^n` (Hertz: n = 1/3).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct HertzContact {
    pub hertz_exponent: f64,
    #[serde(default = "default_hertz_ref")]
    pub hertz_ref_preload_n: f64,
}

pub const DEFAULT_STRIBECK_SPEED_M_S: f64 = 3e-4;
pub const DEFAULT_RESONANCE_HZ: f64 = 3170.0;
pub const DEFAULT_RESONANCE_DAMPING: f64 = 0.05;
pub const DEFAULT_HERTZ_REF_N: f64 = 16.0;
pub const DEFAULT_KNEE_N: f64 = 12.0;

fn default_stribeck_speed() -> f64 {
    DEFAULT_STRIBECK_SPEED_M_S
}
fn default_resonance_hz() -> f64 {
    DEFAULT_RESONANCE_HZ
}
fn default_resonance_damping() -> f64 {
    DEFAULT_RESONANCE_DAMPING
}
fn default_hertz_ref() -> f64 {
    DEFAULT_HERTZ_REF_N
}

/// Names of the library's effects, in a fixed order.
pub const EFFECT_NAMES: [&str; 7] = [
    "rail_friction",
    "assembly_asymmetry",
    "preload_dependent_friction",
    "stribeck_friction",
    "amplifier_rolloff",
    "stator_resonance",
    "hertz_contact",
];

/// A condition of a measured operating point; the residual structure along each is what the
/// model-gap workflow tests against the noise.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Axis {
    Preload,
    Voltage,
    Frequency,
    /// The load level: a row's rank in load within its measured curve.
    Load,
    Direction,
}

impl Axis {
    pub const ALL: [Axis; 5] = [Axis::Preload, Axis::Voltage, Axis::Frequency, Axis::Load, Axis::Direction];

    /// Name in reports and JSON.
    pub fn label(self) -> &'static str {
        match self {
            Axis::Preload => "preload",
            Axis::Voltage => "voltage",
            Axis::Frequency => "frequency",
            Axis::Load => "load level",
            Axis::Direction => "direction",
        }
    }
}

/// An effect's signature: the conditions its law acts on (the variables of the law, mapped to
/// the measured conditions). The model-gap workflow names an effect only when, after its fit, the
/// residuals along these conditions are consistent with noise. Every library effect has one (a
/// test holds this); an unknown name has none.
pub fn signature(effect: &str) -> &'static [Axis] {
    use Axis::*;
    match effect {
        // −c·sign(v) − b·v: the slider's speed (set by the load) and its sign (the drive sense).
        "rail_friction" => &[Load, Direction],
        // Xc·(1 + a·d): the drive sense only.
        "assembly_asymmetry" => &[Direction],
        // μ/(1 + s·max(0, F0 − Fk)): the static preload only.
        "preload_dependent_friction" => &[Preload],
        // μ(slip), slip = ω·X·cos φ − v: the foot's speed (voltage × frequency) and the slider's
        // (the load).
        "stribeck_friction" => &[Voltage, Frequency, Load],
        // Gain 1/√(1 + (f/fc)²) on the drive: the frequency only.
        "amplifier_rolloff" => &[Frequency],
        // Gain |1 + k·(H(jω) − 1)| on the drive: the frequency only.
        "stator_resonance" => &[Frequency],
        // kc·(F0/Fref)ⁿ: the static preload only.
        "hertz_contact" => &[Preload],
        _ => &[],
    }
}

/// The library's own (`'static`) name for `name`; an unknown name is an error that names it and
/// the known ones, on one line. Every effect name a user gives goes through here.
pub fn effect_name(name: &str) -> Result<&'static str> {
    EFFECT_NAMES
        .iter()
        .copied()
        .find(|n| *n == name)
        .ok_or_else(|| anyhow!("unknown effect '{name}' (known: {})", EFFECT_NAMES.join(", ")))
}

/// Every parameter name any effect knows, with the effect it belongs to.
pub const PARAM_NAMES: [(&str, &str); 13] = [
    ("rail_friction", "rail_coulomb_n"),
    ("rail_friction", "rail_viscous_n_s_per_m"),
    ("assembly_asymmetry", "asymmetry_fraction"),
    ("preload_dependent_friction", "mu_drop_per_n"),
    ("preload_dependent_friction", "knee_preload_n"),
    ("stribeck_friction", "stribeck_rise"),
    ("stribeck_friction", "stribeck_speed_m_s"),
    ("amplifier_rolloff", "rolloff_corner_hz"),
    ("stator_resonance", "resonance_strength"),
    ("stator_resonance", "resonance_hz"),
    ("stator_resonance", "resonance_damping_ratio"),
    ("hertz_contact", "hertz_exponent"),
    ("hertz_contact", "hertz_ref_preload_n"),
];

impl Effects {
    pub fn is_none(&self) -> bool {
        *self == Effects::default()
    }

    /// Names of the effects present with a non-zero strength.
    pub fn active(&self) -> Vec<&'static str> {
        EFFECT_NAMES.iter().copied().filter(|n| self.is_active(n)).collect()
    }

    pub fn is_active(&self, name: &str) -> bool {
        match name {
            "rail_friction" => {
                self.rail_friction.is_some_and(|e| e.rail_coulomb_n != 0.0 || e.rail_viscous_n_s_per_m != 0.0)
            }
            "assembly_asymmetry" => self.assembly_asymmetry.is_some_and(|e| e.asymmetry_fraction != 0.0),
            "preload_dependent_friction" => {
                self.preload_dependent_friction.is_some_and(|e| e.mu_drop_per_n != 0.0)
            }
            "stribeck_friction" => self.stribeck_friction.is_some_and(|e| e.stribeck_rise != 0.0),
            "amplifier_rolloff" => self.amplifier_rolloff.is_some_and(|e| e.rolloff_corner_hz != 0.0),
            "stator_resonance" => self.stator_resonance.is_some_and(|e| e.resonance_strength != 0.0),
            "hertz_contact" => self.hertz_contact.is_some_and(|e| e.hertz_exponent != 0.0),
            _ => false,
        }
    }

    /// Removes one effect (back to the base model for that module).
    pub fn clear(&mut self, name: &str) {
        match name {
            "rail_friction" => self.rail_friction = None,
            "assembly_asymmetry" => self.assembly_asymmetry = None,
            "preload_dependent_friction" => self.preload_dependent_friction = None,
            "stribeck_friction" => self.stribeck_friction = None,
            "amplifier_rolloff" => self.amplifier_rolloff = None,
            "stator_resonance" => self.stator_resonance = None,
            "hertz_contact" => self.hertz_contact = None,
            _ => {}
        }
    }

    /// Sets one named parameter, creating its effect with the other parameters at their defaults.
    pub fn set(&mut self, name: &str, value: f64) -> Result<()> {
        match name {
            "rail_coulomb_n" => {
                self.rail_friction
                    .get_or_insert(RailFriction { rail_coulomb_n: 0.0, rail_viscous_n_s_per_m: 0.0 })
                    .rail_coulomb_n = value
            }
            "rail_viscous_n_s_per_m" => {
                self.rail_friction
                    .get_or_insert(RailFriction { rail_coulomb_n: 0.0, rail_viscous_n_s_per_m: 0.0 })
                    .rail_viscous_n_s_per_m = value
            }
            "asymmetry_fraction" => {
                self.assembly_asymmetry
                    .get_or_insert(AssemblyAsymmetry { asymmetry_fraction: 0.0 })
                    .asymmetry_fraction = value
            }
            "mu_drop_per_n" | "knee_preload_n" => {
                let e = self.preload_dependent_friction.get_or_insert(PreloadDependentFriction {
                    mu_drop_per_n: 0.0,
                    knee_preload_n: DEFAULT_KNEE_N,
                });
                if name == "mu_drop_per_n" {
                    e.mu_drop_per_n = value
                } else {
                    e.knee_preload_n = value
                }
            }
            "stribeck_rise" | "stribeck_speed_m_s" => {
                let e = self.stribeck_friction.get_or_insert(StribeckFriction {
                    stribeck_rise: 0.0,
                    stribeck_speed_m_s: DEFAULT_STRIBECK_SPEED_M_S,
                });
                if name == "stribeck_rise" {
                    e.stribeck_rise = value
                } else {
                    e.stribeck_speed_m_s = value
                }
            }
            "rolloff_corner_hz" => {
                self.amplifier_rolloff
                    .get_or_insert(AmplifierRolloff { rolloff_corner_hz: 0.0 })
                    .rolloff_corner_hz = value
            }
            "resonance_strength" | "resonance_hz" | "resonance_damping_ratio" => {
                let e = self.stator_resonance.get_or_insert(StatorResonance {
                    resonance_strength: 0.0,
                    resonance_hz: DEFAULT_RESONANCE_HZ,
                    resonance_damping_ratio: DEFAULT_RESONANCE_DAMPING,
                });
                match name {
                    "resonance_strength" => e.resonance_strength = value,
                    "resonance_hz" => e.resonance_hz = value,
                    _ => e.resonance_damping_ratio = value,
                }
            }
            "hertz_exponent" | "hertz_ref_preload_n" => {
                let e = self.hertz_contact.get_or_insert(HertzContact {
                    hertz_exponent: 0.0,
                    hertz_ref_preload_n: DEFAULT_HERTZ_REF_N,
                });
                if name == "hertz_exponent" {
                    e.hertz_exponent = value
                } else {
                    e.hertz_ref_preload_n = value
                }
            }
            _ => bail!("unknown effect parameter '{name}'"),
        }
        Ok(())
    }

    /// Rejects meaningless values with a one-line message.
    pub fn validate(&self) -> Result<()> {
        let finite_nonneg = |name: &str, v: f64| -> Result<()> {
            if !(v.is_finite() && v >= 0.0) {
                bail!("effects: {name} must be zero or positive, got {v}");
            }
            Ok(())
        };
        if let Some(e) = self.rail_friction {
            finite_nonneg("rail_coulomb_n", e.rail_coulomb_n)?;
            finite_nonneg("rail_viscous_n_s_per_m", e.rail_viscous_n_s_per_m)?;
        }
        if let Some(e) = self.assembly_asymmetry {
            if !(e.asymmetry_fraction.is_finite() && e.asymmetry_fraction.abs() < 0.9) {
                bail!("effects: asymmetry_fraction must be within ±0.9, got {}", e.asymmetry_fraction);
            }
        }
        if let Some(e) = self.preload_dependent_friction {
            finite_nonneg("mu_drop_per_n", e.mu_drop_per_n)?;
            finite_nonneg("knee_preload_n", e.knee_preload_n)?;
        }
        if let Some(e) = self.stribeck_friction {
            finite_nonneg("stribeck_rise", e.stribeck_rise)?;
            if !(e.stribeck_speed_m_s.is_finite() && e.stribeck_speed_m_s > 0.0) {
                bail!("effects: stribeck_speed_m_s must be positive, got {}", e.stribeck_speed_m_s);
            }
        }
        if let Some(e) = self.amplifier_rolloff {
            finite_nonneg("rolloff_corner_hz", e.rolloff_corner_hz)?;
        }
        if let Some(e) = self.stator_resonance {
            if !(e.resonance_strength.is_finite() && (0.0..=1.0).contains(&e.resonance_strength)) {
                bail!("effects: resonance_strength must be in [0, 1], got {}", e.resonance_strength);
            }
            if !(e.resonance_hz.is_finite() && e.resonance_hz > 0.0) {
                bail!("effects: resonance_hz must be positive, got {}", e.resonance_hz);
            }
            if !(e.resonance_damping_ratio.is_finite() && e.resonance_damping_ratio > 0.0) {
                bail!("effects: resonance_damping_ratio must be positive, got {}", e.resonance_damping_ratio);
            }
        }
        if let Some(e) = self.hertz_contact {
            if !(e.hertz_exponent.is_finite() && (0.0..=1.0).contains(&e.hertz_exponent)) {
                bail!("effects: hertz_exponent must be in [0, 1], got {}", e.hertz_exponent);
            }
            if !(e.hertz_ref_preload_n.is_finite() && e.hertz_ref_preload_n > 0.0) {
                bail!("effects: hertz_ref_preload_n must be positive, got {}", e.hertz_ref_preload_n);
            }
        }
        for (k, v) in &self.std_dev {
            if !PARAM_NAMES.iter().any(|(_, n)| n == k) {
                bail!("effects.std_dev: unknown parameter '{k}'");
            }
            finite_nonneg(k, *v)?;
        }
        Ok(())
    }

    /// `hertz_contact`: the contact stiffness at a static preload.
    pub fn contact_stiffness_n_per_m(&self, base_n_per_m: f64, preload_n: f64) -> f64 {
        match self.hertz_contact {
            Some(h) if h.hertz_exponent != 0.0 => {
                base_n_per_m * (preload_n.max(1e-6) / h.hertz_ref_preload_n).powf(h.hertz_exponent)
            }
            _ => base_n_per_m,
        }
    }

    /// `preload_dependent_friction`: factor on μ at a static preload.
    pub fn friction_factor(&self, preload_n: f64) -> f64 {
        match self.preload_dependent_friction {
            Some(e) if e.mu_drop_per_n != 0.0 => {
                1.0 / (1.0 + e.mu_drop_per_n * (preload_n - e.knee_preload_n).max(0.0))
            }
            _ => 1.0,
        }
    }

    /// `assembly_asymmetry`: factor on the tangential stroke for drive sense `direction`.
    pub fn tangential_factor(&self, direction: i8) -> f64 {
        match self.assembly_asymmetry {
            Some(e) => 1.0 + e.asymmetry_fraction * f64::from(direction.signum()),
            None => 1.0,
        }
    }

    /// `amplifier_rolloff` × `stator_resonance`: steady gain on the stack voltage swing at `f`.
    pub fn drive_gain(&self, frequency_hz: f64) -> f64 {
        let mut g = 1.0;
        if let Some(r) = self.amplifier_rolloff {
            if r.rolloff_corner_hz > 0.0 {
                g /= (1.0 + (frequency_hz / r.rolloff_corner_hz).powi(2)).sqrt();
            }
        }
        if let Some(r) = self.stator_resonance {
            if r.resonance_strength != 0.0 {
                // H = ωr²/(ωr² − ω² + 2jζωrω); G = 1 + k·(H − 1).
                let x = frequency_hz / r.resonance_hz;
                let (re_d, im_d) = (1.0 - x * x, 2.0 * r.resonance_damping_ratio * x);
                let den = re_d * re_d + im_d * im_d;
                let (h_re, h_im) = (re_d / den, -im_d / den);
                let k = r.resonance_strength;
                let (g_re, g_im) = (1.0 + k * (h_re - 1.0), k * h_im);
                g *= (g_re * g_re + g_im * g_im).sqrt();
            }
        }
        g
    }
}
