//! `host-sim pil --gcs-locks`: every GCS command the firmware accepts, sent to the control core
//! on the emulated Cortex-M4F (`tools/pil`) between control periods against the plant, and the
//! instructions of each section it runs with the controller locked (on the board: the control
//! tick masked). The target runs the commands through the firmware's own path
//! ([`piezo_drive::gcs::Gcs::execute_shared`], the same function `src/firmware/uart.rs` calls)
//! and counts what runs inside each lock. The host build runs the same commands on its twin of
//! the controller: a reply or latched error that differs between the two is reported, as is a
//! command the script does not reach or whose latched error is not the one the script expects.

use crate::harness::pil::Target;
use crate::harness::sil::{controller_config, Sil};
use crate::motor::params::Params;
use anyhow::{bail, Result};
use piezo_drive::controller::Outputs;
use piezo_drive::gcs::{error, Board, Gcs, LoopStats, Reply, Unshared, COMMANDS};
use piezo_drive::pil_wire::{Command, GcsReport, Tick};
use piezo_drive::recorder::Recorder;
use serde::Serialize;
use std::path::Path;

/// The default budget of one locked section (issue 30): 3 000 instructions, 18 µs at the
/// M4's 170 MHz and one cycle per instruction, a fifth of the control period.
pub const DEFAULT_LOCK_BUDGET: u32 = 3_000;

/// One step of the script.
#[derive(Debug, Clone, PartialEq)]
pub enum Step {
    /// Command bytes as the UART delivers them, and the error `ERR?` would return after them.
    Gcs(Vec<u8>, i32),
    /// Control periods.
    Ticks(u32),
    /// Control periods until the controller is neither moving nor referencing (at most `max`).
    Settle(u32),
    /// The encoder index at this slider position (m) from now on.
    Index(f64),
}

/// A command line (LF added) and the error latched after it.
fn line(text: &str, error: i32) -> Step {
    let mut b = text.as_bytes().to_vec();
    b.push(b'\n');
    Step::Gcs(b, error)
}

