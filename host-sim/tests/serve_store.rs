//! `host-sim serve --store FILE` keeps what the board keeps: `WPA` writes the core's flash record
//! (`piezo_drive::storage::encode`) byte for byte, and a restart loads it as the firmware loads
//! its flash page. So this test, through the virtual controller's TCP port, shows what the board
//! does: every stored parameter comes back after a restart, the others are at their defaults.

use host_sim::motor::params::Params;
use host_sim::virtual_controller::gcs_client::GcsClient;
use piezo_drive::controller::ReferenceSignal;
use std::ffi::OsStr;
use std::path::Path;
use std::process::Child;

mod common;

/// `host-sim serve --store store` on a free port; returns the child and its address.
fn serve(store: &Path) -> (Child, String) {
    common::serve(60, [OsStr::new("--store"), store.as_os_str()])
}

/// Every settable parameter away from its default: id, the value sent (`SPA`, or `VEL`/`ACC`/
/// `DEC` for 0xA–0xC), and what `SPA?` must print for it.
const SET: &[(&str, &str, &str)] = &[
    ("0x1", "55.5", "55.5"),
    ("0x2", "0.002", "0.002"),
    ("0x8", "0.04", "0.04"),
    ("0xA", "1.5", "1.5"),
    ("0xB", "500", "500"),
    ("0xC", "250", "250"),
    ("0x15", "20", "20.000000"),
    ("0x30", "-3.5", "-3.500000"),
    ("0x36", "0.0001", "0.000100"),
    ("0x3F", "0.02", "0.02"),
    ("0x1001", "1500", "1500"),
    ("0x1002", "90", "90"),
    ("0x1003", "0.5", "0.5"),
    ("0x1004", "0.6", "0.6"),
    ("0x1005", "0", "0"),
    ("0x1006", "0.004", "0.004"),
    ("0x1007", "0.3", "0.3"),
    ("0x1008", "-1.25", "-1.25"),
    ("0x1009", "0.003", "0.003"),
    ("0x100A", "0.25", "0.25"),
    ("0x100B", "0.0005", "0.0005"),
    ("0x100D", "0.08", "0.08"),
    ("0x100E", "300", "300"),
    ("0x100F", "4", "4"),
    ("0x1010", "20", "20"),
    ("0x1011", "7", "7"),
    ("0x1012", "0.0125", "0.0125"),
    ("0x1013", "3", "3"),
    ("0x1014", "4000", "4000"),
    ("0x1015", "0.05", "0.05"),
    ("0x1016", "1", "1"),
    ("0x1017", "-1", "-1.000000"),
    ("0x1018", "40", "40"),
    ("0x1019", "100", "100"),
    ("0x101A", "0.45", "0.45"),
    ("0x101B", "0.28", "0.28"),
    ("0x101C", "0.19", "0.19"),
    ("0x101D", "0.6", "0.6"),
    ("0x101E", "0.4", "0.4"),
    ("0x101F", "2.5", "2.5"),
    ("0x1022", "900", "900"),
    ("0x1023", "120", "120"),
    ("0x1024", "1", "1"),
    ("0x1025", "1", "1"),
    ("0x1026", "1", "1"),
    ("0x1040", "1", "1"),
];

/// The read-only parameters (hardware facts, not stored) at the simulated board's values:
/// 50 nm encoder, 10 kHz loop.
/// Counts per mm 20000/1; the acceleration limits the top of an f32 in nm/s^2, in mm/s^2.
const READ_ONLY: &[(&str, &str)] = &[
    ("0xE", "20000"),
    ("0xF", "1"),
    ("0x4A", "3.4028233e32"),
    ("0x4B", "3.4028233e32"),
    ("0x1020", "50"),
    ("0x1021", "10000"),
    ("0xE000200", "0.0001"),
    ("0x16000201", "1024"),
];

/// Another row seen in PI's units (0x50: 0x1018 as a speed): neither stored nor fixed, it
/// comes back as it read before the restart.
const ALIASES: &[&str] = &["0x50"];

/// `SPA?` as (id, value) pairs.
fn all_parameters(c: &mut GcsClient) -> Vec<(String, String)> {
    let reply = c.query("SPA?").expect("SPA?");
    reply
        .lines()
        .map(|l| {
            let (head, value) = l.split_once('=').expect("1 <id>=<value>");
            (head.trim_start_matches("1 ").to_string(), value.to_string())
        })
        .collect()
}

