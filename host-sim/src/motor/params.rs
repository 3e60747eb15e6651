//! The motor's physical parameters: one place, SI units in every name.
//!
//! The default set (`params/prototype.toml`, compiled in) describes the prototype of the
//! shaking-beam paper. Any other set is loaded with `--params FILE`; every field is required so a
//! typo cannot silently fall back to a default.

use anyhow::{bail, Context, Result};

use crate::motor::effects::config::Effects;
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The prototype parameter set shipped with the project.
pub const PROTOTYPE_TOML: &str = include_str!("../../params/prototype.toml");
/// The prototype with every plant parameter sourced (`params/prototype-sourced.toml`, issue 28):
/// the contact's restitution and the friction layer's material damping.
pub const PROTOTYPE_SOURCED_TOML: &str = include_str!("../../params/prototype-sourced.toml");
/// The heavy-slider set (8 kg counterweight, 50 kg slider): the constant-speed model's regime,
/// where the model-gap workflow's base model holds (`params/heavy-slider.toml`).
pub const HEAVY_SLIDER_TOML: &str = include_str!("../../params/heavy-slider.toml");

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Params {
    pub stack: Stack,
    pub amplifier: Amplifier,
    pub stator: Stator,
    pub contact: Contact,
    pub friction: Friction,
    pub slider: Slider,
    pub sensors: Sensors,
    pub integrator: Integrator,
    /// Which steady-state model stands for this motor where a model is fitted to it (the gap
    /// workflow's base); absent: the constant-speed model.
    #[serde(default)]
    pub model: ModelChoice,
    /// Effects beyond the base model (`crate::motor::effects`); optional, absent in the base model.
    #[serde(default, skip_serializing_if = "Effects::is_none")]
    pub effects: Effects,
}

/// Piezo stacks (PL055.30 in the prototype).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Stack {
    /// Free stroke per volt (2.2 µm at 100 V).
    pub stroke_m_per_v: f64,
    /// Effective stack stiffness `kT` in the assembly; the stack force is `kT · stroke` (eq. 3).
    pub stiffness_n_per_m: f64,
}

/// The two-channel high-voltage amplifier between DAC and stacks.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Amplifier {
    pub output_min_v: f64,
    pub output_max_v: f64,
    /// First-order small-signal bandwidth driving the stack capacitance.
    pub bandwidth_hz: f64,
    /// DAC update rate; the amplifier sees a zero-order hold at this rate.
    pub dac_rate_hz: f64,
}

/// Stator normal dynamics, eqs. (1)–(7): foot `m1`, counterweight `m2`, `k1 = kT + kS`, preload `k2`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Stator {
    pub foot_mass_kg: f64,
    pub counterweight_mass_kg: f64,
    /// Flexure stiffness `kS`; `k1 = kT + kS`.
    pub flexure_stiffness_n_per_m: f64,
    pub preload_spring_n_per_m: f64,
    /// ρ = ρ' of eq. (3): share of each stack force that acts normal to the slider.
    pub normal_force_ratio: f64,
    /// λ of eq. (1): tangential foot displacement per metre of summed stack stroke.
    pub tangential_scale: f64,
    /// Damping ratio of the stator's structural modes (across `k1`, and across `k2` unless
    /// `preload_damping_ratio` is given).
    pub damping_ratio: f64,
    /// Damping ratio of the stator's rigid-body mode on the preload spring `k2` (the stator's
    /// guide and the spring mount). Absent: `damping_ratio`. The paper takes the preload as a
    /// constant force (eq. 12); a lightly damped mode here rings between the foot's impacts and
    /// moves the contact arc off the foot's peak speed (see `host-sim trace`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub preload_damping_ratio: Option<f64>,
}

impl Stator {
    /// Damping ratio of the mode on the preload spring.
    pub fn preload_mode_damping_ratio(&self) -> f64 {
        self.preload_damping_ratio.unwrap_or(self.damping_ratio)
    }
}