/// The script: the board readied, every query, the recorder set up, a parameter store, the
/// settings, then referencing, moves and stops, open-loop stepping, reference mode off and on,
/// and the malformed. `cfg_*` values are the controller's, so that each setting changes.
pub fn script(p: &Params) -> Vec<Step> {
    let cfg = controller_config(p);
    let mm = |nm_s: f32| f64::from(nm_s) / 1e6;
    let ok = error::NONE;
    let mut s = vec![Step::Ticks(500)];
    // Queries, idle and servo off.
    for q in [
        "CSV?",
        "ERR?",
        "*IDN?",
        "HLP?",
        "HPA?",
        "SAI?",
        "SAI? ALL",
        "CST?",
        "SPA?",
        "SPA? 1 0xA",
        "TMN?",
        "TMX?",
        "VEL?",
        "ACC?",
        "DEC?",
        "XLT?",
        "XPF?",
        "XDA?",
        "XDF?",
        "XFT?",
        "XTM?",
        "XTS?",
        "POS?",
        "MOV?",
        "ONT?",
        "SVO?",
        "FRF?",
        "RON?",
        "TNR?",
        "HDR?",
        "RTR?",
        "DRC?",
        "DRT?",
        "DRL?",
        "LIM?",
        "TRS?",
        "HAR?",
        "SRG? 1 1",
        "SSN?",
        "VER?",
        "SPA? 1 0x50",
    ] {
        s.push(line(q, ok));
    }
    s.push(Step::Gcs(vec![0x04], ok));
    s.push(Step::Gcs(vec![0x05], ok));
    s.push(Step::Gcs(vec![0x07], ok));
    // A parameter store (servo off and idle only).
    s.push(line("WPA 100", ok));
    // The recorder: actual and commanded position every 10 periods from the next move.
    s.push(line("DRC 1 1 2", ok));
    s.push(line("DRC 2 1 1 3 1 259", ok));
    s.push(line("RTR 10", ok));
    s.push(line("DRT 0 1 0", ok));
    // Settings, each to another value (so that `apply_config` runs); a full `SPA` line.
    s.push(line(&format!("VEL 1 {:.4}", 0.9 * mm(cfg.velocity_max_nm_s)), ok));
    s.push(line(&format!("ACC 1 {:.4}", 0.9 * mm(cfg.accel_max_nm_s2)), ok));
    s.push(line(&format!("DEC 1 {:.4}", 0.9 * mm(cfg.decel_max_nm_s2)), ok));
    let v = 0.8 * mm(cfg.velocity_max_nm_s);
    s.push(line(&format!("SPA 1 0xA {v:.4}"), ok));
    let full: Vec<String> =
        (0..10).map(|i| format!("1 0xA {:.4}", v * (1.0 - 0.01 * f64::from(i)))).collect();
    s.push(line(&format!("SPA {}", full.join(" ")), ok));
    // Servo on, referencing on an index 50 µm behind, moves, stops.
    s.push(line("SVO 1 1", ok));
    s.push(Step::Index(-50e-6));
    s.push(line("FRF 1", ok));
    s.push(Step::Ticks(50));
    s.push(line("FRF?", ok));
    s.push(Step::Settle(100_000));
    s.push(line("MOV 1 0.3", ok));
    s.push(Step::Ticks(200));
    for q in ["POS?", "ONT?", "XDA?", "XTM?", "DRL?"] {
        s.push(line(q, ok));
    }
    s.push(Step::Gcs(vec![0x05], ok));
    s.push(line("MVR 1 0.05", ok));
    s.push(Step::Ticks(100));
    s.push(line("HLT 1", error::STOPPED));
    s.push(line("ERR?", ok));
    s.push(Step::Settle(20_000));
    s.push(line("MOV 1 0.2", ok));
    s.push(Step::Ticks(100));
    s.push(line("STP", error::STOPPED));
    s.push(line("ERR?", ok));
    s.push(Step::Ticks(20));
    s.push(line("MOV 1 0.25", ok));
    s.push(Step::Ticks(50));
    s.push(Step::Gcs(vec![0x18], error::STOPPED));
    s.push(line("ERR?", ok));
    s.push(Step::Settle(20_000));
    s.push(line("DRR? 1 20 1 2", ok));
    s.push(line("DRR?", ok));
    // Open-loop stepping with the servo off.
    s.push(line("SVO 1 0", ok));
    s.push(line("XOS 1 100 80 1500", ok));
    s.push(Step::Ticks(100));
    s.push(Step::Settle(20_000));
    // Reference mode off: set the position; on again.
    s.push(line("RON 1 0", ok));
    s.push(line("POS 1 0.1", ok));
    s.push(line("RON 1 1", ok));
    // Referencing on a limit switch: none wired.
    s.push(line("FNL 1", error::NO_LIMIT_SWITCH));
    s.push(line("ERR?", ok));
    s.push(line("FPL 1", error::NO_LIMIT_SWITCH));
    s.push(line("ERR?", ok));
    // The malformed: an unknown command, a line too long.
    s.push(line("XYZ", error::UNKNOWN_COMMAND));
    s.push(line("ERR?", ok));
    s.push(Step::Gcs([vec![b'A'; 300], vec![b'\n']].concat(), error::COMMAND_TOO_LONG));
    s.push(line("ERR?", ok));
    s
}

/// The command a step's bytes name (as [`COMMANDS`] spells it), or what they are.
pub fn command_name(bytes: &[u8]) -> String {
    match bytes {
        [b] if *b < 0x20 && *b != b'\n' => format!("#{b}"),
        _ if bytes.len() > piezo_drive::gcs::LINE_CAPACITY => "(line too long)".into(),
        _ => {
            let word = bytes.split(|b| b.is_ascii_whitespace()).find(|w| !w.is_empty()).unwrap_or(b"");
            COMMANDS.iter().find(|c| c.name.as_bytes().eq_ignore_ascii_case(word)).map_or_else(
                || format!("(unknown: {})", String::from_utf8_lossy(word)),
                |c| c.name.to_string(),
            )
        }
    }
}

/// The commands of [`COMMANDS`] the script does not send.
pub fn unreached(script: &[Step]) -> Vec<&'static str> {
    COMMANDS
        .iter()
        .map(|c| c.name)
        .filter(|name| !script.iter().any(|s| matches!(s, Step::Gcs(b, _) if command_name(b) == *name)))
        .collect()
}

/// One command's locked sections on the emulated M4.
#[derive(Debug, Clone, Serialize)]
pub struct Lock {
    /// The command as [`COMMANDS`] names it.
    pub command: String,
    /// What was sent (without its LF; a long line shortened).
    pub line: String,
    /// The longest locked section (instructions).
    pub instructions: u32,
    /// Every locked section, in order.
    pub sections: Vec<Section>,
    /// The whole command on the target, locked and not (instructions).
    pub total_instructions: u32,
    /// The error latched after it, and the reply's length.
    pub error: i32,
    pub reply_bytes: u32,
}

