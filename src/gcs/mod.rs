//! INTERIM command protocol — a deliberately minimal stand-in so the firmware branch builds and
//! its UART path can be exercised. The protocol issue replaces this whole module with the real
//! PI GCS 2.0 subset; only the public contract below (the types, [`Board`], [`Gcs::new`],
//! [`Gcs::push_byte`], [`Gcs::execute`]) is what the firmware relies on.
//!
//! Interim commands, one per line (`\n`, `\r` ignored), axis always `1`:
//! `MOV 1 <mm>`, `POS?`, `STP`, `SVO 1 <0|1>`, `STA?` (status), `ERR?` (latched error, then 0),
//! `*IDN?`, `WPA` (store parameters). Error codes: 1 syntax, 2 unknown command, 3 line too long,
//! 10 command refused by the controller, 11 parameter store failed.

use crate::controller::{Controller, ControllerConfig};
use core::fmt::Write as _;

pub const REPLY_CAPACITY: usize = 2048;
pub type Reply = heapless::Vec<u8, REPLY_CAPACITY>;

/// Control-loop timing as the firmware measures it (DWT cycles at `core_clock_hz`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct LoopStats {
    pub step_cycles_last: u32,
    pub step_cycles_max: u32,
    pub overruns: u32,
    pub core_clock_hz: u32,
}

/// What the protocol needs from the board.
pub trait Board {
    /// Stores `cfg` as the boot parameters (WPA); false when that failed.
    fn store_parameters(&mut self, cfg: &ControllerConfig) -> bool;
    /// Device serial number (*IDN?).
    fn serial_number(&self) -> u32;
    fn loop_stats(&self) -> LoopStats;
}

const LINE_CAPACITY: usize = 64;

/// A complete command line, ready to execute.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Pending {
    line: heapless::Vec<u8, LINE_CAPACITY>,
    overflow: bool,
}

#[derive(Debug, Default)]
pub struct Gcs {
    line: heapless::Vec<u8, LINE_CAPACITY>,
    overflow: bool,
    error: i32,
}

impl Gcs {
    pub fn new() -> Self {
        Self::default()
    }

    /// Collects one received byte; a finished line comes back as a [`Pending`] command.
    pub fn push_byte(&mut self, byte: u8) -> Option<Pending> {
        match byte {
            b'\n' => {
                let p = Pending { line: core::mem::take(&mut self.line), overflow: self.overflow };
                self.overflow = false;
                Some(p)
            }
            b'\r' => None,
            _ => {
                if self.line.push(byte).is_err() {
                    self.overflow = true;
                }
                None
            }
        }
    }

    /// Runs a command against the controller (called with the controller locked: keep it short).
    pub fn execute(
        &mut self,
        pending: &Pending,
        ctl: &mut Controller,
        board: &mut dyn Board,
        reply: &mut Reply,
    ) {
        if pending.overflow {
            self.error = 3;
            return;
        }
        let Ok(text) = core::str::from_utf8(&pending.line) else {
            self.error = 1;
            return;
        };
        let mut words = text.split_ascii_whitespace();
        let Some(cmd) = words.next() else { return };
        let args: heapless::Vec<&str, 4> = words.take(4).collect();
        let axis_ok = args.first().is_none_or(|a| *a == "1");
        // A full reply buffer only truncates the answer; nothing here can fail otherwise.
        let _ = match (cmd, args.as_slice()) {
            ("*IDN?", []) => writeln!(reply, "piezo-drive interim protocol, SN {}", board.serial_number()),
            ("POS?", _) if axis_ok && args.len() <= 1 => {
                let nm = ctl.position_nm();
                let sign = if nm < 0 { "-" } else { "" };
                let a = nm.unsigned_abs();
                writeln!(reply, "1={sign}{}.{:06}", a / 1_000_000, a % 1_000_000)
            }
            ("STP", []) => {
                ctl.stop();
                Ok(())
            }
            ("MOV", ["1", mm]) => {
                match parse_mm_to_nm(mm) {
                    Some(nm) => {
                        if ctl.move_to(nm).is_err() {
                            self.error = 10;
                        }
                    }
                    None => self.error = 1,
                }
                Ok(())
            }
            ("SVO", ["1", on @ ("0" | "1")]) => {
                if ctl.set_servo(*on == "1").is_err() {
                    self.error = 10;
                }
                Ok(())
            }
            ("STA?", []) => {
                let s = board.loop_stats();
                writeln!(
                    reply,
                    "state={:?} servo={} on_target={} preload_n={:?} step_cycles_last={} step_cycles_max={} overruns={} core_hz={}",
                    ctl.state(),
                    u8::from(ctl.servo()),
                    u8::from(ctl.on_target()),
                    ctl.preload_n(),
                    s.step_cycles_last,
                    s.step_cycles_max,
                    s.overruns,
                    s.core_clock_hz
                )
            }
            ("ERR?", []) => {
                let e = core::mem::take(&mut self.error);
                writeln!(reply, "{e}")
            }
            ("WPA", _) => {
                if !board.store_parameters(ctl.config()) {
                    self.error = 11;
                }
                Ok(())
            }
            _ => {
                self.error = 2;
                Ok(())
            }
        };
    }
}

/// `"-1.5"` mm → −1 500 000 nm; None for anything that is not a finite number in range.
fn parse_mm_to_nm(s: &str) -> Option<i64> {
    let mm: f64 = s.parse().ok()?;
    let nm = mm * 1e6;
    if !nm.is_finite() || nm.abs() > 9.0e15 {
        return None;
    }
    Some(if nm >= 0.0 { (nm + 0.5) as i64 } else { (nm - 0.5) as i64 })
}
