use host_sim::{params::Params, sil::*};
fn main() {
    let a: Vec<String> = std::env::args().collect();
    let to_nm: i64 = a.get(1).map(|s| s.parse().unwrap()).unwrap_or(1_000_000);
    let ff = a.get(2).map(|s| s == "ff").unwrap_or(true);
    let p = Params::prototype();
    let mut cfg = controller_config(&p);
    cfg.feedforward = ff;
    let mut sil = Sil::new(&p, cfg, 16.0, 1).unwrap();
    sil.run_until(0.05, |_| false);
    println!("preload {:?} limits {:?}", sil.controller.preload_n(), sil.controller.thrust_limits());
    sil.controller.set_servo(true).unwrap();
    sil.controller.move_to(to_nm).unwrap();
    let t0 = sil.time_s();
    let mut k = 0;
    sil.run_until(1.5, |s| {
        k += 1;
        if k % 500 == 0 {
            let c = &s.controller;
            println!("t {:.3} state {:?} pos {} ref {} err {} V {:.1} v {:.3} mm/s fine {} off {:.2} ont {} stack {:?}", s.time_s()-t0, c.state(), c.position_nm(), c.reference_nm(), c.reference_nm()-c.position_nm(), c.drive_voltage_v(), c.speed_nm_s()*1e-6, c.fine_mode(), c.fine_offset_v(), c.on_target(), s.plant.stack_volts());
        }
        s.controller.on_target() && false
    });
    println!(
        "final pos {} plant {:.1} nm maxfe {}",
        sil.controller.position_nm(),
        sil.plant.slider_position_m() * 1e9,
        sil.controller.max_following_error_nm()
    );
}
