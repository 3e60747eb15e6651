//! Issue 13, end to end: a board whose motor is not what its firmware believes measures itself,
//! the model-gap workflow names what is missing, the fitted model goes up without a rebuild, and
//! the same moves run better.
//!
//! The truth (`serve --params TRUE`): the heavy-slider motor with μd 20 % lower (0.28 for 0.35)
//! and 0.4 N of Coulomb friction in the carriage's guide. The firmware (`--firmware-params`):
//! built for the heavy-slider file as it is. Everything goes over GCS, as with a board:
//! `characterize` at three hanging weights (0, 0.3, 0.6 N) and at a second preload (12 N, the
//! user turning the preload screw) → `gap` (base model: the firmware's file) →
//! `calibrate` → ten 1 mm moves, each watched by the controller's data recorder (`moves`),
//! before and after.

use host_sim::motor::params::Params;
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;

mod common;

fn bin() -> &'static str {
    env!("CARGO_BIN_EXE_host-sim")
}

fn tmp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("calibrate-e2e-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    dir.join(name)
}

fn run(args: &[&str]) -> String {
    let out = Command::new(bin()).args(args).output().expect("host-sim runs");
    assert!(out.status.success(), "host-sim {}: {}", args.join(" "), String::from_utf8_lossy(&out.stderr));
    String::from_utf8(out.stdout).expect("utf-8")
}

fn heavy_file() -> String {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("params/heavy-slider.toml").display().to_string()
}

/// Record rate of the moves: 1.1 ms per point, 1.13 s of recording per move (1 024 points).
const RECORD_RATE: u32 = 11;

/// `moves --json` on `addr`: (mean peak following error nm, mean settle s, record period s). A
/// move that has not settled by the end of its recording counts with the recording's length,
/// a lower bound of its settle time, when `unsettled_ok`; otherwise it fails the test.
fn moves(addr: &str, count: usize, unsettled_ok: bool) -> (f64, f64, f64) {
    let json: Value = serde_json::from_str(&run(&[
        "moves",
        "--tcp",
        addr,
        "--count",
        &count.to_string(),
        "--record-rate",
        &RECORD_RATE.to_string(),
        "--json",
    ]))
    .unwrap();
    let rows = json.as_array().expect("one row per move");
    assert_eq!(rows.len(), count);
    let period_s = rows[0]["record_period_s"].as_f64().unwrap();
    let n = rows.len() as f64;
    let fe = rows.iter().map(|r| r["peak_following_error_nm"].as_f64().unwrap()).sum::<f64>() / n;
    let settle = rows
        .iter()
        .map(|r| {
            r["settle_s"].as_f64().unwrap_or_else(|| {
                assert!(unsettled_ok, "move {r} did not settle within its recording");
                piezo_drive::recorder::DEPTH as f64 * period_s
            })
        })
        .sum::<f64>()
        / n;
    eprintln!("moves: {json}");
    (fe, settle, period_s)
}

