//! `host-sim sweep`: the controller across the carriages people own. One row per plant and move
//! (settle time, its ratio to that plant's physical limit, overshoot, peak following error,
//! fault), so a user sees at a glance where the controller does well and where it does not.
//!
//! The physical limit of a 1 mm move is measured on the time-domain plant, not taken from the
//! model: the highest no-load speed the plant reaches at 100 V over 0.5–2.2 kHz (in 100 Hz
//! steps), plus the time to reach it at the stall thrust (`M·v/F_stall`, the steady-state
//! model's stall: the speed-up is under 1 % of a 1 mm move for every carriage here). So is the
//! load of the "70 % of stall" move: 70 % of the highest stall force the plant has over the same
//! band ([`plant_stall_n`]).

use crate::harness::contact_table::TableModel;
use crate::harness::moves::{ready_board_with, run_move, MoveResult};
use crate::harness::sil::controller_config;
use crate::motor::params::Params;
use crate::motor::plant::{steady_speed_m_s, ExternalLoad};
use crate::motor::steady::{OperatingPoint, ThrustModel};
use rayon::prelude::*;
use serde::Serialize;

/// Slider masses of the sweep besides the file's own carriage (kg).
pub const MASSES_KG: [f64; 5] = [0.1, 0.3, 1.0, 5.0, 50.0];

/// Opposing load of a move of the sweep.
#[derive(Clone, Copy)]
enum Load {
    Newton(f64),
    /// This share of the plant's highest stall force over the band ([`plant_stall_n`]).
    StallShare(f64),
}

/// The moves of the sweep: (label, target µm, opposing load, load told to the controller,
/// feedforward on).
const MOVES: [(&str, f64, Load, bool, bool); 7] = [
    ("1 mm", 1000.0, Load::Newton(0.0), false, true),
    ("100 nm step", 0.1, Load::Newton(0.0), false, true),
    ("1 µm step", 1.0, Load::Newton(0.0), false, true),
    ("10 µm step", 10.0, Load::Newton(0.0), false, true),
    ("1 mm, 2 N unknown", 1000.0, Load::Newton(2.0), false, true),
    ("1 mm, 70 % stall unknown", 1000.0, Load::StallShare(0.7), false, true),
    ("1 mm, 2 N known, plain PI", 1000.0, Load::Newton(2.0), true, false),
];

#[derive(Debug, Clone, Serialize)]
pub struct SweepRow {
    pub slider_mass_kg: f64,
    pub mv: String,
    /// Opposing load of the move (N).
    pub load_n: f64,
    pub settle_time_s: Option<f64>,
    /// Settle time over the plant's physical limit against the move's load (1 mm moves, where
    /// the plant moves against the load).
    pub limit_ratio: Option<f64>,
    pub overshoot_nm: f64,
    pub max_following_error_um: f64,
    /// The drive frequency the controller chose (Hz).
    pub drive_frequency_hz: f64,
    pub fault: Option<String>,
}

/// The lowest drive frequency of `--model contact` (Hz): the contact model holds the plant's
/// no-load speed within 2.7 % from here (docs/simulator.md), where the core's constant-speed
/// model stops at the motor table's `lowest_model_freq_hz` (1.2 kHz on the prototype).
pub const CONTACT_LOWEST_HZ: f32 = 700.0;

/// The preload the sweep runs at unless told otherwise (N).
pub const DEFAULT_PRELOAD_N: f64 = 16.0;

/// The plant's physical limit for a move of `distance_m` at `preload_n` (s), and the frequency of
/// its highest no-load speed (Hz).
pub fn physical_limit_s(p: &Params, distance_m: f64, preload_n: f64) -> (f64, f64) {
    let (best_f, best_v) = fastest_against(p, preload_n, 0.0);
    let op = OperatingPoint { preload_n, voltage_v: 100.0, frequency_hz: best_f };
    let stall = ThrustModel::new(p, op).stall_force_n().max(1e-9);
    let speed_up_s = p.slider.mass_kg * best_v / stall;
    (distance_m / best_v.max(1e-9) + speed_up_s, best_f)
}

/// The plant's physical limit for a move of `distance_m` against an opposing `load_n` (s): the
/// distance over the highest steady speed the plant reaches against that load at 100 V over
/// 0.5–2.2 kHz, plus the time to reach it with what the plant's highest stall force `stall_n`
/// leaves over the load. None where the plant does not move against the load.
pub fn loaded_limit_s(p: &Params, distance_m: f64, preload_n: f64, load_n: f64, stall_n: f64) -> Option<f64> {
    let (_, best_v) = fastest_against(p, preload_n, load_n);
    let spare_n = stall_n - load_n;
    (best_v >= MOVING_M_S && spare_n > 0.0).then(|| distance_m / best_v + p.slider.mass_kg * best_v / spare_n)
}

/// The frequency (Hz) where the time-domain plant runs fastest at 100 V against `load_n`, over
/// 0.5–2.2 kHz in 100 Hz steps, and that speed (m/s).
fn fastest_against(p: &Params, preload_n: f64, load_n: f64) -> (f64, f64) {
    let freqs: Vec<f64> = (5..=22).map(|k| 100.0 * f64::from(k)).collect();
    freqs
        .par_iter()
        .map(|&f| (f, steady_speed_m_s(p, preload_n, 100.0, f, 1, load_n)))
        .collect::<Vec<_>>()
        .into_iter()
        .fold((0.0, 0.0), |a, b| if b.1 > a.1 { b } else { a })
}

/// A frequency at which the plant runs slower than this unloaded has no stall force worth the
/// name (m/s).
const MOVING_M_S: f64 = 50e-6;

