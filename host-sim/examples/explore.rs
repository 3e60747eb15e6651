use host_sim::{params::Params, plant, steady::*};
fn main() {
    let a: Vec<String> = std::env::args().collect();
    let mut p = Params::prototype();
    if a.len() > 1 {
        p = Params::load(std::path::Path::new(&a[1])).unwrap();
    }
    for f in [1000.0, 1500.0, 2000.0] {
        let am = amplitudes(&p, 100.0, f);
        println!(
            "f {f} Yn {:.3} um Yc {:.2} nm kcYc {:.2} Xc {:.3} um F {:.2}",
            am.yn_m * 1e6,
            am.yc_m * 1e9,
            am.yc_m * p.contact.stiffness_n_per_m,
            am.xc_m * 1e6,
            am.normal_force_n
        );
    }
    for f0 in [3.0, 5.0, 10.0, 16.0, 20.0, 25.0] {
        let m =
            ThrustModel::new(&p, OperatingPoint { preload_n: f0, voltage_v: 100.0, frequency_hz: 1500.0 });
        println!(
            "F0 {f0} theta/pi {:.3} stall {:.3} v0 {:.3} mm/s",
            m.contact_angle_rad / std::f64::consts::PI,
            m.stall_force_n(),
            m.no_load_speed_m_s() * 1e3
        );
    }
    let t = std::time::Instant::now();
    for (f0, v, f, frac) in [
        (16.0, 100.0, 1500.0, 0.0),
        (16.0, 100.0, 1500.0, 0.5),
        (10.0, 100.0, 1500.0, 0.0),
        (5.0, 50.0, 800.0, 0.3),
        (20.0, 100.0, 2200.0, 0.7),
        (10.0, 75.0, 2200.0, 0.0),
        (16.0, 100.0, 800.0, 0.0),
    ] {
        let m = ThrustModel::new(&p, OperatingPoint { preload_n: f0, voltage_v: v, frequency_hz: f });
        let load = frac * m.stall_force_n();
        let vm = m.speed_at_load_m_s(load).unwrap_or(f64::NAN);
        let vs = plant::steady_speed_m_s(&p, f0, v, f, 1, load);
        println!(
            "F0 {f0} V {v} f {f} load {load:.2}: model {:.4} sim {:.4} mm/s  err {:.2}%",
            vm * 1e3,
            vs * 1e3,
            (vs / vm - 1.0) * 100.0
        );
    }
    eprintln!("{:?}", t.elapsed());
}
