//! The old `m4-count` suite: instruction counts of the core's hot paths (refill, controller
//! step idle/moving/holding, model pieces) on the emulated Cortex-M4F. Runs when no PIL host is
//! attached (`tools/pil/run`).

use cortex_m_semihosting::hprintln;
use piezo_drive::controller::model_cache::{FrequencyChoice, ModelRequest, ModelTable};
use piezo_drive::controller::table_build::TableBuild;
use piezo_drive::controller::{ConfigChange, Controller, Inputs, DAC_SAMPLES_PER_STEP};
use piezo_drive::defaults::controller_config;
use piezo_drive::generator::QuadratureGenerator;
use piezo_drive::recorder::{trigger, DEPTH};
use piezo_drive::Fx;

use crate::{calibrate, counts, Stat, RECORDER};

static mut HALF: [u32; 2 * DAC_SAMPLES_PER_STEP] = [0; 2 * DAC_SAMPLES_PER_STEP];

/// The old `m4-count` suite: instruction counts of the core's hot paths, one by one.
pub fn hot_paths() {
    let k = calibrate();
    hprintln!("calibration: {} instructions per SysTick count", k);

    // The core's square root against micromath's (the design card's f32 maths crate).
    sqrt_against_micromath(k);
    acos_against_micromath(k);
    // The FPU square root (VSQRT through inline asm) on the Cortex-M4F: expect 1.4142135 0.001 0.
    hprintln!(
        "sqrt on the FPU: {} {} {}",
        piezo_drive::fastmath::sqrt_f32(2.0),
        piezo_drive::fastmath::sqrt_f32(1e-6),
        piezo_drive::fastmath::sqrt_f32(-1.0)
    );
    // The drive refill alone: 20 generator samples at full amplitude, packed and stored.
    let cfg = controller_config();
    let mut g = QuadratureGenerator::new(cfg.dac);
    g.set_frequency_hz(2200.0);
    g.set_amplitude_v(100.0);
    let mut fill = Stat::new();
    let mut samples = [[0u16; 2]; DAC_SAMPLES_PER_STEP];
    for i in 0..20_000u32 {
        let half = (i & 1) as usize * DAC_SAMPLES_PER_STEP;
        let c = counts(|| {
            g.fill(&mut samples);
            for (j, s) in samples.iter().enumerate() {
                let w = u32::from(s[0].min(4095)) | (u32::from(s[1].min(4095)) << 16);
                // SAFETY: in bounds, single-threaded.
                unsafe { core::ptr::addr_of_mut!(HALF).cast::<u32>().add(half + j).write_volatile(w) };
            }
        });
        fill.add(c);
    }
    fill.print("refill (generator.fill of 20 sample pairs + pack + store)", k);

    // Controller step: a 1 mm move at 16 N preload with the encoder following the reference,
    // then holding.
    let mut cfg_ff = cfg;
    // `NOFF=1 tools/pil/run`: the same move with plain PI feedback (feedforward off).
    if option_env!("NOFF").is_some() {
        cfg_ff.feedforward = false;
    }
    let mut ctl = Controller::new(cfg_ff).unwrap();
    let preload_word = (16.0 / cfg.preload.newton_per_word) as u16;
    let mut inputs = Inputs { encoder_raw: 0, preload_word, ..Default::default() };
    let mut idle = Stat::new();
    for _ in 0..2_000 {
        idle.add(counts(|| {
            core::hint::black_box(ctl.step(core::hint::black_box(&inputs)));
        }));
        // The board's thread-mode task, outside the tick.
        ctl.background();
    }
    idle.print("Controller::step while idle (servo off)", k);
    ctl.set_servo(true).unwrap();
    ctl.move_to(1_000_000).unwrap();
    let mut moving = Stat::new();
    let mut holding = Stat::new();
    let mut slow = 0;
    for i in 0..8_000u32 {
        inputs.encoder_raw = (ctl.reference_nm() / 50) as u16;
        let was_moving = matches!(ctl.state(), piezo_drive::controller::State::Moving);
        let c = counts(|| {
            core::hint::black_box(ctl.step(core::hint::black_box(&inputs)));
        });
        ctl.background();
        if was_moving {
            if c as f32 * k > 14_000.0 && slow < 12 {
                slow += 1;
                hprintln!("slowest moving ticks: #{} {} instructions, drive {} V", i, (c as f32 * k) as u32, ctl.drive_voltage_v());
            }
            moving.add(c);
        } else {
            holding.add(c);
        }
    }
    moving.print("Controller::step while moving (1 mm at 16 N)", k);
    holding.print("Controller::step while holding", k);
    hprintln!("final state {:?}, position {} nm", ctl.state(), ctl.position_nm());
    recorder_sample(&ctl, k);

    // The states the PIL moves do not visit: referencing (an index search that finds nothing
    // within these periods) and open-loop stepping (servo off, XOS), the tick counted as PIL
    // counts it: the step plus packing the half-buffer.
    let tick_of = |ctl: &mut Controller, inputs: &Inputs| {
        let c = counts(|| {
            let out = ctl.step(core::hint::black_box(inputs));
            for (j, s) in out.dac.iter().enumerate() {
                let w = u32::from(s[0].min(4095)) | (u32::from(s[1].min(4095)) << 16);
                // SAFETY: in bounds, single-threaded.
                unsafe { core::ptr::addr_of_mut!(HALF).cast::<u32>().add(j).write_volatile(w) };
            }
        });
        ctl.background();
        c
    };
    ctl.start_referencing().unwrap();
    let mut referencing = Stat::new();
    for _ in 0..2_000 {
        inputs.encoder_raw = inputs.encoder_raw.wrapping_sub(1);
        referencing.add(tick_of(&mut ctl, &inputs));
    }
    referencing.print("whole tick while referencing (index search)", k);
    ctl.stop();
    ctl.set_servo(false).unwrap();
    ctl.open_loop_step(2_000, 80.0, 1_500.0).unwrap();
    let mut open_loop = Stat::new();
    for _ in 0..2_000 {
        inputs.encoder_raw = inputs.encoder_raw.wrapping_add(2);
        open_loop.add(tick_of(&mut ctl, &inputs));
    }
    open_loop.print("whole tick while stepping open loop (XOS, 80 V, 1.5 kHz)", k);

    // Pieces of the step, through the core's public API (model at 16 N, 100 V, 2.2 kHz).
    let mut limits = Stat::new();
    let mut inverse = Stat::new();
    let mut speed = Stat::new();
    let mut thrust = Stat::new();
    let m = cfg.motor;
    let (p16, v100, f22) = (Fx::from_num(16), Fx::from_num(100), Fx::from_num(2.2));
    for i in 0..500i32 {
        let v = Fx::from_num(10 + i % 80);
        limits.add(counts(|| {
            core::hint::black_box(core::hint::black_box(&ctl).thrust_limits());
        }));
        inverse.add(counts(|| {
            core::hint::black_box(m.voltage_for(p16, f22, v, Fx::from_num(1), v100));
        }));
        let point = m.point(p16, v100, f22);
        speed.add(counts(|| {
            core::hint::black_box(core::hint::black_box(&point).speed_at_load_mm_s(Fx::ZERO));
        }));
        thrust.add(counts(|| {
            core::hint::black_box(core::hint::black_box(&point).thrust_n(v));
        }));
    }
    let pv = m.at_frequency(f22);
    let mut pt = Stat::new();
    let mut inv2 = Stat::new();
    for i in 0..500i32 {
        let v = Fx::from_num(30 + i % 70);
        pt.add(counts(|| {
            core::hint::black_box(core::hint::black_box(&pv).point(p16, v));
        }));
        let sp = Fx::from_num(0.5) + Fx::from_num(i % 20) / 10;
        inv2.add(counts(|| {
            core::hint::black_box(pv.voltage_for(p16, sp, Fx::from_num(0.5), v100));
        }));
    }
    pt.print("PerVolt::point", k);
    // The model table the tick reads (built by the board's thread-mode task).
    // The default 1 kg carriage at 2.2 kHz: light enough that the table comes from orbits.
    let request = ModelRequest {
        per_volt: pv,
        preload_n: 16.0,
        max_drive_v: 100.0,
        frequency_hz: 2200.0,
        choice: FrequencyChoice::fixed(2200.0, pv, 0.0),
        moving_mass_kg: 1.0,
        rail_coulomb_n: 0.0,
        rail_viscous_n_s_per_m: 0.0,
        contact: None,
        generation: 0,
    };
    let mut build = Stat::new();
    let mut table = ModelTable::build(&request);
    for _ in 0..5 {
        build.add(counts(|| table = core::hint::black_box(ModelTable::build(core::hint::black_box(&request)))));
    }
    build.print("ModelTable::build (thread mode on the board)", k);
    // The hand-over: the board's table link copies a finished table into the controller under
    // the tick lock (`src/firmware/model.rs`), as `install_model` does here.
    let mut ctl = Controller::new(controller_config()).unwrap();
    ctl.step(&Inputs { preload_word: 1310, ..Default::default() });
    if let Some(r) = ctl.model_request() {
        let fresh = ModelTable::build(&r);
        let mut install = Stat::new();
        for _ in 0..5 {
            let copy = core::hint::black_box(fresh);
            install.add(counts(|| {
                core::hint::black_box(ctl.install_model(core::hint::black_box(copy)));
            }));
        }
        install.print("Controller::install_model, whole (hosts)", k);
        // The board's hand-over: a part per tick lock, the last one swapping the table in.
        let mut parts = Stat::new();
        let mut last = Stat::new();
        for _ in 0..5 {
            for part in 0..piezo_drive::controller::model_cache::TABLE_PARTS {
                let c = counts(|| {
                    core::hint::black_box(ctl.stage_model(core::hint::black_box(&fresh), part));
                });
                if part + 1 == piezo_drive::controller::model_cache::TABLE_PARTS {
                    last.add(c);
                } else {
                    parts.add(c);
                }
            }
        }
        parts.print("Controller::stage_model, a copying part (one tick lock on the board)", k);
        last.print("Controller::stage_model, the last part: check and swap (one tick lock)", k);
    }
    // The same with the drive frequency chosen from 1.2 to 2.2 kHz (a new table for new settings
    // or a new load; one for a new preload keeps the frequency).
    let khz = |f: f32| Fx::from_num(f / 1000.0);
    let choosing = ModelRequest {
        choice: FrequencyChoice::between(1200.0, 2200.0, 0.0, |f| m.at_frequency(khz(f))),
        ..request
    };
    let mut build_choice = Stat::new();
    for _ in 0..3 {
        build_choice.add(counts(|| {
            core::hint::black_box(ModelTable::build(core::hint::black_box(&choosing)));
        }));
    }
    build_choice.print("ModelTable::build, frequency chosen from 1.2-2.2 kHz", k);
    contact_orbit(k);
    // The same build in slices, as the board's model task runs it (yielding between them): the
    // longest slice is the longest the UART and preload tasks wait for it. A 0.1 kg carriage's
    // grid comes from its periodic motion (the heaviest rows).
    let light = ModelRequest { moving_mass_kg: 0.1, ..choosing };
    for (name, r) in [
        ("TableBuild::step, 1 kg, frequency chosen (one slice of the build)", choosing),
        ("TableBuild::step, 0.1 kg, frequency chosen (one slice of the build)", light),
    ] {
        let mut slices = Stat::new();
        let mut sliced = TableBuild::new(&r);
        let mut done = false;
        while !done {
            slices.add(counts(|| done = core::hint::black_box(&mut sliced).step().is_some()));
        }
        slices.print(name, k);
    }
    let (mut t_inv, mut t_thrust, mut t_speed) = (Stat::new(), Stat::new(), Stat::new());
    let mut hint_v = 50.0f32;
    for i in 0..2000i32 {
        let sp = 1.0 + (i % 200) as f32 / 200.0;
        t_inv.add(counts(|| hint_v = core::hint::black_box(&table).voltage_for(sp, 0.5, hint_v)));
        t_thrust.add(counts(|| {
            core::hint::black_box(core::hint::black_box(&table).thrust_n(63.3, sp));
        }));
        t_speed.add(counts(|| {
            core::hint::black_box(core::hint::black_box(&table).speed_at_load_mm_s(sp));
        }));
    }
    t_inv.print("ModelTable::voltage_for warm (speed ramps 1-2 mm/s)", k);
    t_thrust.print("ModelTable::thrust_n between two table voltages", k);
    t_speed.print("ModelTable::speed_at_load_mm_s", k);
    let mut warm = Stat::new();
    let mut th = Stat::new();
    let mut hint = 50.0f32;
    let pnt = pv.point(p16, v100);
    for i in 0..2000i32 {
        let sp = Fx::from_num(1.0) + Fx::from_num(i % 200) / 200;
        warm.add(counts(|| {
            hint = pv.voltage_near(p16, sp, Fx::from_num(0.5), v100, hint).to_num();
        }));
        th.add(counts(|| {
            core::hint::black_box(core::hint::black_box(&pnt).thrust_n(sp));
        }));
    }
    warm.print("PerVolt::voltage_near warm (speed ramps 1-2 mm/s)", k);
    th.print("thrust_n", k);
    inv2.print("PerVolt::voltage_for at 0.5-2.4 mm/s, 0.5 N", k);
    limits.print("Controller::thrust_limits (per call; the step calls it while active)", k);
    inverse.print("MotorConstants::voltage_for (inverse model, cold start)", k);
    speed.print("ThrustPoint::speed_at_load_mm_s (false position)", k);
    thrust.print("ThrustPoint::thrust_n (one model evaluation)", k);
    // How long each GCS command holds the tick off: `host-sim pil --gcs-locks`; here the parts
    // of its locked sections that are the controller's own code.
    lock_parts(k);
}

