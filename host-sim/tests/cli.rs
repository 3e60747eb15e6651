//! The command line as a user meets it: JSON outputs and one-line errors, never a panic.

use std::process::Command;

fn host_sim(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_host-sim")).args(args).output().expect("host-sim runs")
}

fn assert_one_line_error(args: &[&str], needle: &str) {
    let out = host_sim(args);
    assert!(!out.status.success(), "{args:?} must fail");
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(err.trim_end().lines().count(), 1, "{args:?}: error is not one line: {err}");
    assert!(err.contains(needle), "{args:?}: {err}");
    assert!(!err.contains("panicked"), "{args:?}: {err}");
}

#[test]
fn bad_input_gets_a_one_line_error_and_a_non_zero_exit() {
    assert_one_line_error(&["curve", "--bogus"], "--bogus");
    assert_one_line_error(&["curve", "--preload-n", "-3"], "--preload-n");
    assert_one_line_error(&["curve", "--frequency-hz", "0"], "--frequency-hz");
    assert_one_line_error(&["curve", "--voltage-v", "150"], "--voltage-v");
    assert_one_line_error(&["curve", "--direction", "2"], "--direction");
    assert_one_line_error(&["curve", "--preload-n", "abc"], "abc");
    assert_one_line_error(&["--params", "/nonexistent/params.toml", "paper"], "cannot read parameter file");
    let dir = std::env::temp_dir().join(format!("host-sim-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let bad = dir.join("bad.toml");
    std::fs::write(&bad, "[stack]\nstroke_m_per_v = 'lots'\n").unwrap();
    assert_one_line_error(&["--params", bad.to_str().unwrap(), "paper"], "bad.toml");
    let negative = dir.join("negative.toml");
    let text = host_sim::params::PROTOTYPE_TOML.replace("mass_kg = 50.0", "mass_kg = -1.0");
    std::fs::write(&negative, text).unwrap();
    assert_one_line_error(&["--params", negative.to_str().unwrap(), "paper"], "slider.mass_kg");
}

#[test]
fn curve_json_has_the_promised_fields_and_physical_values() {
    let svg = std::env::temp_dir().join(format!("host-sim-curve-{}.svg", std::process::id()));
    let out = host_sim(&[
        "curve",
        "--preload-n",
        "16",
        "--voltage-v",
        "100",
        "--frequency-hz",
        "1500",
        "--points",
        "4",
        "--json",
        "--plot",
        svg.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("one JSON object");
    let stall = v["stall_force_n"].as_f64().unwrap();
    let v0 = v["no_load_speed_mm_s"].as_f64().unwrap();
    let theta = v["contact_angle_rad"].as_f64().unwrap();
    assert!((3.8..=4.8).contains(&stall));
    assert!(v0 > 0.0 && theta > 0.0 && theta <= std::f64::consts::TAU);
    let points = v["points"].as_array().unwrap();
    assert_eq!(points.len(), 4);
    for p in points {
        let model = p["speed_mm_s_model"].as_f64().unwrap();
        let sim = p["speed_mm_s_sim"].as_f64().unwrap();
        assert!(p["load_n"].as_f64().unwrap() >= 0.0);
        assert!((sim - model).abs() < 0.05 * v0, "{p}");
    }
    let plot = std::fs::read_to_string(&svg).expect("plot written");
    assert!(plot.starts_with("<svg") && plot.contains("time-domain plant"));
}

#[test]
fn paper_json_lists_every_row_with_pass() {
    // The default file's 8 kg counterweight cannot give the paper's stator modes (README, "Real
    // masses"): its model rows pass; the stator rows pass on params/paper-masses.toml.
    let stator_rows = ["first_stator_mode", "second_stator_mode", "counterweight_mass"];
    let out = host_sim(&["paper", "--json"]);
    assert!(out.status.success());
    let rows: Vec<serde_json::Value> = serde_json::from_slice(&out.stdout).unwrap();
    assert!(rows.len() >= 15);
    for r in &rows {
        assert!(r["name"].is_string() && r["paper"].is_string() && r["ours"].is_number());
        assert!(r["unit"].is_string() && r["tolerance"].is_string());
        if !stator_rows.contains(&r["name"].as_str().unwrap()) {
            assert_eq!(r["pass"], serde_json::Value::Bool(true), "{r}");
        }
    }
    // The plant column is there where a row is measured on the plant.
    assert!(rows.iter().any(|r| r["plant"].is_number() && r["plant_pass"].is_boolean()));
    let paper = concat!(env!("CARGO_MANIFEST_DIR"), "/params/paper-masses.toml");
    let out = host_sim(&["--params", paper, "paper", "--model-only", "--json"]);
    assert!(out.status.success());
    let rows: Vec<serde_json::Value> = serde_json::from_slice(&out.stdout).unwrap();
    for r in rows.iter().filter(|r| stator_rows.contains(&r["name"].as_str().unwrap())) {
        assert_eq!(r["pass"], serde_json::Value::Bool(true), "{r}");
    }
}

#[test]
fn the_shipped_parameter_file_round_trips() {
    let p = host_sim::params::Params::prototype();
    let again = host_sim::params::Params::from_toml(&p.to_toml()).unwrap();
    assert_eq!(p, again);
    let unknown = format!("{}\n[extra]\nx = 1\n", host_sim::params::PROTOTYPE_TOML);
    assert!(host_sim::params::Params::from_toml(&unknown).is_err());
}

#[test]
fn slider_mass_override_is_checked_and_applied_after_any_subcommand() {
    assert_one_line_error(&["curve", "--slider-mass-kg", "-1"], "--slider-mass-kg");
    assert_one_line_error(&["paper", "--model-only", "--slider-mass-kg", "0"], "--slider-mass-kg");
    assert_one_line_error(&["trace", "--masses-kg", "0.3,nan"], "--slider-mass-kg");
    // The override reaches the plant: the trace reports the mass it ran.
    let out = host_sim(&["trace", "--frequency-hz", "2000", "--slider-mass-kg", "0.7", "--json"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON");
    let t = &v[0];
    assert_eq!(t["slider_mass_kg"], 0.7);
    // One period of 2 kHz at the plant's 1 µs step: 500 samples, phases within [0, 360].
    let samples = t["samples"].as_array().expect("samples");
    assert_eq!(samples.len(), 500);
    assert!(samples.iter().all(|s| (0.0..=360.0).contains(&s["phase_deg"].as_f64().unwrap())));
    let contact = t["contact_fraction"].as_f64().unwrap();
    assert!(contact > 0.0 && contact < 1.0, "16 N is intermittent contact: {contact}");
}