/// Foot/slider normal contact, eq. (10).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Contact {
    /// `kc = k3 = Ec·Ac/hc` (ceramic 2e9, 45 steel 1e9, epoxy 5e8 N/m).
    pub stiffness_n_per_m: f64,
    /// Coefficient of restitution `e` of the foot landing on the slider: the rebound speed over
    /// the approach speed of the foot alone on the contact spring (a property of the contact
    /// pair; `1 − e²` of the approach's kinetic energy is lost per impact). The plant's contact
    /// is a unilateral Kelvin–Voigt spring–dashpot whose damping ratio gives this `e`
    /// ([`damping_ratio_for_restitution`]); from `e^{−2} ≈ 0.135` (critically damped) to 1.
    pub restitution: f64,
    /// Tangential (shear) stiffness of the friction layer: the pre-sliding spring between foot
    /// and slider while they stick (Coulomb laws). For a layer in shear `kt = G·Ac/hc =
    /// kc/(2(1+ν))`; 0 = rigid (the slider takes the foot's speed exactly while sticking).
    #[serde(default)]
    pub tangential_stiffness_n_per_m: f64,
    /// How the friction layer's shear dashpot and slip are modelled.
    #[serde(default)]
    pub friction_layer: FrictionLayer,
}

/// The steady-state model a parameter file selects (`[model]`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModelChoice {
    #[serde(default)]
    pub steady: SteadyModel,
}

/// The steady-state thrust models of `crate::motor`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum SteadyModel {
    /// Eqs. 13–22 at a constant slider speed (`steady.rs`): exact for a heavy carriage, closed
    /// form and fast.
    #[default]
    ConstantSpeed,
    /// The contact's timing and the carriage's periodic motion (`steady_contact.rs`): the
    /// stator's normal motion solved with its impacts, the carriage riding the foot. Within a
    /// few per cent of the plant on every carriage; milliseconds per point.
    Contact,
}

/// The friction layer's law (Coulomb friction models with `tangential_stiffness_n_per_m > 0`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FrictionLayer {
    /// One Kelvin–Voigt material: the shear dashpot is `kt` times the contact's retardation time
    /// `c3/kc`, independent of the carriage; in slip the layer carries the sliding force and
    /// relaxes toward it (`kt·s + ct·ṡ = F`), so the force is continuous when it sticks again.
    #[default]
    KelvinVoigt,
    /// The earlier law, without a source (issue 28): a dashpot at the contact's damping ratio on
    /// the carriage's mass, `ct = 2ζ·√(kt·M)`, and in slip the layer set to `F/kt` at once. Kept
    /// only while the controller's model is brought to the sourced plant.
    MassScaled,
}

impl Contact {
    /// Damping ratio of the foot on the contact spring that gives [`Contact::restitution`].
    pub fn damping_ratio(&self) -> f64 {
        damping_ratio_for_restitution(self.restitution)
    }
}

/// Restitution of a mass landing on a unilateral Kelvin–Voigt contact of damping ratio `ζ < 1`
/// (no other force acting). The contact force `k·x + c·ẋ` starts at `c·v0` and ends when it
/// falls back to zero (the contact cannot pull), at `ωd·t = θ` with
/// `tan θ = −2ζ√(1−ζ²)/(1−2ζ²)`, θ in (0, π): then
/// `e = −e^{−ζθ/√(1−ζ²)}·(cos θ − ζ/√(1−ζ²)·sin θ)`. At ζ = 1 (the limit) `e = e^{−2}`.
pub fn restitution_for_damping_ratio(zeta: f64) -> f64 {
    let z = zeta.clamp(0.0, 1.0);
    if z >= 1.0 - 1e-12 {
        return (-2.0f64).exp();
    }
    let s = (1.0 - z * z).sqrt();
    let theta = std::f64::consts::PI - (2.0 * z * s).atan2(1.0 - 2.0 * z * z);
    -(-z * theta / s).exp() * (theta.cos() - z / s * theta.sin())
}

