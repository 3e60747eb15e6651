//! Processor in the loop: the firmware's control core, built for `thumbv7em-none-eabihf` with the
//! firmware's release settings (`tools/pil`), runs on QEMU's Cortex-M4F (`mps2-an386`,
//! `-icount shift=0`) and drives the plant. Each control period the host sends the sensor
//! inputs (and a command) through a FIFO, the emulated M4 runs `Controller::step` and packs the
//! DMA half-buffer, and sends back the DAC words, the enable, its state and the instructions the
//! tick took. The host build of the same core runs beside it on the same inputs: every period
//! whose outputs differ is counted (`sil_mismatch_ticks`).

use crate::check;
use crate::harness::moves::FaultReport;
use crate::harness::sil::{controller_config, Sil};
use crate::motor::params::Params;
use crate::motor::plant::ExternalLoad;
use anyhow::{anyhow, bail, Context, Result};
use piezo_drive::controller::model_cache::TableModelKind;
use piezo_drive::controller::{ControllerConfig, Inputs, Outputs, State};
use piezo_drive::pil_wire::{self, Command, GcsReport, Reply, Tick, REPLY_BYTES};
use serde::Serialize;
use std::collections::BTreeMap;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, Stdio};
use std::time::Duration;

/// A fault to provoke during the move.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FaultCase {
    /// The encoder count jumps by 5000 counts (250 µm) 20 ms into the move.
    EncoderJump,
    /// The encoder stops counting 20 ms into the move (the coarse mode's encoder-loss watch).
    EncoderLoss,
    /// The preload falls to 2 N (below the window) 20 ms into the move.
    PreloadLoss,
    /// A load of twice the stall force opposes the move from the start.
    Stall,
    /// Referencing (`FRF`) with the index 1 mm on the +x side and a hard end stop 100 µm on the
    /// −x side, no limit switches: the search toward −x meets the stop and must go safe.
    FrfIntoStop,
    /// One encoder channel lost 20 ms into the move, the other still toggling: the count
    /// flickers between two values (the coarse mode's encoder-loss watch, by net progress).
    EncoderJitter,
    /// Servo off, open-loop stepping (`XOS`, 80 V, 1.5 kHz) toward a positive limit switch at
    /// 100 µm: the run must end in the period that reads the switch.
    LimitHit,
}

/// Where the end stop, the index and the limit switch of the fault cases are (m).
const FRF_STOP_M: f64 = -100e-6;
const FRF_INDEX_M: f64 = 1e-3;
const LIMIT_SWITCH_M: f64 = 100e-6;

/// What one PIL run does (`host-sim pil`; where the ELF comes from, the budget and the output
/// are the CLI's).
#[derive(Debug, Clone)]
pub struct PilOptions {
    /// Target position.
    pub to_um: f64,
    /// Preload force F0.
    pub preload_n: f64,
    /// Constant load opposing the motion, as a hanging weight; not told to the controller.
    pub load_n: f64,
    /// A fault to provoke during the move (the drive must go safe on the target).
    pub fault: Option<FaultCase>,
    /// After the move has settled, also reference and step open loop, so that every state of
    /// the tick runs on the target.
    pub all_states: bool,
    /// Ask for the contact model's table (setting 0x1024) on both builds, as a board would.
    pub contact_table: bool,
}

/// Instruction counts of the ticks spent in one state.
#[derive(Debug, Clone, Default, Serialize)]
pub struct StateTicks {
    pub ticks: u64,
    pub tick_instructions_mean: f64,
    pub tick_instructions_max: u32,
    #[serde(skip)]
    total: u64,
}

