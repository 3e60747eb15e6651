//! PI GCS 2.0 subset over a byte stream (UART on the board, TCP or a pty in `host-sim serve`):
//! a line collector ([`Gcs::push_byte`]) and an executor ([`Gcs::execute`]) that never panic and
//! never allocate.
//!
//! Framing: one command per LF-terminated line, arguments separated by spaces, axis `1`.
//! Replies are `[args=]value` + LF; a multi-line reply ends every line but the last with space +
//! LF; no CR is ever sent. The single bytes 0x05 (`#5`), 0x07 (`#7`) and 0x18 (`#24`) are
//! commands of their own, without LF. A failing command replies nothing and latches a GCS error
//! number that `ERR?` returns and clears; a line with any invalid part executes nothing.

pub mod datarec;
pub mod num;
pub mod params;

use crate::controller::{validate_settings, CommandError, Controller, ControllerConfig, FaultCode, State};
use crate::recorder::Recorder;
use num::{
    parse_decimal, parse_int, write_fixed, write_general, write_i64, write_scaled, write_u64, Decimal,
};

pub const REPLY_CAPACITY: usize = 4096;
pub type Reply = heapless::Vec<u8, REPLY_CAPACITY>;
/// Longest command line (without its LF); longer lines are discarded and latch error 3.
pub const LINE_CAPACITY: usize = 256;
/// Most space-separated tokens on one line.
pub const MAX_TOKENS: usize = 32;

#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct LoopStats {
    pub step_cycles_last: u32,
    pub step_cycles_max: u32,
    pub overruns: u32,
    pub core_clock_hz: u32,
}

/// What the protocol needs from the board besides the controller.
pub trait Board {
    /// `WPA`: queue the parameters for non-volatile memory; false when they cannot be (no
    /// usable flash). Called with the controller locked on the board, so it only takes a copy:
    /// encoding, CRC and the write happen elsewhere, and their outcome comes back through
    /// [`Board::take_store_failure`].
    fn store_parameters(&mut self, cfg: &ControllerConfig) -> bool;
    /// Whether a store is queued or being written: servo and motion commands wait for it
    /// ([`error::CONTROLLER_BUSY`]), as does another `WPA`.
    fn store_pending(&self) -> bool {
        false
    }
    /// A store that failed since the last call, reported once (the next command's `ERR?` reads
    /// [`error::FLASH_PROGRAM_FAILED`]).
    fn take_store_failure(&mut self) -> bool {
        false
    }
    /// Serial number for `*IDN?`.
    fn serial_number(&self) -> u32;
    /// Control-loop timing for a diagnostics query (our extension).
    fn loop_stats(&self) -> LoopStats;
    /// The data recorder (`DRC`, `DRT`, `RTR`, `DRR?`, …; see [`datarec`]), filled by the
    /// board's control tick ([`Recorder::sample`]); none by default, and then the recorder's
    /// commands are unknown commands.
    fn recorder(&self) -> Option<&Recorder> {
        None
    }
}

/// GCS error numbers used here.
pub mod error {
    pub const NONE: i32 = 0;
    pub const PARAM_SYNTAX: i32 = 1;
    pub const UNKNOWN_COMMAND: i32 = 2;
    pub const COMMAND_TOO_LONG: i32 = 3;
    pub const MOVE_WITHOUT_REF_OR_SERVO_OFF: i32 = 5;
    pub const POS_OUT_OF_LIMITS: i32 = 7;
    pub const VEL_OUT_OF_LIMITS: i32 = 8;
    pub const STOPPED: i32 = 10;
    pub const INVALID_AXIS: i32 = 15;
    pub const PARAM_OUT_OF_RANGE: i32 = 17;
    pub const WRONG_PARAM_COUNT: i32 = 24;
    pub const MISSING_PARAM: i32 = 26;
    pub const NOT_ALLOWED: i32 = 34;
    pub const REFERENCING_FAILED: i32 = 45;
    pub const REF_WITH_REF_DISABLED: i32 = 50;
    pub const UNKNOWN_PARAMETER: i32 = 54;
    pub const INVALID_PASSWORD: i32 = 56;
    /// Data recorder: no such record table, record option, record source (axis).
    pub const INVALID_RECORD_TABLE: i32 = 57;
    pub const INVALID_RECORD_OPTION: i32 = 58;
    pub const INVALID_RECORD_SOURCE: i32 = 59;
    pub const READ_ONLY_PARAMETER: i32 = 64;
    /// Data recorder: fewer points recorded than asked for; a table that records nothing.
    pub const NOT_ENOUGH_RECORDED_DATA: i32 = 77;
    pub const TABLE_NOT_CONFIGURED: i32 = 78;
    pub const OPEN_LOOP_WITH_SERVO_ON: i32 = 303;
    pub const SENSOR_SIGNAL_INVALID: i32 = 505;
    pub const CONTROLLER_BUSY: i32 = 1005;
    pub const MOTION_ERROR: i32 = 1024;
    pub const FLASH_PROGRAM_FAILED: i32 = 4001;
    /// Extension: the control loop missed its deadline; the board disabled the amplifier and
    /// the controller is in fault (`XFT?` says 6). Cleared like a motion error (`SVO`).
    pub const CONTROL_LOOP_OVERRUN: i32 = 4100;
}

type Line = heapless::Vec<u8, LINE_CAPACITY>;

/// A complete command, ready for [`Gcs::execute`].
// No allocation: the line travels by value (264 bytes), which is what the firmware queues.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Pending {
    /// A command line without its LF.
    Line(Line),
    /// A line longer than [`LINE_CAPACITY`], discarded up to its LF.
    TooLong,
    /// A single-byte command (0x05, 0x07, 0x18) or another control byte.
    Byte(u8),
}