/// One locked section of a command.
#[derive(Debug, Clone, Serialize)]
pub struct Section {
    /// What runs in it ([`Gcs::locked_sections`]): `snapshot`, `apply_config`
    /// or `command`.
    pub what: &'static str,
    pub instructions: u32,
}

#[derive(Debug, Clone, Serialize)]
pub struct GcsLocksResult {
    pub locks: Vec<Lock>,
    pub max_lock_instructions: u32,
    /// The command with the longest locked section.
    pub max_lock_command: String,
    /// Commands of the firmware's table the run did not measure (none when complete).
    pub unmeasured_commands: Vec<String>,
    /// Commands whose reply or latched error differs between the M4 and the host build, or
    /// whose latched error is not the script's.
    pub mismatches: Vec<String>,
    /// Control periods run, and those whose outputs differ between the M4 and the host build.
    pub ticks: u64,
    pub sil_mismatch_ticks: u64,
}

/// The board of the host twin: as `tools/pil`'s (serial 1, no loop statistics, stores taken).
struct TwinBoard {
    recorder: Box<Recorder>,
}

impl Board for TwinBoard {
    fn store_parameters(&mut self, _: &piezo_drive::controller::ControllerConfig) -> bool {
        true
    }
    fn serial_number(&self) -> u32 {
        1
    }
    fn loop_stats(&self) -> LoopStats {
        LoopStats::default()
    }
    fn recorder(&self) -> Option<&Recorder> {
        Some(&self.recorder)
    }
}

/// Runs `script` on the host build and, when `target` is given, on the emulated M4 beside it.
/// Without a target the locks are the host's (no instructions): what the script does, checked.
pub(crate) fn drive(p: &Params, script: &[Step], mut target: Option<&mut Target>) -> Result<GcsLocksResult> {
    let cfg = controller_config(p);
    if cfg != piezo_drive::defaults::controller_config() {
        bail!("the parameter file does not describe the motor the firmware's defaults were baked for (PIL runs the firmware's own defaults)");
    }
    let mut sil = Sil::new(p, cfg, 16.0, 7)?;
    let mut gcs = Gcs::new();
    let mut board = TwinBoard { recorder: Box::new(Recorder::new()) };
    let mut result = GcsLocksResult {
        locks: Vec::new(),
        max_lock_instructions: 0,
        max_lock_command: String::new(),
        unmeasured_commands: unreached(script).into_iter().map(String::from).collect(),
        mismatches: Vec::new(),
        ticks: 0,
        sil_mismatch_ticks: 0,
    };
    let period = |sil: &mut Sil,
                  board: &mut TwinBoard,
                  target: &mut Option<&mut Target>,
                  result: &mut GcsLocksResult|
     -> Result<()> {
        let inputs = sil.inputs();
        let out: Outputs = sil.controller.step(&inputs);
        sil.controller.background();
        board.recorder.sample(&sil.controller);
        result.ticks += 1;
        match target.as_mut() {
            Some(t) => {
                let reply = t.tick(&Tick { command: Command::None, inputs })?;
                if reply.outputs != out {
                    result.sil_mismatch_ticks += 1;
                }
                sil.apply_next(reply.outputs);
            }
            None => sil.apply_next(out),
        }
        Ok(())
    };
    for step in script {
        match step {
            Step::Ticks(n) => {
                for _ in 0..*n {
                    period(&mut sil, &mut board, &mut target, &mut result)?;
                }
            }
            Step::Settle(max) => {
                for _ in 0..*max {
                    if !sil.controller.in_motion() && !sil.controller.referencing() {
                        break;
                    }
                    period(&mut sil, &mut board, &mut target, &mut result)?;
                }
            }
            Step::Index(x) => sil.index_position_m = Some(*x),
            Step::Gcs(bytes, want) => {
                let mut reply = Reply::new();
                for &b in bytes {
                    if let Some(pending) = gcs.push_byte(b) {
                        gcs.execute_shared(
                            &pending,
                            &mut Unshared(&mut sil.controller),
                            &mut board,
                            &mut reply,
                        );
                    }
                }
                let host = GcsReport {
                    error: gcs.latched_error(),
                    reply_len: reply.len() as u32,
                    reply_crc: piezo_drive::storage::crc32(&reply),
                    ..Default::default()
                };
                let m4 = match target.as_mut() {
                    Some(t) => t.gcs(bytes)?,
                    None => host,
                };
                let shown = String::from_utf8_lossy(bytes.strip_suffix(b"\n").unwrap_or(bytes));
                let shown = match bytes.as_slice() {
                    [b] if *b < 0x20 => format!("0x{b:02X}"),
                    _ if shown.chars().count() > 34 => {
                        format!("{}… ({} bytes)", shown.chars().take(20).collect::<String>(), bytes.len())
                    }
                    _ => shown.into_owned(),
                };
                if (m4.error, m4.reply_len, m4.reply_crc) != (host.error, host.reply_len, host.reply_crc) {
                    result.mismatches.push(format!(
                        "{shown}: the M4 replied {} bytes (CRC {:08x}) with error {}, the host build {} bytes (CRC {:08x}) with error {}",
                        m4.reply_len, m4.reply_crc, m4.error, host.reply_len, host.reply_crc, host.error
                    ));
                } else if host.error != *want {
                    result
                        .mismatches
                        .push(format!("{shown}: error {} after it, the script expects {want}", host.error));
                }
                // The sections the firmware's path runs for these bytes, by name; the M4 must
                // have run as many (a settings command that changes nothing skips its second).
                let mut names: Vec<&'static str> = Vec::new();
                let mut parser = Gcs::new();
                for &b in bytes {
                    if let Some(pending) = parser.push_byte(b) {
                        names.extend(Gcs::locked_sections(&pending));
                    }
                }
                let ran = usize::from(m4.sections);
                if target.is_some() && (ran > names.len() || ran + 1 < names.len()) {
                    result.mismatches.push(format!(
                        "{shown}: the M4 ran {ran} locked sections, the firmware's path has {} ({})",
                        names.len(),
                        names.join(", ")
                    ));
                }
                let sections: Vec<Section> = m4
                    .section_instructions
                    .iter()
                    .take(ran)
                    .zip(names.iter().chain(std::iter::repeat(&"?")))
                    .map(|(&instructions, &what)| Section { what, instructions })
                    .collect();
                let lock = Lock {
                    command: command_name(bytes),
                    line: shown,
                    instructions: m4.max_section(),
                    sections,
                    total_instructions: m4.total_instructions,
                    error: m4.error,
                    reply_bytes: m4.reply_len,
                };
                if lock.instructions > result.max_lock_instructions || result.locks.is_empty() {
                    result.max_lock_instructions = lock.instructions;
                    result.max_lock_command = lock.line.clone();
                }
                result.locks.push(lock);
            }
        }
    }
    Ok(result)
}

