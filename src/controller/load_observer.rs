//! The load estimate the coarse mode's feedforward pushes against (N along +x): an observer (the
//! thrust model run forwards: what the applied drive pushes at the measured speed, less what
//! accelerated the mass, is what the load took) plus an integral on the position error (what the
//! model gets wrong), and what the last moves each way ended with.

use crate::fastmath::clamp_sym_f32;

/// The observer's share of each sample: normally, and while the slider slides back under drive
/// (the load is then far above the estimate: learn faster).
const OBSERVER_GAIN: f32 = 0.005;
const OBSERVER_GAIN_FAST: f32 = 0.02;

/// The settings the load estimate uses.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct LoadObserverConfig {
    /// The told load along +x (N): where the estimate starts.
    pub(super) expected_load_n: f32,
    /// Integral gain on the position error (N per nm·s).
    pub(super) ki_n_per_nm_s: f32,
    /// Feedforward on: without it there is no estimate to carry between moves.
    pub(super) feedforward: bool,
}

/// One coarse period's evidence about the load.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct LoadSample {
    /// What the model says the load took along +x (N: thrust less M·a), when the drive pushes
    /// the way the slider moves at a fair speed; None otherwise (the model is least certain).
    pub(super) observed_n: Option<f32>,
    /// The slider slides back under drive: learn faster.
    pub(super) backslide: bool,
    /// Reference − position (nm).
    pub(super) err_nm: f32,
    /// Extra integral rate (N/s) for a stuck final approach.
    pub(super) push_n_s: Option<f32>,
    pub(super) dt_s: f32,
    /// The model's stall force (N): bounds the integral and the estimate.
    pub(super) stall_n: f32,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct LoadObserver {
    cfg: LoadObserverConfig,
    /// The observer's estimate (N along +x).
    observed_n: f32,
    /// Load correction integrated from position error (N).
    integral_n: f32,
    /// Observer plus integral, bounded by the stall force (N): what the feedforward uses.
    estimate_n: f32,
    /// The estimate (observer plus integral) at the end of the last move each way (+, −) ...
    end_n: [Option<f32>; 2],
    /// ... and the sense of the last move (0: +x, 1: −x).
    last_sense: Option<usize>,
}

impl LoadObserver {
    pub(super) fn new(cfg: LoadObserverConfig) -> Self {
        LoadObserver {
            cfg,
            observed_n: cfg.expected_load_n,
            integral_n: 0.0,
            estimate_n: cfg.expected_load_n,
            end_n: [None; 2],
            last_sense: None,
        }
    }

    /// New settings; `forget` (a new motor calibration, see the settings' `invalidates`): what
    /// was learned was the old model's error, so the estimate starts again from the told load.
    pub(super) fn configure(&mut self, cfg: LoadObserverConfig, forget: bool) {
        self.cfg = cfg;
        if forget {
            self.observed_n = cfg.expected_load_n;
            self.integral_n = 0.0;
            self.estimate_n = cfg.expected_load_n;
            self.end_n = [None; 2];
        }
    }

    /// The load estimate the feedforward pushes against (N along +x).
    pub(super) fn estimate_n(&self) -> f32 {
        self.estimate_n
    }

    /// The sense of the last move commanded (+1 or −1 along x).
    pub(super) fn move_sense(&self) -> f32 {
        if self.last_sense == Some(1) {
            -1.0
        } else {
            1.0
        }
    }

    /// The load estimate a move starts from (`backward`: toward −x). What the observer learns in
    /// a move is the load plus the model's thrust error along the drive; the error changes sign
    /// with the drive, so an estimate carried into a move the other way starts it with twice the
    /// error (ten back-and-forth 1 mm moves, 1 kg carriage, plant μ 15 % below the table's:
    /// 0.71 µm peak following error on the first, 2.0–2.2 on every later one). Once a move each
    /// way has ended, the move starts from the mean of their end estimates: the load, which both
    /// share, without the error.
    pub(super) fn start_move(&mut self, backward: bool) {
        if !self.cfg.feedforward {
            return;
        }
        if let Some(slot) = self.last_sense.and_then(|s| self.end_n.get_mut(s)) {
            *slot = Some(self.observed_n + self.integral_n);
        }
        if let Some(common) = self.shared_load_n() {
            self.observed_n = common;
            self.integral_n = 0.0;
            self.estimate_n = common;
        }
        self.last_sense = Some(usize::from(backward));
    }