/// The controller code inside the GCS commands' locked sections (`src/gcs/lock.rs`):
/// `Controller::apply_config` (the settings commands; `validate_settings` runs off the lock, in
/// `ConfigChange::prepare`), and
/// `Controller::thrust_limits` (`XTM?`'s snapshot) when no model table fits the preload yet (the
/// model task has not built one), which `host-sim pil --gcs-locks` cannot reach (the PIL image
/// builds the table right after the tick that asks for it).
fn lock_parts(k: f32) {
    let cfg = controller_config();
    let mut ctl = Controller::new(cfg).unwrap();
    let inputs = Inputs { preload_word: (16.0 / cfg.preload.newton_per_word) as u16, ..Default::default() };
    for _ in 0..200 {
        ctl.step(&inputs);
    }
    let mut cold = Stat::new();
    for _ in 0..50 {
        cold.add(counts(|| {
            core::hint::black_box(core::hint::black_box(&ctl).thrust_limits());
        }));
    }
    cold.print("Controller::thrust_limits, no model table yet (XTM?'s snapshot)", k);
    let mut valid = Stat::new();
    let mut set = Stat::new();
    let mut other = cfg;
    other.velocity_max_nm_s *= 0.9;
    for i in 0..50 {
        let new = if i % 2 == 0 { other } else { cfg };
        valid.add(counts(|| {
            core::hint::black_box(piezo_drive::controller::validate_settings(core::hint::black_box(&new))).ok();
        }));
        // Prepared off the lock (the settings commands' check), applied under it.
        let change = ConfigChange::prepare(ctl.config(), ctl.config_generation(), new).unwrap();
        set.add(counts(|| {
            core::hint::black_box(ctl.apply_config(core::hint::black_box(&change))).ok();
        }));
    }
    valid.print("validate_settings", k);
    set.print("Controller::apply_config, VEL changed (the settings commands' second lock)", k);
}

