//! What the queries and the settings commands read of the controller, copied in the short
//! locked section they need ([`Snapshot::take`]) instead of a copy of the whole controller
//! (3 KiB with its model table): the settings, the state's scalars, and the counters that
//! latch the errors the controller ran into on its own ([`Latch`]).

use crate::controller::model_cache::{TableModelKind, ThrustInputs};
use crate::controller::{Controller, ControllerConfig, FaultCode, State};
use crate::recorder::Source;

/// The controller's own error counters, read before each command (see `Gcs::latch`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Latch {
    pub faults: u32,
    pub fault: Option<FaultCode>,
    pub reference_failures: u32,
    pub limit_stops: u32,
}

impl Latch {
    pub fn of(ctl: &Controller) -> Self {
        Latch {
            faults: ctl.fault_count(),
            fault: ctl.fault(),
            reference_failures: ctl.reference_failure_count(),
            limit_stops: ctl.limit_stop_count(),
        }
    }
}

/// The controller as a query sees it: the values of its accessors at one instant, under the
/// same names, so that a query reads the same through a snapshot as from the controller.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Snapshot {
    config: ControllerConfig,
    /// The settings' generation (a settings change prepared from this snapshot names it).
    config_generation: u32,
    state: State,
    servo: bool,
    referenced: bool,
    referencing: bool,
    in_motion: bool,
    on_target: bool,
    position_nm: i64,
    target_nm: i64,
    reference_nm: i64,
    preload_n: Option<f32>,
    drive_voltage_v: f32,
    drive_frequency_hz: f32,
    /// Only when asked for (`XTM?`): what the thrust limits read, evaluated off the lock (they
    /// may cost a model point).
    thrust: Option<ThrustInputs>,
    /// The model the table in use came from (`XTS?`).
    table_model: Option<TableModelKind>,
    /// The limit switches as the controller sees them (`LIM?`, `#4`).
    limit_switches: crate::controller::LimitSwitches,
    pub latch: Latch,
}

impl Snapshot {
    /// The locked section of a query or a settings command. `thrust`: also the thrust limits
    /// (`XTM?`).
    pub fn take(ctl: &Controller, thrust: bool) -> Self {
        Snapshot {
            config: *ctl.config(),
            config_generation: ctl.config_generation(),
            state: ctl.state(),
            servo: ctl.servo(),
            referenced: ctl.referenced(),
            referencing: ctl.referencing(),
            in_motion: ctl.in_motion(),
            on_target: ctl.on_target(),
            position_nm: ctl.position_nm(),
            target_nm: ctl.target_nm(),
            reference_nm: ctl.reference_nm(),
            preload_n: ctl.preload_n(),
            drive_voltage_v: ctl.drive_voltage_v(),
            drive_frequency_hz: ctl.drive_frequency_hz(),
            table_model: ctl.table_model(),
            limit_switches: ctl.limit_switches(),
            thrust: thrust.then(|| ctl.thrust_inputs()),
            latch: Latch::of(ctl),
        }
    }

    pub fn config(&self) -> &ControllerConfig {
        &self.config
    }
    pub fn config_generation(&self) -> u32 {
        self.config_generation
    }
    pub fn state(&self) -> State {
        self.state
    }
    pub fn servo(&self) -> bool {
        self.servo
    }
    pub fn referenced(&self) -> bool {
        self.referenced
    }
    pub fn referencing(&self) -> bool {
        self.referencing
    }
    pub fn in_motion(&self) -> bool {
        self.in_motion
    }
    pub fn on_target(&self) -> bool {
        self.on_target
    }
    pub fn position_nm(&self) -> i64 {
        self.position_nm
    }
    pub fn target_nm(&self) -> i64 {
        self.target_nm
    }
    pub fn preload_n(&self) -> Option<f32> {
        self.preload_n
    }
    pub fn drive_voltage_v(&self) -> f32 {
        self.drive_voltage_v
    }
    pub fn limit_switches(&self) -> crate::controller::LimitSwitches {
        self.limit_switches
    }

    pub fn table_model(&self) -> Option<TableModelKind> {
        self.table_model
    }

    pub fn drive_frequency_hz(&self) -> f32 {
        self.drive_frequency_hz
    }
    pub fn fault(&self) -> Option<FaultCode> {
        self.latch.fault
    }
    /// As [`Controller::thrust_limits`] when the snapshot was taken with `thrust`; else None.
    pub fn thrust_limits(&self) -> Option<(f32, f32)> {
        self.thrust.and_then(|t| t.limits())
    }
}

/// The data recorder's "next command" trigger fires on a query after it has answered, from the
/// snapshot the query was answered from.
impl Source for Snapshot {
    fn reference_nm(&self) -> i64 {
        self.reference_nm
    }
    fn position_nm(&self) -> i64 {
        self.position_nm
    }
    fn drive_voltage_v(&self) -> f32 {
        self.drive_voltage_v
    }
    fn drive_frequency_hz(&self) -> f32 {
        self.drive_frequency_hz
    }
    fn preload_n(&self) -> Option<f32> {
        self.preload_n
    }
    fn state(&self) -> State {
        self.state
    }
}
