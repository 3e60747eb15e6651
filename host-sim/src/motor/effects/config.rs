//! The effects' configuration: what a parameter file's optional `[effects.<name>]` sections say,
//! the names, parameters and signatures of the library. No physics here (that is the parent
//! module, `effects`), so the parameter file can hold it without importing the models.

use anyhow::{anyhow, bail, Result};
use serde::{Deserialize, Deserializer, Serialize, Serializer};
use std::collections::BTreeMap;
use std::fmt;
use std::str::FromStr;

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
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub slider_inertia: Option<SliderInertia>,
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

/// The carriage has a finite mass `M = 1/inverse_mass_per_kg` (0: the base model's constant
/// speed, `M = ∞`). In the plant it replaces `slider.mass_kg`; at zero strength the plant keeps
/// `slider.mass_kg` and the steady model stays the constant-speed model, each its side's base.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SliderInertia {
    pub inverse_mass_per_kg: f64,
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

/// One effect of the library. Everything the library says of an effect apart from its physics
/// (its name, parameters, signature and fitted parameters) is in [`Effect::info`], the one table
/// of them; the name is what parameter files (`[effects.<name>]`), `--effect`, the reports and
/// the JSON say.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Effect {
    RailFriction,
    AssemblyAsymmetry,
    PreloadDependentFriction,
    StribeckFriction,
    AmplifierRolloff,
    StatorResonance,
    HertzContact,
    SliderInertia,
}

/// What the library knows of one effect, apart from its physics.
#[derive(Debug)]
pub struct EffectInfo {
    /// Its name (see [`Effect`]).
    pub name: &'static str,
    /// Its parameters in a parameter file's `[effects.<name>]`, the strength first.
    pub params: &'static [&'static str],
    /// Its signature: the conditions its law acts on (the variables of the law, mapped to the
    /// measured conditions). The model-gap workflow names an effect only when, after its fit,
    /// the residuals along these conditions are consistent with noise.
    pub signature: &'static [Axis],
    /// The parameters the model-gap fit varies, strength first. Shape parameters not listed here
    /// (Stribeck speed, resonance frequency and damping, Hertz reference preload) keep the base
    /// file's values or their defaults.
    pub fit: &'static [FitParam],
}

/// One parameter of an effect as the model-gap fit sees it.
#[derive(Debug, Clone, Copy)]
pub struct FitParam {
    pub name: &'static str,
    pub lo: f64,
    pub hi: f64,
    /// The value at which the effect vanishes (score test point).
    pub zero: f64,
    pub starts: &'static [f64],
}

impl Effect {
    /// Every effect of the library, in its fixed order.
    pub const ALL: [Effect; 8] = [
        Effect::RailFriction,
        Effect::AssemblyAsymmetry,
        Effect::PreloadDependentFriction,
        Effect::StribeckFriction,
        Effect::AmplifierRolloff,
        Effect::StatorResonance,
        Effect::HertzContact,
        Effect::SliderInertia,
    ];

    /// What the library knows of this effect: its row of the one table below.
    pub const fn info(self) -> &'static EffectInfo {
        match self {
            Effect::RailFriction => &RAIL_FRICTION,
            Effect::AssemblyAsymmetry => &ASSEMBLY_ASYMMETRY,
            Effect::PreloadDependentFriction => &PRELOAD_DEPENDENT_FRICTION,
            Effect::StribeckFriction => &STRIBECK_FRICTION,
            Effect::AmplifierRolloff => &AMPLIFIER_ROLLOFF,
            Effect::StatorResonance => &STATOR_RESONANCE,
            Effect::HertzContact => &HERTZ_CONTACT,
            Effect::SliderInertia => &SLIDER_INERTIA,
        }
    }

    /// Its name in parameter files, `--effect`, reports and JSON.
    pub const fn name(self) -> &'static str {
        self.info().name
    }

    /// Its parameters in a parameter file, the strength first.
    pub fn params(self) -> &'static [&'static str] {
        self.info().params
    }

    /// Its signature (see [`EffectInfo::signature`]).
    pub fn signature(self) -> &'static [Axis] {
        self.info().signature
    }

    /// The parameters the model-gap fit varies (see [`EffectInfo::fit`]).
    pub fn fit_params(self) -> &'static [FitParam] {
        self.info().fit
    }

    /// The effect a parameter-file parameter belongs to.
    pub fn of_param(param: &str) -> Option<Effect> {
        Effect::ALL.into_iter().find(|e| e.params().contains(&param))
    }
}

