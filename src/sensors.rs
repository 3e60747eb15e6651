//! Encoder unwrapping and the preload force cell.

/// Unwraps the timer's 16-bit quadrature count (as embassy's `Qei` gives it) into a 64-bit
/// position. Valid as long as the slider moves less than half the counter range per read.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Encoder {
    last_raw: u16,
    counts: i64,
    last_delta: i32,
    nm_per_count: i64,
}

impl Encoder {
    pub fn new(first_raw: u16, nm_per_count: u32) -> Self {
        Encoder {
            last_raw: first_raw,
            counts: 0,
            last_delta: 0,
            nm_per_count: i64::from(nm_per_count.max(1)),
        }
    }

    /// Takes a new raw reading; returns the count change since the last one.
    pub fn update(&mut self, raw: u16) -> i32 {
        let delta = i32::from(raw.wrapping_sub(self.last_raw) as i16);
        self.last_raw = raw;
        self.counts = self.counts.saturating_add(i64::from(delta));
        self.last_delta = delta;
        delta
    }

    pub fn counts(&self) -> i64 {
        self.counts
    }
    pub fn last_delta(&self) -> i32 {
        self.last_delta
    }
    pub fn position_nm(&self) -> i64 {
        self.counts.saturating_mul(self.nm_per_count)
    }
    pub fn nm_per_count(&self) -> i64 {
        self.nm_per_count
    }
    /// Declares the present position to be `position_nm` (referencing).
    pub fn set_position_nm(&mut self, position_nm: i64) {
        // In 32 bits: this runs in the control tick (at the reference mark), where a 64-bit
        // division is a software routine (`.ci/elf-gate`). Positions beyond ±2.1 m are outside
        // any travel and clamp. `nm_per_count` ≥ 1 (see `new`): the checked form only keeps a
        // panic path out.
        let p = position_nm.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32;
        let per = i32::try_from(self.nm_per_count).unwrap_or(i32::MAX);
        self.counts = i64::from(p.checked_div(per).unwrap_or(p));
    }
}

/// Calibration of the preload force cell: `force = (word − zero_word) · newton_per_word`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PreloadCalibration {
    pub zero_word: u16,
    pub newton_per_word: f32,
    /// Raw words at or beyond these mean a broken or saturated sensor.
    pub min_valid_word: u16,
    pub max_valid_word: u16,
    /// First-order filter coefficient per sample (0..1]; 1 = no filtering.
    pub filter_alpha: f32,
}

/// Filtered preload reading with a validity flag.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PreloadCell {
    cal: PreloadCalibration,
    filtered_n: f32,
    primed: bool,
    valid: bool,
}

impl PreloadCell {
    pub fn new(cal: PreloadCalibration) -> Self {
        PreloadCell { cal, filtered_n: 0.0, primed: false, valid: false }
    }

    pub fn update(&mut self, word: u16) {
        self.valid = word > self.cal.min_valid_word && word < self.cal.max_valid_word;
        if !self.valid {
            return;
        }
        let n = (f32::from(word) - f32::from(self.cal.zero_word)) * self.cal.newton_per_word;
        if self.primed {
            let a = crate::fastmath::clamp_f32(self.cal.filter_alpha, 1e-4, 1.0);
            self.filtered_n += a * (n - self.filtered_n);
        } else {
            self.filtered_n = n;
            self.primed = true;
        }
    }

    /// The calibration the cell reads with.
    pub fn calibration(&self) -> PreloadCalibration {
        self.cal
    }

    /// Filtered force (N); meaningful only while [`Self::valid`].
    pub fn force_n(&self) -> f32 {
        self.filtered_n
    }
    pub fn valid(&self) -> bool {
        self.valid && self.primed
    }
}
