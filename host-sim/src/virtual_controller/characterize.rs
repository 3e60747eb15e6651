//! `host-sim characterize`: a board measures its own thrust–speed points over GCS, into the
//! model-gap workflow's CSV (`preload_n,voltage_v,frequency_hz,load_n,direction,velocity_mm_s`).
//!
//! Servo off, open-loop bursts (`XOS`) at each amplitude and frequency. The speed is the extra
//! distance of a long burst over a short one divided by the extra time: the start-up and
//! run-out of the two bursts are the same, so they cancel, whatever the carriage's mass. Between
//! operating points the slider goes back to where it started, so the run stays within the travel
//! range (`TMN?`..`TMX?`). The preload is read from the force cell (`XPF?`) before every burst;
//! the load column is the weight the user says is hanging on the slider (`--load-n`).

use crate::gap::measured_csv::{to_csv_string, MeasuredRow, HEADER};
use crate::virtual_controller::gcs_client::GcsClient;
use anyhow::{bail, Context, Result};
use std::io::Write;
use std::path::PathBuf;
use std::time::Duration;

/// What `host-sim characterize` measures, on which controller, into which file.
#[derive(Debug, Clone)]
pub struct CharacterizeOptions {
    /// The controller's GCS over TCP (e.g. `host-sim serve --tcp 127.0.0.1:50000`); one of this
    /// and `serial`.
    pub tcp: Option<String>,
    /// The controller's GCS over a serial port (a board's ST-LINK port, or `host-sim serve --pty`).
    pub serial: Option<PathBuf>,
    /// Baud rate of `serial`.
    pub baud: u32,
    /// Drive amplitudes (V peak-to-peak).
    pub voltages_v: Vec<f64>,
    /// Drive frequencies (Hz).
    pub frequencies_hz: Vec<f64>,
    /// Drive senses (1, -1 or both).
    pub directions: Vec<i8>,
    /// Weight hanging on the slider (N), pulling toward −x: it opposes the +x runs, whose rows
    /// carry it in the load column. Only the user knows it; the controller cannot measure it.
    pub load_n: f64,
    /// Durations of the short and the long burst (s).
    pub burst_s: Vec<f64>,
    /// Largest change of the preload reading during the run (N); more stops the run.
    pub preload_tolerance_n: f64,
    /// Add the rows to an existing file instead of writing a new one.
    pub append: bool,
    /// Output CSV file.
    pub out: PathBuf,
}

impl CharacterizeOptions {
    fn validate(&self) -> Result<()> {
        use crate::check;
        // The board decides the drive's real limits; these only catch typos, in the shared wording.
        check::each("--voltages-v", &self.voltages_v, |f, x| check::in_range(f, x, 0.0, false, 1000.0, "V"))?;
        check::each("--frequencies-hz", &self.frequencies_hz, |f, x| {
            check::in_range(f, x, 0.0, false, 100_000.0, "Hz")
        })?;
        check::each("--directions", &self.directions, |f, d| check::direction(f, i64::from(d)))?;
        check::in_range("--load-n", self.load_n, 0.0, true, 100.0, "N")?;
        check::output_file("--out", &self.out)?;
        if self.load_n > 0.0 && self.directions.contains(&-1) {
            bail!(
                "--load-n {}: the weight pulls toward −x and would help the −x runs, which the load \
                 column cannot express; add --directions 1",
                self.load_n
            );
        }
        match self.burst_s.as_slice() {
            [short, long]
                if short.is_finite() && *short > 0.0 && long.is_finite() && long > short && *long <= 10.0 => {
            }
            b => bail!("--burst-s must be two durations, short < long ≤ 10 s, got {b:?}"),
        }
        if !(self.preload_tolerance_n.is_finite() && self.preload_tolerance_n > 0.0) {
            bail!("--preload-tolerance-n must be a positive force, got {}", self.preload_tolerance_n);
        }
        Ok(())
    }
}

/// The motor as seen over GCS during a run.
struct Stage {
    gcs: GcsClient,
    travel_mm: (f64, f64),
    /// Preload at the start and the allowed drift.
    preload_start_n: f64,
    preload_tolerance_n: f64,
    /// Last preload reading.
    preload_n: f64,
}

impl Stage {
    fn position_mm(&mut self) -> Result<f64> {
        self.gcs.axis_f64("POS? 1")
    }

    fn check_preload(&mut self) -> Result<()> {
        let f = self.gcs.axis_f64("XPF? 1")?;
        if (f - self.preload_start_n).abs() > self.preload_tolerance_n {
            bail!(
                "the preload left its window: {:.3} N at the start, {f:.3} N now (tolerance {} N)",
                self.preload_start_n,
                self.preload_tolerance_n
            );
        }
        self.preload_n = f;
        Ok(())
    }

