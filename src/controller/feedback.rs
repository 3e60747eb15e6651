//! What the sensors say each period: the encoder's position and the slider's filtered speed,
//! and the preload force cell's reading.

use crate::sensors::{Encoder, PreloadCalibration, PreloadCell};

/// Share of each period's encoder speed taken into the speed estimate: a first-order filter of
/// 20 periods (2 ms at 10 kHz).
pub(super) const SPEED_FILTER: f32 = 0.05;

#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Feedback {
    /// Encoder resolution (nm per count): fixed by the hardware.
    nm_per_count: u32,
    /// None until the first reading.
    encoder: Option<Encoder>,
    preload: PreloadCell,
    /// The slider's filtered speed (nm/s along +x) this period and the last.
    speed_nm_s: f32,
    prev_speed_nm_s: f32,
}

impl Feedback {
    pub(super) fn new(nm_per_count: u32, preload: PreloadCalibration) -> Self {
        Feedback {
            nm_per_count,
            encoder: None,
            preload: PreloadCell::new(preload),
            speed_nm_s: 0.0,
            prev_speed_nm_s: 0.0,
        }
    }

    /// New settings: a new preload calibration is re-primed by the next sample.
    pub(super) fn configure(&mut self, preload: PreloadCalibration) {
        if preload != self.preload.calibration() {
            self.preload = PreloadCell::new(preload);
        }
    }

    /// One period's readings (the encoder timer's count, the preload cell's word); true at the
    /// first (the encoder starts counting at 0 there).
    pub(super) fn update(&mut self, encoder_raw: u16, preload_word: u16, dt_s: f32) -> bool {
        self.preload.update(preload_word);
        self.prev_speed_nm_s = self.speed_nm_s;
        match self.encoder.as_mut() {
            None => {
                self.encoder = Some(Encoder::new(encoder_raw, self.nm_per_count));
                true
            }
            Some(e) => {
                let delta = e.update(encoder_raw);
                let v = delta as f32 * e.nm_per_count() as f32 / dt_s;
                // 2 ms speed filter: the encoder quantum (50 nm per 100 µs) is 0.5 mm/s.
                self.speed_nm_s += SPEED_FILTER * (v - self.speed_nm_s);
                false
            }
        }
    }

    pub(super) fn encoder(&self) -> Option<Encoder> {
        self.encoder
    }

    /// Declares the present position to be `position_nm`.
    pub(super) fn set_position_nm(&mut self, position_nm: i64) {
        if let Some(e) = self.encoder.as_mut() {
            e.set_position_nm(position_nm);
        }
    }

    pub(super) fn position_nm(&self) -> i64 {
        self.encoder.map_or(0, |e| e.position_nm())
    }

    pub(super) fn speed_nm_s(&self) -> f32 {
        self.speed_nm_s
    }

    pub(super) fn prev_speed_nm_s(&self) -> f32 {
        self.prev_speed_nm_s
    }

    /// The filtered preload (N); meaningful only while valid ([`Self::preload_n`]).
    pub(super) fn preload_force_n(&self) -> f32 {
        self.preload.force_n()
    }

    /// The preload (N) while the cell reads valid.
    pub(super) fn preload_n(&self) -> Option<f32> {
        self.preload.valid().then(|| self.preload.force_n())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 50 nm counts; preload words 100..4000 valid, 0.01 N per word from word 0, unfiltered.
    fn feedback() -> Feedback {
        let cal = PreloadCalibration {
            zero_word: 0,
            newton_per_word: 0.01,
            min_valid_word: 100,
            max_valid_word: 4000,
            filter_alpha: 1.0,
        };
        Feedback::new(50, cal)
    }

    #[test]
    fn first_reading_is_position_zero() {
        let mut f = feedback();
        assert!(f.update(1234, 1000, 1e-4));
        assert_eq!(f.position_nm(), 0);
        assert!(!f.update(1236, 1000, 1e-4));
        assert_eq!(f.position_nm(), 100);
    }

    #[test]
    fn speed_is_a_first_order_filter() {
        // One count a period: v = 50 nm / 0.1 ms = 0.5 mm/s; after n periods v·(1 − 0.95ⁿ).
        let mut f = feedback();
        f.update(0, 1000, 1e-4);
        for raw in 1..=20u16 {
            f.update(raw, 1000, 1e-4);
        }
        let expected = 5.0e5 * (1.0 - (1.0f32 - SPEED_FILTER).powi(20));
        assert!((f.speed_nm_s() - expected).abs() < 1.0, "{} vs {expected}", f.speed_nm_s());
        assert!(f.prev_speed_nm_s() < f.speed_nm_s());
    }

    #[test]
    fn preload_is_valid_inside_its_words() {
        let mut f = feedback();
        assert_eq!(f.preload_n(), None, "no reading yet");
        f.update(0, 1600, 1e-4);
        // 1600 words · 0.01 N.
        assert!(f.preload_n().is_some_and(|n| (n - 16.0).abs() < 1e-4));
        f.update(0, 4000, 1e-4);
        assert_eq!(f.preload_n(), None, "saturated");
    }
}
