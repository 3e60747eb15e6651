//! The data recorder behind GCS `DRC`/`DRT`/`RTR`/`DRR?` (and `DRC?`, `DRT?`, `RTR?`, `DRL?`,
//! `TNR?`, `HDR?`): [`TABLES`] record tables of [`DEPTH`] points each in one fixed buffer,
//! filled once per control tick from the controller's public state after `step`
//! ([`Recorder::sample`]), read back by the protocol (`gcs::datarec`).
//!
//! Memory: `TABLES × DEPTH` i32 points, 8 × 1 024 × 4 = 32 768 bytes, plus a few words per table
//! (PI's controllers record at least 1 024 points per table; PIPython's datarectools reads the depth
//! from parameter 0x16000201).
//! A point is an integer in the option's own unit (nm, mV, mHz, mN, a state code): the tick only
//! stores, the protocol formats (`gcs::datarec`).
//!
//! Sharing: every field is an atomic, so the recorder is used through `&Recorder` from the tick
//! and from the protocol at once without a lock (on the board it is a `static`, zero-initialised:
//! all tables record nothing, rate 1, trigger 0). Relaxed loads and stores of 32-bit atomics are
//! plain loads and stores on the Cortex-M4. Points below a table's count are never written again
//! until the table restarts, so a reader sees whole points. What restarts or reconfigures a table
//! (`DRC`, `DRT`, `RTR`, a trigger by `MOV`/`MVR`/`XOS`) must not run concurrently with
//! [`Recorder::sample`]: on the board those commands run with the tick masked, as every command
//! that is not a query does. The one exception, the start of an armed table by trigger 2 (next
//! command, which may be a query), is safe beside the tick ([`Recorder::on_command`]). Breaking that rule garbles data, never memory: every index is
//! checked.
//!
//! Time: a recording starts at its trigger with point 1, the state at that moment (the command
//! has just been accepted, before the next step), then one point every `RTR` ticks, after the
//! step. Point k (1-based) is thus `(k − 1) · RTR` periods after the trigger, as PI's
//! `SAMPLE_TIME` says. A table that fills stops at [`DEPTH`] points (its `DRL?` says `DEPTH`).

use crate::controller::{Controller, State};
use core::sync::atomic::{AtomicI32, AtomicU32, Ordering};

/// Record tables (`TNR?`).
pub const TABLES: usize = 8;
/// Points per table: what the build gives it ([`crate::hardware::RECORDER_DEPTH`]).
pub const DEPTH: usize = crate::hardware::RECORDER_DEPTH;
/// Bytes of recorded points.
pub const BUFFER_BYTES: usize = TABLES * DEPTH * core::mem::size_of::<i32>();
/// Largest record rate (`RTR`): one point per 65 535 ticks (6.5 s at 10 kHz).
pub const MAX_RATE: u32 = u16::MAX as u32;

/// A point that has no value (the preload sensor's reading invalid): printed as `nan`.
pub const NO_VALUE: i32 = i32::MIN;

/// Record options: what a table records (`DRC <table> 1 <option>`). PI's numbers where PI has
/// the quantity (1, 2, 3), ours from 256 on (PI's list stops well below).
pub mod option {
    pub const NOTHING: u32 = 0;
    /// The profile's commanded position now (nm; `DRR?` in mm).
    pub const COMMANDED_POSITION: u32 = 1;
    /// The encoder position (nm; mm).
    pub const ACTUAL_POSITION: u32 = 2;
    /// Commanded minus actual position (nm; mm).
    pub const POSITION_ERROR: u32 = 3;
    /// Drive amplitude (mV peak-to-peak; V).
    pub const DRIVE_AMPLITUDE: u32 = 256;
    /// Drive frequency (mHz; Hz).
    pub const DRIVE_FREQUENCY: u32 = 257;
    /// Preload force from the force cell (mN; N), [`super::NO_VALUE`] when the reading is invalid.
    pub const PRELOAD_FORCE: u32 = 258;
    /// Controller state: 0 idle, 1 moving, 2 holding, 3 referencing, 4 open-loop stepping,
    /// 10 + fault code in a fault.
    pub const CONTROLLER_STATE: u32 = 259;
}

