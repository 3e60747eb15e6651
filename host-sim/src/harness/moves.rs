//! Closed-loop moves in the loop: one move (`host-sim move`) and the scripted demo.

use crate::check::ser;
use crate::harness::contact_table::TableModel;
use crate::harness::sil::{controller_config, Sil};
use crate::motor::params::Params;
use crate::motor::plant::ExternalLoad;
use piezo_drive::controller::{CommandError, ControllerConfig, FaultCode, State};
use serde::Serialize;

/// Outcome of one move, measured on the plant's true slider position. JSON values are rounded
/// to what they resolve: times to 1 ns, positions to 0.1 nm, forces to 1e-4 N.
#[derive(Debug, Clone, Serialize)]
pub struct MoveResult {
    #[serde(serialize_with = "ser::um")]
    pub from_um: f64,
    #[serde(serialize_with = "ser::um")]
    pub to_um: f64,
    #[serde(serialize_with = "ser::newton")]
    pub preload_n: f64,
    #[serde(serialize_with = "ser::newton")]
    pub load_n: f64,
    /// Time from the command until the slider is within ±1 count of the target for good
    /// (null when it never settled).
    #[serde(serialize_with = "ser::opt_time_s")]
    pub settle_time_s: Option<f64>,
    /// When the controller's ONT? first said on target.
    #[serde(serialize_with = "ser::opt_time_s")]
    pub on_target_time_s: Option<f64>,
    #[serde(serialize_with = "ser::nm")]
    pub final_error_nm: f64,
    /// Farthest the slider went past the target in the direction of the move (0 if never).
    #[serde(serialize_with = "ser::nm")]
    pub overshoot_nm: f64,
    /// Only when the move ended in a fault: how far the slider went back, against the direction
    /// of the move, from the farthest point it reached (a stall that slides back). Null otherwise.
    #[serde(serialize_with = "ser::opt_nm")]
    pub slide_back_nm: Option<f64>,
    #[serde(serialize_with = "ser::um")]
    pub max_following_error_um: f64,
    /// Drive frequency of coarse motion the controller chose (Hz), at the end of the move.
    pub drive_frequency_hz: f64,
    /// Fault code and text, null when none.
    pub fault: Option<FaultReport>,
    #[serde(skip)]
    pub trace: Vec<TracePoint>,
}

#[derive(Debug, Clone, Serialize)]
pub struct FaultReport {
    pub code: u8,
    pub text: String,
}

#[derive(Debug, Clone, Copy)]
pub struct TracePoint {
    pub time_s: f64,
    pub position_nm: f64,
    pub reference_nm: f64,
    pub drive_v: f64,
    /// Coarse drive frequency the controller uses (Hz).
    pub drive_frequency_hz: f64,
    /// Preload the force cell reads (N).
    pub preload_n: f64,
}

/// A simulated board at rest with servo on, preload settled.
pub fn ready_board(p: &Params, cfg: ControllerConfig, preload_n: f64) -> anyhow::Result<Sil> {
    ready_board_with(p, cfg, preload_n, TableModel::Core)
}

/// [`ready_board`] whose controller takes its model tables from `table_model` from the start.
pub fn ready_board_with(
    p: &Params,
    cfg: ControllerConfig,
    preload_n: f64,
    table_model: TableModel,
) -> anyhow::Result<Sil> {
    try_ready_board_with(p, cfg, preload_n, table_model)?
        .map_err(|(e, _)| anyhow::anyhow!("servo on refused: {}", command_error_text(e)))
}

/// As [`ready_board`], with the controller's refusal of servo on (and the board, for its
/// configuration) as a value instead of an error.
#[allow(clippy::type_complexity)]
pub fn try_ready_board(
    p: &Params,
    cfg: ControllerConfig,
    preload_n: f64,
) -> anyhow::Result<Result<Sil, (piezo_drive::controller::CommandError, Box<Sil>)>> {
    try_ready_board_with(p, cfg, preload_n, TableModel::Core)
}

