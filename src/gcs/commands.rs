//! The command table and dispatch: [`Command`], [`COMMANDS`] (in `HLP?` order),
//! [`WAIT_FOR_STORE`], and [`Gcs::execute`] with what it needs to pick a handler
//! ([`Gcs::is_read_only`], [`Gcs::is_settings_only`]).

use super::args::no_args;
use super::call::{Call, GcsResult, Handler};
use super::framing::{is_space, Out, Pending};
use super::info::{cst_query, csv_query, idn_query, sai_query, xlt_query};
use super::motion::{frf, hlt, mov, mvr, pos, ron, stp, svo, xos};
use super::settings::{
    acc, acc_query, dec, dec_query, hpa_query, spa, spa_query, tmn_query, tmx_query, vel, vel_query, wpa,
};
use super::state::{
    err_query, frf_query, mov_query, ont_query, pos_query, ron_query, svo_query, xda_query, xdf_query,
    xft_query, xpf_query, xtm_query,
};
use super::{datarec, error, Board, Gcs, Reply, MAX_TOKENS};
use crate::controller::{Controller, FaultCode};

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

/// The commands, in the order `HLP?` lists them; the line commands' handlers are in the group
/// modules (`info`, `motion`, `settings`, `state`, `datarec`), one handler each, named after the
/// command (`…_query` for `…?`).
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

impl Gcs {
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
}

/// `HLP?`: the table above, one line per command (it lives beside the table it lists).
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
