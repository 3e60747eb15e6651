//! The command table and dispatch: [`Command`], [`COMMANDS`] (in `HLP?` order),
//! [`WAIT_FOR_STORE`], and what picks and runs a handler: [`Gcs::is_read_only`],
//! [`Gcs::is_settings_only`] and the three runners `lock.rs` calls (a query on a snapshot, a
//! settings command on a copy of the settings, any other command on the locked controller).

use super::args::no_args;
use super::call::{Call, GcsResult, Handler, Query, QueryHandler, Settings, SettingsHandler};
use super::framing::{is_space, Out, Pending};
use super::info::{cst_query, csv_query, idn_query, sai_query, ssn_query, ver_query, xlt_query, xts_query};
use super::motion::{fnl, fpl, frf, hlt, mov, mvr, pos, ron, stp, svo, xos};
use super::settings::{
    acc, acc_query, dec, dec_query, hpa_query, spa, spa_query, tmn_query, tmx_query, vel, vel_query, wpa,
};
use super::snapshot::{Latch, Snapshot};
use super::state::{
    err_query, frf_query, har_query, lim_query, mov_query, ont_query, pos_query, ron_query, srg_query,
    status_register, svo_query, trs_query, write_register, xda_query, xdf_query, xft_query, xpf_query,
    xtm_query,
};
use super::{datarec, error, Board, Gcs, MAX_TOKENS};
use crate::controller::{Controller, ControllerConfig, FaultCode};

/// What runs a command, by what it may touch.
#[derive(Clone, Copy)]
enum Run {
    /// A single-byte command (#5, #7, #24), answered from the byte.
    Byte,
    /// Acts on the controller: runs with it locked.
    Line(Handler),
    /// Reads only: runs on a [`Snapshot`], without the lock.
    Query(QueryHandler),
    /// Changes nothing but the settings: runs on a copy of them, without the lock.
    Settings(SettingsHandler),
}

/// One GCS command: its name, arguments and description as `HLP?` lists them, and what runs it.
pub struct Command {
    pub name: &'static str,
    pub syntax: &'static str,
    pub help: &'static str,
    run: Run,
}

impl Command {
    /// A single-byte command (answered from the byte).
    const fn byte(name: &'static str, help: &'static str) -> Self {
        Command { name, syntax: "", help, run: Run::Byte }
    }
    /// A line command that acts on the controller.
    const fn line(name: &'static str, syntax: &'static str, help: &'static str, run: Handler) -> Self {
        Command { name, syntax, help, run: Run::Line(run) }
    }
    /// A query.
    const fn query(name: &'static str, syntax: &'static str, help: &'static str, run: QueryHandler) -> Self {
        Command { name, syntax, help, run: Run::Query(run) }
    }
    /// A line command that changes only settings.
    const fn settings(
        name: &'static str,
        syntax: &'static str,
        help: &'static str,
        run: SettingsHandler,
    ) -> Self {
        Command { name, syntax, help, run: Run::Settings(run) }
    }
    /// Whether the command only reads (a query, #4, #5, #7).
    pub fn is_query(&self) -> bool {
        matches!(self.run, Run::Query(_)) || matches!(self.name, "#4" | "#5" | "#7")
    }
    /// Whether the command changes nothing but the settings (`SPA`, `VEL`, `ACC`, `DEC`).
    pub fn is_settings(&self) -> bool {
        matches!(self.run, Run::Settings(_))
    }
}

