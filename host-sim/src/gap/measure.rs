//! `host-sim measure`: synthetic measured data from the time-domain plant with hidden effects,
//! over a paper-like grid of steady operating points, with measurement noise.
//!
//! Noise model: each speed gets Gaussian noise of standard deviation
//! `P/100 · (|v| + 0.25·v̄)`, where `v̄` is the mean noiseless speed of the data set (a relative
//! error plus a floor, so near-stall points are not noise-free). Stalled points read 0.

use crate::gap::measured_csv::{to_csv_string, MeasuredRow};
use crate::motor::effects::{Condition, Effect, EffectModel, Effects};
use crate::motor::params::Params;
use crate::motor::plant::steady_speed_m_s;
use anyhow::{anyhow, bail, Context, Result};
use rand::rngs::StdRng;
use rand::SeedableRng;
use rand_distr::{Distribution, StandardNormal};
use rayon::prelude::*;
use std::path::PathBuf;

/// Share of the noise floor in the noise model (see the module docs).
pub const NOISE_FLOOR_OF_MEAN: f64 = 0.25;

/// The operating points of a measurement campaign: every combination of the lists, loads as
/// fractions of the (true) stall force at each drive point.
#[derive(Debug, Clone, PartialEq)]
pub struct Grid {
    pub preloads_n: Vec<f64>,
    pub voltages_v: Vec<f64>,
    pub frequencies_hz: Vec<f64>,
    pub load_fractions: Vec<f64>,
    pub directions: Vec<i8>,
}

impl Grid {
    /// The paper-like grid: 5 preloads × 2 voltages × 3 frequencies × 5 loads × 2 senses = 300 rows.
    pub fn paper() -> Self {
        Grid {
            preloads_n: vec![5.0, 8.0, 11.0, 14.0, 17.0],
            voltages_v: vec![60.0, 100.0],
            frequencies_hz: vec![900.0, 1500.0, 2100.0],
            load_fractions: vec![0.0, 0.2, 0.4, 0.6, 0.75],
            directions: vec![1, -1],
        }
    }

    /// A smaller grid for quick checks: 4 × 2 × 3 × 4 × 2 = 192 rows.
    pub fn compact() -> Self {
        Grid {
            preloads_n: vec![5.0, 9.0, 13.0, 17.0],
            voltages_v: vec![60.0, 100.0],
            frequencies_hz: vec![900.0, 1500.0, 2100.0],
            load_fractions: vec![0.0, 0.25, 0.5, 0.7],
            directions: vec![1, -1],
        }
    }

