//! The steady-state model with the slider's inertia (`steady_inertia`) against its heavy-slider
//! limit (the constant-speed model, eq. 19) and against the time-domain plant over carriage masses.

use host_sim::motor::params::Params;
use host_sim::motor::plant::steady_speed_m_s;
use host_sim::motor::steady::{OperatingPoint, ThrustModel};
use host_sim::motor::steady_inertia::InertialModel;

fn op(preload_n: f64, voltage_v: f64, frequency_hz: f64) -> OperatingPoint {
    OperatingPoint { preload_n, voltage_v, frequency_hz }
}

#[test]
fn a_very_heavy_slider_reproduces_the_constant_speed_model() {
    // M → ∞: the speed cannot change within a period, so the orbit's mean speed is the root of
    // the period-averaged thrust (19) — the closed form of `steady.rs`.
    let mut p = Params::prototype();
    p.slider.mass_kg = 1e5;
    for (f0, f) in [(5.0, 800.0), (16.0, 1500.0), (20.0, 2200.0)] {
        let base = ThrustModel::new(&p, op(f0, 100.0, f));
        let heavy = InertialModel::new(&p, op(f0, 100.0, f));
        for fraction in [0.0, 0.5] {
            let load = fraction * base.stall_force_n();
            let a = heavy.speed_at_load_m_s(load).expect("orbit");
            let b = base.speed_at_load_m_s(load).expect("below stall");
            assert!(
                (a - b).abs() < 0.005 * base.no_load_speed_m_s(),
                "{f0} N {f} Hz load {load}: {a} vs {b}"
            );
        }
        let (sa, sb) = (heavy.stall_force_n(), base.stall_force_n());
        assert!((sa - sb).abs() < 0.005 * sb, "stall {sa} vs {sb}");
    }
}

#[test]
fn a_light_slider_sticks_ripples_and_loses_speed() {
    // The ripple scale μ·kc·Yc/(M·ω) grows as 1/M: a 0.1 kg slider sticks for part of the period
    // and runs slower than a 10 kg one at the same drive.
    let mut p = Params::prototype();
    let point = op(16.0, 100.0, 1500.0);
    p.slider.mass_kg = 10.0;
    let heavy = InertialModel::new(&p, point).orbit(0.0).unwrap();
    p.slider.mass_kg = 0.1;
    let light = InertialModel::new(&p, point).orbit(0.0).unwrap();
    assert!(heavy.stick_fraction < 0.02 && light.stick_fraction > 0.2, "{heavy:?} {light:?}");
    assert!(light.ripple_m_s > 10.0 * heavy.ripple_m_s, "{light:?} {heavy:?}");
    assert!(light.mean_speed_m_s < 0.5 * heavy.mean_speed_m_s);
}

#[test]
fn model_with_inertia_stays_within_its_regression_bounds_of_the_plant_from_0_1_to_50_kg() {
    // A regression bound, not the 5 %: the model with the contact's timing holds that
    // (`tests/steady_contact.rs`).
    // The grid of the issue (slider 0.1–50 kg, 5–20 N, 50–100 V, loads to 70 % of the
    // constant-speed stall force) at 1.5 and 2.2 kHz, on the default stator. Speed errors are taken relative to the plant's no-load speed at the same
    // drive (the speed scale of that thrust–speed curve), since near stall the speed itself
    // passes through zero; where a light slider glued to a foot in permanent contact makes no
    // headway at all, a floor of 10 % of the foot's peak speed ω·Xc stands in for that scale.
    let p0 = Params::prototype();
    let (mut worst, mut worst_at, mut runs, mut within_5) = (0.0f64, String::new(), 0, 0usize);
    let mut constant_worst = 0.0f64;
    for mass in [0.1, 0.3, 1.0, 5.0, 50.0] {
        let mut p = p0.clone();
        p.slider.mass_kg = mass;
        for (f0, v) in [(5.0, 100.0), (16.0, 100.0), (20.0, 50.0)] {
            for f in [1500.0, 2200.0] {
                let point = op(f0, v, f);
                let base = ThrustModel::new(&p, point);
                let model = InertialModel::new(&p, point);
                let scale = steady_speed_m_s(&p, f0, v, f, 1, 0.0).abs().max(0.1 * base.foot_speed_m_s);
                for fraction in [0.0, 0.35, 0.7] {
                    let load = fraction * base.stall_force_n();
                    let plant = steady_speed_m_s(&p, f0, v, f, 1, load);
                    let ours = model.speed_at_load_m_s(load).expect("orbit exists below stall");
                    let err = (ours - plant).abs() / scale.max(plant.abs());
                    within_5 += usize::from(err <= 0.05);
                    if err > worst {
                        worst = err;
                        worst_at = format!("{mass} kg, {f0} N, {v} V, {f} Hz, load {load:.2} N: model {ours:e} plant {plant:e} m/s");
                    }
                    if let Some(c) = base.speed_at_load_m_s(load) {
                        constant_worst = constant_worst.max((c - plant).abs() / scale.max(plant.abs()));
                    }
                    runs += 1;
                }
            }
        }
    }
    assert_eq!(runs, 90);
    eprintln!(
        "worst: {:.1} % at {worst_at}; {within_5} of 90 within 5 %; the constant-speed model's worst: {:.0} %",
        100.0 * worst,
        100.0 * constant_worst
    );
    // 5 % everywhere is not reached. On the paper's stator (1 kg counterweight, its preload mode
    // damped) the plant's contact force is not the harmonic arc of eq. (15) centred on the
    // foot's peak speed: at 1.5 kHz the arc sits ≈ 9° early and is shaped by the stator's
    // landing, and light carriages feel that most. Measured: 33 of 90 points within 5 %, worst
    // 76.5 % (0.1 kg, 16 N, 100 V, 1.5 kHz, 1.59 N: −1.01 against −0.57 mm/s); the
    // constant-speed model's worst 480 %. Regression bounds: every point within 80 %, at least 30
    // within 5 %. The frequencies are 1.5 and 2.2 kHz: below ≈ 1.1 kHz the foot-clamped
    // counterweight mode (857 Hz) makes eq. (7) itself invalid (tests/fixed_model.rs).
    assert!(worst < 0.80, "worst {:.1} % at {worst_at}", 100.0 * worst);
    assert!(within_5 >= 30, "only {within_5} of 90 points within 5 %");
    // And the grid is one where inertia matters: the constant-speed model misses by far more.
    assert!(constant_worst > 1.0, "constant-speed model worst {constant_worst}");
}