/// Every record option: its number, what it is and its unit, for `HDR?` (`2=Actual position of
/// axis (mm)`) and the `NAME` of a `DRR?` column (`Actual position of axis 1 (mm)`).
pub const OPTIONS: &[(u32, &str, &str)] = &[
    (option::NOTHING, "Nothing is recorded", ""),
    (option::COMMANDED_POSITION, "Commanded position", "mm"),
    (option::ACTUAL_POSITION, "Actual position", "mm"),
    (option::POSITION_ERROR, "Position error", "mm"),
    (option::DRIVE_AMPLITUDE, "Drive amplitude", "V peak-to-peak"),
    (option::DRIVE_FREQUENCY, "Drive frequency", "Hz"),
    (option::PRELOAD_FORCE, "Preload force", "N"),
    (
        option::CONTROLLER_STATE,
        "Controller state",
        "0 idle, 1 moving, 2 holding, 3 referencing, 4 open loop, 10 + fault code",
    ),
];

/// Trigger options (`DRT <table> <trigger> 0`): PI's numbers.
pub mod trigger {
    /// The default: as [`ANY_MOVE`].
    pub const DEFAULT: u32 = 0;
    /// Every command that changes the target (`MOV`, `MVR`, `XOS`) starts the recording anew.
    pub const ANY_MOVE: u32 = 1;
    /// The next command of any kind after `DRT` starts the recording (PIPython's default).
    pub const NEXT_COMMAND: u32 = 2;
    /// `DRT` itself starts the recording.
    pub const IMMEDIATELY: u32 = 4;
    /// The next command that changes the target starts the recording; later ones leave it.
    pub const NEXT_MOVE: u32 = 6;
}

/// Every trigger option and its `HDR?` text.
pub const TRIGGERS: &[(u32, &str)] = &[
    (trigger::DEFAULT, "Default setting: as 1"),
    (trigger::ANY_MOVE, "Any command changing the target position (MOV, MVR, XOS) restarts recording"),
    (trigger::NEXT_COMMAND, "Next command, then reset"),
    (trigger::IMMEDIATELY, "Immediately"),
    (trigger::NEXT_MOVE, "Next command changing the target position (MOV, MVR, XOS), then reset"),
];

/// Why a recorder command was refused (the protocol maps each to its GCS error).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RecorderError {
    /// No such record table (GCS 57).
    UnknownTable,
    /// No such record option (GCS 58).
    UnknownOption,
    /// No such trigger option, or a rate out of 1..=[`MAX_RATE`] (GCS 17).
    OutOfRange,
}

/// What a table is doing.
mod phase {
    /// Nothing recorded since the table was configured or armed; waiting for its trigger.
    pub const ARMED: u32 = 0;
    pub const RECORDING: u32 = 1;
    /// Stopped: full.
    pub const FULL: u32 = 2;
}

struct Table {
    option: AtomicU32,
    trigger: AtomicU32,
    phase: AtomicU32,
    /// Points recorded.
    count: AtomicU32,
    /// Ticks since the last point.
    ticks: AtomicU32,
    /// Ticks per point of the recording under way (`RTR` when it started).
    rate: AtomicU32,
    points: [AtomicI32; DEPTH],
}

impl Table {
    const fn new() -> Self {
        Table {
            option: AtomicU32::new(option::NOTHING),
            trigger: AtomicU32::new(trigger::DEFAULT),
            phase: AtomicU32::new(phase::ARMED),
            count: AtomicU32::new(0),
            ticks: AtomicU32::new(0),
            rate: AtomicU32::new(0),
            points: [const { AtomicI32::new(0) }; DEPTH],
        }
    }

    /// Forgets the points; waits for the trigger again.
    fn arm(&self) {
        self.phase.store(phase::ARMED, Ordering::Relaxed);
        self.count.store(0, Ordering::Relaxed);
    }

    /// Point 1 now, then one every `rate` ticks.
    fn start(&self, rate: u32, ctl: &impl Source) {
        let opt = self.option.load(Ordering::Relaxed);
        if opt == option::NOTHING {
            return;
        }
        if let Some(p) = self.points.first() {
            p.store(point(opt, ctl), Ordering::Relaxed);
        }
        self.count.store(1, Ordering::Relaxed);
        self.ticks.store(0, Ordering::Relaxed);
        self.rate.store(rate, Ordering::Relaxed);
        // Last: the tick takes the table as recording only with the rest in place.
        self.phase.store(phase::RECORDING, Ordering::Release);
    }
}

/// The record tables and the record rate.
pub struct Recorder {
    tables: [Table; TABLES],
    /// `RTR` − 1 (so that all-zero memory is the power-up state).
    rate_minus_one: AtomicU32,
}

impl Default for Recorder {
    fn default() -> Self {
        Self::new()
    }
}

/// `v` rounded to the nearest integer, saturating (NaN → 0); no `std` needed.
fn round_i32(v: f32) -> i32 {
    (if v >= 0.0 { v + 0.5 } else { v - 0.5 }) as i32
}

fn nm_i32(nm: i64) -> i32 {
    nm.clamp(i64::from(i32::MIN + 1), i64::from(i32::MAX)) as i32
}