#[test]
fn characterize_gap_calibrate_and_the_same_moves_run_better() {
    let heavy = heavy_file();
    let mut truth = Params::heavy_slider();
    truth.friction.mu_dynamic *= 0.8;
    truth.friction.mu_static *= 0.8;
    truth.effects.set("rail_coulomb_n", 0.4).unwrap();
    let truth_file = tmp("true.toml");
    std::fs::write(&truth_file, truth.to_toml()).unwrap();
    let truth_file = truth_file.display().to_string();
    let serve_args = |load: &str, preload: &str| {
        [
            "--params",
            truth_file.as_str(),
            "--firmware-params",
            heavy.as_str(),
            "--load-n",
            load,
            "--preload-n",
            preload,
        ]
        .map(str::to_string)
        .to_vec()
    };

    // 1. The board measures itself under three weights (a restart of serve = the user hanging
    //    another weight); the weight opposes +x only, so loaded runs go +x. Then once more at
    //    12 N: at one preload the guide's constant force trades against ρ (the normal force's
    //    share). Along the guide friction, the sum of squares of each of 26 runs' one-preload
    //    files had a second valley at 1.0–1.2 N (ρ 0.89) within −7 to +15 % of the one at
    //    0.35 N (ρ 0.67), deeper in 7 of them; the fit took it twice (a fitted 1.09 N). With
    //    a 12 N run's rows added to those two files one valley is left, at 0.37 N.
    let measured = tmp("measured.csv").display().to_string();
    // Small weights (up to about a quarter of the 60 V stall): along larger ones the base model's
    // own curvature against the plant showed as load structure and kept the guide friction a
    // partial candidate in two of three runs.
    for (load, preload) in [("0", "16"), ("0.3", "16"), ("0.6", "16"), ("0", "12")] {
        let (mut server, addr) = common::serve(120, serve_args(load, preload));
        let dirs = if load == "0" { "1,-1" } else { "1" };
        run(&[
            "characterize",
            "--tcp",
            &addr,
            "--voltages-v",
            "60,80,100",
            "--frequencies-hz",
            "1200,1700,2200",
            "--directions",
            dirs,
            "--load-n",
            load,
            "--append",
            "--out",
            &measured,
        ]);
        let _ = server.kill();
        let _ = server.wait();
    }

    // 2. The gap against what the firmware believes: it names the guide friction.
    let report_dir = tmp("gap").display().to_string();
    let gap: Value = serde_json::from_str(&run(&[
        "--params",
        &heavy,
        "gap",
        "--measured",
        &measured,
        "--out",
        &report_dir,
        "--json",
    ]))
    .unwrap();
    let named: Vec<&str> =
        gap["named_effects"].as_array().unwrap().iter().filter_map(Value::as_str).collect();
    assert!(named.contains(&"rail_friction"), "gap named {named:?}, not rail_friction");
    let fitted = format!("{report_dir}/params-fitted.toml");
    let fitted_params = Params::load(Path::new(&fitted)).expect("gap writes the fitted file");
    let rail = fitted_params.effects.rail_friction.expect("rail friction in the fitted file").rail_coulomb_n;
    // The hidden 0.4 N, partly absorbed by the recalibrated λ and ρ of one preload's data.
    assert!(
        (0.15..=0.6).contains(&rail),
        "fitted guide friction {rail} N for a hidden 0.4 N; gap named {named:?}, verdicts {}",
        gap["verdicts"]
    );
    // μd comes back near the truth's 0.28 (the file believes 0.35).
    let mu = fitted_params.friction.mu_dynamic;
    assert!((mu - 0.28).abs() < 0.03, "fitted μd {mu}, truth 0.28");

    // 3. The same ten moves before and after the upload, on one running board.
    let (mut server, addr) = common::serve(120, serve_args("0", "16"));
    // Two moves first: the reference search and the first move after it (whose following error
    // is several times the others', calibrated or not) are not part of the comparison.
    moves(&addr, 2, true);
    let (fe_before, settle_before, period_s) = moves(&addr, 10, true);
    let cal: Value =
        serde_json::from_str(&run(&["--params", &fitted, "calibrate", "--tcp", &addr, "--json"])).unwrap();
    let uploaded = cal["uploaded"].as_array().unwrap();
    // μ, λ, ρ and the guide's two; the moving mass too if the workflow named the carriage's inertia.
    assert_eq!(uploaded.len(), 5 + usize::from(named.contains(&"slider_inertia")));
    assert!(uploaded.iter().all(|u| u["sent"] == u["read_back"]), "{cal}");
    // Everything named that the firmware does not carry is listed as not uploaded, nothing dropped.
    let not_uploaded: Vec<&str> =
        cal["not_uploaded"].as_array().unwrap().iter().filter_map(Value::as_str).collect();
    for name in named.iter().filter(|n| !["rail_friction", "slider_inertia"].contains(n)) {
        assert!(not_uploaded.contains(name), "{name} named by gap but not reported by calibrate");
    }
    let (fe_after, settle_after, _) = moves(&addr, 10, false);
    let _ = server.kill();
    let _ = server.wait();
    eprintln!(
        "mean peak following error {fe_before:.0} → {fe_after:.0} nm, mean settle {settle_before:.4} → {settle_after:.4} s"
    );
    // The issue asks for 2×. Measured 2.0–2.1× (3.6–3.8 → 1.8–1.9 µm) since moves start from the
    // load both senses share (`Controller::start_load_estimate`), which lowered the uncalibrated
    // baseline from 5.0–5.6 µm (2.2–2.7× then); what is left after calibrating is the
    // controller's own on this 50 kg carriage (1.9 µm with the truth uploaded). Bound: 1.6×.
    assert!(
        fe_after <= fe_before / 1.6,
        "peak following error {fe_before:.0} → {fe_after:.0} nm: not 1.6× smaller"
    );
    // Settling: the calibrated model knows the drive pushes with 20 % less friction (μd 0.28, not
    // 0.35) and plans its braking at that lower stall force, about a quarter longer than the
    // uncalibrated plan (whose harder braking the plant still makes: reverse drive brakes with
    // more than the stall force, and the hidden guide friction helps). The braking is about a
    // tenth of the 0.43 s move, so up to some 3 % longer; measured with kp 400 /s 0.434 → 0.444 s
    // (with kp 100 /s, where the harder plan left more to settle, 0.469 → 0.453).
    assert!(
        settle_after <= 1.03 * settle_before + period_s,
        "settle {settle_before:.4} → {settle_after:.4} s: more than 3 % and a record period longer"
    );
}

