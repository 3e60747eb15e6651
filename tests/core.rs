//! The control core's building blocks against independent expectations (f64 math, hand counts).

use piezo_drive::generator::{DacConfig, QuadratureGenerator};
use piezo_drive::profile::Profile;
use piezo_drive::sensors::{Encoder, PreloadCalibration, PreloadCell};
use piezo_drive::{trig, Fx};
use proptest::prelude::*;

fn dac() -> DacConfig {
    DacConfig {
        full_scale_v: 100.0,
        min_v: 0.0,
        max_v: 100.0,
        sample_rate_hz: 200_000,
        min_freq_hz: 500.0,
        max_freq_hz: 2200.0,
        slew_v_per_sample: 0.5,
    }
}

#[test]
fn fixed_point_trig_matches_f64() {
    for i in -700..=700 {
        let x = i as f64 * 0.01;
        let fx = Fx::from_num(x);
        let xr = fx.to_num::<f64>();
        assert!((trig::sin(fx).to_num::<f64>() - xr.sin()).abs() < 1e-4, "sin {x}");
        assert!((trig::cos(fx).to_num::<f64>() - xr.cos()).abs() < 1e-4, "cos {x}");
    }
    for i in -100..=100 {
        let x = i as f64 * 0.01;
        let fx = Fx::from_num(x);
        let xr = fx.to_num::<f64>();
        assert!((trig::acos(fx).to_num::<f64>() - xr.acos()).abs() < 2e-3, "acos {x}");
        assert!((trig::asin(fx).to_num::<f64>() - xr.asin()).abs() < 2e-3, "asin {x}");
    }
}

/// Runs the generator and returns the samples in volts.
fn run(g: &mut QuadratureGenerator, n: usize) -> Vec<[f64; 2]> {
    (0..n)
        .map(|_| {
            let w = g.next_words();
            [f64::from(w[0]) * 100.0 / 4095.0, f64::from(w[1]) * 100.0 / 4095.0]
        })
        .collect()
}

#[test]
fn generator_makes_two_sines_a_quarter_period_apart() {
    let mut g = QuadratureGenerator::new(dac());
    g.set_frequency_hz(2000.0);
    g.set_amplitude_v(80.0);
    run(&mut g, 2000); // ramp up
    let s = run(&mut g, 100); // exactly one period at 200 kS/s
    let (lo, hi) = s.iter().fold((f64::MAX, f64::MIN), |(lo, hi), v| (lo.min(v[0]), hi.max(v[0])));
    assert!((hi - lo - 80.0).abs() < 0.3, "peak-to-peak {}", hi - lo);
    assert!(((hi + lo) / 2.0 - 50.0).abs() < 0.2, "centred on mid-range");
    // Direction +1: channel 2 is channel 1 delayed by a quarter period (25 samples).
    for k in 25..100 {
        assert!((s[k][1] - s[k - 25][0]).abs() < 0.1, "sample {k}");
    }
    g.set_direction(-1);
    run(&mut g, 4000);
    let s = run(&mut g, 100);
    for k in 0..75 {
        assert!((s[k][1] - s[k + 25][0]).abs() < 0.1, "reverse: channel 2 leads, sample {k}");
    }
}

#[test]
fn frequency_is_the_commanded_one_and_clamped() {
    let mut g = QuadratureGenerator::new(dac());
    g.set_amplitude_v(60.0);
    for f in [500.0f32, 1234.0, 2200.0] {
        g.set_frequency_hz(f);
        run(&mut g, 1000);
        let s = run(&mut g, 200_000); // one second
        let crossings = s.windows(2).filter(|w| w[0][0] < 50.0 && w[1][0] >= 50.0).count() as f32;
        assert!((crossings - f).abs() <= 1.0, "{f} Hz: {crossings} rising crossings in 1 s");
    }
    g.set_frequency_hz(10_000.0);
    assert_eq!(g.frequency_hz(), 2200.0);
    g.set_frequency_hz(f32::NAN);
    assert_eq!(g.frequency_hz(), 500.0);
}