/// The data recorder's share of the tick (`Recorder::sample` after the step, as the firmware's
/// tick calls it): no table recording, then all eight recording a point every tick (`RTR 1`,
/// the most it ever does).
fn recorder_sample(ctl: &Controller, k: f32) {
    let mut quiet = Stat::new();
    for _ in 0..200 {
        quiet.add(counts(|| RECORDER.sample(core::hint::black_box(ctl))));
    }
    quiet.print("Recorder::sample, no table recording", k);
    for (i, opt) in [1, 2, 3, 256, 257, 258, 259, 2].into_iter().enumerate() {
        let _ = RECORDER.configure(i + 1, opt);
    }
    let _ = RECORDER.set_trigger(0, trigger::IMMEDIATELY, ctl);
    let mut full = Stat::new();
    for _ in 1..DEPTH {
        full.add(counts(|| RECORDER.sample(core::hint::black_box(ctl))));
    }
    full.print("Recorder::sample, 8 tables recording every tick (RTR 1)", k);
}

/// Instructions and accuracy of the core's `sqrt_f32` (VSQRT) and micromath's `sqrt` over
/// the values the core takes roots of (1e-6 … 1e6, 4000 points, log-spaced).
fn sqrt_against_micromath(k: f32) {
    use micromath::F32Ext;
    let (mut core_stat, mut mm_stat) = (Stat::new(), Stat::new());
    let mut worst_rel = 0.0f32;
    let mut core_exact = true;
    let mut x = 1e-6f32;
    while x < 1e6 {
        let mut a = 0.0f32;
        let mut b = 0.0f32;
        core_stat.add(counts(|| a = core::hint::black_box(piezo_drive::fastmath::sqrt_f32(core::hint::black_box(x)))));
        mm_stat.add(counts(|| b = core::hint::black_box(F32Ext::sqrt(core::hint::black_box(x)))));
        // Reference: VSQRT is IEEE 754 correctly rounded; check it by squaring back in f64.
        let exact = (f64::from(a) * f64::from(a) - f64::from(x)).abs() <= f64::from(x) * 1.2e-7;
        core_exact &= exact;
        worst_rel = worst_rel.max(((b - a) / a).abs());
        x *= 1.00692;
    }
    core_stat.print("fastmath::sqrt_f32 (VSQRT)", k);
    mm_stat.print("micromath F32Ext::sqrt", k);
    hprintln!(
        "  micromath's largest relative error against VSQRT: {}; VSQRT within half an ulp: {}",
        worst_rel,
        core_exact
    );
}