/// One GCS command: its name, arguments and description as `HLP?` lists them, and what runs it.
pub struct Command {
    pub name: &'static str,
    pub syntax: &'static str,
    pub help: &'static str,
    /// The handler of a line command; `None` for the single-byte commands (#5, #7, #24), which
    /// [`Gcs::execute`] answers from the byte itself.
    run: Option<Handler>,
    /// Changes nothing but the controller's settings (see [`Gcs::is_settings_only`]).
    pub settings_only: bool,
}

/// What a line command works with: its arguments (the tokens after the name), the controller,
/// the board and the reply under construction.
struct Call<'c, 'r> {
    args: &'c [&'c [u8]],
    ctl: &'c mut Controller,
    board: &'c mut dyn Board,
    out: &'c mut Out<'r>,
}

type Handler = fn(&mut Gcs, Call) -> GcsResult;

impl Command {
    /// A single-byte command (answered in [`Gcs::execute`] from the byte).
    const fn byte(name: &'static str, help: &'static str) -> Self {
        Command { name, syntax: "", help, run: None, settings_only: false }
    }
    const fn line(name: &'static str, syntax: &'static str, help: &'static str, run: Handler) -> Self {
        Command { name, syntax, help, run: Some(run), settings_only: false }
    }
    /// A line command that changes only settings.
    const fn settings(name: &'static str, syntax: &'static str, help: &'static str, run: Handler) -> Self {
        Command { name, syntax, help, run: Some(run), settings_only: true }
    }
}

/// The commands, in the order `HLP?` lists them; the line commands' handlers are below.
pub static COMMANDS: &[Command] = &[
    Command::byte("#5", "Request Motion Status"),
    Command::byte("#7", "Request Controller Ready Status"),
    Command::byte("#24", "Stop All Axes"),
    Command::line("*IDN?", "", "Get Device Identification", idn_query),
    Command::settings("ACC", "{<AxisID> <Acceleration>}", "Set Closed-Loop Acceleration", acc),
    Command::line("ACC?", "[{<AxisID>}]", "Get Closed-Loop Acceleration", acc_query),
    Command::line("CST?", "[{<AxisID>}]", "Get Assignment Of Stages To Axes", cst_query),
    Command::line("CSV?", "", "Get Current Syntax Version", csv_query),
    Command::settings("DEC", "{<AxisID> <Deceleration>}", "Set Closed-Loop Deceleration", dec),
    Command::line("DEC?", "[{<AxisID>}]", "Get Closed-Loop Deceleration", dec_query),
    Command::line(
        "DRC",
        "{<RecTableID> <Source> <RecOption>}",
        "Set Data Recorder Configuration",
        datarec::drc,
    ),
    Command::line("DRC?", "[{<RecTableID>}]", "Get Data Recorder Configuration", datarec::drc_query),
    Command::line("DRL?", "[{<RecTableID>}]", "Get Number Of Recorded Points", datarec::drl_query),
    Command::line(
        "DRR?",
        "[<StartPoint> [<NumberOfPoints> [{<RecTableID>}]]]",
        "Get Recorded Data Values",
        datarec::drr_query,
    ),
    Command::line(
        "DRT",
        "{<RecTableID> <TriggerSource> <Value>}",
        "Set Data Recorder Trigger Source",
        datarec::drt,
    ),
    Command::line("DRT?", "[{<RecTableID>}]", "Get Data Recorder Trigger Source", datarec::drt_query),
    Command::line("ERR?", "", "Get Error Number", err_query),
    Command::line("FRF", "[{<AxisID>}]", "Fast Reference Move To Reference Mark", frf),
    Command::line("FRF?", "[{<AxisID>}]", "Get Referencing Result", frf_query),
    Command::line("HDR?", "", "Get All Data Recorder Options", datarec::hdr_query),
    Command::line("HLP?", "", "Get List Of Available Commands", hlp_query),
    Command::line("HLT", "[{<AxisID>}]", "Halt Motion Smoothly", hlt),
    Command::line("HPA?", "", "Get List Of Available Parameters", hpa_query),
    Command::line("MOV", "{<AxisID> <Position>}", "Set Target Position", mov),
    Command::line("MOV?", "[{<AxisID>}]", "Get Target Position", mov_query),
    Command::line("MVR", "{<AxisID> <Distance>}", "Set Target Relative To Current Target", mvr),
    Command::line("ONT?", "[{<AxisID>}]", "Get On Target State", ont_query),
    Command::line("POS", "{<AxisID> <Position>}", "Set Real Position (Reference Mode Off)", pos),
    Command::line("POS?", "[{<AxisID>}]", "Get Real Position", pos_query),
    Command::line("RON", "{<AxisID> <ReferenceOn>}", "Set Reference Mode", ron),
    Command::line("RON?", "[{<AxisID>}]", "Get Reference Mode", ron_query),
    Command::line("RTR", "<RecordTableRate>", "Set Record Table Rate", datarec::rtr),
    Command::line("RTR?", "", "Get Record Table Rate", datarec::rtr_query),
    Command::line("SAI?", "[ALL]", "Get List Of Current Axis Identifiers", sai_query),
    Command::settings("SPA", "{<ItemID> <PamID> <PamValue>}", "Set Volatile Memory Parameters", spa),
    Command::line("SPA?", "[{<ItemID> <PamID>}]", "Get Volatile Memory Parameters", spa_query),
    Command::line("STP", "", "Stop All Axes", stp),
    Command::line("SVO", "{<AxisID> <ServoState>}", "Set Servo Mode", svo),
    Command::line("SVO?", "[{<AxisID>}]", "Get Servo Mode", svo_query),
    Command::line("TMN?", "[{<AxisID>}]", "Get Minimum Commandable Position", tmn_query),
    Command::line("TMX?", "[{<AxisID>}]", "Get Maximum Commandable Position", tmx_query),
    Command::line("TNR?", "", "Get Number Of Record Tables", datarec::tnr_query),
    Command::settings("VEL", "{<AxisID> <Velocity>}", "Set Closed-Loop Velocity", vel),
    Command::line("VEL?", "[{<AxisID>}]", "Get Closed-Loop Velocity", vel_query),
    Command::line(
        "WPA",
        "[<Password>]",
        "Save Parameters To Non-Volatile Memory (Servo Off And Idle Only)",
        wpa,
    ),
    Command::line("XDA?", "[{<AxisID>}]", "Get Drive Amplitude In V Peak-To-Peak (extension)", xda_query),
    Command::line("XDF?", "[{<AxisID>}]", "Get Drive Frequency In Hz (extension)", xdf_query),
    Command::line("XFT?", "[{<AxisID>}]", "Get Fault Code And Text (extension)", xft_query),
    Command::line("XLT?", "", "Get Control-Loop Timing (extension)", xlt_query),
    Command::line(
        "XOS",
        "<AxisID> <Cycles> <Amplitude> <Frequency>",
        "Open-Loop Stepping With Servo Off (extension)",
        xos,
    ),
    Command::line("XPF?", "[{<AxisID>}]", "Get Preload Force In N (extension)", xpf_query),
    Command::line(
        "XTM?",
        "[{<AxisID>}]",
        "Get Stall Force In N And No-Load Speed In mm/s At Present Preload (extension)",
        xtm_query,
    ),
];

