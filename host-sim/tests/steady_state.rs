//! The steady-state thrust model against independent references: a direct numerical period
//! average, the paper's literal eq. (22), and the contact-angle relations of physics.md §2.

use host_sim::motor::params::Params;
use host_sim::motor::steady::*;
use std::f64::consts::{PI, TAU};

fn model(preload_n: f64, voltage_v: f64, frequency_hz: f64) -> ThrustModel {
    ThrustModel::new(&Params::prototype(), OperatingPoint { preload_n, voltage_v, frequency_hz })
}

#[test]
fn closed_form_equals_numerical_period_average() {
    let mut cases = 0;
    let mut partial = 0;
    let mut full = 0;
    for preload_n in [1.0, 3.0, 8.0, 16.0, 20.0, 30.0] {
        for voltage_v in [30.0, 60.0, 100.0] {
            for frequency_hz in [500.0, 1500.0, 2200.0] {
                let m = model(preload_n, voltage_v, frequency_hz);
                if m.full_contact() {
                    full += 1;
                } else {
                    partial += 1;
                }
                // Force scale of this point: the largest friction force that can occur.
                let scale = m.mu * (m.preload_n + m.kc_yc_n);
                // Speeds from well backwards to beyond the foot's peak speed, both signs.
                for u in [-1.5, -1.0, -0.6, -0.2, 0.0, 0.1, 0.3, 0.5, 0.7, 0.9, 0.99, 1.0, 1.3] {
                    let v = u * m.foot_speed_m_s;
                    let closed = m.thrust_n(v);
                    let numeric = m.thrust_numeric_n(v, 400_000);
                    assert!(
                        (closed - numeric).abs() <= 1e-3 * scale,
                        "F0 {preload_n} V {voltage_v} f {frequency_hz} u {u}: closed {closed} numeric {numeric}"
                    );
                    cases += 1;
                }
            }
        }
    }
    assert!(partial > 10 && full > 5, "grid must cover both partial ({partial}) and full ({full}) contact");
    assert!(cases > 500);
}

#[test]
fn reverse_direction_is_the_mirror_image() {
    let p = Params::prototype();
    let op = OperatingPoint { preload_n: 12.0, voltage_v: 80.0, frequency_hz: 1200.0 };
    let m = ThrustModel::new(&p, op);
    for u in [-0.8, -0.3, 0.0, 0.4, 0.9] {
        let v = u * m.foot_speed_m_s;
        // Reverse drive on a slider moving at −v pushes exactly as hard, the other way.
        assert!((thrust_n(&p, op, -v, -1) + thrust_n(&p, op, v, 1)).abs() < 1e-12);
    }
}

/// The paper's eq. (22) as printed (Coulomb part), with v_m < ω·Xc and φp < θc/2.
fn paper_eq22_coulomb(m: &ThrustModel, v: f64) -> f64 {
    let r = m.mu * m.kc_yc_n;
    let wx = m.foot_speed_m_s;
    let th = m.contact_angle_rad;
    let c = (0.5 * th).cos();
    -(r / PI) * (0.5 * th).sin() + 2.0 / (PI * wx) * r * (wx * wx - v * v).sqrt() - r * c
        + th / TAU * r * c
        + 2.0 / PI * r * c * (v / wx).asin()
}

#[test]
fn closed_form_is_the_papers_eq_22_where_it_applies() {
    let mut checked = 0;
    for preload_n in [4.0, 10.0, 16.0] {
        let mut m = model(preload_n, 100.0, 1500.0);
        m.viscous_n_s_per_m = 0.0;
        let half = 0.5 * m.contact_angle_rad;
        for u in [0.2f64, 0.5, 0.8, 0.95] {
            // Eq. (22) holds where the equilibrium points P, P' lie inside the contact arc (20).
            if u.acos() >= half {
                continue;
            }
            let v = u * m.foot_speed_m_s;
            let ours = m.thrust_n(v);
            let theirs = paper_eq22_coulomb(&m, v);
            assert!((ours - theirs).abs() < 1e-9 * m.kc_yc_n, "F0 {preload_n} u {u}: {ours} vs {theirs}");
            checked += 1;
        }
    }
    assert!(checked >= 5);
}