    fn check_fault(&mut self) -> Result<()> {
        let fault = self.gcs.axis_value("XFT? 1")?;
        if !fault.starts_with("0 ") && fault != "0" {
            bail!("the controller reports a fault: {fault}");
        }
        Ok(())
    }

    /// One open-loop burst; returns the distance travelled (mm, signed).
    fn burst(&mut self, cycles: i64, voltage_v: f64, frequency_hz: f64) -> Result<f64> {
        self.check_preload()?;
        let start = self.position_mm()?;
        self.gcs.command(&format!("XOS 1 {cycles} {voltage_v} {frequency_hz}"))?;
        let duration = cycles.unsigned_abs() as f64 / frequency_hz;
        self.gcs.wait_until_still(Duration::from_secs_f64(duration + 2.0))?;
        self.check_fault()?;
        let end = self.coasted_position_mm()?;
        let (lo, hi) = self.travel_mm;
        if !(lo..=hi).contains(&end) {
            bail!("the stage left the travel range [{lo}, {hi}] mm: it is at {end:.6} mm (a limit or a runaway)");
        }
        Ok(end - start)
    }

    /// The position once the slider has stopped: the drive is quiet when `#5` says so, but a
    /// heavy carriage still coasts until friction stops it. Two equal readings 20 ms apart.
    fn coasted_position_mm(&mut self) -> Result<f64> {
        let mut last = self.position_mm()?;
        for _ in 0..100 {
            std::thread::sleep(Duration::from_millis(20));
            let now = self.position_mm()?;
            if now == last {
                return Ok(now);
            }
            last = now;
        }
        bail!("the slider keeps moving 2 s after the drive stopped (at {last:.6} mm)")
    }

    /// Whether a run of `distance_mm` from here stays inside the travel range with a margin.
    fn room_for(&mut self, distance_mm: f64) -> Result<bool> {
        let here = self.position_mm()?;
        let (lo, hi) = self.travel_mm;
        let margin = 0.05 * (hi - lo);
        Ok(here + distance_mm >= lo + margin && here + distance_mm <= hi - margin)
    }

    /// Open-loop bursts toward `target_mm` until within `tolerance_mm`, using the distance per
    /// cycle seen so far in each direction (`per_cycle_mm[0]` for +x, `[1]` for −x).
    fn return_to(
        &mut self,
        target_mm: f64,
        voltage_v: f64,
        frequency_hz: f64,
        per_cycle_mm: &mut [f64; 2],
    ) -> Result<()> {
        let tolerance_mm = 0.02;
        for _ in 0..30 {
            let error = target_mm - self.position_mm()?;
            if error.abs() <= tolerance_mm {
                return Ok(());
            }
            let dir: i64 = if error > 0.0 { 1 } else { -1 };
            let slot = usize::from(dir < 0);
            let step = per_cycle_mm[slot];
            // Unknown or stalled this way: a short probe teaches the rate.
            let cycles = if step > 1e-7 {
                ((error.abs() / step).round() as i64).clamp(1, 1_000_000)
            } else {
                (0.02 * frequency_hz).ceil() as i64
            };
            let moved = self.burst(dir * cycles, voltage_v, frequency_hz)?;
            per_cycle_mm[slot] = (moved * dir as f64 / cycles as f64).max(0.0);
        }
        bail!("could not bring the slider back to {target_mm:.4} mm within 30 bursts (stalled or slipping?)")
    }
}

