//! `host-sim moves`: back-and-forth closed-loop moves on a board (or `host-sim serve`) over GCS,
//! each watched by the controller's own data recorder: the peak following error and the settle
//! time of every move, as a user compares them before and after `calibrate`.
//!
//! The recorder (README, "Data recorder") keeps the position error (option 3) and the actual
//! position (option 2), restarted by every `MOV` (trigger 1), one point every `RTR` periods. The
//! peak following error is the largest |error| recorded; the settle time is the time of the first
//! point after which every recorded position stays within the on-target window (`SPA? 0x36`).

use crate::virtual_controller::gcs_client::GcsClient;
use anyhow::{anyhow, bail, Result};
use serde::Serialize;
use std::path::PathBuf;
use std::time::{Duration, Instant};

/// What `host-sim moves` does and where.
#[derive(Debug, Clone)]
pub struct MovesOptions {
    pub tcp: Option<String>,
    pub serial: Option<PathBuf>,
    pub baud: u32,
    /// Length of each move (µm); odd moves go out by it, even ones come back.
    pub distance_um: f64,
    /// Number of moves.
    pub count: usize,
    /// Record rate: one point every this many control periods (`RTR`).
    pub record_rate: u32,
    pub json: bool,
}

/// One move as the recorder saw it.
#[derive(Debug, Clone, Serialize)]
pub struct MoveRecord {
    pub index: usize,
    pub target_mm: f64,
    /// Largest |commanded − actual| recorded during the move (nm).
    pub peak_following_error_nm: f64,
    /// Time from the `MOV` to the point after which the position stays in the window (s); None
    /// when it had not settled by the end of the recording.
    pub settle_s: Option<f64>,
    /// Time between recorded points (s).
    pub record_period_s: f64,
}

/// Record tables used: 1 position error, 2 actual position.
const TABLE_ERROR: u32 = 1;
const TABLE_POSITION: u32 = 2;

fn check(o: &MovesOptions) -> Result<()> {
    crate::check::in_range("--distance-um", o.distance_um, 0.0, true, 100_000.0, "µm")?;
    if o.distance_um == 0.0 {
        bail!("--distance-um must not be 0");
    }
    if !(1..=1000).contains(&o.count) {
        bail!("--count must be 1 to 1000, got {}", o.count);
    }
    if !(1..=65_535).contains(&o.record_rate) {
        bail!("--record-rate must be 1 to 65535 control periods, got {}", o.record_rate);
    }
    Ok(())
}

/// Servo on and referenced (a reference search when the axis has none), recorder set up.
fn prepare(gcs: &mut GcsClient, record_rate: u32) -> Result<()> {
    gcs.command("SVO 1 1")?;
    if gcs.axis_value("FRF? 1")?.trim() != "1" {
        gcs.command("FRF 1")?;
        let deadline = Instant::now() + Duration::from_secs(60);
        while gcs.axis_value("FRF? 1")?.trim() != "1" {
            if Instant::now() > deadline {
                bail!("the reference search did not finish within 60 s");
            }
            std::thread::sleep(Duration::from_millis(20));
        }
    }
    gcs.command(&format!("RTR {record_rate}"))?;
    gcs.command(&format!("DRC {TABLE_ERROR} 1 3 {TABLE_POSITION} 1 2"))?;
    // Trigger 1: every MOV starts both tables anew.
    gcs.command(&format!("DRT {TABLE_ERROR} 1 0 {TABLE_POSITION} 1 0"))
}