#[allow(clippy::type_complexity)]
fn try_ready_board_with(
    p: &Params,
    cfg: ControllerConfig,
    preload_n: f64,
    table_model: TableModel,
) -> anyhow::Result<Result<Sil, (piezo_drive::controller::CommandError, Box<Sil>)>> {
    let mut sil = Sil::new(p, cfg, preload_n, 7)?;
    sil.table_model = table_model;
    // Let the force-cell filter settle before the servo is switched on.
    sil.run_until(0.05, |_| false);
    Ok(match sil.controller.set_servo(true) {
        Ok(()) => Ok(sil),
        Err(e) => Err((e, Box::new(sil))),
    })
}

/// A move to `to_nm` from where the slider is, before it starts: nothing measured yet.
fn unstarted(sil: &Sil, to_nm: i64) -> MoveResult {
    MoveResult {
        from_um: sil.plant.slider_position_m() * 1e6,
        to_um: to_nm as f64 * 1e-3,
        preload_n: sil.plant.preload_force_n(),
        load_n: -sil.plant.load.constant_n,
        settle_time_s: None,
        on_target_time_s: None,
        final_error_nm: f64::NAN,
        overshoot_nm: 0.0,
        slide_back_nm: None,
        max_following_error_um: 0.0,
        drive_frequency_hz: f64::from(sil.controller.coarse_frequency_hz()),
        fault: None,
        trace: Vec::new(),
    }
}

/// Commands a move to `to_nm` and runs until settled for `hold_s` (or `max_s` passed).
pub fn run_move(sil: &mut Sil, to_nm: i64, max_s: f64, hold_s: f64) -> MoveResult {
    let count_nm = sil.plant.params().sensors.encoder_resolution_m * 1e9;
    let from_nm = sil.plant.slider_position_m() * 1e9;
    let t0 = sil.time_s();
    let mut result = unstarted(sil, to_nm);
    if let Err(e) = sil.controller.move_to(to_nm) {
        result.fault = Some(FaultReport { code: 0, text: command_error_text(e).to_string() });
        result.final_error_nm = from_nm - to_nm as f64;
        return result;
    }
    let dir = if to_nm as f64 >= from_nm { 1.0 } else { -1.0 };
    let mut inside_since: Option<f64> = None;
    // Farthest point along the move, and the largest retreat from it since.
    let mut farthest_nm = dir * from_nm;
    let mut retreat_nm: f64 = 0.0;
    let mut k = 0u64;
    while sil.time_s() - t0 < max_s {
        sil.period();
        k += 1;
        let t = sil.time_s() - t0;
        let pos = sil.plant.slider_position_m() * 1e9;
        let err = pos - to_nm as f64;
        result.overshoot_nm = result.overshoot_nm.max(dir * err);
        farthest_nm = farthest_nm.max(dir * pos);
        retreat_nm = retreat_nm.max(farthest_nm - dir * pos);
        let c = &sil.controller;
        result.max_following_error_um =
            result.max_following_error_um.max(c.max_following_error_nm() as f64 * 1e-3);
        // Every period over a move's first 50 ms (small steps settle within it), then every 10th.
        if t < 0.05 || k.is_multiple_of(10) {
            result.trace.push(TracePoint {
                time_s: t,
                position_nm: pos,
                reference_nm: c.reference_nm() as f64,
                drive_v: c.drive_voltage_v() as f64,
                drive_frequency_hz: f64::from(c.coarse_frequency_hz()),
                preload_n: c.preload_n().map_or(f64::NAN, f64::from),
            });
        }
        if result.on_target_time_s.is_none() && c.on_target() {
            result.on_target_time_s = Some(t);
        }
        if let State::Fault(code) = c.state() {
            result.fault = Some(FaultReport { code: code as u8, text: code.text().to_string() });
            result.slide_back_nm = Some(retreat_nm);
            break;
        }
        if err.abs() <= count_nm {
            let since = *inside_since.get_or_insert(t);
            if t - since >= hold_s {
                break;
            }
        } else {
            inside_since = None;
        }
    }
    result.settle_time_s = inside_since;
    result.drive_frequency_hz = f64::from(sil.controller.coarse_frequency_hz());
    result.final_error_nm = sil.plant.slider_position_m() * 1e9 - to_nm as f64;
    result
}

