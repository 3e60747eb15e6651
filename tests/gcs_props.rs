//! The protocol's number handling against closed forms and std, and property tests of the line
//! collector and executor: arbitrary bytes with arbitrary splits never panic, never exceed the
//! bounded buffers, always answer in GCS framing, and leave the parser ready for the next line.

use piezo_drive::controller::{Controller, Inputs};
use piezo_drive::defaults;
use piezo_drive::gcs::num::{
    parse_decimal, parse_int, write_f32, write_fixed, write_general, write_scaled, Decimal,
};
mod common;

use common::TestBoard;
use piezo_drive::gcs::{Gcs, Pending, Reply, LINE_CAPACITY};
use proptest::prelude::*;

fn fixed(v: f64, d: u32) -> String {
    let mut b: heapless::Vec<u8, 64> = heapless::Vec::new();
    assert!(write_fixed(&mut b, v, d));
    String::from_utf8(b.to_vec()).unwrap()
}
fn general(v: f64) -> String {
    let mut b: heapless::Vec<u8, 64> = heapless::Vec::new();
    assert!(write_general(&mut b, v));
    String::from_utf8(b.to_vec()).unwrap()
}
fn scaled(v: i64, d: u32) -> String {
    let mut b: heapless::Vec<u8, 64> = heapless::Vec::new();
    assert!(write_scaled(&mut b, v, d));
    String::from_utf8(b.to_vec()).unwrap()
}
fn dec(s: &str) -> Decimal {
    parse_decimal(s.as_bytes()).unwrap_or_else(|| panic!("{s} should parse"))
}

#[test]
fn decimal_parser_closed_forms() {
    assert_eq!(dec("2.5").scaled_i64(6), Some(2_500_000));
    assert_eq!(dec("-0.000050").scaled_i64(6), Some(-50));
    assert_eq!(dec("+1e-3").scaled_i64(6), Some(1_000));
    assert_eq!(dec("1E2").scaled_i64(0), Some(100));
    assert_eq!(dec(".5").scaled_i64(1), Some(5));
    assert_eq!(dec("5.").scaled_i64(0), Some(5));
    // Half away from zero.
    assert_eq!(dec("0.0000005").scaled_i64(6), Some(1));
    assert_eq!(dec("-0.0000005").scaled_i64(6), Some(-1));
    assert_eq!(dec("0.00000049999").scaled_i64(6), Some(0));
    // Overflow and extremes never panic.
    assert_eq!(dec("9223372036854.775807").scaled_i64(6), Some(i64::MAX));
    assert_eq!(dec("9223372036854.775808").scaled_i64(6), None);
    assert_eq!(dec("1e400").scaled_i64(6), None);
    assert_eq!(dec("1e-400").scaled_i64(6), Some(0));
    assert_eq!(dec("123456789012345678901234567890").scaled_i64(0), None);
    assert_eq!(dec("0.000000000000000000000000000001234").scaled_i64(33), Some(1234));
    assert_eq!(dec("1e999999999999").scaled_i64(0), None);
    assert_eq!(dec("1.5").integer(), None);
    assert_eq!(dec("15e-1").integer(), None);
    assert_eq!(dec("150e-2").integer(), None);
    assert_eq!(dec("200e-2").integer(), Some(2));
    assert_eq!(dec("-7").integer(), Some(-7));
    for bad in [
        "", "-", "+", ".", "e5", "1e", "1e+", "nan", "NaN", "inf", "-inf", "1.2.3", "1x", "0x10", "--1", "1 ",
    ] {
        assert_eq!(parse_decimal(bad.as_bytes()), None, "{bad:?}");
    }
    assert_eq!(parse_int(b"0x3F"), Some(63));
    assert_eq!(parse_int(b"0X1021"), Some(0x1021));
    assert_eq!(parse_int(b"-12"), Some(-12));
    assert_eq!(parse_int(b"99999999999999999999"), None);
    assert_eq!(parse_int(b"0x"), None);
    assert_eq!(parse_int(b"1.0"), None);
}

