//! The motor as the contact model takes it: the stator's normal dynamics (eqs. 4, 6, 10), the
//! stacks' drive (eqs. 1, 3), the contact pair and its friction layer, in SI units and f32. From
//! these the core solves one operating point's contact force ([`crate::normal_motion`]) and the
//! carriage's orbit on it ([`crate::contact_orbit`]); the model table's contact build
//! ([`crate::controller::table_build`]) does that per drive row.
//!
//! Generated with the rest of the motor table from the parameter file (`host-sim
//! firmware-table`), so the board's contact model is the simulator's plant's, constant for
//! constant; the calibrated ρ, λ and μ of the settings replace the file's.

use crate::contact_orbit::Carriage;
use crate::normal_motion::{NormalDrive, Stator};

/// How the friction layer's shear dashpot is set (host-sim's `friction_layer`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum LayerLaw {
    /// One Kelvin–Voigt material in shear and compression: `ct = kt·c3/kc`.
    #[default]
    KelvinVoigt,
    /// The contact's damping ratio on the carriage's mass: `ct = 2ζc·√(kt·M)`.
    MassScaled,
}

/// The motor's constants for the contact model (SI).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ContactMotor {
    /// Free stroke of one stack per volt (m/V), and its stiffness kT (N/m), eq. (3).
    pub stroke_m_per_v: f32,
    pub stack_n_per_m: f32,
    /// The flexure beside the stacks, kS: k1 = kT + kS.
    pub flexure_n_per_m: f32,
    /// m1 and m2, eqs. (4), (6).
    pub foot_mass_kg: f32,
    pub counterweight_mass_kg: f32,
    /// k2, the preload spring.
    pub preload_spring_n_per_m: f32,
    /// Damping ratios of the structural mode (across k1) and the preload mode.
    pub damping_ratio: f32,
    pub preload_damping_ratio: f32,
    /// The contact spring kc (eq. 10) and its damping ratio on the foot (from the pair's
    /// restitution).
    pub contact_n_per_m: f32,
    pub contact_damping_ratio: f32,
    /// The friction layer's shear stiffness kt and its dashpot's law.
    pub tangential_n_per_m: f32,
    pub layer: LayerLaw,
    /// Viscous friction εc of eq. (16) (N·s/m).
    pub viscous_n_s_per_m: f32,
    /// Time constant of each of the amplifier's two equal poles (s).
    pub amplifier_tau_s: f32,
}

/// The calibrated values that replace the file's: ρ (eq. 3), λ (eq. 1) and μ.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Calibration {
    pub normal_force_ratio: f32,
    pub tangential_scale: f32,
    pub mu: f32,
}

/// One operating point of the contact model: what the normal motion and the orbit take.
#[derive(Debug, Clone, Copy)]
pub struct ContactPoint {
    pub stator: Stator,
    pub drive: NormalDrive,
    pub carriage: Carriage,
}

impl ContactMotor {
    /// Whether the constants describe a motor (a table generated before they existed has none).
    pub fn is_present(&self) -> bool {
        self.foot_mass_kg > 0.0 && self.contact_n_per_m > 0.0 && self.stroke_m_per_v > 0.0
    }

    /// The amplifier's gain at `frequency_hz`: two equal poles.
    fn amplifier_gain(&self, frequency_hz: f32) -> f32 {
        let wt = core::f32::consts::TAU * frequency_hz * self.amplifier_tau_s;
        1.0 / (1.0 + wt * wt)
    }

    /// The operating point at a static preload, a drive (V peak-to-peak, both stacks) and a
    /// frequency, for a carriage of `mass_kg` whose guide the table takes off itself.
    pub fn point(
        &self,
        cal: &Calibration,
        preload_n: f32,
        volts: f32,
        frequency_hz: f32,
        mass_kg: f32,
    ) -> ContactPoint {
        let (m1, m2) = (self.foot_mass_kg, self.counterweight_mass_kg);
        let k1 = self.stack_n_per_m + self.flexure_n_per_m;
        let k2 = self.preload_spring_n_per_m;
        let c1 = 2.0 * self.damping_ratio * sqrt(k1 * m1 * m2 / (m1 + m2));
        let c2 = 2.0 * self.preload_damping_ratio * sqrt(k2 * (m1 + m2));
        let kc = self.contact_n_per_m;
        let c3 = 2.0 * self.contact_damping_ratio * sqrt(kc * m1);
        // Eq. (3): each stack's force amplitude kT·stroke, the normal sum √2·ρ of it; eq. (1):
        // the foot's tangential amplitude √2·λ·stroke.
        let stroke_m = self.stroke_m_per_v * 0.5 * volts * self.amplifier_gain(frequency_hz);
        let normal_force_n =
            core::f32::consts::SQRT_2 * cal.normal_force_ratio * self.stack_n_per_m * stroke_m;
        let xc_m = core::f32::consts::SQRT_2 * cal.tangential_scale * stroke_m;
        let kt = self.tangential_n_per_m;
        let ct = match self.layer {
            LayerLaw::KelvinVoigt => kt * c3 / kc,
            LayerLaw::MassScaled => 2.0 * self.contact_damping_ratio * sqrt(kt * mass_kg),
        };
        ContactPoint {
            stator: Stator {
                foot_mass_kg: m1,
                counterweight_mass_kg: m2,
                stack_n_per_m: k1,
                preload_spring_n_per_m: k2,
                stack_damping_n_s_per_m: c1,
                preload_damping_n_s_per_m: c2,
                contact_n_per_m: kc,
                contact_damping_n_s_per_m: c3,
            },
            drive: NormalDrive { frequency_hz, normal_force_n, preload_n },
            carriage: Carriage {
                mass_kg,
                kt_n_per_m: kt,
                ct_n_s_per_m: ct,
                mu_stick: cal.mu,
                mu_dynamic: cal.mu,
                viscous_n_s_per_m: self.viscous_n_s_per_m,
                guide_n_s_per_m: 0.0,
                foot_peak_m_s: core::f32::consts::TAU * frequency_hz * xc_m,
                frequency_hz,
            },
        }
    }
}

/// √x on the FPU (0 for x ≤ 0).
fn sqrt(x: f32) -> f32 {
    crate::fastmath::sqrt_f32(x.max(0.0))
}
