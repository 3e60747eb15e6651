//! The drive frequencies a model table may be built at ([`FrequencyChoice`]): what a request
//! carries for the build to choose from. The choosing itself is `frequency.rs`.

use crate::model::PerVolt;

/// Most drive frequencies a request offers the table build to choose from.
pub const FREQ_CANDIDATES: usize = 12;

/// Candidate spacing at least (Hz): the motor table's own frequency step.
const FREQ_CANDIDATE_STEP_HZ: f32 = 100.0;

/// The drive frequencies a table may be built at, with the per-volt amplitudes at each: the build
/// drives where the model with the carriage's mass gives the highest speed at full drive against
/// `load_n` (`ModelRequest::chosen`, in `frequency.rs`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrequencyChoice {
    pub frequency_hz: [f32; FREQ_CANDIDATES],
    pub per_volt: [PerVolt; FREQ_CANDIDATES],
    /// Candidates in use (1: the frequency is given).
    pub len: usize,
    /// Opposing load the choice is for (N).
    pub load_n: f32,
}

impl FrequencyChoice {
    /// Only `frequency_hz`, for `load_n`.
    pub fn fixed(frequency_hz: f32, per_volt: PerVolt, load_n: f32) -> Self {
        FrequencyChoice {
            frequency_hz: [frequency_hz; FREQ_CANDIDATES],
            per_volt: [per_volt; FREQ_CANDIDATES],
            len: 1,
            load_n,
        }
    }

    /// From `highest_hz` down to `lowest_hz` in steps of at least 100 Hz (at most
    /// [`FREQ_CANDIDATES`]); `per_volt(f)` gives the amplitudes at `f`.
    pub fn between(lowest_hz: f32, highest_hz: f32, load_n: f32, per_volt: impl Fn(f32) -> PerVolt) -> Self {
        let mut c = Self::fixed(highest_hz, per_volt(highest_hz), load_n);
        let span = (highest_hz - lowest_hz).max(0.0);
        let step = FREQ_CANDIDATE_STEP_HZ.max(span / (FREQ_CANDIDATES - 1) as f32);
        for k in 1..FREQ_CANDIDATES {
            let f = highest_hz - step * k as f32;
            if f < lowest_hz - 1e-3 {
                break;
            }
            if let (Some(slot_f), Some(slot_p)) = (c.frequency_hz.get_mut(k), c.per_volt.get_mut(k)) {
                (*slot_f, *slot_p) = (f, per_volt(f));
                c.len = k + 1;
            }
        }
        c
    }
}
