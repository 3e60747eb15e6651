//! What PI's other clients ask: EPICS motorPIGCS2's C-863/C-867 path (`LIM?`, `TRS?`, `HAR?`,
//! the status register `#4`/`SRG?`, counts per unit 0xE/0xF, acceleration limits 0x4A/0x4B,
//! reference velocity 0x50, `FNL`/`FPL`), the compatibility identity (0x1040), and the queries
//! PI's tools send when they connect (`HLP?`, `HPA?`, `HDR?`, `VER?`, `SSN?`, `CSV?`, `SPA?`
//! for every listed id), each answered or refused with PI's error number. Expected replies come
//! from PI's published formats (the C-863 manual's `#4` layout: bit 15 on target, 14
//! referencing, 13 in motion, 12 servo on, 8 error, 2 positive limit, 0 negative limit; PI's
//! error numbers) and from the driver's parsing rules, not from what the code prints.

mod common;

use common::TestBoard;
use piezo_drive::controller::{Controller, Inputs};
use piezo_drive::defaults;
use piezo_drive::gcs::{Gcs, Reply, COMMANDS};
use piezo_drive::settings::counts_per_mm;
use proptest::prelude::*;

/// 16 N on the default 12-bit, 50 N force cell.
const PRELOAD_WORD: u16 = 1310;

struct Rig {
    gcs: Gcs,
    ctl: Controller,
    board: TestBoard,
}

impl Rig {
    fn new() -> Self {
        let mut rig = Rig {
            gcs: Gcs::new(),
            ctl: Controller::new(defaults::controller_config()).unwrap(),
            board: TestBoard::default(),
        };
        rig.steps(10, Inputs::default());
        rig
    }

    fn steps(&mut self, n: usize, extra: Inputs) {
        for _ in 0..n {
            self.ctl.step(&Inputs { preload_word: PRELOAD_WORD, ..extra });
            self.board.recorder.sample(&self.ctl);
            self.ctl.background();
        }
    }

    fn send(&mut self, bytes: &[u8]) -> Vec<u8> {
        let mut all = Vec::new();
        for &b in bytes {
            if let Some(p) = self.gcs.push_byte(b) {
                let mut reply = Reply::new();
                self.gcs.execute(&p, &mut self.ctl, &mut self.board, &mut reply);
                all.extend_from_slice(&reply);
                while self.gcs.reply_pending() {
                    let mut more = Reply::new();
                    self.gcs.continue_reply(&self.board, &mut more);
                    all.extend_from_slice(&more);
                }
            }
        }
        all
    }

    fn text(&mut self, line: &str) -> String {
        String::from_utf8(self.send(line.as_bytes())).unwrap()
    }

    fn transcript(&mut self, pairs: &[(&str, &str)]) {
        for (i, (sent, expected)) in pairs.iter().enumerate() {
            assert_eq!(self.text(sent), *expected, "exchange {i}: sent {sent:?}");
        }
    }

    /// `#4` read as EPICS motorPIGCS2 reads it: four hex digits from the third character on.
    fn register(&mut self) -> u16 {
        let r = self.text("\x04");
        assert!(r.len() == 7 && r.starts_with("0x") && r.ends_with('\n'), "{r:?}");
        u16::from_str_radix(&r[2..6], 16).unwrap()
    }

    fn value(&mut self, line: &str) -> f64 {
        let r = self.text(line);
        r.trim_end().split_once('=').unwrap().1.parse().unwrap()
    }
}

#[test]
fn identity_is_our_own_unless_the_stored_setting_asks_for_the_c867_name() {
    let mut rig = Rig::new();
    rig.transcript(&[
        ("*IDN?\n", "(c)2026 piezo-drive project, PD-SB1, 000042, 0.1.0\n"),
        ("SPA? 1 0x1040\n", "1 0x1040=0\n"),
        ("SPA 1 0x1040 2\n", ""),
        ("ERR?\n", "17\n"),
        ("SPA 1 0x1040 1\n", ""),
        ("ERR?\n", "0\n"),
        // EPICS motorPIGCS2 upper-cases the reply and looks for "C-867"; PIPython takes the second
        // field as the model and still finds none of its own (it compares whole names).
        ("*IDN?\n", "(c)2026 piezo-drive project, PD-SB1 (C-867 compatible), 000042, 0.1.0\n"),
        ("WPA\n", ""),
        ("ERR?\n", "0\n"),
    ]);
    assert!(rig.board.stored.unwrap().idn_c867_compatible, "WPA keeps the identity");
    let text = rig.text("*IDN?\n");
    let fields: Vec<&str> = text.trim_end().split(", ").collect();
    assert_eq!(fields.len(), 4);
    assert!(fields[3].split('.').count() <= 3);
    rig.transcript(&[
        ("SPA 1 0x1040 0\n", ""),
        ("*IDN?\n", "(c)2026 piezo-drive project, PD-SB1, 000042, 0.1.0\n"),
    ]);
}