#[test]
fn wpa_then_restart_brings_back_every_stored_parameter_and_nothing_else() {
    let store = std::env::temp_dir().join(format!("serve-store-{}.bin", std::process::id()));
    let _ = std::fs::remove_file(&store);

    let (mut server, addr) = serve(&store);
    let defaults = {
        let mut c = GcsClient::connect_tcp(&addr).expect("connect");
        let defaults = all_parameters(&mut c);
        for (id, sent, _) in SET {
            match *id {
                "0xA" => c.command(&format!("VEL 1 {sent}")),
                "0xB" => c.command(&format!("ACC 1 {sent}")),
                "0xC" => c.command(&format!("DEC 1 {sent}")),
                _ => c.command(&format!("SPA 1 {id} {sent}")),
            }
            .unwrap_or_else(|e| panic!("{id} = {sent} not accepted: {e}"));
        }
        c.command("WPA 100").expect("WPA");
        (defaults, all_parameters(&mut c))
    };
    let (defaults, stored_view) = defaults;
    let _ = server.kill();
    let _ = server.wait();
    // Every settable parameter was changed: none of them still reads its default.
    for (id, _, shown) in SET {
        let default = defaults.iter().find(|(i, _)| i == id).map(|(_, v)| v.as_str());
        assert_ne!(default, Some(*shown), "{id} was already at its default");
    }

    // The file is the board's record of that configuration, byte for byte.
    let p = Params::prototype();
    let mut expected = host_sim::harness::sil::controller_config(&p);
    let c = &mut expected;
    (c.kp_per_s, c.ki_n_per_nm_s, c.following_error_limit_nm) = (55.5, 0.002, 40_000.0);
    (c.velocity_max_nm_s, c.accel_max_nm_s2, c.decel_max_nm_s2) = (1.5e6, 5e8, 2.5e8);
    (c.travel_max_nm, c.travel_min_nm, c.on_target_window_nm, c.settle_time_s) =
        (20_000_000, -3_500_000, 100, 0.02);
    (c.drive_freq_hz, c.max_drive_v, c.speed_fraction, c.accel_fraction) = (1500.0, 90.0, 0.5, 0.6);
    (c.feedforward, c.fb_kp_v_per_nm, c.fb_ki_v_per_nm_s, c.expected_load_n) = (false, 0.004, 0.3, -1.25);
    (c.profile_wait_lag_nm, c.approach_speed_nm_s, c.fine_window_nm) = (3000.0, 250_000.0, 500.0);
    (c.stall_time_s, c.encoder_jump_counts, c.preload_min_n, c.preload_max_n) = (0.08, 300, 4.0, 20.0);
    c.preload.zero_word = 7;
    c.preload.newton_per_word = 0.0125;
    (c.preload.min_valid_word, c.preload.max_valid_word, c.preload.filter_alpha) = (3, 4000, 0.05);
    (c.reference_signal, c.reference_position_nm) = (ReferenceSignal::NegativeLimit, -1_000_000);
    (c.reference_drive_v, c.reference_timeout_s, c.moving_mass_kg) = (40.0, 100.0, 0.45);
    (c.mu_dynamic, c.tangential_scale, c.normal_force_ratio) = (0.28, 0.19, 0.6);
    (c.rail_coulomb_n, c.rail_viscous_n_s_per_m) = (0.4, 2.5);
    c.drive_freq_min_hz = 900.0;
    c.encoder_loss_counts = 120;
    c.idn_c867_compatible = true;
    c.contact_table = true;
    (c.limit_switches_enabled, c.limit_switch_active_high) = (true, true);
    let record = std::fs::read(&store).expect("WPA wrote the store");
    assert_eq!(record, piezo_drive::storage::encode(&expected).to_vec());

    // Restarted, the virtual controller reads every stored parameter back, and the rest (the
    // read-only hardware facts) at their defaults.
    let (mut server, addr) = serve(&store);
    let after = {
        let mut c = GcsClient::connect_tcp(&addr).expect("connect after restart");
        all_parameters(&mut c)
    };
    let _ = server.kill();
    let _ = server.wait();
    let _ = std::fs::remove_file(&store);
    let mut want: Vec<(String, String)> =
        SET.iter().map(|(id, _, shown)| (id.to_string(), shown.to_string())).collect();
    want.extend(READ_ONLY.iter().map(|(id, v)| (id.to_string(), v.to_string())));
    // In the table's (id) order, as `SPA?` lists them.
    want.sort_by_key(|(id, _)| u32::from_str_radix(id.trim_start_matches("0x"), 16).unwrap_or(u32::MAX));
    let (aliases, after): (Vec<_>, Vec<_>) =
        after.into_iter().partition(|(id, _)| ALIASES.contains(&id.as_str()));
    assert_eq!(after, want);
    for (id, v) in aliases {
        assert!(stored_view.contains(&(id.clone(), v.clone())), "{id}={v} before the restart too");
    }
    for (id, v) in READ_ONLY {
        assert!(defaults.contains(&(id.to_string(), v.to_string())), "{id} default");
    }
}
