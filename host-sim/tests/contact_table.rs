//! The controller's model table from host-sim's contact model (`harness::contact_table`, the
//! `sweep --model contact` instrument of issue 28 item 4) against the time-domain plant.

use host_sim::harness::contact_table::contact_table;
use host_sim::harness::sil::{controller_config, Sil};
use host_sim::motor::params::Params;
use host_sim::motor::plant::steady_speed_m_s;

#[test]
fn the_contact_tables_full_drive_speed_is_the_plants() {
    // The table's no-load speed at full drive against the plant's steady speed at the table's
    // preload and frequency: the light carriage, where the core's own table runs 20-25 % slow
    // (docs/simulator.md), and the default one.
    for mass_kg in [0.1, 1.0] {
        let mut p = Params::prototype();
        p.slider.mass_kg = mass_kg;
        let mut sil = Sil::new(&p, controller_config(&p), 16.0, 7).expect("a board");
        // The controller's first request, as the board's slow task sees it.
        let request = (0..1000)
            .find_map(|_| {
                let inputs = sil.inputs();
                sil.controller.step(&inputs);
                sil.controller.model_request()
            })
            .expect("a request once the preload is read");
        let table = contact_table(&p, &request, request.preload_n);
        let r = table.request();
        let plant_mm_s = steady_speed_m_s(
            &p,
            f64::from(r.preload_n),
            f64::from(r.max_drive_v),
            f64::from(r.frequency_hz),
            1,
            0.0,
        ) * 1e3;
        let table_mm_s = f64::from(table.no_load_mm_s());
        eprintln!(
            "{mass_kg} kg at {} N, {} Hz: table {table_mm_s:.4} mm/s, plant {plant_mm_s:.4}",
            r.preload_n, r.frequency_hz
        );
        assert!(
            (table_mm_s - plant_mm_s).abs() < 0.03 * plant_mm_s,
            "{mass_kg} kg: table {table_mm_s:.4} mm/s against the plant's {plant_mm_s:.4}"
        );
    }
}