/// The commands that wait for a pending parameter store ([`Board::store_pending`]): everything
/// that switches the servo on or starts motion, and another store.
const WAIT_FOR_STORE: [&str; 6] = ["SVO", "MOV", "MVR", "FRF", "XOS", "WPA"];

/// `*IDN?` fields: maker, model, (serial), version (three dot-separated parts at most).
pub const IDN_MAKER: &str = "(c)2026 piezo-drive project";
pub const IDN_MODEL: &str = "PD-SB1";
pub const IDN_VERSION: &str = env!("CARGO_PKG_VERSION");
/// `CST?`: what the axis is.
pub const STAGE_NAME: &str = "SHAKING-BEAM-PIEZO";

type GcsResult = Result<(), i32>;

/// Reply under construction: lines separated by space + LF, closed by LF; tracks overflow.
struct Out<'a> {
    buf: &'a mut Reply,
    lines: u32,
    ok: bool,
}

impl num::Sink for Out<'_> {
    fn put(&mut self, bytes: &[u8]) -> bool {
        self.ok &= self.buf.extend_from_slice(bytes).is_ok();
        self.ok
    }
}

impl Out<'_> {
    fn line(&mut self) {
        if self.lines > 0 {
            self.s(" \n");
        }
        self.lines = self.lines.saturating_add(1);
    }
    #[inline(never)]
    fn s(&mut self, text: &str) {
        num::Sink::put(self, text.as_bytes());
    }
    fn b(&mut self, bytes: &[u8]) {
        num::Sink::put(self, bytes);
    }
    fn u(&mut self, v: u64) {
        write_u64(self, v);
    }
    fn i(&mut self, v: i64) {
        write_i64(self, v);
    }
    /// Nanometres as millimetres with six decimals (`1=2.500000`).
    fn mm(&mut self, nm: i64) {
        write_scaled(self, nm, 6);
    }
    fn fixed(&mut self, v: f64, decimals: u32) {
        write_fixed(self, v, decimals);
    }
    fn general(&mut self, v: f64) {
        write_general(self, v);
    }
    /// Bytes the reply buffer still takes.
    fn room(&self) -> usize {
        self.buf.capacity().saturating_sub(self.buf.len())
    }
    /// Ends the last line as one more follows in the next reply (space + LF), so that
    /// [`Out::finish`] adds nothing.
    fn open_end(&mut self) {
        if self.lines > 0 {
            self.s(" \n");
        }
        self.lines = 0;
    }
    fn finish(&mut self) {
        if self.lines > 0 {
            self.s("\n");
        }
    }
}

/// Protocol state: the line being received, the latched error, the reference mode.
pub struct Gcs {
    line: Line,
    overflow: bool,
    error: i32,
    reference_mode: bool,
    seen_faults: u32,
    seen_reference_failures: u32,
    seen_limit_stops: u32,
    /// The rest of a `DRR?` reply, while one is being sent.
    drr: Option<datarec::DrrCursor>,
}

impl Default for Gcs {
    fn default() -> Self {
        Self::new()
    }
}

fn is_space(b: u8) -> bool {
    b == b' ' || b == b'\t' || b == b'\r'
}

fn command_error(e: CommandError) -> i32 {
    match e {
        CommandError::Faulted(_) => error::MOTION_ERROR,
        CommandError::ServoOff => error::MOVE_WITHOUT_REF_OR_SERVO_OFF,
        CommandError::OutOfTravel => error::POS_OUT_OF_LIMITS,
        CommandError::PreloadInvalid => error::SENSOR_SIGNAL_INVALID,
        CommandError::PreloadOutOfWindow => error::MOTION_ERROR,
        CommandError::InvalidValue => error::PARAM_OUT_OF_RANGE,
        CommandError::ServoOn => error::OPEN_LOOP_WITH_SERVO_ON,
        CommandError::Busy => error::CONTROLLER_BUSY,
    }
}

fn axis(t: &[u8]) -> GcsResult {
    if t == b"1" {
        Ok(())
    } else {
        Err(error::INVALID_AXIS)
    }
}

fn number(t: &[u8]) -> Result<Decimal, i32> {
    parse_decimal(t).ok_or(error::PARAM_SYNTAX)
}

/// Axes of a query: none means all (axis 1 once); each given axis is answered in turn.
fn query_axes(args: &[&[u8]]) -> Result<usize, i32> {
    for a in args {
        axis(a)?;
    }
    Ok(args.len().max(1))
}

