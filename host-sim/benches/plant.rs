//! Plant speed and steady-state model throughput.
//!
//! `plant/run_10ms` reports its throughput in simulated microseconds per second, so its
//! "Melem/s" figure reads directly as simulated seconds per wall-clock second (real-time factor).
//! `steady/thrust_n` reports thrust evaluations per second.

use criterion::{black_box, criterion_group, criterion_main, Criterion, Throughput};
use host_sim::motor::params::Params;
use host_sim::motor::plant::{Plant, QuadratureSine};
use host_sim::motor::steady::{OperatingPoint, ThrustModel};

fn plant(c: &mut Criterion) {
    let p = Params::prototype();
    let mut g = c.benchmark_group("plant");
    g.sample_size(20);
    let sim_s = 0.01;
    g.throughput(Throughput::Elements((sim_s * 1e6) as u64));
    g.bench_function("run_10ms", |b| {
        let mut plant = Plant::new(&p, 16.0);
        let mut drive =
            QuadratureSine { voltage_v: 100.0, frequency_hz: 1500.0, direction: 1, mid_v: 50.0, ramp_s: 0.0 };
        // Start from steady running so the benchmark measures the usual contact pattern.
        plant.run(&mut drive, 0.02);
        b.iter(|| plant.run(&mut drive, sim_s));
    });
    // The sourced prototype (Kelvin–Voigt friction layer): its steps with the layer's switches
    // located, and the same plant taking every step whole (before they were located).
    let sourced = Params::from_toml(include_str!("../params/prototype-sourced.toml")).expect("valid file");
    for (name, locate) in [("run_10ms_sourced", true), ("run_10ms_sourced_whole_steps", false)] {
        g.bench_function(name, |b| {
            let mut plant = Plant::new(&sourced, 16.0);
            if !locate {
                plant.without_friction_switch_location();
            }
            let mut drive = QuadratureSine {
                voltage_v: 100.0,
                frequency_hz: 1500.0,
                direction: 1,
                mid_v: 50.0,
                ramp_s: 0.0,
            };
            plant.run(&mut drive, 0.02);
            b.iter(|| plant.run(&mut drive, sim_s));
        });
    }
    // The heavy-slider set (8 kg counterweight, 50 kg slider, rigid stick) the default was until
    // the plant got the paper's masses: the before of the real-masses change.
    let heavy = Params::from_toml(include_str!("../params/heavy-slider.toml")).expect("valid file");
    g.bench_function("run_10ms_heavy_slider", |b| {
        let mut plant = Plant::new(&heavy, 16.0);
        let mut drive =
            QuadratureSine { voltage_v: 100.0, frequency_hz: 1500.0, direction: 1, mid_v: 50.0, ramp_s: 0.0 };
        plant.run(&mut drive, 0.02);
        b.iter(|| plant.run(&mut drive, sim_s));
    });
    g.finish();
}

fn steady(c: &mut Criterion) {
    let p = Params::prototype();
    let m = ThrustModel::new(&p, OperatingPoint { preload_n: 16.0, voltage_v: 100.0, frequency_hz: 1500.0 });
    let mut g = c.benchmark_group("steady");
    g.throughput(Throughput::Elements(1));
    g.bench_function("thrust_n", |b| {
        let mut v = 0.0;
        b.iter(|| {
            v = (v + 1e-5) % 2e-3;
            black_box(m.thrust_n(black_box(v)))
        })
    });
    g.bench_function("model_at_operating_point", |b| {
        b.iter(|| {
            black_box(ThrustModel::new(
                &p,
                black_box(OperatingPoint { preload_n: 16.0, voltage_v: 100.0, frequency_hz: 1500.0 }),
            ))
        })
    });
    g.bench_function("stall_and_no_load", |b| {
        b.iter(|| black_box((m.stall_force_n(), m.no_load_speed_m_s())))
    });
    // The model with a 0.3 kg slider's inertia: one periodic orbit (bisection on the start speed).
    let mut light = p.clone();
    light.slider.mass_kg = 0.3;
    let im = host_sim::motor::steady_inertia::InertialModel::new(
        &light,
        OperatingPoint { preload_n: 16.0, voltage_v: 100.0, frequency_hz: 1500.0 },
    );
    g.bench_function("inertia_no_load_orbit", |b| b.iter(|| black_box(im.orbit(black_box(0.0)))));
    g.finish();
}

/// One `Controller::step` (the firmware's 10 kHz entry) while moving, and the fixed-point model
/// against the f64 model on the same point.
fn core(c: &mut Criterion) {
    use host_sim::harness::moves::ready_board;
    use host_sim::harness::sil::{controller_config, motor_constants};
    use piezo_drive::Fx;
    let p = Params::prototype();
    let mut sil = ready_board(&p, controller_config(&p), 16.0).expect("board");
    sil.controller.move_to(5_000_000).expect("move");
    sil.run_until(0.05, |_| false);
    let inputs = sil.inputs();
    let mut g = c.benchmark_group("core");
    g.throughput(Throughput::Elements(1));
    g.bench_function("controller_step_moving", |b| {
        b.iter(|| black_box(sil.controller.step(black_box(&inputs))))
    });
    let k = motor_constants(&p);
    let fx = k.point(Fx::from_num(16), Fx::from_num(100), Fx::from_num(1.5));
    g.bench_function("thrust_fixed_point", |b| b.iter(|| black_box(fx.thrust_n(black_box(Fx::from_num(1))))));
    let m = ThrustModel::new(&p, OperatingPoint { preload_n: 16.0, voltage_v: 100.0, frequency_hz: 1500.0 });
    g.bench_function("thrust_f64", |b| b.iter(|| black_box(m.thrust_n(black_box(1e-3)))));
    g.bench_function("inverse_fixed_point", |b| {
        b.iter(|| {
            black_box(k.voltage_for(
                Fx::from_num(16),
                Fx::from_num(2.2),
                black_box(Fx::from_num(1.5)),
                Fx::from_num(1),
                Fx::from_num(100),
            ))
        })
    });
    g.finish();
}

criterion_group!(benches, plant, steady, core);
criterion_main!(benches);