/// The highest stall force the time-domain plant has at `preload_n` and 100 V over 0.5–2.2 kHz
/// (in 100 Hz steps; N), and where (Hz): at each frequency where it moves unloaded, the load at
/// which its steady speed falls to zero, bisected to 0.01 N.
pub fn plant_stall_n(p: &Params, preload_n: f64) -> (f64, f64) {
    let stall_at = |f: f64| {
        let (mut lo, mut hi) = (0.0f64, 2.0 * p.friction.mu_dynamic * preload_n);
        // Where the motor hardly moves unloaded (0.5 kHz for light carriages) the speed is
        // noise about zero, and a bisection on its sign finds nothing real.
        if steady_speed_m_s(p, preload_n, 100.0, f, 1, lo) < MOVING_M_S {
            return 0.0;
        }
        while hi - lo > 0.01 {
            let mid = 0.5 * (lo + hi);
            if steady_speed_m_s(p, preload_n, 100.0, f, 1, mid) > 0.0 {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        lo
    };
    let freqs: Vec<f64> = (5..=22).map(|k| 100.0 * f64::from(k)).collect();
    freqs.par_iter().map(|&f| (stall_at(f), f)).collect::<Vec<_>>().into_iter().fold((0.0, 0.0), |a, b| {
        if b.0 > a.0 {
            b
        } else {
            a
        }
    })
}

/// One move of the sweep: target, opposing load, whether the controller is told the load,
/// feedforward on, and the plant's limit for it (s).
struct Case {
    to_um: f64,
    load_n: f64,
    known: bool,
    feedforward: bool,
    limit_s: Option<f64>,
}

fn one(p: &Params, preload_n: f64, case: Case, table_model: &TableModel) -> anyhow::Result<MoveResult> {
    let Case { to_um, load_n, known, feedforward, limit_s } = case;
    let mut cfg = controller_config(p);
    cfg.feedforward = feedforward;
    if known {
        cfg.expected_load_n = load_n as f32;
    }
    // The contact model of the case's own carriage (the sweep's controller is told its mass),
    // and the band where it holds (docs/simulator.md) for the frequency to be chosen from.
    let table_model = match table_model {
        TableModel::Core => TableModel::Core,
        TableModel::CoreContact => {
            cfg.contact_table = true;
            cfg.drive_freq_min_hz = CONTACT_LOWEST_HZ;
            TableModel::Core
        }
        TableModel::Contact(_) => {
            cfg.drive_freq_min_hz = CONTACT_LOWEST_HZ;
            TableModel::Contact(Box::new(p.clone()))
        }
    };
    let mut sil = ready_board_with(p, cfg, preload_n, table_model)?;
    sil.set_load(ExternalLoad::opposing(load_n, 1));
    // Time enough for a plant that a load slows to a crawl (0.1 kg at 18 N against 0.5 N makes
    // 0.12 mm/s: 8.5 s for 1 mm).
    let max_s = (3.0 + 5.0 * to_um * 1e-6 / 2.0e-3).max(3.0 * limit_s.unwrap_or(0.0));
    Ok(run_move(&mut sil, (to_um * 1e3).round() as i64, max_s, 0.05))
}

/// Runs every move on every plant at `preload_n` (in parallel); `progress(done, total)` after each.
/// `table_model`: where the controller's model table comes from (any `Contact` file stands for
/// each case's own).
pub fn run(
    p: &Params,
    preload_n: f64,
    table_model: &TableModel,
    progress: impl Fn(usize, usize) + Sync,
) -> anyhow::Result<Vec<SweepRow>> {
    let mut masses = vec![p.slider.mass_kg];
    masses.extend(MASSES_KG.iter().copied().filter(|&m| (m - p.slider.mass_kg).abs() > 1e-12));
    let (limits, stalls): (Vec<f64>, Vec<f64>) = masses
        .iter()
        .map(|&m| {
            let mut q = p.clone();
            q.slider.mass_kg = m;
            (physical_limit_s(&q, 1e-3, preload_n).0, plant_stall_n(&q, preload_n).0)
        })
        .unzip();
    let cases: Vec<(usize, usize)> =
        (0..masses.len()).flat_map(|i| (0..MOVES.len()).map(move |j| (i, j))).collect();
    let done = std::sync::atomic::AtomicUsize::new(0);
    let total = cases.len();
    cases
        .par_iter()
        .map(|&(i, j)| {
            let (label, to_um, load, known, ff) = MOVES[j];
            let load_n = match load {
                Load::Newton(n) => n,
                // Rounded to 0.01 N, as printed.
                Load::StallShare(share) => (share * stalls[i] * 100.0).round() / 100.0,
            };
            let mut q = p.clone();
            q.slider.mass_kg = masses[i];
            let limit_s = if load_n == 0.0 {
                Some(limits[i])
            } else {
                loaded_limit_s(&q, to_um * 1e-6, preload_n, load_n, stalls[i])
            };
            let case = Case { to_um, load_n, known, feedforward: ff, limit_s };
            let r = one(&q, preload_n, case, table_model)?;
            progress(done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1, total);
            let limit_ratio = limit_s.filter(|_| to_um == 1000.0).zip(r.settle_time_s).map(|(l, t)| t / l);
            Ok(SweepRow {
                slider_mass_kg: masses[i],
                mv: label.to_string(),
                load_n,
                settle_time_s: r.settle_time_s,
                limit_ratio,
                overshoot_nm: r.overshoot_nm,
                max_following_error_um: r.max_following_error_um,
                drive_frequency_hz: r.drive_frequency_hz,
                fault: r.fault.map(|f| f.text.to_string()),
            })
        })
        .collect()
}
