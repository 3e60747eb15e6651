//! The controller's model table from host-sim's contact model (`motor::steady_contact`) instead
//! of the core's own build: what the controller would do with a model that is the motor (issue
//! 28 item 4), measured on the host. Not for the board: one such table solves the stator's
//! normal motion at each of the grid's 33 drives and the carriage's orbit at each of its 33
//! loads, far past what the Cortex-M4 may spend on a table build (docs/simulator.md).

use crate::motor::params::Params;
use crate::motor::steady::OperatingPoint;
use crate::motor::steady_contact::{ContactModel, OrbitStart};
use piezo_drive::controller::model_cache::{with_guide_friction, ModelRequest, ModelTable};

/// Where the controller's model table comes from in a loop harness.
#[derive(Debug, Clone, Default)]
pub enum TableModel {
    /// The core's own build (`ModelTable::build`), as on the board.
    #[default]
    Core,
    /// The contact model of this parameter file (the firmware's belief; the carriage's mass is
    /// the one the controller is told).
    Contact(Box<Params>),
    /// The core's own build from its copy of the contact model (setting 0x1024 = 1), as a board
    /// told to use it builds it.
    CoreContact,
}

/// The table for `request` from the contact model of `p` at the static preload `static_n` (N):
/// the frequency chosen where the contact model runs fastest at full drive against the choice's
/// load, then every row of the grid and the speed table from the contact model's orbits (each
/// load's search started from the last one's orbit at the same drive). The request's own preload
/// is the force cell's reading, which under drive is the mean contact force, not the static
/// preload the model takes (see `harness::sil`).
pub fn contact_table(p: &Params, request: &ModelRequest, static_n: f32) -> ModelTable {
    let mut told = p.clone();
    told.slider.mass_kg = f64::from(request.moving_mass_kg);
    // The table takes the guide's friction off by itself (the request's rail friction).
    told.effects.rail_friction = None;
    let model_at = |volts: f32, frequency_hz: f32| {
        let op = OperatingPoint {
            preload_n: f64::from(static_n),
            voltage_v: f64::from(volts),
            frequency_hz: f64::from(frequency_hz),
        };
        ContactModel::new(&told, op)
    };
    let chosen = request.chosen_with(|candidate| {
        let model = model_at(candidate.max_drive_v, candidate.frequency_hz);
        with_guide_friction(candidate, candidate.choice.load_n.max(0.0), |foot_load| {
            model.speed_at_load_m_s(f64::from(foot_load)).map_or(0.0, |v| (v * 1e3) as f32)
        })
    });
    let mut models: Vec<(f32, ContactModel, Option<OrbitStart>)> = Vec::new();
    ModelTable::from_speed_law(&chosen, |volts, load_n| {
        let i = match models.iter().position(|m| m.0 == volts) {
            Some(i) => i,
            None => {
                models.push((volts, model_at(volts, chosen.frequency_hz), None));
                models.len() - 1
            }
        };
        let (_, model, hint) = models.get_mut(i)?;
        let (orbit, start) = model.orbit_near(f64::from(load_n), *hint)?;
        *hint = Some(start);
        Some((orbit.mean_speed_m_s * 1e3) as f32)
    })
}