    /// The load a move knows is real (N along +x): what the last moves each way share, else the
    /// told one. Braking counts on it, not on the rest of the estimate.
    pub(super) fn known_load_n(&self) -> f32 {
        self.shared_load_n().unwrap_or(self.cfg.expected_load_n)
    }

    /// The mean of the end estimates of the last move each way (N along +x), once both exist.
    fn shared_load_n(&self) -> Option<f32> {
        match self.end_n {
            [Some(plus), Some(minus)] => Some(0.5 * (plus + minus)),
            _ => None,
        }
    }

    /// One coarse period: the observer takes the sample, the integral the position error; returns
    /// the new estimate (N along +x).
    pub(super) fn update(&mut self, s: &LoadSample) -> f32 {
        if let Some(sample) = s.observed_n {
            let gain = if s.backslide { OBSERVER_GAIN_FAST } else { OBSERVER_GAIN };
            self.observed_n += gain * (sample - self.observed_n);
            // What the integral built while the slider lagged is the load the observer is
            // learning now: hand it over at the observer's rate, or both push and the slider
            // runs ahead.
            self.integral_n -= gain * self.integral_n;
        }
        let mut integral_rate = self.cfg.ki_n_per_nm_s * s.err_nm;
        if let Some(push) = s.push_n_s {
            integral_rate += push;
        }
        self.integral_n = clamp_sym_f32(self.integral_n + integral_rate * s.dt_s, s.stall_n);
        self.estimate_n = clamp_sym_f32(self.observed_n + self.integral_n, s.stall_n);
        self.estimate_n
    }