#[test]
fn limit_switches_reference_switch_and_hard_stops_as_the_driver_asks() {
    // The core has no limit switches wired (limit_switches()): LIM? 0, so the driver asks HAR?
    // (no hard-stop referencing) and TRS? (FRF has a mark: 1).
    let mut rig = Rig::new();
    rig.transcript(&[
        ("LIM? 1\n", "1=0\n"),
        ("LIM?\n", "1=0\n"),
        ("HAR? 1\n", "1=0\n"),
        ("TRS? 1\n", "1=1\n"),
        ("LIM? 2\n", ""),
        ("ERR?\n", "15\n"),
        // Referencing on a limit switch without limit switches: PI's 32 (no limit switch).
        ("FNL 1\n", ""),
        ("ERR?\n", "32\n"),
        ("FPL\n", ""),
        ("ERR?\n", "32\n"),
        ("FNL 2\n", ""),
        ("ERR?\n", "15\n"),
        ("FRF? 1\n", "1=0\n"),
    ]);
    assert!(!rig.ctl.referencing());
}

#[test]
fn status_register_follows_servo_motion_referencing_target_and_errors() {
    let mut rig = Rig::new();
    // Servo off, idle, nothing latched.
    assert_eq!(rig.register(), 0x0000);
    // An error waiting for ERR? sets bit 8 until read.
    rig.send(b"XYZ\n");
    assert_eq!(rig.register(), 0x0100);
    assert_eq!(rig.text("ERR?\n"), "2\n");
    assert_eq!(rig.register(), 0x0000);
    // Referencing: bits 14 and 13 (in motion), #7 busy, as the driver's poll reads them.
    rig.transcript(&[("FRF 1\n", ""), ("ERR?\n", "0\n")]);
    assert_eq!(rig.register() & 0x6000, 0x6000);
    assert_eq!(rig.send(b"\x07"), [0xB0, b'\n']);
    rig.steps(1, Inputs { index: true, ..Default::default() });
    assert_eq!(rig.register() & 0x6000, 0x0000);
    // Servo on, holding: bit 12; on target (bit 15) once settled (0x3F, 10 ms = 100 periods).
    rig.transcript(&[("SVO 1 1\n", ""), ("ERR?\n", "0\n")]);
    assert_eq!(rig.register() & 0x1000, 0x1000);
    rig.steps(200, Inputs::default());
    assert_eq!(rig.text("ONT? 1\n"), "1=1\n");
    assert_eq!(rig.register(), 0x9000);
    // A move (the encoder does not follow here): in motion, not on target.
    rig.transcript(&[("MOV 1 0.01\n", ""), ("ERR?\n", "0\n")]);
    assert_eq!(rig.register() & 0xA000, 0x2000);
    // SRG? answers the same register in PI's query form.
    let r = rig.register();
    assert_eq!(rig.text("SRG? 1 1\n"), format!("1 1=0x{r:04X}\n"));
    rig.transcript(&[
        ("SRG? 1 2\n", ""),
        ("ERR?\n", "17\n"),
        ("SRG? 2 1\n", ""),
        ("ERR?\n", "15\n"),
        ("SRG? 1\n", ""),
        ("ERR?\n", "24\n"),
    ]);
}

#[test]
fn counts_per_unit_is_the_encoder_resolution_in_lowest_terms() {
    // Hand values: 1 mm = 1e6 nm.
    assert_eq!(counts_per_mm(50), (20_000, 1));
    assert_eq!(counts_per_mm(1), (1_000_000, 1));
    assert_eq!(counts_per_mm(3), (1_000_000, 3));
    assert_eq!(counts_per_mm(64), (15_625, 1));
    assert_eq!(counts_per_mm(80), (12_500, 1));
    assert_eq!(counts_per_mm(1_000_000), (1, 1));
    assert_eq!(counts_per_mm(300), (10_000, 3));
    // The default board's 50 nm encoder, as the driver asks (decimal ids): 20000 counts per mm,
    // so its resolution (0xF / 0xE) is 50 nm. Read-only.
    let mut rig = Rig::new();
    rig.transcript(&[
        ("SPA? 1 14\n", "1 0xE=20000\n"),
        ("SPA? 1 15\n", "1 0xF=1\n"),
        ("SPA 1 14 10000\n", ""),
        ("ERR?\n", "64\n"),
    ]);
}