/// `{<AxisID> <Value>}` pairs: every pair is checked (axis, then `check` on the value), and the
/// value of the last pair is the one that counts (one axis). A line with any bad pair executes
/// nothing, so the same checks must pass for every pair, not only the last.
fn pairs<T>(args: &[&[u8]], mut check: impl FnMut(&[u8]) -> Result<T, i32>) -> Result<T, i32> {
    if args.is_empty() {
        return Err(error::MISSING_PARAM);
    }
    if args.len() % 2 != 0 {
        return Err(error::WRONG_PARAM_COUNT);
    }
    let mut last = Err(error::MISSING_PARAM);
    for pair in args.chunks(2) {
        if let [a, v] = pair {
            axis(a)?;
            last = Ok(check(v)?);
        }
    }
    last
}

/// A position or distance in mm as nanometres; beyond i64 it is out of limits.
fn position_nm(t: &[u8]) -> Result<i64, i32> {
    number(t)?.scaled_i64(6).ok_or(error::POS_OUT_OF_LIMITS)
}

/// `nm` within the travel limits (`TMN?`..`TMX?`), else error 7.
fn within_travel(ctl: &Controller, nm: i64) -> Result<i64, i32> {
    let c = ctl.config();
    if nm < c.travel_min_nm || nm > c.travel_max_nm {
        return Err(error::POS_OUT_OF_LIMITS);
    }
    Ok(nm)
}

fn no_args(args: &[&[u8]]) -> GcsResult {
    if args.is_empty() {
        Ok(())
    } else {
        Err(error::WRONG_PARAM_COUNT)
    }
}

/// A boolean argument: exactly `0` or `1`.
fn flag(t: &[u8]) -> Result<bool, i32> {
    match parse_decimal(t).ok_or(error::PARAM_SYNTAX)?.integer() {
        Some(0) => Ok(false),
        Some(1) => Ok(true),
        _ => Err(error::PARAM_OUT_OF_RANGE),
    }
}

fn to_f32(d: &Decimal) -> Option<f32> {
    let v = d.to_f64()? as f32;
    v.is_finite().then_some(v)
}

impl Gcs {
    pub fn new() -> Self {
        Gcs {
            line: Line::new(),
            overflow: false,
            error: error::NONE,
            reference_mode: true,
            seen_faults: 0,
            seen_reference_failures: 0,
            seen_limit_stops: 0,
            drr: None,
        }
    }

    /// Cheap: collect one received byte. Some(..) once a complete command (a line, or a
    /// single-byte command) is ready.
    pub fn push_byte(&mut self, byte: u8) -> Option<Pending> {
        match byte {
            b'\n' => {
                let pending = if self.overflow {
                    Pending::TooLong
                } else {
                    Pending::Line(core::mem::take(&mut self.line))
                };
                self.line.clear();
                self.overflow = false;
                Some(pending)
            }
            // A NUL between lines is line noise (a port opening), not a command.
            0x00 if self.line.is_empty() && !self.overflow => None,
            // Control bytes other than tab and CR are commands of their own (#5, #7, #24; any
            // other is an unknown command), wherever they arrive.
            0x00..=0x08 | 0x0b | 0x0c | 0x0e..=0x1f => Some(Pending::Byte(byte)),
            _ => {
                if self.line.push(byte).is_err() {
                    self.overflow = true;
                }
                None
            }
        }
    }

    /// Forgets a partly received line (e.g. when a client disconnects mid-line).
    pub fn discard_partial_line(&mut self) {
        self.line.clear();
        self.overflow = false;
    }

    /// Whether `pending` only reads the controller: such a command may run on a copy of the
    /// controller (see [`Controller`]'s `Clone`) taken in a short critical section, so the
    /// control tick is never held off while it formats its reply. The queries (`…?`) and the
    /// single-byte status requests #5 and #7 read; every other command (#24 stops) writes, as
    /// does anything that is not a known command (it only latches an error, which lives here,
    /// not in the controller, so running it on a copy would be harmless too).
    pub fn is_read_only(pending: &Pending) -> bool {
        match pending {
            Pending::Byte(b) => *b == 0x05 || *b == 0x07,
            Pending::TooLong => true,
            Pending::Line(line) => {
                let Some(cmd) = line.split(|&b| is_space(b)).find(|t| !t.is_empty()) else {
                    return true; // empty line
                };
                COMMANDS.iter().any(|c| {
                    c.name.as_bytes().eq_ignore_ascii_case(cmd) && c.run.is_some() && c.name.ends_with('?')
                })
            }
        }
    }

    /// Whether `pending` changes nothing but the controller's settings (`SPA`, `VEL`, `ACC`,
    /// `DEC`): the settings change only through commands, so such a command can run on a copy of
    /// the controller (parsing, range checks, the trial `validate_settings`: up to ~15 000
    /// instructions for a full `SPA` line on the Cortex-M4) and the board then only applies the
    /// copy's settings to the real controller with [`Controller::set_config`] if they differ.
    pub fn is_settings_only(pending: &Pending) -> bool {
        let Pending::Line(line) = pending else { return false };
        let Some(cmd) = line.split(|&b| is_space(b)).find(|t| !t.is_empty()) else {
            return false;
        };
        COMMANDS.iter().any(|c| c.settings_only && c.name.as_bytes().eq_ignore_ascii_case(cmd))
    }

    /// Whether the last command's reply goes on (a `DRR?` longer than one reply buffer): call
    /// [`Gcs::continue_reply`] with an empty buffer and send what it adds until this is false.
    /// A new command drops what is left.
    pub fn reply_pending(&self) -> bool {
        self.drr.is_some()
    }

    /// The next part of a reply that goes on (see [`Gcs::reply_pending`]), appended to `reply`
    /// (give it an empty one: a part is as long as the buffer takes).
    pub fn continue_reply(&mut self, board: &dyn Board, reply: &mut Reply) {
        let Some(mut cursor) = self.drr.take() else { return };
        let Some(rec) = board.recorder() else { return };
        let mut out = Out { buf: reply, lines: 0, ok: true };
        let before = cursor.rows_left();
        if datarec::write_rows(&mut cursor, rec, &mut out) {
            if cursor.rows_left() == before {
                // No room for a single row: the caller's buffer was not empty. Give up.
                return;
            }
            out.open_end();
            self.drr = Some(cursor);
        } else {
            out.finish();
        }
    }