/// Instructions of the core's `acos_f32` (the model table's φp column), micromath's `acos` and
/// the fixed-point `trig::acos` it replaced, over [−1, 1] (4001 points); the largest differences
/// from `acos_f32` (which the host tests hold within 7e-5 rad of the true acos).
fn acos_against_micromath(k: f32) {
    use micromath::F32Ext;
    let (mut core_stat, mut mm_stat, mut fx_stat) = (Stat::new(), Stat::new(), Stat::new());
    let (mut worst_mm, mut worst_fx) = (0.0f32, 0.0f32);
    for i in 0..=4000 {
        let x = -1.0 + i as f32 / 2000.0;
        let (mut a, mut b, mut c) = (0.0f32, 0.0f32, Fx::ZERO);
        core_stat.add(counts(|| a = core::hint::black_box(piezo_drive::fastmath::acos_f32(core::hint::black_box(x)))));
        mm_stat.add(counts(|| b = core::hint::black_box(F32Ext::acos(core::hint::black_box(x)))));
        let xf = piezo_drive::fastmath::fx_from_f32(x);
        fx_stat.add(counts(|| c = core::hint::black_box(piezo_drive::trig::acos(core::hint::black_box(xf)))));
        worst_mm = worst_mm.max((b - a).abs());
        worst_fx = worst_fx.max((c.to_num::<f32>() - a).abs());
    }
    core_stat.print("fastmath::acos_f32 (A&S 4.4.45, VSQRT)", k);
    mm_stat.print("micromath F32Ext::acos", k);
    fx_stat.print("trig::acos (fixed point, table) + conversion in", k);
    hprintln!("  largest difference from acos_f32: micromath {} rad, trig::acos {} rad", worst_mm, worst_fx);
}