#[test]
fn acceleration_limits_are_the_most_acc_and_dec_accept() {
    let mut rig = Rig::new();
    let max_acc = rig.value("SPA? 1 74\n");
    let max_dec = rig.value("SPA? 1 75\n");
    assert_eq!(max_acc, max_dec);
    // The top of an f32 in nm/s^2, in mm/s^2.
    assert!((max_acc / (f64::from(f32::MAX) / 1e6) - 1.0).abs() < 1e-6, "{max_acc}");
    // The driver clamps its acceleration to them and sets 0xB and 0xC with %.12g: any value up
    // to them is accepted, above them refused.
    rig.transcript(&[
        ("SPA 1 11 50\n", ""),
        ("SPA 1 12 50\n", ""),
        ("ERR?\n", "0\n"),
        ("ACC? 1\n", "1=50\n"),
        ("DEC? 1\n", "1=50\n"),
        ("SPA 1 74 10\n", ""),
        ("ERR?\n", "64\n"),
    ]);
    rig.send(format!("SPA 1 11 {:.12e}\n", max_acc * 0.999_999).as_bytes());
    assert_eq!(rig.text("ERR?\n"), "0\n");
    rig.send(format!("SPA 1 11 {:.12e}\n", max_acc * 1.01).as_bytes());
    assert_eq!(rig.text("ERR?\n"), "17\n");
}

#[test]
fn reference_velocity_sets_the_reference_drive_through_the_model() {
    let mut rig = Rig::new();
    let cfg = *rig.ctl.config();
    // The default search drive (0x1018, 50 V) seen as a speed: above 0, below the foot's peak
    // tangential speed at 50 V (the slider cannot outrun the foot that drives it).
    let foot_mm_s_per_v = cfg.per_volt().foot_speed_mm_s_per_v.to_num::<f64>();
    let v0 = rig.value("SPA? 1 0x50\n");
    assert!(v0 > 0.0 && v0 < foot_mm_s_per_v * 50.0, "{v0} mm/s");
    // The driver's home: SPA 1 0x50 <HVEL>, then ERR? must be 0. A slower search needs less drive.
    rig.transcript(&[("SPA 1 0x50 0.500000\n", ""), ("ERR?\n", "0\n")]);
    let drive_v = rig.value("SPA? 1 0x1018\n");
    assert!(drive_v > 0.0 && drive_v < 50.0, "{drive_v} V");
    assert!(0.5 < foot_mm_s_per_v * drive_v, "the foot at {drive_v} V is slower than 0.5 mm/s");
    // Read back as set, to the 0.01 V steps of the conversion.
    let back = rig.value("SPA? 1 0x50\n");
    assert!((back - 0.5).abs() < 0.01, "{back}");
    rig.transcript(&[("SPA 1 0x50 0.250000\n", ""), ("ERR?\n", "0\n")]);
    assert!(rig.value("SPA? 1 0x1018\n") < drive_v);
    // Faster than full drive can go (the foot's peak speed at 100 V), or not positive: 17,
    // nothing changes.
    let too_fast = foot_mm_s_per_v * 100.0 * 1.01;
    let before = rig.text("SPA? 1 0x1018\n");
    for bad in [format!("{too_fast:.6}"), "0".into(), "-1".into()] {
        rig.send(format!("SPA 1 0x50 {bad}\n").as_bytes());
        assert_eq!(rig.text("ERR?\n"), "17\n", "{bad}");
        assert_eq!(rig.text("SPA? 1 0x1018\n"), before);
    }
}

#[test]
fn version_and_serial_number() {
    Rig::new().transcript(&[
        ("VER?\n", "FW_ARM: V0.1.0\n"),
        ("SSN?\n", "000042\n"),
        ("SSN? 1\n", ""),
        ("ERR?\n", "24\n"),
        // Renaming axes (TVI? lists the characters SAI may use) and the link's settings
        // (IFC?/IFS?) are not offered: unknown commands, as on a PI controller without them.
        ("TVI?\n", ""),
        ("ERR?\n", "2\n"),
        ("IFC?\n", ""),
        ("ERR?\n", "2\n"),
        ("IFS?\n", ""),
        ("ERR?\n", "2\n"),
    ]);
}