    /// The latched error (without clearing it).
    pub fn latched_error(&self) -> i32 {
        self.error
    }

    /// Execute it against the controller and append the reply bytes (possibly none).
    pub fn execute(
        &mut self,
        pending: &Pending,
        ctl: &mut Controller,
        board: &mut dyn Board,
        reply: &mut Reply,
    ) {
        // Errors the controller ran into on its own since the last command.
        if ctl.fault_count() != self.seen_faults {
            self.seen_faults = ctl.fault_count();
            self.error = if ctl.fault() == Some(FaultCode::Overrun) {
                error::CONTROL_LOOP_OVERRUN
            } else {
                error::MOTION_ERROR
            };
        }
        if ctl.reference_failure_count() != self.seen_reference_failures {
            self.seen_reference_failures = ctl.reference_failure_count();
            self.error = error::REFERENCING_FAILED;
        }
        if ctl.limit_stop_count() != self.seen_limit_stops {
            // A limit switch stopped a move or an open-loop run: the slider is at the end of
            // its travel on that side.
            self.seen_limit_stops = ctl.limit_stop_count();
            self.error = error::POS_OUT_OF_LIMITS;
        }
        if board.take_store_failure() {
            self.error = error::FLASH_PROGRAM_FAILED;
        }
        self.drr = None;
        let start = reply.len();
        let mut out = Out { buf: reply, lines: 0, ok: true };
        let result = match pending {
            Pending::Byte(b) => self.byte_command(*b, ctl, &mut out),
            Pending::TooLong => Err(error::COMMAND_TOO_LONG),
            Pending::Line(line) => self.line_command(line, ctl, board, &mut out),
        };
        out.finish();
        let result = if out.ok { result } else { Err(error::COMMAND_TOO_LONG) };
        // The recorder's trigger 2: any command but the `DRT` that sets it.
        if let Some(rec) = board.recorder() {
            let drt = matches!(pending, Pending::Line(l)
                if l.split(|&b| is_space(b)).find(|t| !t.is_empty()).is_some_and(|c| c.eq_ignore_ascii_case(b"DRT")));
            if !drt {
                rec.on_command(ctl);
            }
        }
        if let Err(code) = result {
            reply.truncate(start);
            self.error = code;
            self.drr = None;
        }
    }

    fn byte_command(&mut self, b: u8, ctl: &mut Controller, out: &mut Out) -> GcsResult {
        match b {
            0x05 => {
                out.line();
                out.u(u64::from(ctl.in_motion()));
            }
            0x07 => {
                out.line();
                out.b(&[if ctl.referencing() { 0xB0 } else { 0xB1 }]);
            }
            0x18 => {
                ctl.stop();
                return Err(error::STOPPED);
            }
            _ => return Err(error::UNKNOWN_COMMAND),
        }
        Ok(())
    }

    fn line_command(
        &mut self,
        line: &[u8],
        ctl: &mut Controller,
        board: &mut dyn Board,
        out: &mut Out,
    ) -> GcsResult {
        let mut tokens: heapless::Vec<&[u8], MAX_TOKENS> = heapless::Vec::new();
        for t in line.split(|&b| is_space(b)).filter(|t| !t.is_empty()) {
            tokens.push(t).map_err(|_| error::WRONG_PARAM_COUNT)?;
        }
        let Some((cmd, args)) = tokens.split_first() else {
            return Ok(()); // empty line
        };
        let command = COMMANDS
            .iter()
            .find(|c| c.name.as_bytes().eq_ignore_ascii_case(cmd))
            .ok_or(error::UNKNOWN_COMMAND)?;
        let run = command.run.ok_or(error::UNKNOWN_COMMAND)?;
        // A parameter store parks the drive and writes the flash: nothing may start meanwhile.
        if board.store_pending() && WAIT_FOR_STORE.contains(&command.name) {
            return Err(error::CONTROLLER_BUSY);
        }
        run(self, Call { args, ctl, board, out })
    }

    /// `XYZ? [{<AxisID>}]`: one `1=value` line per requested axis.
    fn axis_query(&self, args: &[&[u8]], out: &mut Out, mut value: impl FnMut(&mut Out)) -> GcsResult {
        let n = query_axes(args)?;
        for _ in 0..n {
            out.line();
            out.s("1=");
            value(out);
        }
        Ok(())
    }

    fn check_preload(&self, ctl: &Controller) -> GcsResult {
        let f = ctl.preload_n().ok_or(error::SENSOR_SIGNAL_INVALID)?;
        let c = ctl.config();
        if f < c.preload_min_n || f > c.preload_max_n {
            return Err(error::MOTION_ERROR);
        }
        Ok(())
    }

    /// Whether a closed-loop move may start: servo on, referenced (with reference mode on),
    /// not referencing.
    fn move_allowed(&self, ctl: &Controller) -> GcsResult {
        if ctl.referencing() {
            return Err(error::CONTROLLER_BUSY);
        }
        if !ctl.servo() || (self.reference_mode && !ctl.referenced()) {
            return Err(error::MOVE_WITHOUT_REF_OR_SERVO_OFF);
        }
        Ok(())
    }

