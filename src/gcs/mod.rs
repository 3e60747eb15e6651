//! PI GCS 2.0 subset over a byte stream (UART on the board, TCP or a pty in `host-sim serve`):
//! a line collector ([`Gcs::push_byte`]) and an executor ([`Gcs::execute`]) that never panic and
//! never allocate.
//!
//! Framing: one command per LF-terminated line, arguments separated by spaces, axis `1`.
//! Replies are `[args=]value` + LF; a multi-line reply ends every line but the last with space +
//! LF; no CR is ever sent. The single bytes 0x04 (`#4`), 0x05 (`#5`), 0x07 (`#7`) and 0x18
//! (`#24`) are commands of their own, without LF. A failing command replies nothing and latches a GCS error
//! number that `ERR?` returns and clears; a line with any invalid part executes nothing.
//!
//! Where things are, from the bottom up (no file imports one above it): `framing` (line
//! assembly, [`Pending`], the reply buffer), `call` (what a handler gets and returns), `args`
//! (argument checks shared by the handlers), the handlers by group: `motion` (servo,
//! referencing, moves, stops), `state` (queries of the controller's state), `settings`
//! (parameters, motion and travel limits, `WPA`), `info` (identification, loop timing),
//! [`datarec`] (the data recorder, and a `DRR?` reply that goes on over several buffers); and
//! on top `commands` ([`COMMANDS`], [`Gcs::execute`] and `HLP?`, which lists the table) and
//! [`lock`] (what runs with a shared controller locked: [`Gcs::execute_shared`]). Here:
//! the protocol state [`Gcs`], the [`Board`] interface and the [`error`] numbers.

mod args;
mod call;
mod commands;
pub mod datarec;
mod framing;
mod info;
pub mod lock;
mod motion;
pub mod num;
pub mod params;
pub mod session;
mod settings;
pub mod snapshot;
mod state;

pub use commands::{Command, COMMANDS};
pub use framing::Pending;
pub use info::{IDN_COMPATIBLE, IDN_MAKER, IDN_MODEL, IDN_VERSION, STAGE_NAME};
pub use lock::{SharedController, Unshared};
pub use session::LinkSession;
pub use state::{limit_switches, LimitSwitches};

use crate::controller::ControllerConfig;
use crate::recorder::Recorder;
use framing::Line;

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
    /// The model table's background build (`XTS?`): whether one is running, and how long the
    /// last complete one took (µs; 0 where the board builds in no time of its own, as hosts do).
    fn table_build(&self) -> TableBuildStatus {
        TableBuildStatus::default()
    }
}

/// What [`Board::table_build`] reports.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct TableBuildStatus {
    pub running: bool,
    pub last_build_us: u32,
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
    /// Referencing on a limit switch (`FNL`/`FPL`) with none wired.
    pub const NO_LIMIT_SWITCH: i32 = 32;
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
    /// Longest part of a reply that goes on ([`Gcs::set_reply_part`]).
    part_bytes: usize,
}

impl Default for Gcs {
    fn default() -> Self {
        Self::new()
    }
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
            part_bytes: REPLY_CAPACITY,
        }
    }

    /// Formats a reply that goes on over several buffers (`DRR?`) in parts of at most `bytes`
    /// (at least [`datarec::PART_MIN`], at most [`REPLY_CAPACITY`]; the header of `DRR?` is
    /// written whole): a board that must notice received bytes between parts (#24) keeps each
    /// part's formatting short. [`REPLY_CAPACITY`] until set.
    pub fn set_reply_part(&mut self, bytes: usize) {
        self.part_bytes = bytes.clamp(datarec::PART_MIN, REPLY_CAPACITY);
    }

    /// Drops what is left of a reply that goes on (`#24` cut it short).
    pub fn abandon_reply(&mut self) {
        self.drr = None;
    }

    /// The latched error (without clearing it).
    pub fn latched_error(&self) -> i32 {
        self.error
    }
}
