//! Friction between the foot and the slider for the Coulomb laws (seed eq. 16 and the interface
//! paper's static/dynamic law), with the friction layer between them: one step of the tangential
//! contact, shared by the time-domain plant and the steady-state model with the contact's timing
//! (`steady_contact`), so the two integrate the same law.

use crate::motor::params::FrictionLayer;

/// The layer's constants and the friction coefficients of one run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrictionLaw {
    /// Shear stiffness `kt` of the friction layer; 0 = rigid.
    pub kt_n_per_m: f64,
    /// Its shear dashpot `ct`.
    pub ct_n_s_per_m: f64,
    pub layer: FrictionLayer,
    /// μd: sliding.
    pub mu_dynamic: f64,
    /// εc of eq. (16).
    pub viscous_n_s_per_m: f64,
}

/// A step's length and the carriage's mass with what the law's implicit updates take from them,
/// computed once per step length: every step of the steady model's orbits (hundreds of millions
/// in a gap analysis) divided by them five to seven times, a quarter of an orbit's time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepScale {
    pub dt_s: f64,
    /// dt/M: the carriage's speed change per newton-step.
    pub dt_per_kg: f64,
    /// M/dt (rigid contact).
    kg_per_dt: f64,
    /// 1/dt: the layer's shear rate from its change.
    per_dt: f64,
    /// The stick trial's force per unit of shear rate, `a` (Kelvin–Voigt: kt·dt/4 + ct/2,
    /// mass-scaled: kt·dt + ct), and `1/(1 + dt/M·a)`.
    stick_n_s_per_m: f64,
    stick_inv: f64,
    /// Kelvin–Voigt relaxation: ct/dt and `1/(kt + ct/dt)`.
    ct_per_dt: f64,
    relax_inv: f64,
    /// εc's implicit share: `k = εc·dt/M` and `1/(1 + k)`.
    viscous_k: f64,
    viscous_inv: f64,
    /// Kelvin–Voigt slip: relax by the exact `e^{−dt·kt/ct}` instead of implicit Euler
    /// ([`StepScale::with_exact_relaxation`]); the decay factor.
    exact_relaxation: bool,
    relax_decay: f64,
}

impl StepScale {
    pub fn new(law: &FrictionLaw, dt_s: f64, mass_kg: f64) -> Self {
        let (kt, ct) = (law.kt_n_per_m, law.ct_n_s_per_m);
        let dt_per_kg = dt_s / mass_kg;
        let stick_n_s_per_m = match law.layer {
            FrictionLayer::KelvinVoigt => 0.25 * kt * dt_s + 0.5 * ct,
            FrictionLayer::MassScaled => kt * dt_s + ct,
        };
        let ct_per_dt = ct / dt_s;
        let viscous_k = law.viscous_n_s_per_m * dt_per_kg;
        StepScale {
            dt_s,
            dt_per_kg,
            kg_per_dt: mass_kg / dt_s,
            per_dt: 1.0 / dt_s,
            stick_n_s_per_m,
            stick_inv: 1.0 / (1.0 + dt_per_kg * stick_n_s_per_m),
            ct_per_dt,
            relax_inv: 1.0 / (kt + ct_per_dt),
            viscous_k,
            viscous_inv: 1.0 / (1.0 + viscous_k),
            exact_relaxation: false,
            relax_decay: if ct > 0.0 { (-dt_s * kt / ct).exp() } else { 0.0 },
        }
    }

    /// The same step with the Kelvin–Voigt layer's relaxation in slip solved exactly: under the
    /// step's constant sliding force `F` the layer obeys `kt·s + ct·ṡ = F`, linear, so
    /// `s(dt) = F/kt + (s0 − F/kt)·e^{−dt·kt/ct}`. Implicit Euler (the default) lags that by
    /// a share of `dt·kt/ct` of the relaxation; the plant's step is of the order of `ct/kt`.
    pub fn with_exact_relaxation(mut self) -> Self {
        self.exact_relaxation = true;
        self
    }
}