/// Polls until `ONT?` says on target (or the timeout).
fn wait_on_target(gcs: &mut GcsClient, timeout: Duration) -> Result<()> {
    let deadline = Instant::now() + timeout;
    loop {
        if gcs.axis_value("ONT? 1")?.trim() == "1" {
            return Ok(());
        }
        let fault = gcs.axis_value("XFT? 1")?;
        if !fault.starts_with("0 ") && fault != "0" {
            bail!("the controller reports a fault: {fault}");
        }
        if Instant::now() > deadline {
            bail!("not on target within {} s", timeout.as_secs_f64());
        }
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// The recorded columns (error, position) in mm, once the tables are full.
fn read_tables(gcs: &mut GcsClient, depth: usize, timeout: Duration) -> Result<Vec<(f64, f64)>> {
    let deadline = Instant::now() + timeout;
    loop {
        let drl = gcs.query(&format!("DRL? {TABLE_ERROR}"))?;
        let points: usize = drl
            .trim()
            .split('=')
            .nth(1)
            .and_then(|v| v.trim().parse().ok())
            .ok_or_else(|| anyhow!("DRL? answered '{}'", drl.trim()))?;
        if points >= depth {
            break;
        }
        if Instant::now() > deadline {
            bail!("the recorder had {points} of {depth} points after {} s", timeout.as_secs_f64());
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let reply = gcs.query(&format!("DRR? 1 {depth} {TABLE_ERROR} {TABLE_POSITION}"))?;
    let rows: Vec<(f64, f64)> = reply
        .lines()
        .filter(|l| !l.trim_start().starts_with('#') && !l.trim().is_empty())
        .map(|l| {
            let mut it = l.split_whitespace().map(str::parse::<f64>);
            match (it.next(), it.next()) {
                (Some(Ok(e)), Some(Ok(x))) => Ok((e, x)),
                _ => Err(anyhow!("DRR? row '{l}' is not two numbers")),
            }
        })
        .collect::<Result<_>>()?;
    if rows.len() != depth {
        bail!("DRR? gave {} rows, {depth} expected", rows.len());
    }
    Ok(rows)
}

/// Settle time: the first point after which every position is within `window_mm` of the
/// target, as a time after the trigger (point k at `(k − 1)·period`).
fn settle_time_s(rows: &[(f64, f64)], target_mm: f64, window_mm: f64, period_s: f64) -> Option<f64> {
    let last_out = rows.iter().rposition(|&(_, x)| (x - target_mm).abs() > window_mm + 1e-9);
    match last_out {
        None => Some(0.0),
        Some(k) if k + 1 < rows.len() => Some((k + 1) as f64 * period_s),
        Some(_) => None,
    }
}

/// Runs the moves and returns what the recorder saw of each.
pub fn run_moves(
    gcs: &mut GcsClient,
    o: &MovesOptions,
    mut progress: impl FnMut(usize),
) -> Result<Vec<MoveRecord>> {
    check(o)?;
    prepare(gcs, o.record_rate)?;
    let depth = gcs.param_f64(0x1600_0201)? as usize;
    let servo_s = gcs.param_f64(0x0E00_0200)?;
    let window_mm = gcs.param_f64(0x36)?;
    let period_s = servo_s * f64::from(o.record_rate);
    let start_mm = gcs.axis_f64("POS? 1")?;
    let (lo, hi) = (gcs.axis_f64("TMN? 1")?, gcs.axis_f64("TMX? 1")?);
    let far_mm = start_mm + o.distance_um * 1e-3;
    if !(lo..=hi).contains(&far_mm) {
        bail!("a move to {far_mm:.6} mm leaves the travel range [{lo}, {hi}] mm");
    }
    let mut out = Vec::with_capacity(o.count);
    for i in 0..o.count {
        let target_mm = if i % 2 == 0 { far_mm } else { start_mm };
        gcs.command(&format!("MOV 1 {target_mm:.6}"))?;
        let recording = Duration::from_secs_f64(depth as f64 * period_s + 5.0);
        wait_on_target(gcs, recording)?;
        let rows = read_tables(gcs, depth, recording)?;
        let peak_mm = rows.iter().fold(0.0f64, |m, &(e, _)| m.max(e.abs()));
        out.push(MoveRecord {
            index: i + 1,
            target_mm,
            peak_following_error_nm: peak_mm * 1e6,
            settle_s: settle_time_s(&rows, target_mm, window_mm, period_s),
            record_period_s: period_s,
        });
        progress(i + 1);
    }
    Ok(out)
}

pub fn run(o: &MovesOptions) -> Result<()> {
    check(o)?;
    let mut gcs = GcsClient::open(o.tcp.as_deref(), o.serial.as_deref(), o.baud)?;
    let show = crate::check::show_progress() && !o.json;
    let moves = run_moves(&mut gcs, o, |done| {
        if show {
            eprint!("\rmoves: {done}/{}", o.count);
        }
    })?;
    if show {
        eprintln!();
    }
    if o.json {
        println!("{}", serde_json::to_string(&moves)?);
        return Ok(());
    }
    println!("{:>4} {:>12} {:>20} {:>12}", "move", "target mm", "peak foll. err nm", "settle s");
    for m in &moves {
        let settle = m.settle_s.map_or("not settled".to_string(), |s| format!("{s:.4}"));
        println!("{:>4} {:>12.6} {:>20.0} {:>12}", m.index, m.target_mm, m.peak_following_error_nm, settle);
    }
    println!("(recorded every {:.4} s)", moves.first().map_or(0.0, |m| m.record_period_s));
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::settle_time_s;

    #[test]
    fn settle_time_is_the_point_after_the_last_one_outside_the_window() {
        let rows = |xs: &[f64]| xs.iter().map(|&x| (0.0, x)).collect::<Vec<_>>();
        // Points at 0, 2, 4, … ms; out of ±0.05 at 0 and 4 ms (index 2), in from index 3 on.
        let r = rows(&[0.0, 0.9, 1.06, 1.04, 0.97, 1.0]);
        assert_eq!(settle_time_s(&r, 1.0, 0.05, 0.002), Some(0.006));
        // In from the start; never in by the end.
        assert_eq!(settle_time_s(&rows(&[1.0, 1.01]), 1.0, 0.05, 0.002), Some(0.0));
        assert_eq!(settle_time_s(&rows(&[0.0, 0.5, 0.8]), 1.0, 0.05, 0.002), None);
    }
}
