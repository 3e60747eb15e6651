//! Each held row of physics.md §5, computed from the default parameter set and checked against
//! the band we hold (the paper's figure with its tolerance). Test point: 100 V, 1.5 kHz, ceramic.

use host_sim::motor::params::Params;
use host_sim::motor::steady::{amplitudes, OperatingPoint, ThrustModel};

fn at(preload_n: f64) -> ThrustModel {
    ThrustModel::new(
        &Params::prototype(),
        OperatingPoint { preload_n, voltage_v: 100.0, frequency_hz: 1500.0 },
    )
}

#[test]
fn stall_thrust_at_16n_is_within_3_8_to_4_8_n_around_the_papers_4_2_to_4_5_n() {
    // physics.md §5's held band: the paper simulates 4.5 N and measures 4.2 N.
    let f = at(16.0).stall_force_n();
    assert!((3.8..=4.8).contains(&f), "stall {f} N");
}

#[test]
fn stall_thrust_ratio_16n_over_10n_is_about_1_5() {
    let r = at(16.0).stall_force_n() / at(10.0).stall_force_n();
    assert!((1.2..=1.7).contains(&r), "ratio {r}");
}

#[test]
fn no_load_speed_at_10n_and_16n_is_about_2_5_mm_s_and_nearly_equal() {
    let v10 = at(10.0).no_load_speed_m_s() * 1e3;
    let v16 = at(16.0).no_load_speed_m_s() * 1e3;
    assert!((2.0..=3.0).contains(&v10), "10 N: {v10} mm/s");
    assert!((2.0..=3.0).contains(&v16), "16 N: {v16} mm/s");
    assert!(v10.max(v16) / v10.min(v16) <= 1.2, "{v10} vs {v16}");
}

#[test]
fn contact_becomes_permanent_near_20n() {
    // θc = 2π first at F0 = kc·Yc: find it by scanning the preload, not by reading kc·Yc.
    let mut f0 = 1.0;
    while !at(f0).full_contact() && f0 < 100.0 {
        f0 += 0.05;
    }
    assert!((17.0..=23.0).contains(&f0), "full contact from {f0} N");
    assert!(at(f0).contact_angle_rad >= std::f64::consts::TAU - 1e-9);
}

#[test]
fn speed_falls_above_25n() {
    let v16 = at(16.0).no_load_speed_m_s();
    let v25 = at(25.0).no_load_speed_m_s();
    let v40 = at(40.0).no_load_speed_m_s();
    assert!(v25 < v16 && v40 < v25, "{v16} {v25} {v40}");
}

#[test]
fn non_contact_amplitude_is_0_75_um_rising_with_frequency() {
    let p = Params::prototype();
    let y: Vec<f64> = [1000.0, 1500.0, 2000.0].iter().map(|&f| amplitudes(&p, 100.0, f).yn_m * 1e6).collect();
    for v in &y {
        assert!((0.6..=0.9).contains(v), "{y:?}");
    }
    assert!(y[0] < y[1] && y[1] < y[2], "not rising: {y:?}");
}

#[test]
fn max_thrust_ceramic_vs_epoxy_contact_at_the_papers_fixed_amplitude() {
    // Fig. 9 of the paper: ℜ = μ·kc·Yc with Yc held, kc from 2e9 (ceramic) to 5e8 (epoxy).
    let p = Params::prototype();
    let ceramic = at(16.0);
    let epoxy = ceramic.with_contact_force_amplitude(ceramic.kc_yc_n * 5e8 / p.contact.stiffness_n_per_m);
    let (fc, fe) = (ceramic.stall_force_n(), epoxy.stall_force_n());
    assert!(fc > 4.0, "ceramic {fc}");
    assert!(fc / fe > 2.5, "ceramic {fc} epoxy {fe}");
    assert!((0.5..=1.5).contains(&fe), "epoxy {fe} N, paper ≈ 1 N");
}

#[test]
fn the_paper_command_flags_every_model_row_as_passing() {
    // A regression bound on the command's own flags: every row of the steady-state model is
    // flagged passing on the default file, the stator's modes and counterweight among them
    // (computed from the plant's state matrix). Each row is judged against its tolerance text,
    // independently of the flag, in `cli.rs` (`paper_json_lists_every_row_with_pass`).
    let rows = host_sim::paper::rows(&Params::prototype(), host_sim::paper::Evaluate::ModelOnly, |_| {});
    assert!(rows.len() >= 15);
    for r in &rows {
        assert!(r.pass, "{} = {} {} outside {}", r.name, r.ours, r.unit, r.tolerance);
    }
}