/// What one step of the tangential contact acts on.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StepInput<'a> {
    /// The step's length and the carriage's mass ([`StepScale::new`] of the same law).
    pub scale: &'a StepScale,
    /// Slider speed at the start of the step.
    pub slider_m_s: f64,
    /// External force on the slider over the step (load, guide), along +x.
    pub external_n: f64,
    /// Mean normal contact force over the step.
    pub contact_n: f64,
    /// Foot's tangential speed at the end of the step.
    pub foot_m_s: f64,
    /// Sticking limit as a coefficient (μd for Coulomb, μs for static/dynamic, times effects).
    pub mu_stick: f64,
    /// Factor on μd while sliding (effects; 1 in the base model).
    pub mu_scale: f64,
}

/// What the interface did over the last step.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Mode {
    /// No contact.
    #[default]
    Free,
    Stick,
    /// Sliding, the friction on the slider along +x or −x.
    SlipForward,
    SlipBack,
}

/// The friction layer's state: its shear (foot contact point minus slider) and shear rate, and
/// what the interface did over the last step.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Layer {
    pub shear_m: f64,
    pub shear_rate_m_s: f64,
    pub mode: Mode,
}

/// The mode of a step that passed `friction_n` (not sticking).
#[inline]
fn sliding_mode(contact_n: f64, friction_n: f64) -> Mode {
    if contact_n <= 0.0 {
        Mode::Free
    } else if friction_n >= 0.0 {
        Mode::SlipForward
    } else {
        Mode::SlipBack
    }
}

impl Layer {
    /// One step: the friction force on the slider over the step (N). The slider's new speed is
    /// then `v + dt·(external + friction)/m` (the law is implicit in it).
    #[inline]
    pub fn step(&mut self, law: &FrictionLaw, i: &StepInput) -> f64 {
        if law.kt_n_per_m <= 0.0 {
            let (friction, mode) = rigid(law, i);
            self.mode = mode;
            return friction;
        }
        match law.layer {
            FrictionLayer::KelvinVoigt => self.kelvin_voigt(law, i),
            FrictionLayer::MassScaled => self.mass_scaled(law, i),
        }
    }

    /// A Kelvin–Voigt layer (shear spring `kt`, dashpot `ct`) in series with the Coulomb
    /// interface. While the interface sticks, the layer carries the foot's motion relative to the
    /// slider; when the force it would need exceeds the sticking limit the interface slides at
    /// μd·Fc, and the layer, carrying that force, relaxes toward `F/kt` with its own time
    /// constant `ct/kt` (`kt·s + ct·ṡ = F`). Re-sticking happens when the interface's slip speed
    /// `vf − ṡ − v` crosses zero, so the force is continuous. Without contact the layer relaxes
    /// toward zero the same way. Implicit in the slider speed and the shear, so a stiff layer on
    /// a light slider stays stable.
    #[inline]
    fn kelvin_voigt(&mut self, law: &FrictionLaw, i: &StepInput) -> f64 {
        let (c, kt) = (i.scale, law.kt_n_per_m);
        // Stick trial by the trapezoidal rule (energy-conserving for the undamped spring, so the
        // step adds no damping of its own): the layer shears at u = vf − v, s' = s + dt·(u0 + u)/2,
        // and the force over the step is F = kt·(s + s')/2 + ct·(u0 + u)/2 with u0 last step's
        // shear rate; v = v_old + dt·(ext + F)/m.
        let u0 = self.shear_rate_m_s;
        let a = c.stick_n_s_per_m;
        let v_stick = (i.slider_m_s
            + c.dt_per_kg * (i.external_n + kt * self.shear_m + a * (u0 + i.foot_m_s)))
            * c.stick_inv;
        let u = i.foot_m_s - v_stick;
        let trial = kt * self.shear_m + a * (u0 + u);
        if i.contact_n > 0.0 && trial.abs() <= i.mu_stick * i.contact_n {
            self.shear_m += 0.5 * c.dt_s * (u0 + u);
            self.shear_rate_m_s = u;
            self.mode = Mode::Stick;
            return trial;
        }
        // Sliding (or no contact: no force through the interface).
        let slide =
            if i.contact_n > 0.0 { i.mu_scale * law.mu_dynamic * i.contact_n * trial.signum() } else { 0.0 };
        // The layer relaxes toward slide/kt: kt·s' + ct·(s' − s)/dt = slide (implicit Euler: no
        // overshoot however short ct/kt is against the step).
        if c.exact_relaxation {
            // Exact: the shear rate at the step's end from the layer's own law.
            let s_eq = slide / kt;
            let s_new = s_eq + (self.shear_m - s_eq) * c.relax_decay;
            self.shear_rate_m_s = if law.ct_n_s_per_m > 0.0 {
                (slide - kt * s_new) / law.ct_n_s_per_m
            } else {
                (s_new - self.shear_m) * c.per_dt
            };
            self.shear_m = s_new;
        } else {
            let s_new = (slide + c.ct_per_dt * self.shear_m) * c.relax_inv;
            self.shear_rate_m_s = (s_new - self.shear_m) * c.per_dt;
            self.shear_m = s_new;
        }
        self.mode = sliding_mode(i.contact_n, slide);
        if i.contact_n > 0.0 {
            slide + viscous(law, i, slide)
        } else {
            0.0
        }
    }