/// The carriage's swing about its mean line within a drive period on the time-domain plant (half
/// its peak-to-peak deviation from the straight line through each period's ends), over 20
/// periods at a steady sine.
fn plant_swing_nm(p: &Params, preload_n: f64, voltage_v: f64, frequency_hz: f64) -> f64 {
    use host_sim::motor::plant::{Plant, QuadratureSine};
    let mut plant = Plant::new(p, preload_n);
    let mut drive =
        QuadratureSine { voltage_v, frequency_hz, direction: 1, mid_v: p.amplifier_mid_v(), ramp_s: 0.01 };
    plant.run(&mut drive, 0.06);
    let (periods, samples) = (20, 90);
    let mut sum = 0.0;
    for _ in 0..periods {
        let mut xs = vec![plant.slider_position_m()];
        for _ in 0..samples {
            plant.run(&mut drive, 1.0 / (frequency_hz * f64::from(samples)));
            xs.push(plant.slider_position_m());
        }
        let (x0, x1) = (xs[0], xs[samples as usize]);
        let dev = xs.iter().enumerate().map(|(i, x)| x - x0 - (x1 - x0) * i as f64 / f64::from(samples));
        let (lo, hi) = dev.fold((f64::MAX, f64::MIN), |(lo, hi), d| (lo.min(d), hi.max(d)));
        sum += 0.5 * (hi - lo);
    }
    sum / f64::from(periods) * 1e9
}

/// The core's estimate of that swing (`ModelTable::swing_nm`, which the controller uses to hand a
/// light carriage to the fine mode while it still moves) is the smaller of the foot's stroke
/// (a carriage that sticks to the foot follows it) and μ·F0/(M·ω²) (friction is at most μ·Fc,
/// and Fc averages the preload over a period). Against the plant at 16 and 18 N, where light
/// carriages stick, it is right within 0.6–1.25×; at 5 N the foot grips so little that light
/// carriages swing less (0.3–1.0× the estimate at 100 V), and it stays an upper bound within 1.35×.
#[test]
fn the_carriages_swing_within_a_period_is_the_foots_stroke_or_the_friction_impulse() {
    use host_sim::harness::sil::controller_config;
    use piezo_drive::controller::model_cache::ModelTable;
    use piezo_drive::controller::{Controller, Inputs};
    for preload_n in [5.0, 16.0, 18.0] {
        for frequency_hz in [1200.0, 2200.0] {
            for mass_kg in [0.05, 0.1, 0.3, 1.0, 5.0] {
                let mut p = Params::prototype();
                p.slider.mass_kg = mass_kg;
                let mut cfg = controller_config(&p);
                (cfg.drive_freq_hz, cfg.drive_freq_min_hz) = (frequency_hz as f32, frequency_hz as f32);
                let mut c = Controller::new(cfg).expect("config");
                let word = (preload_n as f32 / cfg.preload.newton_per_word).round() as u16;
                c.step(&Inputs { preload_word: word, ..Default::default() });
                let table = ModelTable::build(&c.model_request().expect("a table is wanted"));
                for voltage_v in [30.0, 60.0, 100.0] {
                    let model = f64::from(table.swing_nm(voltage_v as f32));
                    let plant = plant_swing_nm(&p, preload_n, voltage_v, frequency_hz);
                    let ratio = plant / model;
                    let (lo, hi) = if preload_n < 10.0 { (0.2, 1.35) } else { (0.6, 1.25) };
                    assert!(
                        (lo..=hi).contains(&ratio),
                        "{mass_kg} kg, {preload_n} N, {frequency_hz} Hz, {voltage_v} V: plant {plant:.0} nm, \
                         estimate {model:.0} nm"
                    );
                }
            }
        }
    }
}