#[derive(Debug, Clone, Serialize)]
pub struct PilResult {
    pub to_um: f64,
    pub preload_n: f64,
    pub load_n: f64,
    pub settle_time_s: Option<f64>,
    pub final_error_nm: f64,
    pub overshoot_nm: f64,
    pub fault: Option<FaultReport>,
    /// With `--fault`: periods from the fault until the target's outputs were safe (enable off,
    /// both DAC words within 1 LSB of mid-range at the end of the period); 1 = the very period
    /// in which the fault was seen.
    pub fault_safe_after_ticks: Option<u64>,
    /// With `--fault`: periods from the event (the injection 20 ms in; with `frf-into-stop` the
    /// slider meeting the end stop) to the period whose state is the fault (1 = that period).
    pub fault_after_event_ticks: Option<u64>,
    /// With `--fault limit-hit`: periods from the first period that read the switch active to
    /// the one that ended the run (1 = that very period).
    pub limit_stop_ticks: Option<u64>,
    pub ticks: u64,
    /// The whole tick on the M4: `Controller::step` plus packing 20 sample pairs into the DMA
    /// half-buffer.
    pub tick_instructions_mean: f64,
    pub tick_instructions_max: u32,
    /// `Controller::step` alone.
    pub step_instructions_mean: f64,
    pub step_instructions_max: u32,
    /// The lower-rate work after a step (building the model table; a thread-mode task on the
    /// board, outside the tick): how often it ran and its largest run.
    pub background_runs: u64,
    pub background_instructions_max: u32,
    /// The model the installed table came from at the end of the run (`"inertial"`,
    /// `"contact"`), and the instructions of the last table build, whole (on the board: all its
    /// slices, in thread mode).
    pub table_model: Option<&'static str>,
    pub table_build_instructions: u32,
    /// Per state the tick ran in (the state before its step).
    pub per_state: BTreeMap<&'static str, StateTicks>,
    /// Periods whose outputs (DAC words, enable) differ between the M4 and the host build.
    pub sil_mismatch_ticks: u64,
    /// The first such period (counted from the start of the run), if any.
    pub sil_first_mismatch_tick: Option<u64>,
    /// Largest difference of a DAC word between the two builds (LSB).
    pub sil_max_dac_difference_lsb: u16,
    /// Periods in which the amplifier enable differs between the two builds.
    pub sil_enable_mismatch_ticks: u64,
}

/// Builds `tools/pil` for the target and returns its ELF.
pub fn build_target(progress: &mut dyn FnMut(&str)) -> Result<PathBuf> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tools/pil");
    progress("building the core for thumbv7em-none-eabihf (tools/pil, firmware release settings)");
    let status = std::process::Command::new(std::env::var("CARGO").unwrap_or_else(|_| "cargo".into()))
        .args(["build", "--release", "--quiet"])
        .current_dir(&dir)
        // The program links with cortex-m-rt's link.x only (no defmt).
        .env("RUSTFLAGS", "-C link-arg=-Tlink.x")
        .env_remove("CARGO_TARGET_DIR")
        .status()
        .with_context(|| format!("cannot run cargo in {}", dir.display()))?;
    if !status.success() {
        bail!("building {} failed (is the thumbv7em-none-eabihf target installed?)", dir.display());
    }
    Ok(dir.join("target/thumbv7em-none-eabihf/release/pil"))
}

/// The emulated M4 and the two FIFOs to it.
pub(crate) struct Target {
    qemu: Child,
    to_target: std::fs::File,
    from_target: std::fs::File,
    dir: PathBuf,
}