    fn spa(&mut self, args: &[&[u8]], ctl: &mut Controller) -> GcsResult {
        if args.is_empty() {
            return Err(error::MISSING_PARAM);
        }
        if args.len() % 3 != 0 {
            return Err(error::WRONG_PARAM_COUNT);
        }
        let mut cfg = *ctl.config();
        for triple in args.chunks(3) {
            let [item, id, value] = triple else { return Err(error::WRONG_PARAM_COUNT) };
            axis(item)?;
            let p =
                params::find(parse_int(id).ok_or(error::PARAM_SYNTAX)?).ok_or(error::UNKNOWN_PARAMETER)?;
            let v = number(value)?;
            if p.read_only {
                return Err(error::READ_ONLY_PARAMETER);
            }
            let x = params::from_gcs(p, &v).ok_or(error::PARAM_OUT_OF_RANGE)?;
            if !(p.set)(&mut cfg, x) {
                return Err(error::PARAM_OUT_OF_RANGE);
            }
        }
        ctl.set_config(cfg).map_err(|_| error::PARAM_OUT_OF_RANGE)
    }

    fn spa_query(&self, args: &[&[u8]], ctl: &Controller, out: &mut Out) -> GcsResult {
        let cfg = ctl.config();
        if args.is_empty() {
            for p in params::PARAMS {
                param_line(out, p, cfg);
            }
            return Ok(());
        }
        if args.len() % 2 != 0 {
            return Err(error::WRONG_PARAM_COUNT);
        }
        // Check everything before answering anything.
        for pair in args.chunks(2) {
            let [item, id] = pair else { return Err(error::WRONG_PARAM_COUNT) };
            axis(item)?;
            params::find(parse_int(id).ok_or(error::PARAM_SYNTAX)?).ok_or(error::UNKNOWN_PARAMETER)?;
        }
        for pair in args.chunks(2) {
            if let [_, id] = pair {
                if let Some(p) = parse_int(id).and_then(params::find) {
                    param_line(out, p, cfg);
                }
            }
        }
        Ok(())
    }
}

// ---- the line commands: one handler each, named after the command (`…_query` for `…?`) ----

fn idn_query(_gcs: &mut Gcs, c: Call) -> GcsResult {
    let Call { args, board, out, .. } = c;
    no_args(args)?;
    out.line();
    out.s(IDN_MAKER);
    out.s(", ");
    out.s(IDN_MODEL);
    out.s(", ");
    // Six digits at least, as PI prints serial numbers.
    let serial = board.serial_number();
    let mut p = 100_000u32;
    while p > 1 && serial < p {
        out.s("0");
        p /= 10;
    }
    out.u(u64::from(serial));
    out.s(", ");
    out.s(IDN_VERSION);
    Ok(())
}

fn csv_query(_gcs: &mut Gcs, c: Call) -> GcsResult {
    let Call { args, out, .. } = c;
    no_args(args)?;
    out.line();
    out.s("2.0");
    Ok(())
}

fn err_query(gcs: &mut Gcs, c: Call) -> GcsResult {
    let Call { args, out, .. } = c;
    no_args(args)?;
    out.line();
    out.i(i64::from(gcs.error));
    gcs.error = error::NONE;
    Ok(())
}

fn hlp_query(_gcs: &mut Gcs, c: Call) -> GcsResult {
    let Call { args, out, .. } = c;
    no_args(args)?;
    out.line();
    out.s("The following commands are valid:");
    for c in COMMANDS {
        out.line();
        out.s(c.name);
        if !c.syntax.is_empty() {
            out.s(" ");
            out.s(c.syntax);
        }
        out.s(" ");
        out.s(c.help);
    }
    out.line();
    out.s("end of help");
    Ok(())
}

fn hpa_query(_gcs: &mut Gcs, c: Call) -> GcsResult {
    let Call { args, out, .. } = c;
    no_args(args)?;
    out.line();
    out.s("#Possible parameters of this device:");
    for p in params::PARAMS {
        out.line();
        out.s("0x");
        hex(out, p.id);
        out.s("=\t0\t1\t");
        out.s(p.kind.name());
        out.s("\t");
        out.s(p.group);
        out.s("\t");
        out.s(p.description);
        if !p.unit.is_empty() {
            out.s(" (");
            out.s(p.unit);
            out.s(")");
        }
    }
    out.line();
    out.s("end of help");
    Ok(())
}

fn sai_query(_gcs: &mut Gcs, c: Call) -> GcsResult {
    let Call { args, out, .. } = c;
    match args {
        [] => {}
        [all] if all.eq_ignore_ascii_case(b"ALL") => {}
        [_] => return Err(error::PARAM_SYNTAX),
        _ => return Err(error::WRONG_PARAM_COUNT),
    }
    out.line();
    out.s("1");
    Ok(())
}

fn cst_query(gcs: &mut Gcs, c: Call) -> GcsResult {
    let Call { args, out, .. } = c;
    gcs.axis_query(args, out, |out| out.s(STAGE_NAME))?;
    Ok(())
}

fn svo_query(gcs: &mut Gcs, c: Call) -> GcsResult {
    let Call { args, ctl, out, .. } = c;
    gcs.axis_query(args, out, |out| out.u(u64::from(ctl.servo())))?;
    Ok(())
}

fn ron_query(gcs: &mut Gcs, c: Call) -> GcsResult {
    let Call { args, out, .. } = c;
    let ron = gcs.reference_mode;
    gcs.axis_query(args, out, |out| out.u(u64::from(ron)))?;
    Ok(())
}

fn frf_query(gcs: &mut Gcs, c: Call) -> GcsResult {
    let Call { args, ctl, out, .. } = c;
    gcs.axis_query(args, out, |out| out.u(u64::from(ctl.referenced())))?;
    Ok(())
}

fn ont_query(gcs: &mut Gcs, c: Call) -> GcsResult {
    let Call { args, ctl, out, .. } = c;
    gcs.axis_query(args, out, |out| out.u(u64::from(ctl.on_target())))?;
    Ok(())
}

fn pos_query(gcs: &mut Gcs, c: Call) -> GcsResult {
    let Call { args, ctl, out, .. } = c;
    gcs.axis_query(args, out, |out| out.mm(ctl.position_nm()))?;
    Ok(())
}

fn mov_query(gcs: &mut Gcs, c: Call) -> GcsResult {
    let Call { args, ctl, out, .. } = c;
    gcs.axis_query(args, out, |out| out.mm(ctl.target_nm()))?;
    Ok(())
}