    pub fn len(&self) -> usize {
        self.preloads_n.len()
            * self.voltages_v.len()
            * self.frequencies_hz.len()
            * self.load_fractions.len()
            * self.directions.len()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Conditions with loads resolved against the stall force of the steady-state model with
    /// the given (true) effects.
    pub fn conditions(&self, p: &Params) -> Vec<Condition> {
        let mut out = Vec::with_capacity(self.len());
        for &preload_n in &self.preloads_n {
            for &voltage_v in &self.voltages_v {
                for &frequency_hz in &self.frequencies_hz {
                    for &direction in &self.directions {
                        let c0 = Condition { preload_n, voltage_v, frequency_hz, load_n: 0.0, direction };
                        let m = EffectModel::new(p, &c0);
                        let stall = (m.thrust_n(0.0) - m.rail_coulomb_n).max(0.0);
                        for &fr in &self.load_fractions {
                            out.push(Condition { load_n: fr * stall, ..c0 });
                        }
                    }
                }
            }
        }
        out
    }
}

impl Grid {
    /// As [`Grid::conditions`], the loads as fractions of the stall force of the contact model
    /// (`steady_contact`, the model with the contact's timing and the file's carriage) instead
    /// of the closed form's. On a light carriage the closed form's stall is several times the
    /// plant's (0.1 kg, sourced plant, 5 N, 60 V: 1.75 N against about 0.3 N), and most of the
    /// grid's loaded rows then run backwards; the contact model is within a few per cent of the
    /// plant from 0.1 to 50 kg.
    pub fn conditions_at_contact_stall(&self, p: &Params) -> Vec<Condition> {
        use crate::motor::steady::OperatingPoint;
        use crate::motor::steady_contact::{ContactModel, ContactProfile};
        let mut out = Vec::with_capacity(self.len());
        for &preload_n in &self.preloads_n {
            for &voltage_v in &self.voltages_v {
                for &frequency_hz in &self.frequencies_hz {
                    let op = OperatingPoint { preload_n, voltage_v, frequency_hz };
                    let profile = std::sync::Arc::new(ContactProfile::new(p, op));
                    for &direction in &self.directions {
                        let stall = ContactModel::with_profile(p, profile.clone(), direction).stall_force_n();
                        let c0 = Condition { preload_n, voltage_v, frequency_hz, load_n: 0.0, direction };
                        for &fr in &self.load_fractions {
                            out.push(Condition { load_n: fr * stall, ..c0 });
                        }
                    }
                }
            }
        }
        out
    }
}

/// Noiseless plant speeds (mm/s) at each condition; both cores through rayon. `progress` is
/// called from worker threads with the number of finished points.
pub fn plant_speeds_mm_s(p: &Params, conds: &[Condition], progress: &(dyn Fn() + Sync)) -> Vec<f64> {
    conds
        .par_iter()
        .map(|c| {
            let v =
                steady_speed_m_s(p, c.preload_n, c.voltage_v, c.frequency_hz, c.direction, c.load_n) * 1e3;
            progress();
            v
        })
        .collect()
}

/// Adds the noise model of the module docs; stalled points (|v| < 1 nm/s) read exactly 0.
pub fn with_noise(conds: &[Condition], speeds_mm_s: &[f64], noise_pct: f64, seed: u64) -> Vec<MeasuredRow> {
    let mut rng = StdRng::seed_from_u64(seed);
    let mean = speeds_mm_s.iter().map(|v| v.abs()).sum::<f64>() / speeds_mm_s.len().max(1) as f64;
    conds
        .iter()
        .zip(speeds_mm_s)
        .enumerate()
        .map(|(i, (c, &v))| {
            let z: f64 = StandardNormal.sample(&mut rng);
            let stalled = v.abs() < 1e-6;
            let sigma = noise_pct / 100.0 * (v.abs() + NOISE_FLOOR_OF_MEAN * mean);
            MeasuredRow {
                line: i + 2,
                preload_n: c.preload_n,
                voltage_v: c.voltage_v,
                frequency_hz: c.frequency_hz,
                load_n: c.load_n,
                direction: c.direction,
                velocity_mm_s: if stalled { 0.0 } else { v + sigma * z },
            }
        })
        .collect()
}

/// The whole synthetic measurement: plant with the hidden effects of `p`, noise, rows.
pub fn synthesize(
    p: &Params,
    grid: &Grid,
    noise_pct: f64,
    seed: u64,
    progress: &(dyn Fn() + Sync),
) -> Vec<MeasuredRow> {
    let conds = grid.conditions(p);
    let speeds = plant_speeds_mm_s(p, &conds, progress);
    with_noise(&conds, &speeds, noise_pct, seed)
}

/// Parses `NAME:param=value[,param=value]` into `effects`.
pub fn parse_effect_spec(spec: &str, effects: &mut Effects) -> Result<()> {
    let (name, rest) = spec
        .split_once(':')
        .ok_or_else(|| anyhow!("--effect '{spec}': expected NAME:param=value[,param=value]"))?;
    let effect: Effect = name.parse().map_err(|e| anyhow!("--effect '{spec}': {e}"))?;
    for kv in rest.split(',') {
        let (k, v) = kv
            .split_once('=')
            .ok_or_else(|| anyhow!("--effect '{spec}': expected param=value, got '{kv}'"))?;
        let (k, v) = (k.trim(), v.trim());
        if !effect.params().contains(&k) {
            bail!("--effect '{spec}': '{k}' is not a parameter of {effect}");
        }
        let value: f64 = v.parse().map_err(|_| anyhow!("--effect '{spec}': '{v}' is not a number"))?;
        effects.set(k, value)?;
    }
    Ok(())
}

/// What `host-sim measure` synthesises: the hidden effects, the noise and the grid.
#[derive(Debug, Clone)]
pub struct MeasureOptions {
    /// Hidden effects, each `NAME:param=value[,param=value]`.
    pub effects: Vec<String>,
    /// Measurement noise, percent of each speed (plus a floor of a quarter of the mean speed).
    pub noise_pct: f64,
    /// Random seed of the noise.
    pub seed: u64,
    /// Grid of operating points: `paper` (300 rows) or `compact` (192 rows).
    pub grid: String,
    /// Instead of the grid's preloads (N).
    pub preloads_n: Option<Vec<f64>>,
    /// Instead of the grid's voltages (V peak-to-peak).
    pub voltages_v: Option<Vec<f64>>,
    /// Instead of the grid's frequencies (Hz).
    pub frequencies_hz: Option<Vec<f64>>,
    /// Instead of the grid's loads, as fractions of the stall force at each drive point (0 to <1).
    pub load_fractions: Option<Vec<f64>>,
    /// Instead of the grid's drive senses (1, -1 or both).
    pub directions: Option<Vec<i8>>,
    /// Output CSV file.
    pub out: PathBuf,
}

pub fn run(args: MeasureOptions, params: &Params) -> Result<()> {
    use crate::check;
    check::output_file("--out", &args.out)?;
    let mut p = params.clone();
    for spec in &args.effects {
        parse_effect_spec(spec, &mut p.effects)?;
    }
    p.validate()?;
    if !(args.noise_pct.is_finite() && (0.0..=50.0).contains(&args.noise_pct)) {
        bail!("--noise-pct must be in [0, 50], got {}", args.noise_pct);
    }
    let mut grid = match args.grid.as_str() {
        "paper" => Grid::paper(),
        "compact" => Grid::compact(),
        g => bail!("--grid must be 'paper' or 'compact', got '{g}'"),
    };
    let range = p.amplifier.output_max_v - p.amplifier.output_min_v;
    // The same checks and wording as the single-value flags of the other subcommands.
    if let Some(v) = args.preloads_n {
        check::each("--preloads-n", &v, check::preload_n)?;
        grid.preloads_n = v;
    }
    if let Some(v) = args.voltages_v {
        check::each("--voltages-v", &v, |f, x| check::voltage_v(f, x, range))?;
        grid.voltages_v = v;
    }
    if let Some(v) = args.frequencies_hz {
        check::each("--frequencies-hz", &v, |f, x| check::frequency_hz(f, x, p.amplifier.dac_rate_hz))?;
        grid.frequencies_hz = v;
    }
    if let Some(v) = args.load_fractions {
        check::each("--load-fractions", &v, |f, x| {
            if x >= 1.0 {
                bail!("{f} must be in [0, 1), got {x}");
            }
            check::in_range(f, x, 0.0, true, 1.0, "")
        })?;
        grid.load_fractions = v;
    }
    if let Some(v) = args.directions {
        check::each("--directions", &v, |f, d| check::direction(f, i64::from(d)))?;
        grid.directions = v;
    }
    let bar = if check::show_progress() {
        indicatif::ProgressBar::new(grid.len() as u64)
    } else {
        indicatif::ProgressBar::hidden()
    };
    bar.set_style(
        indicatif::ProgressStyle::with_template("measure {bar:40} {pos}/{len} operating points ({eta})")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let rows = synthesize(&p, &grid, args.noise_pct, args.seed, &|| bar.inc(1));
    bar.finish_and_clear();
    let hidden = p.effects.active();
    let mut text = format!(
        "# host-sim measure: plant with hidden effects [{}], noise {} %, seed {}\n",
        hidden.iter().map(|e| e.name()).collect::<Vec<_>>().join(", "),
        args.noise_pct,
        args.seed
    );
    text.push_str(&to_csv_string(&rows));
    std::fs::write(&args.out, text).with_context(|| format!("cannot write {}", args.out.display()))?;
    eprintln!("{} operating points written to {}", rows.len(), args.out.display());
    Ok(())
}