/// The script on the emulated M4 (and the host build beside it).
pub fn run(p: &Params, elf: &Path) -> Result<GcsLocksResult> {
    let script = script(p);
    let mut target = Target::start(elf)?;
    let result = drive(p, &script, Some(&mut target));
    target.finish();
    result
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every command of the firmware's table is in the script, so every one is measured.
    #[test]
    fn the_script_sends_every_command_the_firmware_knows() {
        let p = Params::prototype();
        assert_eq!(unreached(&script(&p)), Vec::<&str>::new());
        // And the check can fail: without its motion commands the script misses them.
        let cut: Vec<Step> = script(&p)
            .into_iter()
            .filter(|s| !matches!(s, Step::Gcs(b, _) if command_name(b) == "MOV" || command_name(b) == "#24"))
            .collect();
        assert_eq!(unreached(&cut), vec!["#24", "MOV"]);
    }

    #[test]
    fn command_names_as_the_table_spells_them() {
        assert_eq!(command_name(b"mov 1 0.3\n"), "MOV");
        assert_eq!(command_name(b"  spa? 1 0xA\n"), "SPA?");
        assert_eq!(command_name(&[0x18]), "#24");
        assert_eq!(command_name(&[0x05]), "#5");
        assert_eq!(command_name(b"XYZ\n"), "(unknown: XYZ)");
        assert_eq!(command_name(&[b'A'; 300]), "(line too long)");
    }

    /// The script on the host build alone: every command ends with the error the script
    /// expects (a move accepted, a stop latching 10, …), so on the target it measures the paths
    /// it names.
    #[test]
    fn the_script_does_what_it_says_on_the_host_build() {
        let p = Params::prototype();
        let r = drive(&p, &script(&p), None).unwrap();
        assert_eq!(r.mismatches, Vec::<String>::new());
        assert!(r.unmeasured_commands.is_empty());
        assert!(r.ticks > 2_000, "{} periods", r.ticks);
    }
}