#[test]
fn every_parameter_hpa_lists_answers_spa() {
    let mut rig = Rig::new();
    let hpa = rig.text("HPA?\n");
    let ids: Vec<String> =
        hpa.lines().filter_map(|l| l.trim_end().split_once("=\t").map(|(id, _)| id.to_string())).collect();
    assert!(ids.len() > 40);
    for id in ids {
        let reply = rig.text(&format!("SPA? 1 {id}\n"));
        let (head, value) = reply.trim_end_matches('\n').split_once('=').unwrap();
        assert_eq!(head, format!("1 {id}"));
        assert!(value.parse::<f64>().is_ok_and(f64::is_finite), "{id}: {reply:?}");
        assert_eq!(rig.text("ERR?\n"), "0\n", "{id}");
    }
}

/// The queries `HLP?` lists that answer with no argument in any state (the rest need
/// arguments or something recorded, and say so with an error).
const NEED_MORE: &[(&str, i32)] = &[("DRR?", 78)];

#[test]
fn every_query_hlp_lists_answers_without_arguments() {
    let mut rig = Rig::new();
    let hlp = rig.text("HLP?\n");
    let names: Vec<&str> = hlp.lines().skip(1).filter_map(|l| l.split(' ').next()).collect();
    assert_eq!(names.len(), COMMANDS.len() + 1, "each command and `end`");
    for name in names.iter().filter(|n| n.ends_with('?')) {
        let reply = rig.text(&format!("{name}\n"));
        let err: i32 = rig.text("ERR?\n").trim().parse().unwrap();
        match NEED_MORE.iter().find(|(n, _)| n == name) {
            Some((_, code)) => assert_eq!((reply.as_str(), err), ("", *code), "{name}"),
            None => {
                assert!(!reply.is_empty() && reply.ends_with('\n'), "{name}: silence");
                assert_eq!(err, 0, "{name}");
            }
        }
    }
}

/// PI's setters that have a query of the same name with `?` (GCS 2.0), and those that have none.
const PAIRED: &[&str] = &["ACC", "DEC", "DRC", "DRT", "FRF", "MOV", "POS", "RON", "RTR", "SPA", "SVO", "VEL"];
const UNPAIRED: &[&str] = &["FNL", "FPL", "HLT", "MVR", "STP", "WPA"];

#[test]
fn every_command_hlp_lists_has_its_query_form_where_pi_has_one() {
    let mut rig = Rig::new();
    let hlp = rig.text("HLP?\n");
    let names: Vec<&str> = hlp.lines().skip(1).filter_map(|l| l.split(' ').next()).collect();
    for name in names.iter().filter(|n| !n.ends_with('?') && !n.starts_with('#') && **n != "end") {
        let query = format!("{name}?");
        if PAIRED.contains(name) {
            assert!(names.contains(&query.as_str()), "{name} without {query}");
            let reply = rig.text(&format!("{query}\n"));
            assert!(!reply.is_empty(), "{query}: silence");
            assert_eq!(rig.text("ERR?\n"), "0\n", "{query}");
        } else {
            // No query on PI's controllers either (or an extension of ours): unknown, 2.
            assert!(UNPAIRED.contains(name) || name.starts_with('X'), "{name}: which is it?");
            assert_eq!(rig.text(&format!("{query}\n")), "", "{query}");
            assert_eq!(rig.text("ERR?\n"), "2\n", "{query}");
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    /// Any query `HLP?` lists, with any arguments: it answers (and latches nothing), or answers
    /// nothing and latches a GCS error number (one PI uses: the list below). Never silence
    /// without an error, never an answer with one.
    #[test]
    fn a_query_answers_or_latches_an_error(
        queries in proptest::collection::vec(
            (prop::sample::select(COMMANDS.iter().filter(|c| c.name.ends_with('?')).map(|c| c.name).collect::<Vec<_>>()),
             proptest::collection::vec(
                prop::sample::select(vec!["1", "2", "0", "ALL", "0x50", "14", "74", "0x1040", "x", "-1", "1e3"]),
                0..4)),
            1..20),
    ) {
        let mut rig = Rig::new();
        for (name, args) in queries {
            let reply = rig.text(&format!("{name} {}\n", args.join(" ")));
            let err: i32 = rig.text("ERR?\n").trim().parse().unwrap();
            if reply.is_empty() {
                prop_assert!([1, 2, 15, 17, 24, 26, 54, 57, 77, 78, 505].contains(&err), "{} {:?}: error {}", name, args, err);
            } else {
                prop_assert_eq!(err, 0, "{} {:?} answered {:?}", name, args, reply);
                prop_assert!(reply.ends_with('\n') && !reply.ends_with(" \n") && !reply.contains('\r'));
            }
            rig.steps(3, Inputs::default());
        }
    }
}