#[test]
fn exact_and_paper_contact_angle_agree_at_full_contact_and_differ_below() {
    let kc_yc = 20.0;
    // Full contact: both relations give θc = 2π at F0 = kc·Yc and beyond.
    assert!((contact_angle_exact(kc_yc, kc_yc) - TAU).abs() < 1e-9);
    assert!((contact_angle_paper(kc_yc, kc_yc) - TAU).abs() < 1e-9);
    assert_eq!(contact_angle_exact(25.0, kc_yc), TAU);
    // The dropped 2·sin(θc/2) term vanishes at 2π: both mean contact forces are kc·Yc there.
    assert!((mean_contact_exact(TAU) - 1.0).abs() < 1e-12);
    assert!((mean_contact_paper(TAU) - 1.0).abs() < 1e-12);
    // At θc = π the exact mean contact force is kc·Yc/π, the paper's (14) gives zero.
    assert!((mean_contact_exact(PI) - 1.0 / PI).abs() < 1e-12);
    assert!(mean_contact_paper(PI).abs() < 1e-12);
    // As F0 → 0 the exact contact angle closes (θc → 0); the paper's stays at π.
    assert!(contact_angle_exact(1e-6, kc_yc) < 0.05);
    assert!((contact_angle_paper(1e-6, kc_yc) - PI).abs() < 1e-3);
    // Hand check of the exact relation at θc = 3π/2: F0/(kc·Yc) = (2 sin(3π/4) − (3π/2) cos(3π/4))/(2π).
    let ratio = (2.0 * (0.75 * PI).sin() - 1.5 * PI * (0.75 * PI).cos()) / TAU;
    assert!((contact_angle_exact(ratio * kc_yc, kc_yc) - 1.5 * PI).abs() < 1e-9);
    // The solve inverts the exact relation over the whole range (the angle from the forward
    // closed form back to itself), down to arcs of a hundredth of a radian.
    for i in 1..200 {
        let theta = TAU * f64::from(i) / 200.0;
        let back = contact_angle_exact(mean_contact_exact(theta) * kc_yc, kc_yc);
        assert!((back - theta).abs() < 1e-9 * theta.max(1.0), "θc {theta}: solved {back}");
    }
}

#[test]
fn stall_force_is_mu_f0_while_the_whole_contact_arc_drives() {
    // θc ≤ π: at standstill the foot moves forwards on the whole contact arc, so F = μ·F0 (+ εc part).
    let m = model(3.0, 100.0, 1500.0);
    assert!(m.contact_angle_rad <= PI);
    let viscous = m.viscous_n_s_per_m * m.foot_speed_m_s * (0.5 * m.contact_angle_rad).sin() / PI;
    assert!((m.stall_force_n() - (m.mu * 3.0 + viscous)).abs() < 1e-9);
    // Full contact at standstill: F = 2·μ·kc·Yc/π, independent of the preload.
    let f = model(40.0, 100.0, 1500.0);
    assert!(f.full_contact());
    assert!((f.stall_force_n() - 2.0 * f.mu * f.kc_yc_n / PI).abs() < 1e-9);
}

#[test]
fn no_load_speed_is_a_root_and_below_the_foot_speed() {
    for preload_n in [5.0, 16.0, 25.0] {
        let m = model(preload_n, 100.0, 1500.0);
        let v0 = m.no_load_speed_m_s();
        assert!(v0 > 0.0 && v0 < m.foot_speed_m_s);
        assert!(m.thrust_n(v0).abs() < 1e-9 * m.kc_yc_n);
        // Thrust falls with speed (a stable operating point).
        assert!(m.thrust_n(0.9 * v0) > 0.0 && m.thrust_n(1.1 * v0) < 0.0);
    }
}

#[test]
fn amplitudes_follow_eqs_5_and_7() {
    // Hand evaluation of (5) and (7) for the prototype at 1 kHz.
    let p = Params::prototype();
    let a = amplitudes(&p, 100.0, 1000.0);
    let w2 = (TAU * 1000.0f64).powi(2);
    let (m1, m2) = (p.stator.foot_mass_kg, p.stator.counterweight_mass_kg);
    let k1 = p.stack.stiffness_n_per_m + p.stator.flexure_stiffness_n_per_m;
    let (k2, k3) = (p.stator.preload_spring_n_per_m, p.contact.stiffness_n_per_m);
    let y_free = a.normal_force_n * (k2 - w2 * m2) / ((k1 - w2 * m1) * (k2 - w2 * m2) - w2 * m1 * k1);
    let y_contact = a.normal_force_n * (k2 - w2 * m2) / ((k1 + k3 - w2 * m1) * (k1 + k2 - w2 * m2) - k1 * k1);
    assert!((a.yn_m - y_free.abs()).abs() < 1e-15);
    assert!((a.yc_m - y_contact.abs()).abs() < 1e-15);
    // Contact stage amplitude is tens of times smaller than the free amplitude.
    assert!(a.yn_m / a.yc_m > 20.0);
}