    /// [`FrictionLayer::MassScaled`]: backward Euler with the dashpot on the carriage's mass; in
    /// slip the layer is set to the sliding force's shear at once.
    fn mass_scaled(&mut self, law: &FrictionLaw, i: &StepInput) -> f64 {
        let (c, kt, ct) = (i.scale, law.kt_n_per_m, law.ct_n_s_per_m);
        if i.contact_n <= 0.0 {
            self.shear_m = 0.0;
            self.mode = Mode::Free;
            return 0.0;
        }
        let a = c.stick_n_s_per_m;
        let v_new =
            (i.slider_m_s + c.dt_per_kg * (i.external_n + kt * self.shear_m + a * i.foot_m_s)) * c.stick_inv;
        let trial = kt * (self.shear_m + c.dt_s * (i.foot_m_s - v_new)) + ct * (i.foot_m_s - v_new);
        if trial.abs() <= i.mu_stick * i.contact_n {
            self.shear_m += c.dt_s * (i.foot_m_s - v_new);
            self.mode = Mode::Stick;
            trial
        } else {
            let slide = i.mu_scale * law.mu_dynamic * i.contact_n * trial.signum();
            self.shear_m = slide / kt;
            self.mode = sliding_mode(i.contact_n, slide);
            slide + viscous(law, i, slide)
        }
    }
}

/// Rigid contact (no layer): the friction needed to make the slider move with the foot at the end
/// of the step, if within the sticking limit; otherwise sliding friction (plus εc's viscous part)
/// in the direction of that need.
fn rigid(law: &FrictionLaw, i: &StepInput) -> (f64, Mode) {
    let need = i.scale.kg_per_dt * (i.foot_m_s - i.slider_m_s) - i.external_n;
    if i.contact_n <= 0.0 {
        (0.0, Mode::Free)
    } else if need.abs() <= i.mu_stick * i.contact_n {
        (need, Mode::Stick)
    } else {
        let coulomb = i.mu_scale * law.mu_dynamic * i.contact_n * need.signum();
        (coulomb + viscous(law, i, coulomb), sliding_mode(i.contact_n, coulomb))
    }
}

/// εc's viscous part `εc·(ẋ − v_new)`, implicit: `v_new` from this same update with `coulomb`.
#[inline]
fn viscous(law: &FrictionLaw, i: &StepInput, coulomb: f64) -> f64 {
    let c = i.scale;
    let v_new =
        (i.slider_m_s + c.dt_per_kg * (i.external_n + coulomb) + c.viscous_k * i.foot_m_s) * c.viscous_inv;
    law.viscous_n_s_per_m * (i.foot_m_s - v_new)
}