    /// The load the feedforward counts along the drive `dir` (N, opposing it when positive).
    /// While braking, what the observer learned beyond the known load (told, or shared by the
    /// moves each way) is not counted on to help when it opposes the motion: it is a real load or
    /// the model's thrust error, and the error goes with the drive (at 5 N preload the model's
    /// thrust at cruise was 0.9 N high; fed forward as a load that would brake the slider, it kept
    /// the drive forward and the 1 kg carriage overshot 1 mm by 677 nm, now 94). A real unknown
    /// load then brakes a little more than planned, and the approach finishes.
    pub(super) fn counted_along_n(&self, dir: f32, braking: bool) -> f32 {
        let bias_along = dir * self.estimate_n;
        let known_along = dir * self.known_load_n();
        if braking {
            known_along + (bias_along - known_along).min(0.0)
        } else {
            bias_along
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn observer(expected_load_n: f32) -> LoadObserver {
        LoadObserver::new(LoadObserverConfig { expected_load_n, ki_n_per_nm_s: 0.0, feedforward: true })
    }

    fn sample(observed_n: Option<f32>, err_nm: f32) -> LoadSample {
        LoadSample { observed_n, backslide: false, err_nm, push_n_s: None, dt_s: 1e-4, stall_n: 10.0 }
    }

    #[test]
    fn starts_from_the_told_load() {
        let o = observer(2.0);
        assert_eq!(o.estimate_n(), 2.0);
        assert_eq!(o.known_load_n(), 2.0);
    }

    #[test]
    fn observer_is_a_first_order_filter() {
        // Constant sample s from b0: b_n = s + (b0 − s)·(1 − g)ⁿ.
        let mut o = observer(0.0);
        for _ in 0..200 {
            o.update(&sample(Some(3.0), 0.0));
        }
        let expected = 3.0 * (1.0 - (1.0f32 - OBSERVER_GAIN).powi(200));
        assert!((o.estimate_n() - expected).abs() < 1e-4, "{} vs {expected}", o.estimate_n());
    }

    #[test]
    fn backslide_learns_four_times_faster() {
        let mut o = observer(0.0);
        o.update(&LoadSample { backslide: true, ..sample(Some(1.0), 0.0) });
        assert!((o.estimate_n() - OBSERVER_GAIN_FAST).abs() < 1e-7);
    }

    #[test]
    fn integral_hands_over_to_the_observer() {
        // ki·err·dt = 1e-3 · 1000 · 1e-4 = 1e-4 N per period: 100 periods build 0.01 N.
        let mut o = LoadObserver::new(LoadObserverConfig {
            expected_load_n: 0.0,
            ki_n_per_nm_s: 1e-3,
            feedforward: true,
        });
        for _ in 0..100 {
            o.update(&sample(None, 1000.0));
        }
        assert!((o.estimate_n() - 0.01).abs() < 1e-6);
        // An observed sample equal to the estimate keeps the observer; the integral loses g of
        // itself: 0.01·(1 − 0.005) with no error left.
        o.update(&sample(Some(0.0), 0.0));
        assert!((o.estimate_n() - 0.01 * (1.0 - OBSERVER_GAIN)).abs() < 1e-7);
    }

    #[test]
    fn estimate_is_bounded_by_the_stall_force() {
        let mut o = observer(0.0);
        let s = LoadSample { push_n_s: Some(1e6), stall_n: 4.0, ..sample(None, 0.0) };
        assert_eq!(o.update(&s), 4.0);
        let s = LoadSample { push_n_s: Some(-1e6), stall_n: 4.0, ..sample(None, 0.0) };
        o.update(&s);
        assert_eq!(o.update(&s), -4.0);
    }

    #[test]
    fn moves_each_way_share_their_mean() {
        let mut o = observer(0.0);
        o.start_move(false);
        // The forward move ends at +3 N (observer only).
        for _ in 0..5000 {
            o.update(&sample(Some(3.0), 0.0));
        }
        o.start_move(true);
        assert_eq!(o.known_load_n(), 0.0, "one way only: the told load");
        for _ in 0..5000 {
            o.update(&sample(Some(1.0), 0.0));
        }
        // Closed forms of the two first-order runs: from 0 toward 3, then from there toward 1.
        let decay = (1.0f32 - OBSERVER_GAIN).powi(5000);
        let forward_end = 3.0 * (1.0 - decay);
        let backward_end = 1.0 + (forward_end - 1.0) * decay;
        o.start_move(false);
        // Both ends known: the move starts from their mean.
        let mean = 0.5 * (forward_end + backward_end);
        assert!((o.estimate_n() - mean).abs() < 1e-5);
        assert_eq!(o.known_load_n(), o.estimate_n());
        assert_eq!(o.move_sense(), 1.0);
    }

    #[test]
    fn braking_does_not_count_on_an_opposing_excess() {
        let mut o = observer(1.0);
        o.estimate_n = 3.0;
        // Driving +x against 3 N (told 1 N): all of it while speeding up, the told 1 N braking.
        assert_eq!(o.counted_along_n(1.0, false), 3.0);
        assert_eq!(o.counted_along_n(1.0, true), 1.0);
        // Driving −x the estimate assists (−3): counted in full, braking or not.
        assert_eq!(o.counted_along_n(-1.0, true), -3.0);
    }

    #[test]
    fn recalibration_forgets_what_was_learned() {
        let mut o = observer(0.0);
        o.update(&sample(Some(5.0), 0.0));
        let cfg = LoadObserverConfig { expected_load_n: 1.5, ki_n_per_nm_s: 0.0, feedforward: true };
        o.configure(cfg, false);
        assert!(o.estimate_n() != 1.5);
        o.configure(cfg, true);
        assert_eq!(o.estimate_n(), 1.5);
    }
}