#[test]
fn formatters_closed_forms() {
    assert_eq!(scaled(2_500_000, 6), "2.500000");
    assert_eq!(scaled(-50, 6), "-0.000050");
    assert_eq!(scaled(0, 6), "0.000000");
    assert_eq!(scaled(i64::MIN, 6), "-9223372036854.775808");
    assert_eq!(scaled(i64::MAX, 0), "9223372036854775807");
    assert_eq!(fixed(15.995116, 3), "15.995");
    assert_eq!(fixed(-0.0005, 3), "-0.001");
    assert_eq!(fixed(2200.0, 1), "2200.0");
    assert_eq!(fixed(f64::NAN, 3), "0.000");
    assert_eq!(general(0.92f32 as f64), "0.92");
    assert_eq!(general(2e-4f32 as f64), "0.0002");
    assert_eq!(general(2200.0), "2200");
    assert_eq!(general(-50.0), "-50");
    assert_eq!(general(0.0), "0");
    assert_eq!(general(10.0), "10");
    assert_eq!(general(50.0 / 4095.0), "0.01221001");
    // From 1e18 up, exponent form: f32::MAX = 340282346638528859811704183484516925440.
    let f = |x: f32| {
        let mut b: heapless::Vec<u8, 64> = heapless::Vec::new();
        assert!(write_f32(&mut b, x));
        String::from_utf8(b.to_vec()).unwrap()
    };
    // Rust's shortest round-trip form is the independent reference.
    for x in [f32::MAX, f32::MAX / 1e6, 1e20, -2.5e19, 1e19, 1.234_567_8e28] {
        assert_eq!(f(x), format!("{x:e}"));
    }
    assert_eq!(f(f32::MAX), "3.4028235e38");
    // Below 1e18 a whole f32 prints all its digits (1e18 as an f32 is 999999984306749440).
    for x in [9.9e17f32, 1e18] {
        assert_eq!(f(x), (x as i64).to_string());
    }
}

