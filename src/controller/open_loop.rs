//! Open-loop stepping (GCS `XOS`, servo off): a number of drive periods at a given amplitude
//! and frequency; and the end of any open-loop motion.

use super::{Activity, Controller, Inputs};

/// An open-loop run: control periods left, amplitude (V peak-to-peak), frequency, direction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct OpenLoopRun {
    pub(super) periods: u32,
    pub(super) volts: f32,
    pub(super) frequency_hz: f32,
    pub(super) direction: i8,
}

impl Controller {
    pub(super) fn open_loop(&mut self, inputs: &Inputs) {
        let Activity::OpenLoop(mut run) = self.status.activity else { return };
        let here = self.position_nm();
        self.motion.profile_mut().reset(here);
        let blocked =
            (run.direction < 0 && inputs.negative_limit) || (run.direction > 0 && inputs.positive_limit);
        if blocked {
            self.supervisor.note_limit_stop();
        }
        if run.periods == 0 || blocked {
            return self.end_open_loop_motion();
        }
        run.periods -= 1;
        self.status.activity = Activity::OpenLoop(run);
        self.drive.generator.set_direction(run.direction);
        self.drive.generator.set_frequency_hz(run.frequency_hz);
        self.drive.generator.set_amplitude_v(run.volts);
        self.drive.commanded_v = run.volts;
    }

    /// End of referencing or open-loop stepping: hold here with the servo on, else go quiet.
    pub(super) fn end_open_loop_motion(&mut self) {
        self.drive.generator.set_amplitude_v(0.0);
        self.drive.commanded_v = 0.0;
        self.hold_here_or_quiet();
    }
}
