//! The test double of the board the protocol talks to, shared by the GCS, property and safety
//! tests: it keeps what `WPA` stored, can fail a store or keep one pending, has a data recorder
//! and fixed loop statistics.
#![allow(dead_code)]

use piezo_drive::controller::ControllerConfig;
use piezo_drive::gcs::{Board, LoopStats};
use piezo_drive::recorder::Recorder;

#[derive(Default)]
pub struct TestBoard {
    /// What the last accepted `WPA` stored.
    pub stored: Option<ControllerConfig>,
    /// Refuse stores (as a board without usable flash).
    pub fail_store: bool,
    /// A store queued and not yet written (the board's flash task has it).
    pub store_pending: bool,
    /// A store that failed after `WPA` was acknowledged, not yet reported.
    pub store_failed: bool,
    pub recorder: Recorder,
}

impl Board for TestBoard {
    fn store_parameters(&mut self, cfg: &ControllerConfig) -> bool {
        if self.fail_store {
            return false;
        }
        self.stored = Some(*cfg);
        true
    }
    fn store_pending(&self) -> bool {
        self.store_pending
    }
    fn take_store_failure(&mut self) -> bool {
        std::mem::take(&mut self.store_failed)
    }
    fn serial_number(&self) -> u32 {
        42
    }
    fn loop_stats(&self) -> LoopStats {
        LoopStats { step_cycles_last: 12, step_cycles_max: 34, overruns: 0, core_clock_hz: 170_000_000 }
    }
    fn recorder(&self) -> Option<&Recorder> {
        Some(&self.recorder)
    }
}
