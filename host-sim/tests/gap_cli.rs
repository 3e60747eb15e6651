//! `host-sim measure` and `host-sim gap` as a user meets them: the end-to-end command with its
//! JSON and files, and line-numbered one-line errors for malformed measured files.

use host_sim::gap::measured_csv::parse;
use std::process::Command;

fn host_sim(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_host-sim")).args(args).output().expect("host-sim runs")
}

fn tmp(name: &str) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join(format!("host-sim-gap-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

const HEADER: &str = "preload_n,voltage_v,frequency_hz,load_n,direction,velocity_mm_s\n";

#[test]
fn malformed_rows_are_reported_with_their_line_number() {
    let cases: [(&str, &str); 7] = [
        ("16,100,1500,0,1,2.1\n16,100,abc,0,1,2.0\n", "line 3: 'frequency_hz' is not a number: 'abc'"),
        ("16,100,1500,0,1,2.1\n16,100,1500,0\n", "line 3: missing column 'velocity_mm_s'"),
        ("16,100,1500,0,1,2.1\n-4,100,1500,0,1,2.0\n", "line 3: 'preload_n' must be positive"),
        ("16,100,1500,0,2,2.1\n", "line 2: 'direction' must be +1 or -1"),
        ("16,100,1500,-1,1,2.1\n", "line 2: 'load_n' must be zero or positive"),
        ("16,100,1500,0,1,\n", "line 2: empty value for 'velocity_mm_s'"),
        ("16,100,1500,0,1,NaN\n", "line 2: 'velocity_mm_s' is not finite"),
    ];
    for (body, expected) in cases {
        let text = format!("{HEADER}{body}");
        let err = parse(&text).unwrap_err().to_string();
        assert!(err.contains(expected), "{body:?}: {err}");
    }
    let err = parse("preload_n,voltage_v,load_n,velocity_mm_s\n16,100,0,2\n").unwrap_err().to_string();
    assert!(err.contains("line 1: header has no column 'frequency_hz'"), "{err}");
    assert!(parse(HEADER).unwrap_err().to_string().contains("no data rows"));
}

#[test]
fn direction_may_be_missing_and_extra_columns_are_ignored() {
    let rows = parse(
        "note,preload_n,voltage_v,frequency_hz,load_n,velocity_mm_s,temp_c\nA,16,100,1500,0.5,2.0,21\n",
    )
    .unwrap();
    assert_eq!(rows.len(), 1);
    assert_eq!(rows[0].direction, 1);
    assert_eq!(rows[0].load_n, 0.5);
    assert_eq!(rows[0].velocity_mm_s, 2.0);
    assert_eq!(rows[0].line, 2);
}

#[test]
fn the_cli_reports_bad_measured_files_on_one_line_with_a_non_zero_exit() {
    let bad = tmp("bad.csv");
    std::fs::write(&bad, format!("{HEADER}16,100,1500,0,1,2.1\n16,100,1500,0,1,fast\n")).unwrap();
    for args in [
        vec!["gap", "--measured", bad.to_str().unwrap(), "--out", tmp("out-bad").to_str().unwrap()],
        vec!["gap", "--measured", "/nonexistent/data.csv"],
        vec!["measure", "--effect", "warp_drive:x=1", "--out", tmp("x.csv").to_str().unwrap()],
        vec!["measure", "--effect", "rail_friction:mu=1", "--out", tmp("x.csv").to_str().unwrap()],
        vec![
            "measure",
            "--effect",
            "rail_friction:rail_coulomb_n=-1",
            "--out",
            tmp("x.csv").to_str().unwrap(),
        ],
    ] {
        let out = host_sim(&args);
        assert!(!out.status.success(), "{args:?} must fail");
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(err.trim_end().lines().count(), 1, "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
    }
    let out =
        host_sim(&["gap", "--measured", bad.to_str().unwrap(), "--out", tmp("out-bad").to_str().unwrap()]);
    assert!(String::from_utf8_lossy(&out.stderr).contains("line 3: 'velocity_mm_s' is not a number: 'fast'"));
}

/// measure (plant, hidden roll-off) → gap --json on a small grid: the named effect, the fields,
/// the report, the plots and an updated parameter file that loads.
#[test]
fn measure_then_gap_end_to_end() {
    let csv = tmp("measured.csv");
    let out_dir = tmp("report");
    // The gap workflow's base model is the constant-speed model: its workflow runs on the
    // heavy-slider set, where that model holds.
    let heavy = concat!(env!("CARGO_MANIFEST_DIR"), "/params/heavy-slider.toml");
    let m = host_sim(&[
        "--params",
        heavy,
        "measure",
        "--effect",
        "amplifier_rolloff:rolloff_corner_hz=2500",
        "--noise-pct",
        "1",
        "--seed",
        "4",
        "--grid",
        "compact",
        "--out",
        csv.to_str().unwrap(),
    ]);
    assert!(m.status.success(), "{}", String::from_utf8_lossy(&m.stderr));
    let g = host_sim(&[
        "--params",
        heavy,
        "gap",
        "--measured",
        csv.to_str().unwrap(),
        "--out",
        out_dir.to_str().unwrap(),
        "--json",
    ]);
    assert!(g.status.success(), "{}", String::from_utf8_lossy(&g.stderr));
    let v: serde_json::Value = serde_json::from_slice(&g.stdout).expect("one JSON object");
    assert_eq!(v["named_effects"], serde_json::json!(["amplifier_rolloff"]));
    let before = v["gap_before"].as_f64().unwrap();
    let after = v["gap_after"].as_f64().unwrap();
    assert!(after < 0.4 * before, "{before} -> {after}");
    let cands = v["candidates"].as_array().unwrap();
    assert_eq!(
        cands.len(),
        host_sim::motor::effects::EFFECT_NAMES.len(),
        "every library effect is a candidate in round 1"
    );
    for c in cands {
        for field in ["name", "score", "lr", "delta_bic", "cv_improvement", "params"] {
            assert!(!c[field].is_null(), "{field} missing in {c}");
        }
    }
    assert!(v["ambiguity"].is_array());
    // The roll-off leaves its own condition (the frequency) at noise: named, nothing partial.
    assert_eq!(v["partial_candidates"], serde_json::json!([]));
    let tests = v["signature_tests"].as_array().unwrap();
    assert_eq!(tests.len(), 1);
    assert_eq!(tests[0]["effect"], "amplifier_rolloff");
    assert_eq!(tests[0]["named"], true);
    let freq =
        tests[0]["structure"].as_array().unwrap().iter().find(|a| a["condition"] == "frequency").unwrap();
    assert_eq!(freq["signature"], true);
    assert!(freq["chi2_per_dof"].as_f64().unwrap() <= freq["noise_limit_per_dof"].as_f64().unwrap());
    for f in ["report.md", "curves.svg", "residuals.svg", "params-fitted.toml"] {
        assert!(out_dir.join(f).exists(), "{f} not written");
    }
    let fitted = host_sim::motor::params::Params::load(&out_dir.join("params-fitted.toml")).expect("loads");
    let fc = fitted.effects.amplifier_rolloff.expect("effect written").rolloff_corner_hz;
    assert!((fc - 2500.0).abs() < 500.0, "{fc}");
    assert!(fitted.effects.std_dev.contains_key("rolloff_corner_hz"));
    let md = std::fs::read_to_string(out_dir.join("report.md")).unwrap();
    assert!(md.contains("amplifier_rolloff") && md.contains("curves.svg"));
    assert!(md.contains("| amplifier_rolloff | frequency ") && md.contains("| named |"), "{md}");
}

/// `measure --effect` with a name the library does not know: one line naming it and the known
/// ones, a non-zero exit, no file written.
#[test]
fn measure_refuses_an_unknown_effect_name() {
    let csv = tmp("unknown-effect.csv");
    let m = host_sim(&["measure", "--effect", "rail:rail_coulomb_n=1", "--out", csv.to_str().unwrap()]);
    assert!(!m.status.success());
    let err = String::from_utf8_lossy(&m.stderr);
    assert_eq!(
        err.trim_end(),
        "error: --effect 'rail:rail_coulomb_n=1': unknown effect 'rail' (known: rail_friction, \
         assembly_asymmetry, preload_dependent_friction, stribeck_friction, amplifier_rolloff, \
         stator_resonance, hertz_contact, slider_inertia)"
    );
    assert!(!csv.exists(), "nothing written");
}