/// The state code of option 259.
pub fn state_code(s: State) -> i32 {
    match s.number() {
        Ok(n) => i32::from(n),
        Err(code) => 10 + code as i32,
    }
}

/// What a point is taken from: the controller, or a snapshot of it (a query's, so that the
/// "next command" trigger can fire after a query has answered, without the controller).
pub trait Source {
    fn reference_nm(&self) -> i64;
    fn position_nm(&self) -> i64;
    fn drive_voltage_v(&self) -> f32;
    fn drive_frequency_hz(&self) -> f32;
    fn preload_n(&self) -> Option<f32>;
    fn state(&self) -> State;
}

impl Source for Controller {
    fn reference_nm(&self) -> i64 {
        Controller::reference_nm(self)
    }
    fn position_nm(&self) -> i64 {
        Controller::position_nm(self)
    }
    fn drive_voltage_v(&self) -> f32 {
        Controller::drive_voltage_v(self)
    }
    fn drive_frequency_hz(&self) -> f32 {
        Controller::drive_frequency_hz(self)
    }
    fn preload_n(&self) -> Option<f32> {
        Controller::preload_n(self)
    }
    fn state(&self) -> State {
        Controller::state(self)
    }
}

/// The point option `opt` records for the controller as it is now.
#[inline]
fn point(opt: u32, ctl: &impl Source) -> i32 {
    match opt {
        option::COMMANDED_POSITION => nm_i32(ctl.reference_nm()),
        option::ACTUAL_POSITION => nm_i32(ctl.position_nm()),
        option::POSITION_ERROR => nm_i32(ctl.reference_nm().saturating_sub(ctl.position_nm())),
        option::DRIVE_AMPLITUDE => round_i32(ctl.drive_voltage_v() * 1000.0),
        option::DRIVE_FREQUENCY => round_i32(ctl.drive_frequency_hz() * 1000.0),
        option::PRELOAD_FORCE => {
            ctl.preload_n().map_or(NO_VALUE, |f| round_i32(f * 1000.0).max(NO_VALUE + 1))
        }
        option::CONTROLLER_STATE => state_code(ctl.state()),
        _ => 0,
    }
}

/// Decimals a point of option `opt` is printed with (its integer unit is 10^-decimals of the
/// protocol's: nm → mm is 6).
pub fn decimals(opt: u32) -> u32 {
    match opt {
        option::COMMANDED_POSITION | option::ACTUAL_POSITION | option::POSITION_ERROR => 6,
        option::DRIVE_AMPLITUDE | option::DRIVE_FREQUENCY | option::PRELOAD_FORCE => 3,
        _ => 0,
    }
}

/// Whether `opt` is a record option this recorder has.
pub fn known_option(opt: u32) -> bool {
    OPTIONS.iter().any(|(o, _, _)| *o == opt)
}

/// Whether `t` is a trigger option this recorder has.
pub fn known_trigger(t: u32) -> bool {
    TRIGGERS.iter().any(|(o, _)| *o == t)
}

impl Recorder {
    /// The power-up state: every table records nothing, trigger 0, rate 1 (all zero bits).
    pub const fn new() -> Self {
        Recorder { tables: [const { Table::new() }; TABLES], rate_minus_one: AtomicU32::new(0) }
    }

    /// Table `id` (1-based).
    fn table(&self, id: usize) -> Result<&Table, RecorderError> {
        id.checked_sub(1).and_then(|i| self.tables.get(i)).ok_or(RecorderError::UnknownTable)
    }

    /// Checks a table id (1-based).
    pub fn check_table(id: usize) -> Result<(), RecorderError> {
        if (1..=TABLES).contains(&id) {
            Ok(())
        } else {
            Err(RecorderError::UnknownTable)
        }
    }

    /// `DRC`: table `id` records `opt` from now on; its points are forgotten and it waits for
    /// its trigger.
    pub fn configure(&self, id: usize, opt: u32) -> Result<(), RecorderError> {
        let t = self.table(id)?;
        if !known_option(opt) {
            return Err(RecorderError::UnknownOption);
        }
        t.arm();
        t.option.store(opt, Ordering::Relaxed);
        Ok(())
    }

    /// The record option of table `id`.
    pub fn option(&self, id: usize) -> Result<u32, RecorderError> {
        Ok(self.table(id)?.option.load(Ordering::Relaxed))
    }