pub fn run(args: &CharacterizeOptions) -> Result<()> {
    args.validate()?;
    // Check the output before any motion.
    if args.append && args.out.exists() {
        std::fs::OpenOptions::new()
            .append(true)
            .open(&args.out)
            .with_context(|| format!("cannot append to {}", args.out.display()))?;
    } else {
        std::fs::write(&args.out, "").with_context(|| format!("cannot write {}", args.out.display()))?;
    }
    let gcs = GcsClient::open(args.tcp.as_deref(), args.serial.as_deref(), args.baud)?;
    let mut stage = Stage {
        gcs,
        travel_mm: (0.0, 0.0),
        preload_start_n: 0.0,
        preload_tolerance_n: args.preload_tolerance_n,
        preload_n: 0.0,
    };
    let idn = stage.gcs.query("*IDN?")?;
    eprintln!("characterize: {}", idn.trim());
    stage.gcs.error()?; // a client's leftover error is not ours
    stage.check_fault()?;
    if stage.gcs.axis_value("SVO? 1")? != "0" {
        eprintln!("characterize: switching the servo off (open-loop bursts need it off)");
        stage.gcs.command("SVO 1 0")?;
    }
    stage.travel_mm = (stage.gcs.axis_f64("TMN? 1")?, stage.gcs.axis_f64("TMX? 1")?);
    stage.preload_start_n = stage.gcs.axis_f64("XPF? 1")?;
    stage.preload_n = stage.preload_start_n;
    let model_speed_mm_s = stage
        .gcs
        .axis_value("XTM? 1")?
        .split_whitespace()
        .nth(1)
        .and_then(|v| v.parse::<f64>().ok())
        .filter(|v| v.is_finite() && *v > 0.0)
        .unwrap_or(10.0);
    let home_mm = stage.position_mm()?;
    let (lo, hi) = stage.travel_mm;
    if !(lo..=hi).contains(&home_mm) {
        bail!("the slider is at {home_mm} mm, outside the travel range [{lo}, {hi}] mm");
    }

    let (short_s, long_s) = (args.burst_s[0], args.burst_s[1]);
    let total = args.voltages_v.len() * args.frequencies_hz.len() * args.directions.len();
    let bar = indicatif::ProgressBar::new(total as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template("characterize {bar:40} {pos}/{len} operating points ({eta})")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let mut rows = Vec::with_capacity(total);
    for &voltage_v in &args.voltages_v {
        for &frequency_hz in &args.frequencies_hz {
            let mut per_cycle_mm = [0.0f64; 2];
            for &direction in &args.directions {
                let dir = i64::from(direction);
                let n_short = (short_s * frequency_hz).round().max(1.0) as i64;
                let n_long = (long_s * frequency_hz).round().max(n_short as f64 + 1.0) as i64;
                // Room for each burst at the rate seen so far; before any, one and a half
                // times the model's no-load speed at full drive (`XTM?`).
                let slot = usize::from(direction < 0);
                let mut d = [0.0f64; 2];
                for (k, cycles) in [n_short, n_long].into_iter().enumerate() {
                    let rate = if per_cycle_mm[slot] > 0.0 {
                        1.5 * per_cycle_mm[slot]
                    } else {
                        1.5 * model_speed_mm_s / frequency_hz
                    };
                    let run_mm = dir as f64 * rate * cycles as f64;
                    if !stage.room_for(run_mm)? {
                        stage.return_to(home_mm, voltage_v, frequency_hz, &mut per_cycle_mm)?;
                        if !stage.room_for(run_mm)? {
                            bail!(
                                "the travel range [{lo}, {hi}] mm has no room for a burst of {:.3} s \
                                 at {voltage_v} V, {frequency_hz} Hz (about {:.3} mm from {home_mm:.4} mm); \
                                 shorten --burst-s or start nearer the middle",
                                cycles as f64 / frequency_hz,
                                run_mm.abs()
                            );
                        }
                    }
                    d[k] = stage.burst(dir * cycles, voltage_v, frequency_hz)?;
                    per_cycle_mm[slot] = (d[k] * dir as f64 / cycles as f64).max(0.0);
                }
                let (d_short, d_long) = (d[0], d[1]);
                let speed_mm_s = (d_long - d_short) * dir as f64 / ((n_long - n_short) as f64 / frequency_hz);
                rows.push(MeasuredRow {
                    line: rows.len() + 2,
                    preload_n: (stage.preload_n * 1e3).round() / 1e3,
                    voltage_v,
                    frequency_hz,
                    load_n: if direction > 0 { args.load_n } else { 0.0 },
                    direction,
                    // A slider that does not advance (or is pulled back) is stalled: 0, as in
                    // the workflow's CSV.
                    velocity_mm_s: speed_mm_s.max(0.0),
                });
                bar.inc(1);
            }
            stage.return_to(home_mm, voltage_v, frequency_hz, &mut per_cycle_mm)?;
        }
    }
    bar.finish_and_clear();

    let csv = to_csv_string(&rows);
    if args.append && std::fs::metadata(&args.out).map(|m| m.len() > 0).unwrap_or(false) {
        let body = csv.strip_prefix(HEADER).unwrap_or(&csv).trim_start_matches('\n');
        let mut f = std::fs::OpenOptions::new().append(true).open(&args.out)?;
        f.write_all(body.as_bytes()).with_context(|| format!("cannot append to {}", args.out.display()))?;
    } else {
        let text = format!(
            "# host-sim characterize: {}, open-loop bursts of {short_s} s and {long_s} s\n{csv}",
            idn.trim()
        );
        std::fs::write(&args.out, text).with_context(|| format!("cannot write {}", args.out.display()))?;
    }
    eprintln!(
        "{} operating points written to {} (servo off, slider back at {home_mm:.4} mm)",
        rows.len(),
        args.out.display()
    );
    Ok(())
}