/// The commands, in the order `HLP?` lists them; the line commands' handlers are in the group
/// modules (`info`, `motion`, `settings`, `state`, `datarec`), one handler each, named after the
/// command (`…_query` for `…?`).
pub static COMMANDS: &[Command] = &[
    Command::byte("#4", "Request Status Register"),
    Command::byte("#5", "Request Motion Status"),
    Command::byte("#7", "Request Controller Ready Status"),
    Command::byte("#24", "Stop All Axes"),
    Command::query("*IDN?", "", "Get Device Identification", idn_query),
    Command::settings("ACC", "{<AxisID> <Acceleration>}", "Set Closed-Loop Acceleration", acc),
    Command::query("ACC?", "[{<AxisID>}]", "Get Closed-Loop Acceleration", acc_query),
    Command::query("CST?", "[{<AxisID>}]", "Get Assignment Of Stages To Axes", cst_query),
    Command::query("CSV?", "", "Get Current Syntax Version", csv_query),
    Command::settings("DEC", "{<AxisID> <Deceleration>}", "Set Closed-Loop Deceleration", dec),
    Command::query("DEC?", "[{<AxisID>}]", "Get Closed-Loop Deceleration", dec_query),
    Command::line(
        "DRC",
        "{<RecTableID> <Source> <RecOption>}",
        "Set Data Recorder Configuration",
        datarec::drc,
    ),
    Command::query("DRC?", "[{<RecTableID>}]", "Get Data Recorder Configuration", datarec::drc_query),
    Command::query("DRL?", "[{<RecTableID>}]", "Get Number Of Recorded Points", datarec::drl_query),
    Command::query(
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
    Command::query("DRT?", "[{<RecTableID>}]", "Get Data Recorder Trigger Source", datarec::drt_query),
    Command::query("ERR?", "", "Get Error Number", err_query),
    Command::line("FNL", "[{<AxisID>}]", "Fast Reference Move To Negative Limit", fnl),
    Command::line("FPL", "[{<AxisID>}]", "Fast Reference Move To Positive Limit", fpl),
    Command::line("FRF", "[{<AxisID>}]", "Fast Reference Move To Reference Mark", frf),
    Command::query("FRF?", "[{<AxisID>}]", "Get Referencing Result", frf_query),
    Command::query("HAR?", "[{<AxisID>}]", "Indicate Hard Stops For Referencing", har_query),
    Command::query("HDR?", "", "Get All Data Recorder Options", datarec::hdr_query),
    Command::query("HLP?", "", "Get List Of Available Commands", hlp_query),
    Command::line("HLT", "[{<AxisID>}]", "Halt Motion Smoothly", hlt),
    Command::query("HPA?", "", "Get List Of Available Parameters", hpa_query),
    Command::query("LIM?", "[{<AxisID>}]", "Indicate Limit Switches", lim_query),
    Command::line("MOV", "{<AxisID> <Position>}", "Set Target Position", mov),
    Command::query("MOV?", "[{<AxisID>}]", "Get Target Position", mov_query),
    Command::line("MVR", "{<AxisID> <Distance>}", "Set Target Relative To Current Target", mvr),
    Command::query("ONT?", "[{<AxisID>}]", "Get On Target State", ont_query),
    Command::line("POS", "{<AxisID> <Position>}", "Set Real Position (Reference Mode Off)", pos),
    Command::query("POS?", "[{<AxisID>}]", "Get Real Position", pos_query),
    Command::line("RON", "{<AxisID> <ReferenceOn>}", "Set Reference Mode", ron),
    Command::query("RON?", "[{<AxisID>}]", "Get Reference Mode", ron_query),
    Command::line("RTR", "<RecordTableRate>", "Set Record Table Rate", datarec::rtr),
    Command::query("RTR?", "", "Get Record Table Rate", datarec::rtr_query),
    Command::query("SAI?", "[ALL]", "Get List Of Current Axis Identifiers", sai_query),
    Command::settings("SPA", "{<ItemID> <PamID> <PamValue>}", "Set Volatile Memory Parameters", spa),
    Command::query("SPA?", "[{<ItemID> <PamID>}]", "Get Volatile Memory Parameters", spa_query),
    Command::query("SRG?", "[{<AxisID> <RegisterID>}]", "Query Status Register Value", srg_query),
    Command::query("SSN?", "", "Get Device Serial Number", ssn_query),
    Command::line("STP", "", "Stop All Axes", stp),
    Command::line("SVO", "{<AxisID> <ServoState>}", "Set Servo Mode", svo),
    Command::query("SVO?", "[{<AxisID>}]", "Get Servo Mode", svo_query),
    Command::query("TMN?", "[{<AxisID>}]", "Get Minimum Commandable Position", tmn_query),
    Command::query("TMX?", "[{<AxisID>}]", "Get Maximum Commandable Position", tmx_query),
    Command::query("TNR?", "", "Get Number Of Record Tables", datarec::tnr_query),
    Command::query("TRS?", "[{<AxisID>}]", "Indicate Reference Switch", trs_query),
    Command::settings("VEL", "{<AxisID> <Velocity>}", "Set Closed-Loop Velocity", vel),
    Command::query("VEL?", "[{<AxisID>}]", "Get Closed-Loop Velocity", vel_query),
    Command::query("VER?", "", "Get Versions Of Firmware", ver_query),
    Command::line(
        "WPA",
        "[<Password>]",
        "Save Parameters To Non-Volatile Memory (Servo Off And Idle Only)",
        wpa,
    ),
    Command::query("XDA?", "[{<AxisID>}]", "Get Drive Amplitude In V Peak-To-Peak (extension)", xda_query),
    Command::query("XDF?", "[{<AxisID>}]", "Get Drive Frequency In Hz (extension)", xdf_query),
    Command::query("XFT?", "[{<AxisID>}]", "Get Fault Code And Text (extension)", xft_query),
    Command::query("XLT?", "", "Get Control-Loop Timing (extension)", xlt_query),
    Command::line(
        "XOS",
        "<AxisID> <Cycles> <Amplitude> <Frequency>",
        "Open-Loop Stepping With Servo Off (extension)",
        xos,
    ),
    Command::query("XPF?", "[{<AxisID>}]", "Get Preload Force In N (extension)", xpf_query),
    Command::query(
        "XTM?",
        "[{<AxisID>}]",
        "Get Stall Force In N And No-Load Speed In mm/s At Present Preload (extension)",
        xtm_query,
    ),
    Command::query("XTS?", "", "Get The Model Table In Use And Its Background Build (extension)", xts_query),
];

/// The commands that wait for a pending parameter store ([`Board::store_pending`]): everything
/// that switches the servo on or starts motion, and another store.
const WAIT_FOR_STORE: [&str; 6] = ["SVO", "MOV", "MVR", "FRF", "XOS", "WPA"];

/// A received command, split and looked up without the controller: what [`Gcs`]'s runners
/// take.
// On the stack for one command, never moved into a collection.
#[allow(clippy::large_enum_variant)]
pub(super) enum Parsed<'p> {
    /// A single-byte command (0x04, 0x05, 0x07, 0x18, any other control byte).
    Byte(u8),
    /// An empty line: nothing to do, nothing to answer.
    Empty,
    /// A line command and its arguments.
    Line(&'static Command, heapless::Vec<&'p [u8], MAX_TOKENS>),
    /// A command that cannot run (too long, too many tokens, unknown): its error.
    Refused(i32),
}