fn tmn_query(gcs: &mut Gcs, c: Call) -> GcsResult {
    let Call { args, ctl, out, .. } = c;
    gcs.axis_query(args, out, |out| out.mm(ctl.config().travel_min_nm))?;
    Ok(())
}

fn tmx_query(gcs: &mut Gcs, c: Call) -> GcsResult {
    let Call { args, ctl, out, .. } = c;
    gcs.axis_query(args, out, |out| out.mm(ctl.config().travel_max_nm))?;
    Ok(())
}

fn vel_query(gcs: &mut Gcs, c: Call) -> GcsResult {
    let Call { args, ctl, out, .. } = c;
    let v = f64::from(ctl.config().velocity_max_nm_s / 1e6);
    gcs.axis_query(args, out, |out| out.general(v))?;
    Ok(())
}

fn acc_query(gcs: &mut Gcs, c: Call) -> GcsResult {
    let Call { args, ctl, out, .. } = c;
    let v = f64::from(ctl.config().accel_max_nm_s2 / 1e6);
    gcs.axis_query(args, out, |out| out.general(v))?;
    Ok(())
}

fn dec_query(gcs: &mut Gcs, c: Call) -> GcsResult {
    let Call { args, ctl, out, .. } = c;
    let v = f64::from(ctl.config().decel_max_nm_s2 / 1e6);
    gcs.axis_query(args, out, |out| out.general(v))?;
    Ok(())
}

fn xpf_query(gcs: &mut Gcs, c: Call) -> GcsResult {
    let Call { args, ctl, out, .. } = c;
    let f = ctl.preload_n().ok_or(error::SENSOR_SIGNAL_INVALID)?;
    gcs.axis_query(args, out, |out| out.fixed(f64::from(f), 3))?;
    Ok(())
}

fn xda_query(gcs: &mut Gcs, c: Call) -> GcsResult {
    let Call { args, ctl, out, .. } = c;
    let v = f64::from(ctl.drive_voltage_v());
    gcs.axis_query(args, out, |out| out.fixed(v, 3))?;
    Ok(())
}

fn xdf_query(gcs: &mut Gcs, c: Call) -> GcsResult {
    let Call { args, ctl, out, .. } = c;
    let f = f64::from(ctl.drive_frequency_hz());
    gcs.axis_query(args, out, |out| out.fixed(f, 1))?;
    Ok(())
}

fn xft_query(gcs: &mut Gcs, c: Call) -> GcsResult {
    let Call { args, ctl, out, .. } = c;
    let fault = ctl.fault();
    gcs.axis_query(args, out, |out| match fault {
        Some(code) => {
            out.u(code as u64);
            out.s(" ");
            out.s(code.text());
        }
        None => out.s("0 no fault"),
    })?;
    Ok(())
}

fn xtm_query(gcs: &mut Gcs, c: Call) -> GcsResult {
    let Call { args, ctl, out, .. } = c;
    let (stall, speed) = ctl.thrust_limits().ok_or(error::SENSOR_SIGNAL_INVALID)?;
    gcs.axis_query(args, out, |out| {
        out.fixed(f64::from(stall), 3);
        out.s(" ");
        out.fixed(f64::from(speed), 3);
    })?;
    Ok(())
}

fn xlt_query(_gcs: &mut Gcs, c: Call) -> GcsResult {
    let Call { args, board, out, .. } = c;
    no_args(args)?;
    let s = board.loop_stats();
    for (key, v) in [
        ("step_cycles_last", s.step_cycles_last),
        ("step_cycles_max", s.step_cycles_max),
        ("overruns", s.overruns),
        ("core_clock_hz", s.core_clock_hz),
    ] {
        out.line();
        out.s(key);
        out.s("=");
        out.u(u64::from(v));
    }
    Ok(())
}

fn svo(gcs: &mut Gcs, c: Call) -> GcsResult {
    let Call { args, ctl, .. } = c;
    let on = pairs(args, flag)?;
    if ctl.referencing() {
        return Err(error::CONTROLLER_BUSY);
    }
    if ctl.fault().is_none() && ctl.servo() == on {
        // Already so: nothing to do (servo on again must not re-anchor a moving
        // slider's reference where it stands).
        return Ok(());
    }
    if ctl.fault().is_some() {
        // As on PI controllers after a motion error: switching the servo (on or off)
        // again is the recovery. Check what servo-on needs before clearing.
        if on {
            gcs.check_preload(ctl)?;
        }
        ctl.clear_fault();
    }
    ctl.set_servo(on).map_err(command_error)?;
    Ok(())
}

fn ron(gcs: &mut Gcs, c: Call) -> GcsResult {
    let Call { args, .. } = c;
    gcs.reference_mode = pairs(args, flag)?;
    Ok(())
}

fn frf(gcs: &mut Gcs, c: Call) -> GcsResult {
    let Call { args, ctl, .. } = c;
    for a in args {
        axis(a)?;
    }
    if !gcs.reference_mode {
        return Err(error::REF_WITH_REF_DISABLED);
    }
    ctl.start_referencing().map_err(command_error)?;
    Ok(())
}

fn pos(gcs: &mut Gcs, c: Call) -> GcsResult {
    let Call { args, ctl, .. } = c;
    // Within the travel limits: beyond them the distance to a later target could
    // overflow, and the stage cannot be there anyway.
    let nm = pairs(args, |t| within_travel(ctl, position_nm(t)?))?;
    if gcs.reference_mode {
        return Err(error::NOT_ALLOWED);
    }
    if ctl.in_motion() {
        return Err(error::CONTROLLER_BUSY);
    }
    ctl.set_reference_here(nm);
    Ok(())
}

/// A command that changes the target was accepted: the recorder's move trigger.
fn moved(ctl: &Controller, board: &dyn Board) {
    if let Some(rec) = board.recorder() {
        rec.on_move(ctl);
    }
}