// The table of the effects: name, file parameters, signature (the comment says why), fitted
// parameters.

const RAIL_FRICTION: EffectInfo = EffectInfo {
    name: "rail_friction",
    params: &["rail_coulomb_n", "rail_viscous_n_s_per_m"],
    // −c·sign(v) − b·v: the slider's speed (set by the load) and its sign (the drive sense).
    signature: &[Axis::Load, Axis::Direction],
    fit: &[FitParam { name: "rail_coulomb_n", lo: 0.0, hi: 10.0, zero: 0.0, starts: &[0.1, 0.6] }],
};

const ASSEMBLY_ASYMMETRY: EffectInfo = EffectInfo {
    name: "assembly_asymmetry",
    params: &["asymmetry_fraction"],
    // Xc·(1 + a·d): the drive sense only.
    signature: &[Axis::Direction],
    fit: &[FitParam { name: "asymmetry_fraction", lo: -0.5, hi: 0.5, zero: 0.0, starts: &[-0.05, 0.05] }],
};

const PRELOAD_DEPENDENT_FRICTION: EffectInfo = EffectInfo {
    name: "preload_dependent_friction",
    params: &["mu_drop_per_n", "knee_preload_n"],
    // μ/(1 + s·max(0, F0 − Fk)): the static preload only.
    signature: &[Axis::Preload],
    fit: &[
        FitParam { name: "mu_drop_per_n", lo: 0.0, hi: 1.0, zero: 0.0, starts: &[0.02] },
        // The workflow starts the knee between the measured preloads instead.
        FitParam { name: "knee_preload_n", lo: 0.0, hi: 60.0, zero: 12.0, starts: &[12.0] },
    ],
};

const STRIBECK_FRICTION: EffectInfo = EffectInfo {
    name: "stribeck_friction",
    params: &["stribeck_rise", "stribeck_speed_m_s"],
    // μ(slip), slip = ω·X·cos φ − v: the foot's speed (voltage × frequency) and the slider's (the
    // load).
    signature: &[Axis::Voltage, Axis::Frequency, Axis::Load],
    fit: &[FitParam { name: "stribeck_rise", lo: 0.0, hi: 5.0, zero: 0.0, starts: &[0.2, 1.0] }],
};

const AMPLIFIER_ROLLOFF: EffectInfo = EffectInfo {
    name: "amplifier_rolloff",
    params: &["rolloff_corner_hz"],
    // Gain 1/√(1 + (f/fc)²) on the drive: the frequency only.
    signature: &[Axis::Frequency],
    // Fitted as q = (1 kHz / fc)² (q = 0: no roll-off); `rolloff_corner_hz` follows from it.
    fit: &[FitParam { name: "rolloff_q", lo: 0.0, hi: 4.0, zero: 0.0, starts: &[0.05, 0.4] }],
};

const STATOR_RESONANCE: EffectInfo = EffectInfo {
    name: "stator_resonance",
    params: &["resonance_strength", "resonance_hz", "resonance_damping_ratio"],
    // Gain |1 + k·(H(jω) − 1)| on the drive: the frequency only.
    signature: &[Axis::Frequency],
    fit: &[FitParam { name: "resonance_strength", lo: 0.0, hi: 1.0, zero: 0.0, starts: &[0.05, 0.3] }],
};

const HERTZ_CONTACT: EffectInfo = EffectInfo {
    name: "hertz_contact",
    params: &["hertz_exponent", "hertz_ref_preload_n"],
    // kc·(F0/Fref)ⁿ: the static preload only.
    signature: &[Axis::Preload],
    fit: &[FitParam { name: "hertz_exponent", lo: 0.0, hi: 1.0, zero: 0.0, starts: &[0.1, 0.4] }],
};