impl<'p> Parsed<'p> {
    pub(super) fn of(pending: &'p Pending) -> Self {
        match pending {
            Pending::Byte(b) => Parsed::Byte(*b),
            Pending::TooLong => Parsed::Refused(error::COMMAND_TOO_LONG),
            Pending::Line(line) => {
                let mut tokens: heapless::Vec<&[u8], MAX_TOKENS> = heapless::Vec::new();
                for t in line.split(|&b| is_space(b)).filter(|t| !t.is_empty()) {
                    if tokens.push(t).is_err() {
                        return Parsed::Refused(error::WRONG_PARAM_COUNT);
                    }
                }
                let Some(cmd) = tokens.first() else { return Parsed::Empty };
                match COMMANDS.iter().find(|c| c.name.as_bytes().eq_ignore_ascii_case(cmd)) {
                    Some(c) if !matches!(c.run, Run::Byte) => Parsed::Line(c, tokens),
                    _ => Parsed::Refused(error::UNKNOWN_COMMAND),
                }
            }
        }
    }

    /// How it runs: on a snapshot, on a copy of the settings, or on the locked controller.
    pub(super) fn shape(&self) -> Shape {
        match self {
            Parsed::Byte(0x18) => Shape::Locked,
            Parsed::Byte(_) | Parsed::Empty | Parsed::Refused(_) => Shape::Query,
            Parsed::Line(c, _) => match c.run {
                Run::Query(_) => Shape::Query,
                Run::Settings(_) => Shape::Settings,
                Run::Line(_) | Run::Byte => Shape::Locked,
            },
        }
    }

    /// Whether answering it needs [`crate::controller::Controller::thrust_limits`] (`XTM?`).
    pub(super) fn needs_thrust(&self) -> bool {
        matches!(self, Parsed::Line(c, _) if c.name == "XTM?")
    }
}

/// See [`Parsed::shape`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Shape {
    Query,
    Settings,
    Locked,
}

impl Gcs {
    /// Whether `pending` only reads the controller: it is answered from a [`Snapshot`] taken in
    /// a short locked section, so the control tick is never held off while it formats its
    /// reply. The queries (`…?`), the single-byte status requests #5 and #7, an empty line and
    /// a command that cannot run (it only latches an error, which lives here) read; every
    /// other command (#24 stops) writes.
    pub fn is_read_only(pending: &Pending) -> bool {
        Parsed::of(pending).shape() == Shape::Query
    }

    /// Whether `pending` changes nothing but the controller's settings (`SPA`, `VEL`, `ACC`,
    /// `DEC`): it is parsed and checked on a copy of the settings (up to ~15 000 instructions
    /// for a full `SPA` line on the Cortex-M4) and the board then hands the new settings to
    /// [`Controller::set_config`] under the lock, if they differ.
    pub fn is_settings_only(pending: &Pending) -> bool {
        Parsed::of(pending).shape() == Shape::Settings
    }

    /// Errors the controller ran into on its own since the last command, and a failed store.
    fn latch(&mut self, l: &Latch, board: &mut dyn Board) {
        if l.faults != self.seen_faults {
            self.seen_faults = l.faults;
            self.error = if l.fault == Some(FaultCode::Overrun) {
                error::CONTROL_LOOP_OVERRUN
            } else {
                error::MOTION_ERROR
            };
        }
        if l.reference_failures != self.seen_reference_failures {
            self.seen_reference_failures = l.reference_failures;
            self.error = error::REFERENCING_FAILED;
        }
        if l.limit_stops != self.seen_limit_stops {
            // A limit switch stopped a move or an open-loop run: the slider is at the end of
            // its travel on that side.
            self.seen_limit_stops = l.limit_stops;
            self.error = error::POS_OUT_OF_LIMITS;
        }
        if board.take_store_failure() {
            self.error = error::FLASH_PROGRAM_FAILED;
        }
    }