fn mov(gcs: &mut Gcs, c: Call) -> GcsResult {
    let Call { args, ctl, board, .. } = c;
    // Syntax of every pair, then whether a move is allowed at all, then the limits
    // of every pair.
    pairs(args, position_nm)?;
    gcs.move_allowed(ctl)?;
    let target = pairs(args, |t| within_travel(ctl, position_nm(t)?))?;
    ctl.move_to(target).map_err(command_error)?;
    moved(ctl, board);
    Ok(())
}

fn mvr(gcs: &mut Gcs, c: Call) -> GcsResult {
    let Call { args, ctl, board, .. } = c;
    pairs(args, position_nm)?;
    gcs.move_allowed(ctl)?;
    let base = ctl.target_nm();
    let target = pairs(args, |t| {
        let target = base.checked_add(position_nm(t)?).ok_or(error::POS_OUT_OF_LIMITS)?;
        within_travel(ctl, target)
    })?;
    ctl.move_to(target).map_err(command_error)?;
    moved(ctl, board);
    Ok(())
}

/// `VEL`, `ACC`, `DEC`: one of the closed-loop motion limits, each pair checked as the whole
/// configuration it would make.
fn motion_limit(name: &str, c: Call) -> GcsResult {
    let Call { args, ctl, .. } = c;
    let bad = if name == "VEL" { error::VEL_OUT_OF_LIMITS } else { error::PARAM_OUT_OF_RANGE };
    // Each pair's value is checked as the whole configuration it would make.
    let cfg = pairs(args, |t| {
        let x = to_f32(&number(t)?).map(|x| x * 1e6).filter(|x| x.is_finite() && *x > 0.0);
        let x = x.ok_or(bad)?;
        let mut cfg = *ctl.config();
        match name {
            "VEL" => cfg.velocity_max_nm_s = x,
            "ACC" => cfg.accel_max_nm_s2 = x,
            _ => cfg.decel_max_nm_s2 = x,
        }
        validate_settings(&cfg).map_err(|_| bad)?;
        Ok(cfg)
    })?;
    ctl.set_config(cfg).map_err(|_| bad)?;
    Ok(())
}

fn vel(_gcs: &mut Gcs, c: Call) -> GcsResult {
    motion_limit("VEL", c)
}

fn acc(_gcs: &mut Gcs, c: Call) -> GcsResult {
    motion_limit("ACC", c)
}

fn dec(_gcs: &mut Gcs, c: Call) -> GcsResult {
    motion_limit("DEC", c)
}

fn stp(_gcs: &mut Gcs, c: Call) -> GcsResult {
    let Call { args, ctl, .. } = c;
    no_args(args)?;
    ctl.stop();
    Err(error::STOPPED)
}

fn hlt(_gcs: &mut Gcs, c: Call) -> GcsResult {
    let Call { args, ctl, .. } = c;
    for a in args {
        axis(a)?;
    }
    ctl.halt();
    Err(error::STOPPED)
}

fn spa(gcs: &mut Gcs, c: Call) -> GcsResult {
    let Call { args, ctl, .. } = c;
    gcs.spa(args, ctl)?;
    Ok(())
}

fn spa_query(gcs: &mut Gcs, c: Call) -> GcsResult {
    let Call { args, ctl, out, .. } = c;
    gcs.spa_query(args, ctl, out)?;
    Ok(())
}

fn wpa(_gcs: &mut Gcs, c: Call) -> GcsResult {
    let Call { args, ctl, board, .. } = c;
    match args {
        [] => {}
        [pw] if *pw == b"100" => {}
        [_] => return Err(error::INVALID_PASSWORD),
        _ => return Err(error::WRONG_PARAM_COUNT),
    }
    // Writing the flash stalls the CPU (about 20 ms on the board): only with the
    // drive quiet, servo off and nothing moving.
    if ctl.state() != State::Idle || ctl.servo() || ctl.in_motion() || ctl.referencing() {
        return Err(error::NOT_ALLOWED);
    }
    if !board.store_parameters(ctl.config()) {
        return Err(error::FLASH_PROGRAM_FAILED);
    }
    Ok(())
}

fn xos(_gcs: &mut Gcs, c: Call) -> GcsResult {
    let Call { args, ctl, board, .. } = c;
    let [a, cycles, amplitude, frequency] = args else {
        return Err(if args.is_empty() { error::MISSING_PARAM } else { error::WRONG_PARAM_COUNT });
    };
    axis(a)?;
    let cycles = parse_int(cycles).ok_or(error::PARAM_SYNTAX)?;
    let amplitude = number(amplitude)?;
    let frequency = number(frequency)?;
    let cycles = i32::try_from(cycles)
        .ok()
        .filter(|c| *c != 0 && c.unsigned_abs() <= 1_000_000)
        .ok_or(error::PARAM_OUT_OF_RANGE)?;
    let amplitude = to_f32(&amplitude).ok_or(error::PARAM_OUT_OF_RANGE)?;
    let frequency = to_f32(&frequency).ok_or(error::PARAM_OUT_OF_RANGE)?;
    ctl.open_loop_step(cycles, amplitude, frequency).map_err(command_error)?;
    moved(ctl, board);
    Ok(())
}

fn hex(out: &mut Out, v: u32) {
    let digits = b"0123456789ABCDEF";
    let mut started = false;
    for shift in (0..8).rev() {
        let d = ((v >> (shift * 4)) & 0xF) as usize;
        if d != 0 || started || shift == 0 {
            started = true;
            if let Some(c) = digits.get(d) {
                out.b(&[*c]);
            }
        }
    }
}

fn param_line(out: &mut Out, p: &params::Param, cfg: &ControllerConfig) {
    out.line();
    out.s("1 0x");
    hex(out, p.id);
    out.s("=");
    params::write_gcs(out, p, (p.get)(cfg));
}