proptest! {
    #[test]
    fn decimal_parse_matches_std(v in -1e12f64..1e12, exp in -30i32..30) {
        let x = v * 10f64.powi(exp);
        for s in [format!("{x}"), format!("{x:e}"), format!("{x:.9}")] {
            let d = parse_decimal(s.as_bytes()).unwrap();
            let ours = d.to_f64().unwrap();
            let std: f64 = s.parse().unwrap();
            prop_assert!((ours - std).abs() <= std.abs() * 1e-15, "{s}: {ours} vs {std}");
        }
    }

    #[test]
    fn millimetres_to_nanometres_is_exact(nm in -50_000_000_000i64..50_000_000_000) {
        // What POS? prints, MOV reads back to the same nanometre.
        let s = scaled(nm, 6);
        prop_assert_eq!(dec(&s).scaled_i64(6), Some(nm));
        prop_assert_eq!(s.parse::<f64>().unwrap(), nm as f64 / 1e6);
    }

    #[test]
    fn fixed_is_within_half_a_unit(v in -1e9f64..1e9, d in 0u32..7) {
        let s = fixed(v, d);
        let back: f64 = s.parse().unwrap();
        let unit = 10f64.powi(-(d as i32));
        prop_assert!((back - v).abs() <= 0.5 * unit + v.abs() * 1e-15, "{v} {d} {s}");
        let digits = s.split('.').nth(1).map_or(0, str::len);
        prop_assert_eq!(digits as u32, d);
    }

    #[test]
    fn general_keeps_seven_significant_digits(v in -1e6f64..1e6) {
        let s = general(v);
        let back: f64 = s.parse().unwrap();
        prop_assert!((back - v).abs() <= v.abs() * 1e-6 + 1e-12, "{v} -> {s}");
        prop_assert!(!s.ends_with('.') && (!s.contains('.') || !s.ends_with('0')), "{s}");
    }

    #[test]
    fn f32_parameters_read_back_exactly(bits in any::<u32>(), exponent in 98u32..176, zero in 0u8..20) {
        // SPA? prints an f32 so that SPA (parse_decimal, to_f64, then f32) sets the same f32:
        // any sign and mantissa with a magnitude from 2^-29 (1.9e-9) to 2^49 (5.6e14), and 0,
        // with at most nine significant digits after the point.
        let x = if zero == 0 { 0.0 } else { f32::from_bits((bits & 0x807F_FFFF) | (exponent << 23)) };
        let mut b: heapless::Vec<u8, 64> = heapless::Vec::new();
        prop_assert!(write_f32(&mut b, x));
        let s = String::from_utf8(b.to_vec()).unwrap();
        let back = dec(&s).to_f64().unwrap() as f32;
        prop_assert_eq!(back, x, "{}", s);
        let significant = s.trim_start_matches('-').replace('.', "");
        let significant = significant.trim_start_matches('0');
        // Whole numbers beyond nine digits print all their digits (no exponent notation).
        prop_assert!(significant.trim_end_matches('0').len() <= 9 || !s.contains('.'), "{}", s);
        prop_assert!(!s.ends_with('.') && (!s.contains('.') || !s.ends_with('0')), "{}", s);
    }

    #[test]
    fn huge_f32_parameters_read_back_exactly(bits in any::<u32>(), exponent in 187u32..255) {
        // 2^60 (1.2e18) to f32::MAX: the exponent form reads back as the same f32, nine
        // significant digits at most.
        let x = f32::from_bits((bits & 0x807F_FFFF) | (exponent << 23));
        let mut b: heapless::Vec<u8, 64> = heapless::Vec::new();
        prop_assert!(write_f32(&mut b, x));
        let s = String::from_utf8(b.to_vec()).unwrap();
        prop_assert_eq!(dec(&s).to_f64().unwrap() as f32, x, "{}", s);
        let (mantissa, _) = s.trim_start_matches('-').split_once('e').unwrap();
        prop_assert!(mantissa.replace('.', "").len() <= 9, "{}", s);
    }

    #[test]
    fn a_bad_first_pair_moves_nothing(first in -200.0f64..200.0, second in -40.0f64..40.0) {
        // MOV with two pairs: the second counts only if the first is within TMN?..TMX? too.
        let mut gcs = Gcs::new();
        let mut ctl = Controller::new(defaults::controller_config()).unwrap();
        let mut board = TestBoard::default();
        let inputs = Inputs { preload_word: 1310, ..Default::default() };
        ctl.step(&inputs);
        let mut send = |gcs: &mut Gcs, ctl: &mut Controller, text: &str| {
            let mut all = Vec::new();
            for &b in text.as_bytes() {
                if let Some(p) = gcs.push_byte(b) {
                    let mut reply = Reply::new();
                    gcs.execute(&p, ctl, &mut board, &mut reply);
                    all.extend_from_slice(&reply);
                }
            }
            String::from_utf8(all).unwrap()
        };
        prop_assert_eq!(send(&mut gcs, &mut ctl, "RON 1 0\nSVO 1 1\nERR?\n"), "0\n");
        let line = format!("MOV 1 {first:.6} 1 {second:.6}\nERR?\nMOV?\n");
        let got = send(&mut gcs, &mut ctl, &line);
        if first.abs() <= 50.0 {
            prop_assert_eq!(got, format!("0\n1={second:.6}\n"));
        } else {
            prop_assert_eq!(got, "7\n1=0.000000\n");
        }
    }

    #[test]
    fn arbitrary_bytes_never_break_the_protocol(
        bytes in proptest::collection::vec(any::<u8>(), 0..2000),
        splits in proptest::collection::vec(1usize..300, 1..20),
    ) {
        let mut gcs = Gcs::new();
        let mut ctl = Controller::new(defaults::controller_config()).unwrap();
        ctl.step(&Inputs { preload_word: 1310, ..Default::default() });
        let mut board = TestBoard::default();
        // Arbitrary chunks, as a UART or a socket delivers them, with control steps in between.
        let mut rest: &[u8] = &bytes;
        let mut k = 0;
        while !rest.is_empty() {
            let n = splits[k % splits.len()].min(rest.len());
            k += 1;
            let (chunk, tail) = rest.split_at(n);
            rest = tail;
            for &b in chunk {
                if let Some(p) = gcs.push_byte(b) {
                    if let Pending::Line(l) = &p {
                        prop_assert!(l.len() <= LINE_CAPACITY);
                        prop_assert!(!l.contains(&b'\n'));
                    }
                    let mut reply = Reply::new();
                    gcs.execute(&p, &mut ctl, &mut board, &mut reply);
                    check_framing(&reply)?;
                }
            }
            ctl.step(&Inputs { preload_word: 1310, ..Default::default() });
        }
        // Ready for the next line, whatever came before.
        let mut last = Reply::new();
        for &b in b"\nCSV?\n" {
            if let Some(p) = gcs.push_byte(b) {
                last.clear();
                gcs.execute(&p, &mut ctl, &mut board, &mut last);
            }
        }
        prop_assert_eq!(last.as_slice(), b"2.0\n");
    }

    #[test]
    fn well_formed_commands_with_random_arguments(
        cmds in proptest::collection::vec(
            (prop::sample::select(vec![
                "MOV", "MVR", "POS", "SVO", "RON", "FRF", "VEL", "ACC", "DEC", "SPA", "SPA?", "XOS",
                "POS?", "MOV?", "ONT?", "HLT", "STP", "SAI?", "HPA?", "HLP?", "WPA", "ERR?", "XTM?",
                "DRC", "DRC?", "DRT", "DRT?", "RTR", "RTR?", "DRL?", "DRR?", "TNR?", "HDR?",
            ]),
            proptest::collection::vec(
                prop::sample::select(vec![
                    "1", "0", "2", "-1", "0x1", "0xA", "0x1005", "0x30", "1e3", "-2.5", "0.0001",
                    "1e400", "ALL", "x", "100", "2200", "50", "-0", "99999999999999999999",
                    "4", "6", "8", "9", "256", "259", "1024", "1025",
                ]),
                0..6,
            )),
            1..40,
        ),
    ) {
        let mut gcs = Gcs::new();
        let mut ctl = Controller::new(defaults::controller_config()).unwrap();
        let mut board = TestBoard::default();
        for (cmd, args) in cmds {
            let line = format!("{cmd} {}\n", args.join(" "));
            for &b in line.as_bytes() {
                if let Some(p) = gcs.push_byte(b) {
                    let mut reply = Reply::new();
                    gcs.execute(&p, &mut ctl, &mut board, &mut reply);
                    // A long DRR? comes in parts: the whole reply is one framed answer.
                    let mut whole = reply.to_vec();
                    while gcs.reply_pending() {
                        let mut more = Reply::new();
                        gcs.continue_reply(&board, &mut more);
                        prop_assert!(!more.is_empty());
                        whole.extend_from_slice(&more);
                    }
                    check_framing(&whole)?;
                }
            }
            for _ in 0..5 {
                ctl.step(&Inputs { preload_word: 1310, ..Default::default() });
                board.recorder.sample(&ctl);
            }
        }
    }
}

/// GCS framing: nothing, or lines ending in LF, every line but the last with a space before
/// it, the last without; never a CR.
fn check_framing(reply: &[u8]) -> Result<(), TestCaseError> {
    if reply.is_empty() {
        return Ok(());
    }
    prop_assert!(!reply.contains(&b'\r'));
    prop_assert_eq!(reply.last(), Some(&b'\n'));
    let body = &reply[..reply.len() - 1];
    if let Some(&c) = body.last() {
        prop_assert_ne!(
            c,
            b' ',
            "single or last line ends with a space: {:?}",
            String::from_utf8_lossy(reply)
        );
    }
    for (i, &b) in body.iter().enumerate() {
        if b == b'\n' {
            prop_assert!(i > 0 && body[i - 1] == b' ');
        }
    }
    Ok(())
}