/// A fit the firmware cannot take is refused whole with the reason, and nothing changes; an
/// effect the fixed-point model does not carry is reported, not dropped silently.
#[test]
fn calibrate_refuses_another_motor_whole_and_reports_what_it_cannot_carry() {
    use host_sim::virtual_controller::gcs_client::GcsClient;
    let (mut server, addr) = common::serve(60, std::iter::empty::<&str>());
    let table = {
        let mut c = GcsClient::connect_tcp(&addr).expect("connect");
        c.query("SPA? 1 0x101B 1 0x101C 1 0x101D").expect("SPA?")
    };
    // λ ten times the prototype's: another motor. μ in the same file is fine on its own.
    let mut far = Params::prototype();
    far.stator.tangential_scale *= 10.0;
    far.friction.mu_dynamic = 0.3;
    let far_file = tmp("far.toml");
    std::fs::write(&far_file, far.to_toml()).unwrap();
    let out = Command::new(bin())
        .args(["--params", &far_file.display().to_string(), "calibrate", "--tcp", &addr])
        .output()
        .expect("runs");
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("nothing was changed") && err.contains("4×"), "{err}");
    let after = {
        let mut c = GcsClient::connect_tcp(&addr).expect("connect");
        c.query("SPA? 1 0x101B 1 0x101C 1 0x101D").expect("SPA?")
    };
    assert_eq!(after, table, "a refused calibration changed the controller");

    // Stribeck friction and a rail: the rail goes up, Stribeck is listed as not uploaded.
    let mut with = Params::prototype();
    with.effects.set("stribeck_rise", 0.5).unwrap();
    with.effects.set("rail_coulomb_n", 0.2).unwrap();
    let with_file = tmp("stribeck.toml");
    std::fs::write(&with_file, with.to_toml()).unwrap();
    let cal: Value = serde_json::from_str(&run(&[
        "--params",
        &with_file.display().to_string(),
        "calibrate",
        "--tcp",
        &addr,
        "--json",
    ]))
    .unwrap();
    let _ = server.kill();
    let _ = server.wait();
    assert_eq!(cal["not_uploaded"], serde_json::json!(["stribeck_friction"]), "{cal}");
    let rail =
        cal["uploaded"].as_array().unwrap().iter().find(|u| u["id"] == 0x101E).expect("0x101E sent").clone();
    assert_eq!(rail["read_back"].as_f64(), Some(0.2));
    assert!(
        cal["uploaded"].as_array().unwrap().iter().all(|u| u["id"] != 0x101A),
        "no inertia effect: mass kept"
    );
}