const SLIDER_INERTIA: EffectInfo = EffectInfo {
    name: "slider_inertia",
    params: &["inverse_mass_per_kg"],
    // Each contact arc kicks the carriage by ≈ μ·kc·Yc/(M·ω) against a foot speed ω·Xc: the
    // relative ripple goes as 1/(M·ω²) (the frequency). kc·Yc and Xc both scale with the voltage,
    // so the drive enters through the contact arc, set by preload/(kc·Yc) (the preload and the
    // voltage), and the load through load/(μ·kc·Yc) (the load).
    signature: &[Axis::Preload, Axis::Voltage, Axis::Frequency, Axis::Load],
    // Up to 10 /kg (a 100 g carriage).
    fit: &[FitParam { name: "inverse_mass_per_kg", lo: 0.0, hi: 10.0, zero: 0.0, starts: &[0.3, 2.0] }],
};

/// An unknown name is an error that names it and the known ones, on one line. Every effect name
/// a user gives goes through here.
impl FromStr for Effect {
    type Err = anyhow::Error;
    fn from_str(name: &str) -> Result<Self> {
        Effect::ALL
            .into_iter()
            .find(|e| e.name() == name)
            .ok_or_else(|| anyhow!("unknown effect '{name}' (known: {})", EFFECT_NAMES.join(", ")))
    }
}

impl fmt::Display for Effect {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl Serialize for Effect {
    fn serialize<S: Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        s.serialize_str(self.name())
    }
}

impl<'de> Deserialize<'de> for Effect {
    fn deserialize<D: Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        let name = String::deserialize(d)?;
        name.parse().map_err(serde::de::Error::custom)
    }
}

/// Names of the library's effects, in [`Effect::ALL`]'s order.
pub const EFFECT_NAMES: [&str; 8] = {
    let mut names = [""; 8];
    let mut i = 0;
    while i < names.len() {
        names[i] = Effect::ALL[i].name();
        i += 1;
    }
    names
};

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

/// The signature of the effect named `effect` (see [`EffectInfo::signature`]); an unknown name
/// has none.
pub fn signature(effect: &str) -> &'static [Axis] {
    effect.parse::<Effect>().map_or(&[], Effect::signature)
}

/// The library's own (`'static`) name for `name`; an unknown name is an error that names it and
/// the known ones, on one line (as [`Effect::from_str`]).
pub fn effect_name(name: &str) -> Result<&'static str> {
    name.parse::<Effect>().map(Effect::name)
}

impl Effects {
    pub fn is_none(&self) -> bool {
        *self == Effects::default()
    }

    /// The effects present with a non-zero strength.
    pub fn active(&self) -> Vec<Effect> {
        Effect::ALL.into_iter().filter(|e| self.is_active(*e)).collect()
    }

    pub fn is_active(&self, effect: Effect) -> bool {
        match effect {
            Effect::RailFriction => {
                self.rail_friction.is_some_and(|e| e.rail_coulomb_n != 0.0 || e.rail_viscous_n_s_per_m != 0.0)
            }
            Effect::AssemblyAsymmetry => self.assembly_asymmetry.is_some_and(|e| e.asymmetry_fraction != 0.0),
            Effect::PreloadDependentFriction => {
                self.preload_dependent_friction.is_some_and(|e| e.mu_drop_per_n != 0.0)
            }
            Effect::StribeckFriction => self.stribeck_friction.is_some_and(|e| e.stribeck_rise != 0.0),
            Effect::AmplifierRolloff => self.amplifier_rolloff.is_some_and(|e| e.rolloff_corner_hz != 0.0),
            Effect::StatorResonance => self.stator_resonance.is_some_and(|e| e.resonance_strength != 0.0),
            Effect::HertzContact => self.hertz_contact.is_some_and(|e| e.hertz_exponent != 0.0),
            Effect::SliderInertia => self.slider_inertia.is_some_and(|e| e.inverse_mass_per_kg != 0.0),
        }
    }