#[test]
fn changes_of_frequency_amplitude_and_direction_never_step_the_output() {
    let mut g = QuadratureGenerator::new(dac());
    g.set_frequency_hz(2200.0);
    g.set_amplitude_v(100.0);
    let mut last = g.next_words();
    // Largest honest change per sample: the sine's own slope plus the slew limit, in words.
    let slope_words = 2.0 * std::f64::consts::PI * 2200.0 / 200_000.0 * 2047.5;
    let slew_words = 0.5 / 100.0 * 4095.0;
    let bound = (slope_words + slew_words + 2.0) as i32;
    for step in 0..40_000 {
        match step {
            5_000 => g.set_frequency_hz(700.0),
            10_000 => g.set_direction(-1),
            15_000 => g.set_amplitude_v(20.0),
            20_000 => g.set_direction(1),
            25_000 => g.set_static_offsets_v([30.0, -30.0]),
            30_000 => g.ramp_to_quiet(),
            _ => {}
        }
        let w = g.next_words();
        for ch in 0..2 {
            let d = (i32::from(w[ch]) - i32::from(last[ch])).abs();
            assert!(d <= bound, "step {step} ch {ch}: jump of {d} words (bound {bound})");
        }
        last = w;
    }
    assert!(g.is_quiet());
}

proptest! {
    #[test]
    fn no_command_sequence_leaves_the_voltage_and_frequency_range(
        cmds in proptest::collection::vec((0u8..6, -1e4f32..1e4f32), 1..60)
    ) {
        let mut cfg = dac();
        cfg.min_v = 5.0;
        cfg.max_v = 95.0;
        let mut g = QuadratureGenerator::new(cfg);
        let (lo, hi) = g.word_limits();
        for (kind, x) in cmds {
            match kind {
                0 => g.set_frequency_hz(x),
                1 => g.set_amplitude_v(x),
                2 => g.set_direction(if x < 0.0 { -1 } else { 1 }),
                3 => g.set_static_offsets_v([x, -x]),
                4 => g.ramp_static_offsets_v([x, x * 0.5], 20),
                _ => g.quiet_within(20),
            }
            prop_assert!(g.frequency_hz() >= 500.0 && g.frequency_hz() <= 2200.0);
            for _ in 0..50 {
                let w = g.next_words();
                prop_assert!(w[0] >= lo && w[0] <= hi && w[1] >= lo && w[1] <= hi, "{:?} outside {}..{}", w, lo, hi);
            }
        }
    }
}

#[test]
fn encoder_unwraps_the_16_bit_counter_both_ways() {
    let mut e = Encoder::new(65_530, 50);
    let mut raw: u16 = 65_530;
    let mut truth: i64 = 0;
    for step in [3i64, 10, 100, 30_000, 30_000, -20_000, -32_000, -32_000, 7] {
        raw = raw.wrapping_add(step as u16);
        truth += step;
        e.update(raw);
        assert_eq!(e.counts(), truth);
        assert_eq!(e.position_nm(), truth * 50);
    }
}

#[test]
fn preload_cell_calibrates_filters_and_flags_bad_words() {
    let cal = PreloadCalibration {
        zero_word: 100,
        newton_per_word: 0.01,
        min_valid_word: 0,
        max_valid_word: 4095,
        filter_alpha: 0.1,
    };
    let mut c = PreloadCell::new(cal);
    assert!(!c.valid());
    c.update(1700); // (1700 − 100) · 0.01 = 16 N
    assert!(c.valid());
    assert!((c.force_n() - 16.0).abs() < 1e-4);
    for _ in 0..200 {
        c.update(1300); // 12 N
    }
    assert!((c.force_n() - 12.0).abs() < 1e-3, "filtered to the new value: {}", c.force_n());
    c.update(4095);
    assert!(!c.valid(), "a saturated word is not a force");
    c.update(0);
    assert!(!c.valid(), "a zero word means a broken cell");
}