    /// `DRT`: table `id` (0: every table) waits for trigger `trig` (its points are forgotten);
    /// [`trigger::IMMEDIATELY`] starts it now, with `ctl` as it is.
    pub fn set_trigger(&self, id: usize, trig: u32, ctl: &Controller) -> Result<(), RecorderError> {
        if id != 0 {
            self.table(id)?;
        }
        if !known_trigger(trig) {
            return Err(RecorderError::OutOfRange);
        }
        let rate = self.rate();
        for (i, t) in self.tables.iter().enumerate() {
            if id == 0 || id == i + 1 {
                t.arm();
                t.trigger.store(trig, Ordering::Relaxed);
                if trig == trigger::IMMEDIATELY {
                    t.start(rate, ctl);
                }
            }
        }
        Ok(())
    }

    /// The trigger option of table `id`.
    pub fn trigger(&self, id: usize) -> Result<u32, RecorderError> {
        Ok(self.table(id)?.trigger.load(Ordering::Relaxed))
    }

    /// `RTR`: one point every `rate` ticks, for recordings that start from now on.
    pub fn set_rate(&self, rate: u32) -> Result<(), RecorderError> {
        if !(1..=MAX_RATE).contains(&rate) {
            return Err(RecorderError::OutOfRange);
        }
        self.rate_minus_one.store(rate - 1, Ordering::Relaxed);
        Ok(())
    }

    /// `RTR?`.
    pub fn rate(&self) -> u32 {
        self.rate_minus_one.load(Ordering::Relaxed).min(MAX_RATE - 1) + 1
    }

    /// Ticks per point of table `id`'s recording (the rate when it started; `RTR` before any).
    pub fn table_rate(&self, id: usize) -> Result<u32, RecorderError> {
        let t = self.table(id)?;
        Ok(match t.rate.load(Ordering::Relaxed) {
            0 => self.rate(),
            r => r,
        })
    }

    /// `DRL?`: points recorded in table `id` ([`DEPTH`] once full).
    pub fn points(&self, id: usize) -> Result<usize, RecorderError> {
        let n = self.table(id)?.count.load(Ordering::Acquire) as usize;
        Ok(n.min(DEPTH))
    }

    /// Point `index` (0-based) of table `id`, if recorded.
    pub fn point(&self, id: usize, index: usize) -> Option<i32> {
        let t = self.table(id).ok()?;
        if index >= t.count.load(Ordering::Acquire) as usize {
            return None;
        }
        t.points.get(index).map(|p| p.load(Ordering::Relaxed))
    }

    /// A command that changes the target (`MOV`, `MVR`, `XOS`) was accepted: the tables
    /// waiting for one start, with `ctl` as it is now.
    pub fn on_move(&self, ctl: &Controller) {
        let rate = self.rate();
        for t in &self.tables {
            let fire = match t.trigger.load(Ordering::Relaxed) {
                trigger::DEFAULT | trigger::ANY_MOVE => true,
                trigger::NEXT_MOVE => t.phase.load(Ordering::Relaxed) == phase::ARMED,
                _ => false,
            };
            if fire {
                t.start(rate, ctl);
            }
        }
    }

    /// A command other than `DRT` ran: the tables waiting for the next command start, with
    /// `ctl` as it is now. Only an armed table starts, which the tick does not touch until its
    /// phase says recording (stored last): safe beside the tick, so a query (which the board runs
    /// without holding the tick off) may be that command.
    pub fn on_command(&self, ctl: &impl Source) {
        let rate = self.rate();
        for t in &self.tables {
            if t.trigger.load(Ordering::Relaxed) == trigger::NEXT_COMMAND
                && t.phase.load(Ordering::Relaxed) == phase::ARMED
            {
                t.start(rate, ctl);
            }
        }
    }

    /// Once per control tick, after `Controller::step`: a point in every recording table
    /// whose rate says so. A few loads and stores per recording table.
    pub fn sample(&self, ctl: &Controller) {
        for t in &self.tables {
            if t.phase.load(Ordering::Acquire) != phase::RECORDING {
                continue;
            }
            let ticks = t.ticks.load(Ordering::Relaxed).wrapping_add(1);
            if ticks < t.rate.load(Ordering::Relaxed) {
                t.ticks.store(ticks, Ordering::Relaxed);
                continue;
            }
            t.ticks.store(0, Ordering::Relaxed);
            let n = t.count.load(Ordering::Relaxed) as usize;
            match t.points.get(n) {
                Some(p) => {
                    p.store(point(t.option.load(Ordering::Relaxed), ctl), Ordering::Relaxed);
                    t.count.store(n as u32 + 1, Ordering::Release);
                    if n + 1 >= DEPTH {
                        t.phase.store(phase::FULL, Ordering::Relaxed);
                    }
                }
                None => t.phase.store(phase::FULL, Ordering::Relaxed),
            }
        }
    }
}