/// The contact model in the core (`normal_motion` and `contact_orbit`, not yet in the table
/// build: issue 28 item 3) on the sourced prototype's stator (`params/prototype-sourced.toml` via
/// host-sim's `core_normal_motion`, 100 V): the stator's normal motion from rest to its settled
/// contact force at three operating points, then the 1 kg carriage's orbits on the 16 N, 2.2 kHz
/// force: one solve at no load and against 2 N, and a 17-load table hinted load to load.
fn contact_orbit(k: f32) {
    use piezo_drive::contact_orbit::{Carriage, Orbits};
    use piezo_drive::normal_motion::{NormalDrive, NormalMotion, Stator};
    let stator = Stator {
        foot_mass_kg: 0.06,
        counterweight_mass_kg: 1.0,
        stack_n_per_m: 2.7e7,
        preload_spring_n_per_m: 2e6,
        stack_damping_n_s_per_m: 123.6245,
        preload_damping_n_s_per_m: 1456.022,
        contact_n_per_m: 2e9,
        contact_damping_n_s_per_m: 3962.407,
    };
    let mut working = None;
    for (preload_n, frequency_hz, normal_force_n) in
        [(16.0f32, 2200.0f32, 15.943_133f32), (16.0, 1500.0, 15.985_793), (5.0, 2200.0, 15.943_133)]
    {
        let drive = NormalDrive { frequency_hz, normal_force_n, preload_n };
        let mut motion = None;
        let new = counts(|| motion = Some(NormalMotion::new(core::hint::black_box(&stator), &drive)));
        let Some(Ok(motion)) = motion else {
            hprintln!("normal motion at {} N, {} Hz: refused", preload_n, frequency_hz);
            continue;
        };
        let mut profile = None;
        let settle = counts(|| profile = Some(core::hint::black_box(&motion).settle()));
        match profile {
            Some(Ok(p)) => {
                hprintln!(
                    "normal motion, {} N, {} Hz: transitions {} instructions, settle {} ({} periods, pattern {}, {} per period), {} event steps, mean {} N",
                    preload_n,
                    frequency_hz,
                    (new as f32 * k) as u32,
                    (settle as f32 * k) as u32,
                    p.periods,
                    p.pattern,
                    (settle as f32 * k / f32::from(p.periods.max(1))) as u32,
                    p.force.events(),
                    p.force.mean_n()
                );
                if working.is_none() {
                    working = Some(p.force);
                }
            }
            other => hprintln!("normal motion at {} N, {} Hz: {:?}", preload_n, frequency_hz, other.map(|r| r.err())),
        }
    }
    let Some(force) = working else {
        return;
    };
    let carriage = Carriage {
        mass_kg: 1.0,
        kt_n_per_m: 7.7e8,
        ct_n_s_per_m: 1350.0,
        mu_stick: 0.35,
        mu_dynamic: 0.35,
        viscous_n_s_per_m: 0.0,
        guide_n_s_per_m: 0.0,
        foot_peak_m_s: 4.28e-3,
        frequency_hz: 2200.0,
    };
    let orbits = Orbits::new(&force, carriage);
    // A 17-load speed table (0 to 2.4 N), each load searched from the last one's orbit.
    let mut hint = None;
    let mut last = f32::NAN;
    let table = counts(|| {
        for k in 0..17u8 {
            let load_n = 2.4 * f32::from(k) / 16.0;
            if let Some((speed, start)) = core::hint::black_box(&orbits).orbit_near(load_n, hint) {
                hint = Some(start);
                last = speed;
            }
        }
    });
    hprintln!(
        "contact orbits, 17 loads hinted from the last: {} instructions ({} per load), {} mm/s at 2.4 N",
        (table as f32 * k) as u32,
        (table as f32 * k / 17.0) as u32,
        last * 1e3
    );
    // The same table with each search started where the last two orbits point.
    let loads: [f32; 17] = core::array::from_fn(|k| 2.4 * k as f32 / 16.0);
    let mut along = [None; 17];
    let table_along = counts(|| along = core::hint::black_box(&orbits).speeds_along(&loads));
    hprintln!(
        "contact orbits, 17 loads along the table (starts extrapolated): {} instructions ({} per load), {} mm/s at 2.4 N",
        (table_along as f32 * k) as u32,
        (table_along as f32 * k / 17.0) as u32,
        along[16].unwrap_or(f32::NAN) * 1e3
    );
    for load_n in [0.0f32, 2.0] {
        let mut speed = None;
        let c = counts(|| speed = core::hint::black_box(&orbits).mean_speed_m_s(core::hint::black_box(load_n)));
        hprintln!(
            "contact orbit, 1 kg, 16 N, 2.2 kHz, {} N: {} instructions, {} mm/s ({} event steps)",
            load_n,
            (c as f32 * k) as u32,
            speed.unwrap_or(f32::NAN) * 1e3,
            force.events()
        );
    }
}