#[test]
fn profile_respects_limits_reaches_the_target_and_replans() {
    let (v_max, a_max, dt) = (2.5e6f32, 8.0e7f32, 1e-4f32);
    let mut p = Profile::at_rest(0);
    p.set_target(1_000_000);
    let mut last_v = 0.0f32;
    let mut steps = 0;
    while !p.done() {
        p.step(dt, v_max, || a_max, a_max);
        let v = p.velocity_nm_s();
        assert!(v.abs() <= v_max * 1.0001, "speed {v}");
        if p.done() {
            // Arrival sets the speed to zero: only from a speed one braking step could absorb.
            assert!(last_v.abs() <= 2.0 * a_max * dt, "arrived at {last_v} nm/s");
        } else {
            assert!(
                (v - last_v).abs() <= a_max * dt * 1.0001,
                "acceleration {} at step {steps}",
                (v - last_v) / dt
            );
        }
        assert!(p.position_nm() <= 1_000_000, "no overshoot of the reference");
        last_v = v;
        steps += 1;
        assert!(steps < 20_000);
    }
    assert_eq!(p.position_nm(), 1_000_000);
    // Hand calculation: 1 mm at 2.5 mm/s with 0.08 m/s² ramps takes d/v + v/a = 0.431 s.
    let t = steps as f32 * dt;
    assert!((t - 0.43125).abs() < 0.005, "took {t} s");
    // A new target behind a moving reference: it brakes, turns round and arrives.
    let mut p = Profile::at_rest(0);
    p.set_target(1_000_000);
    for _ in 0..1000 {
        p.step(dt, v_max, || a_max, a_max);
    }
    p.set_target(-200_000);
    let mut turned = false;
    for _ in 0..20_000 {
        p.step(dt, v_max, || a_max, a_max);
        turned |= p.velocity_nm_s() < 0.0;
        if p.done() {
            break;
        }
    }
    assert!(turned && p.done() && p.position_nm() == -200_000);
}

#[test]
fn the_core_square_root_is_correctly_rounded_like_the_m4fs_vsqrt() {
    // IEEE 754 square root is correctly rounded, on the M4F's VSQRT and in std alike: the host
    // build must return the very same bits, or host and target runs of the core drift apart
    // (`host-sim pil` counts such periods). Every exponent, 64 mantissas each, subnormals too.
    use piezo_drive::fastmath::sqrt_f32;
    let mut checked = 0;
    for exponent in 0u32..255 {
        for k in 0u32..64 {
            let mantissa = k.wrapping_mul(0x9E37_79B9) >> 9; // spread over the 23 bits
            let v = f32::from_bits((exponent << 23) | mantissa);
            if v <= 0.0 {
                continue;
            }
            assert_eq!(sqrt_f32(v).to_bits(), v.sqrt().to_bits(), "√{v:e}");
            checked += 1;
        }
    }
    assert!(checked > 16_000);
    assert_eq!(sqrt_f32(0.0), 0.0);
    assert_eq!(sqrt_f32(-4.0), 0.0);
    assert_eq!(sqrt_f32(f32::NAN), 0.0);
    assert_eq!(sqrt_f32(f32::INFINITY), f32::INFINITY);
}

