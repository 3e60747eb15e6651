//! Referencing (GCS `FRF`): open-loop drive toward the mark (encoder index or negative limit
//! switch), the reference set where it is found.

use super::{Activity, Controller, Inputs, ReferenceSignal};

/// A search for the reference mark: direction, control periods spent, and whether an index
/// search fell back to the negative limit switch.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct ReferenceSearch {
    direction: i8,
    elapsed_ticks: u32,
    on_limit: bool,
}

impl ReferenceSearch {
    /// Toward −x first.
    pub(super) fn start() -> Self {
        ReferenceSearch { direction: -1, elapsed_ticks: 0, on_limit: false }
    }

    /// The drive's direction (±1).
    pub(super) fn direction(&self) -> i8 {
        self.direction
    }
}

impl Controller {
    pub(super) fn reference(&mut self, inputs: &Inputs) {
        let Activity::Referencing(mut search) = self.status.activity else { return };
        let here = self.position_nm();
        // No profile to follow while searching: keep the reference on the slider.
        self.motion.profile_mut().reset(here);
        let found = match self.cfg.reference_signal {
            ReferenceSignal::Index if search.on_limit => inputs.negative_limit,
            ReferenceSignal::Index => inputs.index,
            ReferenceSignal::NegativeLimit => inputs.negative_limit,
        };
        if found {
            let mut at = self.cfg.reference_position_nm;
            if let (ReferenceSignal::Index, false, Some(raw), Some(e)) =
                (self.cfg.reference_signal, search.on_limit, inputs.index_raw, self.feedback.encoder())
            {
                // Counts moved since the latched edge (well within ±2¹⁵ in one period).
                let since = i64::from(inputs.encoder_raw.wrapping_sub(raw) as i16);
                at = at.saturating_add(since.saturating_mul(e.nm_per_count()));
            }
            self.set_reference_here(at);
            self.end_open_loop_motion();
            return;
        }
        if self.cfg.reference_signal == ReferenceSignal::Index && !search.on_limit {
            if inputs.negative_limit && search.direction < 0 {
                search.direction = 1;
            } else if inputs.positive_limit && search.direction > 0 {
                // The whole travel without an index: the scale has none. Back to the negative
                // limit switch and reference on it.
                search.on_limit = true;
                search.direction = -1;
            }
        }
        search.elapsed_ticks = search.elapsed_ticks.saturating_add(1);
        self.status.activity = Activity::Referencing(search);
        if search.elapsed_ticks > self.cfg.ticks_for_s(self.cfg.reference_timeout_s) {
            return self.reference_failed();
        }
        self.drive.generator.set_direction(search.direction);
        self.drive.generator.set_frequency_hz(self.cfg.drive_freq_hz);
        self.drive.generator.set_amplitude_v(self.cfg.reference_drive_v);
        self.drive.commanded_v = self.cfg.reference_drive_v;
    }

    pub(super) fn reference_failed(&mut self) {
        self.supervisor.note_reference_failure();
        self.status.referenced = false;
        self.end_open_loop_motion();
    }
}