    /// Closes the reply: a failed command (or a reply that overflowed) replies nothing and
    /// latches its error.
    fn conclude(&mut self, result: GcsResult, mut out: Out, start: usize) {
        out.finish();
        let result = if out.ok { result } else { Err(error::COMMAND_TOO_LONG) };
        if let Err(code) = result {
            out.buf.truncate(start);
            self.error = code;
            self.drr = None;
        }
    }

    /// A query (or what only latches an error) on a snapshot: no lock.
    pub(super) fn run_query(&mut self, parsed: &Parsed, snap: &Snapshot, board: &mut dyn Board, out: Out) {
        self.latch(&snap.latch, board);
        self.drr = None;
        let start = out.buf.len();
        let mut out = out;
        let result = match parsed {
            Parsed::Byte(0x04) => {
                out.line();
                write_register(&mut out, status_register(self.error, snap));
                Ok(())
            }
            Parsed::Byte(0x05) => {
                out.line();
                out.u(u64::from(snap.in_motion()));
                Ok(())
            }
            Parsed::Byte(0x07) => {
                out.line();
                out.b(&[if snap.referencing() { 0xB0 } else { 0xB1 }]);
                Ok(())
            }
            Parsed::Empty => Ok(()),
            Parsed::Refused(code) => Err(*code),
            Parsed::Line(c, tokens) => match c.run {
                Run::Query(run) => run(
                    self,
                    Query { args: tokens.get(1..).unwrap_or_default(), ctl: snap, board, out: &mut out },
                ),
                _ => Err(error::UNKNOWN_COMMAND),
            },
            Parsed::Byte(_) => Err(error::UNKNOWN_COMMAND),
        };
        self.conclude(result, out, start);
        // The recorder's trigger 2 (any command but `DRT`), after the reply as on the
        // controller, from the snapshot.
        if let Some(rec) = board.recorder() {
            rec.on_command(snap);
        }
    }

    /// A settings command on a copy of the snapshot's settings: no lock. The new settings, when
    /// they differ from the snapshot's, for the board to set.
    pub(super) fn run_settings(
        &mut self,
        parsed: &Parsed,
        snap: &Snapshot,
        board: &mut dyn Board,
        out: Out,
    ) -> Option<ControllerConfig> {
        self.latch(&snap.latch, board);
        self.drr = None;
        let start = out.buf.len();
        let mut cfg = *snap.config();
        let result = match parsed {
            Parsed::Line(c, tokens) => match c.run {
                Run::Settings(run) => {
                    run(self, Settings { args: tokens.get(1..).unwrap_or_default(), cfg: &mut cfg })
                }
                _ => Err(error::UNKNOWN_COMMAND),
            },
            _ => Err(error::UNKNOWN_COMMAND),
        };
        let ok = result.is_ok();
        self.conclude(result, out, start);
        if let Some(rec) = board.recorder() {
            rec.on_command(snap);
        }
        (ok && cfg != *snap.config()).then_some(cfg)
    }

    /// Any other command, on the controller (locked by the caller).
    pub(super) fn run_locked(
        &mut self,
        parsed: &Parsed,
        ctl: &mut Controller,
        board: &mut dyn Board,
        out: Out,
    ) {
        self.latch(&Latch::of(ctl), board);
        self.drr = None;
        let start = out.buf.len();
        let result = match parsed {
            Parsed::Byte(0x18) => {
                ctl.stop();
                Err(error::STOPPED)
            }
            Parsed::Line(c, tokens) => match c.run {
                // A parameter store parks the drive and writes the flash: nothing may start
                // meanwhile.
                Run::Line(_) if board.store_pending() && WAIT_FOR_STORE.contains(&c.name) => {
                    Err(error::CONTROLLER_BUSY)
                }
                Run::Line(run) => run(self, Call { args: tokens.get(1..).unwrap_or_default(), ctl, board }),
                _ => Err(error::UNKNOWN_COMMAND),
            },
            _ => Err(error::UNKNOWN_COMMAND),
        };
        // The recorder's trigger 2: any command but the `DRT` that sets it.
        if let Some(rec) = board.recorder() {
            if !matches!(parsed, Parsed::Line(c, _) if c.name == "DRT") {
                rec.on_command(ctl);
            }
        }
        self.conclude(result, out, start);
    }
}

/// `HLP?`: the table above, one line per command (it lives beside the table it lists).
fn hlp_query(_gcs: &mut Gcs, c: Query) -> GcsResult {
    let Query { args, out, .. } = c;
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