impl Drop for Target {
    fn drop(&mut self) {
        let _ = self.qemu.kill();
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

impl Target {
    pub(crate) fn start(elf: &Path) -> Result<Self> {
        if !elf.is_file() {
            bail!("no target program at {}", elf.display());
        }
        // QEMU runs in the FIFOs' directory: give it an absolute path.
        let elf = elf.canonicalize().with_context(|| format!("cannot resolve {}", elf.display()))?;
        let dir = std::env::temp_dir().join(format!("host-sim-pil-{}", std::process::id()));
        std::fs::create_dir_all(&dir).with_context(|| format!("cannot make {}", dir.display()))?;
        for name in ["pil-in", "pil-out"] {
            let path = dir.join(name);
            let _ = std::fs::remove_file(&path);
            let c = std::ffi::CString::new(path.as_os_str().as_encoded_bytes())?;
            // SAFETY: a valid NUL-terminated path; mkfifo touches nothing else.
            if unsafe { libc::mkfifo(c.as_ptr(), 0o600) } != 0 {
                bail!("mkfifo {} failed: {}", path.display(), std::io::Error::last_os_error());
            }
        }
        let mut qemu = std::process::Command::new("qemu-system-arm")
            .args(["-machine", "mps2-an386", "-cpu", "cortex-m4", "-icount", "shift=0", "-nographic"])
            .args(["-monitor", "none", "-serial", "none"])
            .args(["-semihosting-config", "enable=on,target=native", "-kernel"])
            .arg(&elf)
            .current_dir(&dir)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .context("cannot start qemu-system-arm (apt-get install qemu-system-arm)")?;
        // Opening a FIFO blocks until the other end opens: do it on a thread, with a deadline.
        let (tx, rx) = std::sync::mpsc::channel();
        let (pin, pout) = (dir.join("pil-in"), dir.join("pil-out"));
        std::thread::spawn(move || {
            let files = std::fs::OpenOptions::new()
                .write(true)
                .open(&pin)
                .and_then(|w| std::fs::File::open(&pout).map(|r| (w, r)));
            let _ = tx.send(files);
        });
        // Wait for the target to open its ends; give up early if QEMU exits.
        let deadline = std::time::Instant::now() + Duration::from_secs(30);
        let opened = loop {
            match rx.recv_timeout(Duration::from_millis(100)) {
                Ok(files) => break Some(files),
                Err(_) if std::time::Instant::now() >= deadline => break None,
                Err(_) => {
                    if qemu.try_wait().ok().flatten().is_some() {
                        break None;
                    }
                }
            }
        };
        let (to_target, from_target) = match opened {
            Some(files) => files.context("opening the FIFOs to the emulated M4")?,
            None => {
                let _ = qemu.kill();
                let _ = std::fs::remove_dir_all(&dir);
                let mut out = String::new();
                for stream in [
                    qemu.stdout.take().map(|s| Box::new(s) as Box<dyn Read>),
                    qemu.stderr.take().map(|s| Box::new(s) as Box<dyn Read>),
                ]
                .into_iter()
                .flatten()
                {
                    let mut s = stream;
                    let _ = s.read_to_string(&mut out);
                }
                bail!("the emulated M4 did not open its FIFOs: {}", out.trim().replace('\n', "; "));
            }
        };
        Ok(Target { qemu, to_target, from_target, dir })
    }

    pub(crate) fn tick(&mut self, tick: &Tick) -> Result<Reply> {
        self.to_target.write_all(&pil_wire::encode_tick(tick)).context("writing to the emulated M4")?;
        let mut buf = [0u8; REPLY_BYTES];
        self.read_answer(&mut buf)?;
        Ok(pil_wire::decode_reply(&buf))
    }

    /// Fills `buf` from the target; when it stops answering, the error carries what QEMU printed.
    fn read_answer(&mut self, buf: &mut [u8]) -> Result<()> {
        self.from_target.read_exact(buf).map_err(|e| {
            let mut out = String::new();
            if let Some(mut s) = self.qemu.stdout.take() {
                let _ = s.read_to_string(&mut out);
            }
            anyhow!("the emulated M4 stopped answering ({e}): {}", out.trim())
        })
    }

    /// GCS command bytes (as the UART delivers them) through the target's protocol, every
    /// locked section counted.
    pub(crate) fn gcs(&mut self, bytes: &[u8]) -> Result<GcsReport> {
        if bytes.len() > pil_wire::GCS_MAX_BYTES {
            bail!("{} command bytes, at most {} go in one frame", bytes.len(), pil_wire::GCS_MAX_BYTES);
        }
        self.to_target
            .write_all(&pil_wire::encode_gcs_header(bytes.len()))
            .context("writing to the emulated M4")?;
        self.to_target.write_all(bytes).context("writing to the emulated M4")?;
        let mut buf = [0u8; pil_wire::GCS_REPORT_BYTES];
        self.read_answer(&mut buf)?;
        Ok(pil_wire::decode_gcs_report(&buf))
    }

    pub(crate) fn finish(mut self) {
        // The exit frame gets no reply: the target leaves QEMU.
        let _ = self
            .to_target
            .write_all(&pil_wire::encode_tick(&Tick { command: Command::Exit, inputs: Inputs::default() }));
        wait_or_kill(&mut self.qemu, Duration::from_secs(5));
    }
}

/// Waits up to `limit` for `child` to exit, then kills it.
fn wait_or_kill(child: &mut Child, limit: Duration) {
    let start = std::time::Instant::now();
    while start.elapsed() < limit {
        if child.try_wait().ok().flatten().is_some() {
            return;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let _ = child.kill();
}

/// The safe state of the outputs: enable off and, by the end of the period, both words within
/// 1 LSB of mid-range (the words may ramp there within the period, as in the SIL tests).
fn is_safe(out: &Outputs, mid: u16) -> bool {
    let last = out.dac.last().copied().unwrap_or([mid; 2]);
    !out.amp_enable && last.iter().all(|&w| (i32::from(w) - i32::from(mid)).abs() <= 1)
}

/// The arguments, checked with the same rules and words as every other subcommand (before the
/// target is built or started).
pub fn validate(args: &PilOptions) -> Result<()> {
    check::position_um("--to-um", args.to_um)?;
    check::preload_n("--preload-n", args.preload_n)?;
    check::load_n("--load-n", args.load_n)?;
    Ok(())
}

/// One closed-loop move with the control code on the emulated M4.
pub fn run(p: &Params, args: &PilOptions, elf: &Path) -> Result<PilResult> {
    validate(args)?;
    // The target boots with the firmware's defaults: the plant must be the motor they describe.
    // The target boots with the firmware's defaults and is told the carriage's mass (0x101A)
    // and the table's model (0x1024) over GCS, as a user would; the host build the same.
    let file_cfg = controller_config(p);
    let mut cfg = piezo_drive::defaults::controller_config();
    let mut motor = file_cfg.motor;
    motor.moving_mass_kg = cfg.motor.moving_mass_kg;
    let same_motor = ControllerConfig { motor, moving_mass_kg: cfg.moving_mass_kg, ..file_cfg } == cfg;
    if !same_motor {
        bail!("the parameter file does not describe the motor the firmware's defaults were baked for (PIL runs the firmware's own defaults; regenerate src/motor_table.rs for it first)");
    }
    cfg.moving_mass_kg = file_cfg.moving_mass_kg;
    cfg.contact_table = args.contact_table;
    let mid = ((p.amplifier_mid_v() / p.amplifier.output_max_v) * 4095.0).round() as u16;
    let mut sil = Sil::new(p, cfg, args.preload_n, 7)?;
    let to_nm = (args.to_um * 1e3).round() as i64;
    let dir = if to_nm >= 0 { 1 } else { -1 };
    let mut load_n = args.load_n;
    if args.fault == Some(FaultCase::Stall) {
        let stall = crate::motor::steady::ThrustModel::new(
            p,
            crate::motor::steady::OperatingPoint {
                preload_n: args.preload_n,
                voltage_v: 100.0,
                frequency_hz: 2200.0,
            },
        )
        .stall_force_n();
        load_n = 2.0 * stall;
    }
    let mut target = Target::start(elf)?;
    let mut told = format!("SPA 1 0x101A {}\n", cfg.moving_mass_kg);
    if args.contact_table {
        told.push_str("SPA 1 0x1024 1\n");
    }
    target.gcs(told.as_bytes())?;
    let mut result = PilResult {
        to_um: args.to_um,
        preload_n: args.preload_n,
        load_n,
        settle_time_s: None,
        final_error_nm: f64::NAN,
        overshoot_nm: 0.0,
        fault: None,
        fault_safe_after_ticks: None,
        fault_after_event_ticks: None,
        limit_stop_ticks: None,
        ticks: 0,
        tick_instructions_mean: 0.0,
        tick_instructions_max: 0,
        step_instructions_mean: 0.0,
        step_instructions_max: 0,
        background_runs: 0,
        background_instructions_max: 0,
        table_model: None,
        table_build_instructions: 0,
        per_state: BTreeMap::new(),
        sil_mismatch_ticks: 0,
        sil_first_mismatch_tick: None,
        sil_max_dac_difference_lsb: 0,
        sil_enable_mismatch_ticks: 0,
    };
    let (mut tick_total, mut step_total) = (0u64, 0u64);
    let mut state_before = pil_wire::state_code(State::Idle);
    // One period on both builds: the command first, then the step on the same inputs.
    let mut period = |sil: &mut Sil, command: Command, result: &mut PilResult| -> Result<Reply> {
        let inputs = sil.inputs();
        let reply = target.tick(&Tick { command, inputs })?;
        let host_refused = command.apply(&mut sil.controller);
        let host_out = sil.controller.step(&inputs);
        sil.controller.background();
        if host_out != reply.outputs || host_refused != reply.command_refused {
            result.sil_mismatch_ticks += 1;
            result.sil_first_mismatch_tick.get_or_insert(result.ticks);
            let worst = host_out
                .dac
                .iter()
                .flatten()
                .zip(reply.outputs.dac.iter().flatten())
                .map(|(a, b)| a.abs_diff(*b))
                .max()
                .unwrap_or(0);
            result.sil_max_dac_difference_lsb = result.sil_max_dac_difference_lsb.max(worst);
            if host_out.amp_enable != reply.outputs.amp_enable {
                result.sil_enable_mismatch_ticks += 1;
            }
        }
        sil.apply_next(reply.outputs);
        result.ticks += 1;
        tick_total += u64::from(reply.tick_instructions);
        step_total += u64::from(reply.step_instructions);
        result.tick_instructions_max = result.tick_instructions_max.max(reply.tick_instructions);
        result.step_instructions_max = result.step_instructions_max.max(reply.step_instructions);
        if reply.background_instructions > 0 {
            result.background_runs += 1;
            result.background_instructions_max =
                result.background_instructions_max.max(reply.background_instructions);
            result.table_build_instructions = reply.background_instructions;
        }
        let s = result.per_state.entry(pil_wire::state_name(state_before)).or_default();
        s.ticks += 1;
        s.total += u64::from(reply.tick_instructions);
        s.tick_instructions_max = s.tick_instructions_max.max(reply.tick_instructions);
        state_before = reply.state;
        Ok(reply)
    };
    // Ready the board as `move` does: let the force-cell filter settle, then servo on.
    let t_ready = sil.time_s() + 0.05;
    while sil.time_s() < t_ready {
        period(&mut sil, Command::None, &mut result)?;
    }
    if period(&mut sil, Command::Servo(true), &mut result)?.command_refused {
        bail!("servo on refused by the target (preload {} N outside the window?)", args.preload_n);
    }
    sil.set_load(ExternalLoad::opposing(load_n, dir));
    let count_nm = p.sensors.encoder_resolution_m * 1e9;
    let t0 = sil.time_s();
    let max_s = 2.0 + 5.0 * args.to_um.abs() * 1e-6 / 2.0e-3;
    let hold_s = 0.05;
    let mut inside_since: Option<f64> = None;
    let mut command = match args.fault {
        Some(FaultCase::FrfIntoStop) => {
            sil.plant.end_stops_m = Some((FRF_STOP_M, 1.0));
            sil.index_position_m = Some(FRF_INDEX_M);
            Command::Reference
        }
        Some(FaultCase::LimitHit) => {
            period(&mut sil, Command::Servo(false), &mut result)?;
            sil.limits_m = Some((-1.0, LIMIT_SWITCH_M));
            Command::OpenLoop { cycles: 3000, amplitude_v: 80.0, frequency_hz: 1500.0 }
        }
        _ => Command::MoveTo(to_nm),
    };
    let mut fault_at: Option<u64> = None;
    let mut injected = false;
    // The period (its number in `result.ticks`) of the fault case's event.
    let mut event_at: Option<u64> = None;
    while sil.time_s() - t0 < max_s {
        let t = sil.time_s() - t0;
        if !injected && t >= 0.02 {
            let counts = sil.plant.encoder_counts();
            match args.fault {
                Some(FaultCase::EncoderJump) => sil.encoder_offset_counts += 5_000,
                Some(FaultCase::EncoderLoss) => sil.frozen_encoder_counts = Some(counts),
                Some(FaultCase::EncoderJitter) => sil.jittering_encoder_counts = Some(counts),
                Some(FaultCase::PreloadLoss) => sil.plant.set_preload_n(2.0),
                _ => {}
            }
            if matches!(
                args.fault,
                Some(
                    FaultCase::EncoderJump
                        | FaultCase::EncoderLoss
                        | FaultCase::EncoderJitter
                        | FaultCase::PreloadLoss
                )
            ) {
                event_at = Some(result.ticks);
            }
            injected = true;
        }
        // The stop met, the switch read: this period's inputs are the board's reading now.
        let x_m = sil.plant.slider_position_m();
        match args.fault {
            Some(FaultCase::FrfIntoStop) if sil.plant.at_end_stop() => {
                event_at.get_or_insert(result.ticks);
            }
            Some(FaultCase::LimitHit) if x_m >= LIMIT_SWITCH_M => {
                event_at.get_or_insert(result.ticks);
            }
            _ => {}
        }
        let reply = period(&mut sil, command, &mut result)?;
        if command != Command::None && reply.command_refused {
            bail!("the target refused the fault case's command ({command:?})");
        }
        command = Command::None;
        if args.fault == Some(FaultCase::LimitHit) {
            if let Some(at) = event_at {
                if reply.state != pil_wire::state_code(State::OpenLoop) && result.limit_stop_ticks.is_none() {
                    result.limit_stop_ticks = Some(result.ticks - at);
                }
                // A few periods more, then the case is done.
                if result.ticks - at >= 20 || reply.state & 0x80 != 0 {
                    break;
                }
            } else if reply.state != pil_wire::state_code(State::OpenLoop) {
                bail!(
                    "open-loop stepping ended before the switch (state {})",
                    pil_wire::state_name(reply.state)
                );
            }
        }
        let pos = sil.plant.slider_position_m() * 1e9;
        let err = pos - to_nm as f64;
        result.overshoot_nm = result.overshoot_nm.max(f64::from(dir) * err);
        result.final_error_nm = err;
        if reply.state & 0x80 != 0 {
            if fault_at.is_none() {
                result.fault_after_event_ticks = event_at.map(|at| result.ticks - at);
            }
            let n = fault_at.get_or_insert(result.ticks);
            if result.fault_safe_after_ticks.is_none() && is_safe(&reply.outputs, mid) {
                result.fault_safe_after_ticks = Some(result.ticks - *n + 1);
            }
            if result.fault.is_none() {
                let text = match pil_wire::decode_state(reply.state) {
                    Some(State::Fault(code)) => code.text(),
                    _ => "unknown fault",
                };
                result.fault = Some(FaultReport { code: reply.state & 0x7f, text: text.to_string() });
            }
            // A few periods more to see the outputs settle into the safe state.
            if result.ticks - *n >= 3 {
                break;
            }
            continue;
        }
        if err.abs() <= count_nm {
            let since = *inside_since.get_or_insert(t);
            if t - since >= hold_s {
                result.settle_time_s = Some(since);
                break;
            }
        } else {
            inside_since = None;
        }
    }
    if args.all_states && result.fault.is_none() && result.settle_time_s.is_some() {
        // Referencing: toward −x until the index 50 µm behind the start, then holding there.
        sil.index_position_m = Some(-50e-6);
        if period(&mut sil, Command::Reference, &mut result)?.command_refused {
            bail!("the target refused to reference");
        }
        let mut state = pil_wire::state_code(State::Referencing);
        let t_limit = sil.time_s() + 10.0;
        while state == pil_wire::state_code(State::Referencing) && sil.time_s() < t_limit {
            state = period(&mut sil, Command::None, &mut result)?.state;
        }
        if state != pil_wire::state_code(State::Holding) {
            bail!("referencing did not end in holding (state {})", pil_wire::state_name(state));
        }
        // Servo off, then open-loop stepping forward.
        period(&mut sil, Command::Servo(false), &mut result)?;
        let step = Command::OpenLoop { cycles: 300, amplitude_v: 80.0, frequency_hz: 1500.0 };
        if period(&mut sil, step, &mut result)?.command_refused {
            bail!("the target refused open-loop stepping");
        }
        let t_limit = sil.time_s() + 1.0;
        while state != pil_wire::state_code(State::Idle) && sil.time_s() < t_limit {
            state = period(&mut sil, Command::None, &mut result)?.state;
        }
        if state != pil_wire::state_code(State::Idle) {
            bail!("open-loop stepping did not end (state {})", pil_wire::state_name(state));
        }
    }
    target.finish();
    result.table_model = sil.controller.table_model().map(|m| match m {
        TableModelKind::Inertial => "inertial",
        TableModelKind::Contact => "contact",
    });
    let n = result.ticks.max(1) as f64;
    result.tick_instructions_mean = tick_total as f64 / n;
    result.step_instructions_mean = step_total as f64 / n;
    for s in result.per_state.values_mut() {
        s.tick_instructions_mean = s.total as f64 / s.ticks.max(1) as f64;
    }
    Ok(result)
}