/// The damping ratio whose [`restitution_for_damping_ratio`] is `e` (bisection: `e(ζ)` falls
/// monotonically from 1 at ζ = 0 to `e^{−2}` at ζ = 1); `e` outside that range is clamped.
/// The last answer is kept per thread: the contact's dashpot is asked for at every row of every
/// evaluation of the gap workflow, always of the same restitution, and its 80 bisection steps
/// (each an arctangent, an exponential, a sine and a cosine) were a tenth of the workflow's time.
pub fn damping_ratio_for_restitution(e: f64) -> f64 {
    thread_local! {
        static LAST: std::cell::Cell<Option<(u64, f64)>> = const { std::cell::Cell::new(None) };
    }
    if let Some((bits, zeta)) = LAST.with(std::cell::Cell::get) {
        if bits == e.to_bits() {
            return zeta;
        }
    }
    let zeta = bisect_damping_ratio(e);
    LAST.with(|last| last.set(Some((e.to_bits(), zeta))));
    zeta
}

fn bisect_damping_ratio(e: f64) -> f64 {
    let (mut lo, mut hi) = (0.0, 1.0);
    if e >= 1.0 {
        return 0.0;
    }
    if e <= restitution_for_damping_ratio(1.0) {
        return 1.0;
    }
    for _ in 0..80 {
        let mid = 0.5 * (lo + hi);
        if restitution_for_damping_ratio(mid) > e {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FrictionModel {
    /// Seed eq. (16): Coulomb with μd and a viscous part εc; stick solved exactly.
    Coulomb,
    /// Stick holds up to μs·Fc, slip at μd·Fc (interface paper, Fig. 1b).
    StaticDynamic,
    /// LuGre bristle model (interface paper, Fig. 1d).
    Lugre,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Friction {
    pub model: FrictionModel,
    /// μd: sliding friction coefficient.
    pub mu_dynamic: f64,
    /// μs: sticking limit (static/dynamic and LuGre's Stribeck peak).
    pub mu_static: f64,
    /// εc of eq. (16).
    pub viscous_n_s_per_m: f64,
    /// LuGre σ0 per newton of normal force.
    pub lugre_bristle_stiffness_per_m: f64,
    /// LuGre σ1 per newton of normal force.
    pub lugre_bristle_damping_s_per_m: f64,
    /// LuGre Stribeck speed.
    pub lugre_stribeck_speed_m_s: f64,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Slider {
    /// Moving mass, carriage plus what hangs on it.
    pub mass_kg: f64,
    /// Viscous drag of the guide.
    pub damping_n_s_per_m: f64,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Sensors {
    pub encoder_resolution_m: f64,
    pub force_cell_full_scale_n: f64,
    pub force_cell_adc_bits: u32,
    pub force_cell_noise_n: f64,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Integrator {
    /// Fixed plant step.
    pub step_s: f64,
}

impl Params {
    pub fn prototype() -> Self {
        // The shipped file is checked by a test; failing here would be a build defect.
        Self::from_toml(PROTOTYPE_TOML).expect("params/prototype.toml is valid")
    }

    /// The sourced prototype ([`PROTOTYPE_SOURCED_TOML`]).
    pub fn prototype_sourced() -> Self {
        Self::from_toml(PROTOTYPE_SOURCED_TOML).expect("params/prototype-sourced.toml is valid")
    }

    /// The heavy-slider set ([`HEAVY_SLIDER_TOML`]).
    pub fn heavy_slider() -> Self {
        Self::from_toml(HEAVY_SLIDER_TOML).expect("params/heavy-slider.toml is valid")
    }

    pub fn from_toml(text: &str) -> Result<Self> {
        let p: Params = toml::from_str(text).map_err(|e| {
            // One line: "line L, column C: message" instead of toml's multi-line excerpt.
            let (line, col) = match e.span() {
                Some(span) => {
                    let before = &text[..span.start.min(text.len())];
                    (
                        before.matches('\n').count() + 1,
                        before.len() - before.rfind('\n').map_or(0, |i| i + 1) + 1,
                    )
                }
                None => (0, 0),
            };
            // toml's message can run over several lines ("invalid table header\nexpected ..."):
            // keep the error on one.
            let message: Vec<&str> = e.message().lines().map(str::trim).filter(|l| !l.is_empty()).collect();
            anyhow::anyhow!("line {line}, column {col}: {}", message.join("; "))
        })?;
        p.validate()?;
        Ok(p)
    }

    pub fn load(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path)
            .with_context(|| format!("cannot read parameter file {}", path.display()))?;
        Self::from_toml(&text).with_context(|| format!("in {}", path.display()))
    }

    pub fn to_toml(&self) -> String {
        toml::to_string_pretty(self).unwrap_or_default()
    }

    /// Rejects values that make the physics meaningless (negative masses, zero stiffness, ...).
    pub fn validate(&self) -> Result<()> {
        let positive = [
            ("stack.stroke_m_per_v", self.stack.stroke_m_per_v),
            ("stack.stiffness_n_per_m", self.stack.stiffness_n_per_m),
            ("amplifier.bandwidth_hz", self.amplifier.bandwidth_hz),
            ("amplifier.dac_rate_hz", self.amplifier.dac_rate_hz),
            ("stator.foot_mass_kg", self.stator.foot_mass_kg),
            ("stator.counterweight_mass_kg", self.stator.counterweight_mass_kg),
            ("stator.preload_spring_n_per_m", self.stator.preload_spring_n_per_m),
            ("stator.normal_force_ratio", self.stator.normal_force_ratio),
            ("stator.tangential_scale", self.stator.tangential_scale),
            ("contact.stiffness_n_per_m", self.contact.stiffness_n_per_m),
            ("friction.mu_dynamic", self.friction.mu_dynamic),
            ("friction.lugre_bristle_stiffness_per_m", self.friction.lugre_bristle_stiffness_per_m),
            ("friction.lugre_stribeck_speed_m_s", self.friction.lugre_stribeck_speed_m_s),
            ("slider.mass_kg", self.slider.mass_kg),
            ("sensors.encoder_resolution_m", self.sensors.encoder_resolution_m),
            ("sensors.force_cell_full_scale_n", self.sensors.force_cell_full_scale_n),
            ("integrator.step_s", self.integrator.step_s),
        ];
        for (name, v) in positive {
            if !(v.is_finite() && v > 0.0) {
                bail!("{name} must be a positive number, got {v}");
            }
        }
        let non_negative = [
            ("stator.flexure_stiffness_n_per_m", self.stator.flexure_stiffness_n_per_m),
            ("stator.damping_ratio", self.stator.damping_ratio),
            ("stator.preload_damping_ratio", self.stator.preload_mode_damping_ratio()),
            ("contact.tangential_stiffness_n_per_m", self.contact.tangential_stiffness_n_per_m),
            ("friction.viscous_n_s_per_m", self.friction.viscous_n_s_per_m),
            ("friction.lugre_bristle_damping_s_per_m", self.friction.lugre_bristle_damping_s_per_m),
            ("slider.damping_n_s_per_m", self.slider.damping_n_s_per_m),
            ("sensors.force_cell_noise_n", self.sensors.force_cell_noise_n),
        ];
        for (name, v) in non_negative {
            if !(v.is_finite() && v >= 0.0) {
                bail!("{name} must be zero or positive, got {v}");
            }
        }
        let e_min = restitution_for_damping_ratio(1.0);
        if !(self.contact.restitution >= e_min && self.contact.restitution <= 1.0) {
            bail!(
                "contact.restitution must be within {e_min:.3}–1 (critically damped to elastic), got {}",
                self.contact.restitution
            );
        }
        if self.friction.mu_static < self.friction.mu_dynamic {
            bail!("friction.mu_static must be at least friction.mu_dynamic");
        }
        if self.amplifier.output_max_v.partial_cmp(&self.amplifier.output_min_v)
            != Some(std::cmp::Ordering::Greater)
        {
            bail!("amplifier.output_max_v must exceed amplifier.output_min_v");
        }
        if !(1..=24).contains(&self.sensors.force_cell_adc_bits) {
            bail!("sensors.force_cell_adc_bits must be 1..=24");
        }
        if self.integrator.step_s > 1e-4 {
            bail!("integrator.step_s above 100 µs cannot resolve the drive period");
        }
        self.effects.validate()
    }

    /// `k1 = kT + kS` (paper §2.1).
    pub fn k1_n_per_m(&self) -> f64 {
        self.stack.stiffness_n_per_m + self.stator.flexure_stiffness_n_per_m
    }

    /// Mid-range voltage: the sine drive swings around it.
    pub fn amplifier_mid_v(&self) -> f64 {
        0.5 * (self.amplifier.output_min_v + self.amplifier.output_max_v)
    }
}