pub fn command_error_text(e: piezo_drive::controller::CommandError) -> &'static str {
    use piezo_drive::controller::CommandError::*;
    match e {
        Faulted(code) => code.text(),
        ServoOff => "servo is off",
        OutOfTravel => "target outside the travel range",
        PreloadInvalid => "preload sensor reading invalid",
        PreloadOutOfWindow => "preload outside the usable window",
        InvalidValue => "invalid value",
        ServoOn => "servo is on",
        Busy => "referencing in progress",
    }
}

/// One closed-loop move from 0 at a preload and an opposing load.
#[derive(Debug, Clone, Copy)]
pub struct MoveSpec {
    pub to_um: f64,
    pub preload_n: f64,
    /// Load opposing the move (N).
    pub load_n: f64,
    /// Thrust-model feedforward on (off: plain PI feedback).
    pub feedforward: bool,
    /// Tell the controller the load beforehand (its `expected_load_n`) instead of leaving the
    /// observer to find it.
    pub load_known: bool,
}

pub fn single_move(p: &Params, spec: MoveSpec) -> anyhow::Result<MoveResult> {
    let MoveSpec { to_um, preload_n, load_n, feedforward, load_known } = spec;
    let mut cfg = controller_config(p);
    cfg.feedforward = feedforward;
    if load_known {
        cfg.expected_load_n = (load_n * to_um.signum()) as f32;
    }
    let (min_n, max_n) = (cfg.preload_min_n, cfg.preload_max_n);
    let mut sil = match try_ready_board(p, cfg, preload_n)? {
        Ok(sil) => sil,
        Err((e, sil)) => {
            // Refused before it starts: the result says why, in a sentence (with the window when
            // that is the reason), and the slider has not moved.
            let text = match e {
                CommandError::PreloadOutOfWindow => format!(
                    "servo on refused: the preload {:.2} N is outside the usable window {min_n:.1}–{max_n:.1} N",
                    sil.plant.preload_force_n()
                ),
                other => format!("servo on refused: {}", command_error_text(other)),
            };
            let code =
                if e == CommandError::PreloadOutOfWindow { FaultCode::PreloadOutOfWindow as u8 } else { 0 };
            return Ok(MoveResult {
                from_um: 0.0,
                to_um,
                load_n,
                final_error_nm: -to_um * 1e3,
                fault: Some(FaultReport { code, text }),
                ..unstarted(&sil, (to_um * 1e3).round() as i64)
            });
        }
    };
    let to_nm = (to_um * 1e3).round() as i64;
    sil.set_load(ExternalLoad::opposing(load_n, if to_nm >= 0 { 1 } else { -1 }));
    let distance_m = to_um.abs() * 1e-6;
    let max_s = 2.0 + 5.0 * distance_m / 2.0e-3;
    Ok(run_move(&mut sil, to_nm, max_s, 0.05))
}

/// One row of the demo table.
#[derive(Debug, Clone, Serialize)]
pub struct DemoRow {
    pub step: &'static str,
    /// Where the step lies in the demo's trace (s); equal for rows with no motion traced.
    #[serde(skip)]
    pub trace_span_s: (f64, f64),
    pub target_um: f64,
    pub result: String,
    pub settle_time_s: Option<f64>,
    pub final_error_nm: f64,
    pub overshoot_nm: f64,
    pub max_following_error_um: f64,
}

