//! `host-sim characterize` against `host-sim serve`: the board measuring itself over GCS must
//! give what the plant gives (`host-sim measure`, noiseless, same operating points), stay inside
//! the travel range, and refuse what it cannot do before moving anything.

use host_sim::gap::measured_csv;
use host_sim::virtual_controller::gcs_client::GcsClient;
use std::process::{Child, Command};

mod common;

fn bin() -> &'static str {
    env!("CARGO_BIN_EXE_host-sim")
}

/// `host-sim serve` on a free port; returns the child and its address.
fn serve() -> (Child, String) {
    common::serve(120, std::iter::empty::<&str>())
}

fn tmp(name: &str) -> std::path::PathBuf {
    std::env::temp_dir().join(format!("characterize-{}-{name}", std::process::id()))
}

#[test]
fn self_measured_speeds_match_the_plant_and_stay_in_range() {
    let (mut server, addr) = serve();
    // A short travel range: the run must return between points to fit.
    {
        let mut c = GcsClient::connect_tcp(&addr).expect("connect");
        c.command("SPA 1 0x15 1.2").expect("TMX");
        c.command("SPA 1 0x30 -1.2").expect("TMN");
    }
    let out = tmp("measured.csv");
    let run = Command::new(bin())
        .args(["characterize", "--tcp", &addr, "--voltages-v", "60,100", "--frequencies-hz", "900,2100"])
        .arg("--out")
        .arg(&out)
        .output()
        .expect("characterize runs");
    assert!(run.status.success(), "characterize failed: {}", String::from_utf8_lossy(&run.stderr));
    let position_mm = {
        let mut c = GcsClient::connect_tcp(&addr).expect("connect again");
        c.axis_f64("POS? 1").expect("POS?")
    };
    let _ = server.kill();
    let _ = server.wait();
    assert!(position_mm.abs() <= 0.05, "slider not brought back: {position_mm} mm");

    let measured = measured_csv::read(&out).expect("characterize writes the workflow's CSV");
    assert_eq!(measured.len(), 8, "2 voltages × 2 frequencies × 2 senses");
    // The plant's own steady speeds at the same points, noiseless.
    let reference = tmp("reference.csv");
    let m = Command::new(bin())
        .args(["measure", "--preloads-n", "16", "--voltages-v", "60,100", "--frequencies-hz", "900,2100"])
        .args(["--load-fractions", "0", "--directions", "1,-1", "--noise-pct", "0", "--out"])
        .arg(&reference)
        .output()
        .expect("measure runs");
    assert!(m.status.success(), "{}", String::from_utf8_lossy(&m.stderr));
    let reference = measured_csv::read(&reference).expect("measure CSV");
    for r in &measured {
        assert!((r.preload_n - 16.0).abs() < 0.2, "preload read {} N, serve runs 16 N", r.preload_n);
        let want = reference
            .iter()
            .find(|q| {
                q.voltage_v == r.voltage_v && q.frequency_hz == r.frequency_hz && q.direction == r.direction
            })
            .expect("same operating point in the reference");
        // Encoder counts of 50 nm over ~0.15 s, the force cell's noise through the preload
        // reading, and the drive's DAC and filter: a few per cent, not more.
        let tol = 0.03 * want.velocity_mm_s.abs() + 0.01;
        assert!(
            (r.velocity_mm_s - want.velocity_mm_s).abs() <= tol,
            "{} V {} Hz dir {}: characterize {:.4} mm/s, plant {:.4} mm/s",
            r.voltage_v,
            r.frequency_hz,
            r.direction,
            r.velocity_mm_s,
            want.velocity_mm_s
        );
    }
}

#[test]
fn refuses_what_it_cannot_do_before_moving() {
    let run = |args: &[&str]| Command::new(bin()).arg("characterize").args(args).output().expect("runs");
    let out = tmp("x.csv");
    let out = out.to_str().expect("utf-8 path");
    // A weight pulling toward −x helps the −x runs: the load column cannot say that.
    let r = run(&["--tcp", "127.0.0.1:9", "--load-n", "1", "--out", out]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(!r.status.success() && err.contains("--load-n 1") && err.contains("--directions 1"), "{err}");
    let r = run(&["--tcp", "127.0.0.1:9", "--burst-s", "0.2,0.1", "--out", out]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(!r.status.success() && err.contains("--burst-s"), "{err}");
    // The output is checked before connecting.
    let r = run(&["--tcp", "127.0.0.1:9", "--out", "/no/such/dir/m.csv"]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(!r.status.success() && err.contains("/no/such/dir/m.csv"), "{err}");
    // Nobody listening: the address is named.
    let r = run(&["--tcp", "127.0.0.1:9", "--out", out]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(!r.status.success() && err.contains("127.0.0.1:9"), "{err}");
}