#[test]
fn pil_frames_round_trip_and_reject_unknown_commands() {
    use piezo_drive::controller::{FaultCode, Inputs, Outputs, State, DAC_SAMPLES_PER_STEP};
    use piezo_drive::pil_wire::*;
    for command in [
        Command::None,
        Command::Servo(true),
        Command::Servo(false),
        Command::MoveTo(-123_456_789_012),
        Command::ClearFault,
        Command::Reference,
        Command::OpenLoop { cycles: -300, amplitude_v: 80.5, frequency_hz: 1234.5 },
        Command::Exit,
    ] {
        let inputs = Inputs {
            encoder_raw: 0xBEEF,
            preload_word: 4095,
            index: true,
            index_raw: if command == Command::None { None } else { Some(0x1234) },
            negative_limit: false,
            positive_limit: true,
            limits_wired: command == Command::Reference,
        };
        let t = Tick { command, inputs };
        assert_eq!(decode_tick(&encode_tick(&t)), Some(t));
    }
    let mut bad = encode_tick(&Tick { command: Command::None, inputs: Inputs::default() });
    bad[0] = 7;
    assert_eq!(decode_tick(&bad), None);
    let mut dac = [[0u16; 2]; DAC_SAMPLES_PER_STEP];
    for (i, d) in dac.iter_mut().enumerate() {
        *d = [i as u16 * 200, 4095 - i as u16];
    }
    let r = Reply {
        outputs: Outputs { dac, amp_enable: true },
        state: state_code(State::Fault(FaultCode::EncoderJump)),
        command_refused: true,
        tick_instructions: 123_456,
        step_instructions: 99_999,
        background_instructions: 70_001,
    };
    assert_eq!(decode_reply(&encode_reply(&r)), r);
    assert_eq!(state_name(r.state), "fault");
    // Every state the controller can be in comes back from its byte; other bytes are refused.
    let states = [State::Idle, State::Moving, State::Holding, State::Referencing, State::OpenLoop];
    for s in states.into_iter().chain(FaultCode::ALL.into_iter().map(State::Fault)) {
        assert_eq!(decode_state(state_code(s)), Some(s));
    }
    assert_eq!(decode_state(5), None);
    assert_eq!(decode_state(0x80), None);
    assert_eq!(state_name(0x80), "unknown");
    assert_eq!(r.state & 0x7f, FaultCode::EncoderJump as u8);
    // A GCS frame: its header is no tick, and its report comes back whole.
    let header = encode_gcs_header(301);
    assert_eq!(decode_gcs_header(&header), Some(301));
    assert_eq!(decode_tick(&header), None);
    assert_eq!(
        decode_gcs_header(&encode_tick(&Tick { command: Command::None, inputs: Inputs::default() })),
        None
    );
    assert_eq!(decode_gcs_header(&encode_gcs_header(70_000)), Some(GCS_MAX_BYTES));
    let g = GcsReport {
        commands: 2,
        sections: 5,
        section_instructions: [2_880, 5_440, 7, 0xFFFF_FFFF],
        total_instructions: 34_200,
        error: -4_100,
        reply_len: 4_096,
        reply_crc: 0xDEAD_BEEF,
    };
    assert_eq!(decode_gcs_report(&encode_gcs_report(&g)), g);
    assert_eq!(g.max_section(), 0xFFFF_FFFF);
}

/// The model table's acos (Abramowitz & Stegun 4.4.45) against the f64 acos: within 7e-5 rad
/// over [−1, 1], exact at the ends, π/2 for NaN, clamped outside.
#[test]
fn acos_f32_within_its_stated_error() {
    use piezo_drive::fastmath::acos_f32;
    let mut worst = 0.0f64;
    for i in 0..=20_000 {
        let x = -1.0 + 2.0 * f64::from(i) / 20_000.0;
        let err = (f64::from(acos_f32(x as f32)) - x.acos()).abs();
        worst = worst.max(err);
    }
    assert!(worst < 7e-5, "worst {worst}");
    assert!(acos_f32(1.0).abs() < 1e-6);
    assert!((f64::from(acos_f32(-1.0)) - std::f64::consts::PI).abs() < 1e-6);
    assert!((acos_f32(f32::NAN) - std::f32::consts::FRAC_PI_2).abs() < 1e-4);
    assert_eq!(acos_f32(3.0), acos_f32(1.0));
    assert_eq!(acos_f32(-3.0), acos_f32(-1.0));
}

#[test]
fn fault_code_all_lists_every_code_once_in_order() {
    // The codes are 1, 2, … with no gap: ALL must hold each, in order (a fault added to the enum
    // but not to ALL leaves a gap at the end or in the middle).
    for (i, f) in piezo_drive::controller::FaultCode::ALL.iter().enumerate() {
        assert_eq!(*f as u8, i as u8 + 1, "{f:?}");
        assert!(!f.text().is_empty());
    }
}
