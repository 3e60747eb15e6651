//! What a calibration of the board is: the parameter file's values the firmware takes, by GCS
//! parameter id, and the one `SPA` line that sets them (`calibrate` sends it to a board,
//! `calibrate --tune` to the simulated one).

use crate::motor::effects::Effect;
use crate::motor::params::Params;

/// The effects the firmware's model carries (through the parameters below).
const CARRIED: &[Effect] = &[Effect::RailFriction, Effect::SliderInertia];

/// The values to upload: (id, parameter-file name, value), in one `SPA` line.
pub fn calibration_values(p: &Params) -> Vec<(u32, &'static str, f32)> {
    let rail = p
        .effects
        .rail_friction
        .unwrap_or(crate::motor::effects::RailFriction { rail_coulomb_n: 0.0, rail_viscous_n_s_per_m: 0.0 });
    // f32 is what the controller keeps; what is sent is what it will read back.
    let mut values = vec![
        (0x101B, "friction.mu_dynamic", p.friction.mu_dynamic as f32),
        (0x101C, "stator.tangential_scale", p.stator.tangential_scale as f32),
        (0x101D, "stator.normal_force_ratio", p.stator.normal_force_ratio as f32),
        // Absent from the file = no guide friction: a calibration before this one is cleared.
        (0x101E, "rail_friction.rail_coulomb_n", rail.rail_coulomb_n as f32),
        (0x101F, "rail_friction.rail_viscous_n_s_per_m", rail.rail_viscous_n_s_per_m as f32),
    ];
    // The carriage's inertia found by the workflow is the controller's moving mass; without the
    // effect the mass the user set stays.
    if let Some(i) = p.effects.slider_inertia.filter(|i| i.inverse_mass_per_kg > 0.0) {
        values.insert(0, (0x101A, "slider_inertia (moving mass, kg)", (1.0 / i.inverse_mass_per_kg) as f32));
    }
    values
}

/// The file's active effects the firmware cannot take.
pub fn not_carried(p: &Params) -> Vec<String> {
    p.effects.active().into_iter().filter(|e| !CARRIED.contains(e)).map(|e| e.name().to_string()).collect()
}

/// The `SPA` line that sets `values` on axis 1, all in one command (checked as a whole).
pub fn spa_line(values: &[(u32, &'static str, f32)]) -> String {
    values.iter().fold(String::from("SPA"), |mut s, (id, _, v)| {
        s.push_str(&format!(" 1 0x{id:X} {v}"));
        s
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_carriage_inertia_goes_up_as_the_moving_mass_and_other_effects_are_listed() {
        let mut p = Params::heavy_slider();
        assert!(calibration_values(&p).iter().all(|(id, _, _)| *id != 0x101A), "no effect: mass kept");
        p.effects.set("inverse_mass_per_kg", 0.25).unwrap();
        p.effects.set("stribeck_rise", 0.5).unwrap();
        let mass = calibration_values(&p).into_iter().find(|(id, _, _)| *id == 0x101A).map(|(_, _, v)| v);
        assert_eq!(mass, Some(4.0));
        assert_eq!(not_carried(&p), vec!["stribeck_friction".to_string()]);
    }
}