    /// Removes one effect (back to the base model for that module).
    pub fn clear(&mut self, effect: Effect) {
        match effect {
            Effect::RailFriction => self.rail_friction = None,
            Effect::AssemblyAsymmetry => self.assembly_asymmetry = None,
            Effect::PreloadDependentFriction => self.preload_dependent_friction = None,
            Effect::StribeckFriction => self.stribeck_friction = None,
            Effect::AmplifierRolloff => self.amplifier_rolloff = None,
            Effect::StatorResonance => self.stator_resonance = None,
            Effect::HertzContact => self.hertz_contact = None,
            Effect::SliderInertia => self.slider_inertia = None,
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
            "inverse_mass_per_kg" => {
                self.slider_inertia
                    .get_or_insert(SliderInertia { inverse_mass_per_kg: 0.0 })
                    .inverse_mass_per_kg = value
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
        if let Some(e) = self.slider_inertia {
            finite_nonneg("inverse_mass_per_kg", e.inverse_mass_per_kg)?;
        }
        for (k, v) in &self.std_dev {
            if Effect::of_param(k).is_none() {
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

    /// `slider_inertia`: 1/M when present with a non-zero strength, else 0 (the constant-speed
    /// model of an infinitely heavy slider).
    pub fn inverse_mass_per_kg(&self) -> f64 {
        self.slider_inertia.map_or(0.0, |e| e.inverse_mass_per_kg)
    }

    /// `slider_inertia`: the carriage mass the plant simulates, `1/inverse_mass_per_kg`, or the
    /// file's `slider.mass_kg` when the effect is absent or at zero strength.
    pub fn slider_mass_kg(&self, file_mass_kg: f64) -> f64 {
        match self.slider_inertia {
            Some(e) if e.inverse_mass_per_kg != 0.0 => 1.0 / e.inverse_mass_per_kg,
            _ => file_mass_kg,
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The name is the effect's one spelling: parsed, printed and serialised alike, and an
    /// unknown name is the one-line error that lists the known ones.
    #[test]
    fn an_effect_is_named_the_same_everywhere() {
        for e in Effect::ALL {
            assert_eq!(e.name().parse::<Effect>().unwrap(), e);
            assert_eq!(e.to_string(), e.name());
            let json = serde_json::to_string(&e).unwrap();
            assert_eq!(json, format!("\"{}\"", e.name()));
            assert_eq!(serde_json::from_str::<Effect>(&json).unwrap(), e);
        }
        assert_eq!(EFFECT_NAMES.to_vec(), Effect::ALL.map(Effect::name).to_vec());
        let err = "warp_drive".parse::<Effect>().unwrap_err().to_string();
        assert_eq!(err, format!("unknown effect 'warp_drive' (known: {})", EFFECT_NAMES.join(", ")));
        assert!(serde_json::from_str::<Effect>("\"warp_drive\"").is_err());
    }

    /// The table agrees with the parameter file: every parameter it lists sets its own effect
    /// (and no other), its strength (listed first) makes the effect active, and a fitted
    /// parameter is one of the file's or the roll-off's internal `rolloff_q`; each fitted
    /// parameter's zero and starts lie within its bounds.
    #[test]
    fn the_table_agrees_with_the_parameter_file() {
        for e in Effect::ALL {
            assert!(!e.params().is_empty() && !e.signature().is_empty() && !e.fit_params().is_empty());
            for (i, p) in e.params().iter().enumerate() {
                assert_eq!(Effect::of_param(p), Some(e), "{p}");
                let mut fx = Effects::default();
                fx.set(p, 0.5).unwrap();
                fx.validate().unwrap();
                if i == 0 {
                    assert_eq!(fx.active(), vec![e], "{p}");
                }
                fx.clear(e);
                assert!(fx.is_none(), "{p}");
            }
            for f in e.fit_params() {
                assert!(e.params().contains(&f.name) || f.name == "rolloff_q", "{e}: {}", f.name);
                assert!(f.lo <= f.zero && f.zero <= f.hi, "{e}: {}", f.name);
                assert!(f.starts.iter().all(|s| (f.lo..=f.hi).contains(s)), "{e}: {}", f.name);
            }
        }
        assert_eq!(Effect::of_param("rolloff_q"), None);
    }
}