/// The scripted demo: long move, 10 µm / 1 µm / 100 nm steps, a move against 2 N, a preload
/// change while holding, and an out-of-window preload that must be refused.
pub fn demo(p: &Params, mut progress: impl FnMut(&str)) -> anyhow::Result<(Vec<DemoRow>, Vec<TracePoint>)> {
    let cfg = controller_config(p);
    let mut sil = ready_board(p, cfg, 16.0)?;
    let mut rows = Vec::new();
    let mut trace = Vec::new();
    let mut offset_s = 0.0;
    let mut record =
        |label: &'static str, r: MoveResult, rows: &mut Vec<DemoRow>, trace: &mut Vec<TracePoint>| {
            let outcome = match &r.fault {
                Some(f) => format!("refused/fault: {}", f.text),
                None if r.settle_time_s.is_some() => "settled ±1 count".to_string(),
                None => "did not settle".to_string(),
            };
            for t in &r.trace {
                trace.push(TracePoint { time_s: t.time_s + offset_s, ..*t });
            }
            let start_s = offset_s;
            offset_s += r.trace.last().map_or(0.0, |t| t.time_s);
            rows.push(DemoRow {
                step: label,
                trace_span_s: (start_s, offset_s),
                target_um: r.to_um,
                result: outcome,
                settle_time_s: r.settle_time_s,
                final_error_nm: r.final_error_nm,
                overshoot_nm: r.overshoot_nm,
                max_following_error_um: r.max_following_error_um,
            });
        };
    progress("long move to 1 mm");
    let r = run_move(&mut sil, 1_000_000, 3.0, 0.05);
    record("long move 1 mm", r, &mut rows, &mut trace);
    for (label, delta) in [("step +10 µm", 10_000), ("step +1 µm", 1_000), ("step +100 nm", 100)] {
        progress(label);
        let target = sil.controller.target_nm() + delta;
        let r = run_move(&mut sil, target, 1.0, 0.05);
        record(label, r, &mut rows, &mut trace);
    }
    progress("move against 2 N");
    sil.set_load(ExternalLoad::opposing(2.0, -1));
    let r = run_move(&mut sil, 500_000, 3.0, 0.05);
    record("move −0.51 mm against 2 N", r, &mut rows, &mut trace);
    sil.set_load(ExternalLoad::default());
    progress("preload change while holding");
    let before = sil.plant.slider_position_m();
    sil.plant.set_preload_n(12.0);
    sil.run_until(0.2, |_| false);
    let drift_nm = (sil.plant.slider_position_m() - before) * 1e9;
    rows.push(DemoRow {
        step: "preload 16 → 12 N while holding",
        trace_span_s: (offset_s, offset_s),
        target_um: sil.controller.target_nm() as f64 * 1e-3,
        result: match sil.controller.state() {
            State::Holding => {
                format!("held (preload reads {:.2} N)", sil.controller.preload_n().unwrap_or(f32::NAN))
            }
            s => format!("{s:?}"),
        },
        settle_time_s: None,
        final_error_nm: sil.plant.slider_position_m() * 1e9 - sil.controller.target_nm() as f64,
        overshoot_nm: drift_nm.abs(),
        max_following_error_um: 0.0,
    });
    progress("out-of-window preload");
    sil.controller.set_servo(false).ok();
    sil.plant.set_preload_n(2.0);
    sil.run_until(0.1, |_| false);
    let refused = sil.controller.set_servo(true).err().or_else(|| sil.controller.move_to(0).err());
    rows.push(DemoRow {
        step: "preload 2 N: servo on + move refused",
        trace_span_s: (offset_s, offset_s),
        target_um: 0.0,
        result: match refused {
            Some(e) => format!("refused: {}", command_error_text(e)),
            None => "ACCEPTED (unexpected)".to_string(),
        },
        settle_time_s: None,
        final_error_nm: f64::NAN,
        overshoot_nm: 0.0,
        max_following_error_um: 0.0,
    });
    Ok((rows, trace))
}
