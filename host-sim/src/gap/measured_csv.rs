//! Measured steady operating points: the CSV input contract of the model-gap workflow.
//!
//! `preload_n,voltage_v,frequency_hz,load_n,direction,velocity_mm_s` with a header; `direction`
//! may be missing (then +1); extra columns are ignored. A malformed row stops the run with its
//! line number: nothing is silently dropped.

use anyhow::{anyhow, bail, Context, Result};
use std::path::Path;

/// One measured steady operating point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeasuredRow {
    /// Line in the file (1 = header).
    pub line: usize,
    pub preload_n: f64,
    pub voltage_v: f64,
    pub frequency_hz: f64,
    /// External force opposing the commanded motion (≥ 0).
    pub load_n: f64,
    /// Drive sense, +1 or −1.
    pub direction: i8,
    /// Steady speed along the commanded direction (0 when stalled).
    pub velocity_mm_s: f64,
}

pub const HEADER: &str = "preload_n,voltage_v,frequency_hz,load_n,direction,velocity_mm_s";

const REQUIRED: [&str; 5] = ["preload_n", "voltage_v", "frequency_hz", "load_n", "velocity_mm_s"];

pub fn read(path: &Path) -> Result<Vec<MeasuredRow>> {
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("cannot read measured file {}", path.display()))?;
    parse(&text).with_context(|| format!("in {}", path.display()))
}

/// Parses the whole file; the first malformed row is an error naming its line.
pub fn parse(text: &str) -> Result<Vec<MeasuredRow>> {
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(true)
        .flexible(true)
        .trim(csv::Trim::All)
        .comment(Some(b'#'))
        .from_reader(text.as_bytes());
    let headers = reader.headers().map_err(|e| anyhow!("line 1: cannot read the header: {e}"))?.clone();
    let col = |name: &str| headers.iter().position(|h| h == name);
    let mut idx = [0usize; 5];
    for (i, name) in REQUIRED.iter().enumerate() {
        idx[i] =
            col(name).ok_or_else(|| anyhow!("line 1: header has no column '{name}' (expected {HEADER})"))?;
    }
    let dir_col = col("direction");
    let mut rows = Vec::new();
    for rec in reader.records() {
        let rec = rec.map_err(|e| {
            let line = e.position().map_or(0, |p| p.line());
            anyhow!("line {line}: {e}")
        })?;
        let line = rec.position().map_or(0, |p| p.line() as usize);
        if rec.iter().all(|f| f.is_empty()) {
            continue;
        }
        let field = |i: usize, name: &str| -> Result<f64> {
            let s = rec.get(i).ok_or_else(|| anyhow!("line {line}: missing column '{name}'"))?;
            if s.is_empty() {
                bail!("line {line}: empty value for '{name}'");
            }
            let v: f64 = s.parse().map_err(|_| anyhow!("line {line}: '{name}' is not a number: '{s}'"))?;
            if !v.is_finite() {
                bail!("line {line}: '{name}' is not finite: '{s}'");
            }
            Ok(v)
        };
        let preload_n = field(idx[0], "preload_n")?;
        let voltage_v = field(idx[1], "voltage_v")?;
        let frequency_hz = field(idx[2], "frequency_hz")?;
        let load_n = field(idx[3], "load_n")?;
        let velocity_mm_s = field(idx[4], "velocity_mm_s")?;
        let direction = match dir_col {
            Some(i) => {
                let d = field(i, "direction")?;
                if d == 1.0 {
                    1
                } else if d == -1.0 {
                    -1
                } else {
                    bail!("line {line}: 'direction' must be +1 or -1, got {d}");
                }
            }
            None => 1,
        };
        if preload_n <= 0.0 {
            bail!("line {line}: 'preload_n' must be positive, got {preload_n}");
        }
        if voltage_v <= 0.0 {
            bail!("line {line}: 'voltage_v' must be positive, got {voltage_v}");
        }
        if frequency_hz <= 0.0 {
            bail!("line {line}: 'frequency_hz' must be positive, got {frequency_hz}");
        }
        if load_n < 0.0 {
            bail!("line {line}: 'load_n' must be zero or positive (it opposes the motion), got {load_n}");
        }
        rows.push(MeasuredRow { line, preload_n, voltage_v, frequency_hz, load_n, direction, velocity_mm_s });
    }
    if rows.is_empty() {
        bail!("no data rows (expected a header and one row per operating point)");
    }
    Ok(rows)
}

pub fn to_csv_string(rows: &[MeasuredRow]) -> String {
    let mut s = String::from(HEADER);
    s.push('\n');
    for r in rows {
        s.push_str(&format!(
            "{},{},{},{:.6},{},{:.6}\n",
            r.preload_n, r.voltage_v, r.frequency_hz, r.load_n, r.direction, r.velocity_mm_s
        ));
    }
    s
}
