//! Coarse mode: the sine drive, its voltage from the inverse thrust model (feedforward: profile
//! speed plus position feedback, against the load observer's estimate), or plain PI without the
//! model.

use super::load_observer::LoadSample;
use super::{Controller, State, DAC_SAMPLES_PER_STEP};

/// In the final approach the slider counts as stuck below this share of the approach speed:
/// all of it, as the measured speed lags the slider by milliseconds (at a quarter, a 0.3 kg
/// carriage at 5 N started pushing 3.5 ms later, and 10 µm took 21 ms instead of 18).
const APPROACH_STUCK_SHARE: f32 = 1.0;
/// A stuck final approach adds thrust at a rate that reaches the stall force in this time (s).
const APPROACH_RAMP_S: f32 = 0.02;
/// ... or in this many times the time a heavy carriage takes to reach the approach speed at the
/// stall force (the push then exceeds what was missing by at most a tenth of the stall force).
const APPROACH_RAMP_ANSWER_TIMES: f32 = 200.0;

impl Controller {
    /// The sine's peak-to-peak swing the amplifier's range leaves it (V): a hold's static offset
    /// still on the stacks clips the sine on one side until it is back to centre. Without this the
    /// model's thrust at the set amplitude was too high there: a 5 kg carriage's speed-up from a
    /// hold measured it as mass (`mass.rs`; 8.8–9.1 kg against 7.7 from rest, μ 15 % low).
    fn swing_v(&self) -> f32 {
        self.fine.sine_swing_v(self.drive.generator.amplitude_v())
    }

    pub(super) fn coarse(&mut self, err_nm: f32) {
        let v_ref = self.motion.profile().velocity_nm_s();
        let mut v_cmd = v_ref + self.cfg.kp_per_s * err_nm;
        if self.motion.profile().done() {
            // Final approach outside the fine range: below ~0.2 mm/s the model's crawl speeds are
            // not worth trusting, so approach at a speed the motor surely makes.
            v_cmd = err_nm.signum() * v_cmd.abs().max(self.cfg.approach_speed_nm_s);
        }
        let mut dir: i8 = if v_cmd >= 0.0 { 1 } else { -1 };
        let volts = if self.cfg.feedforward {
            self.feedforward_v(err_nm, v_ref, v_cmd, dir)
        } else {
            let (volts, signed_dir) = self.plain_pi_v(err_nm);
            dir = signed_dir;
            volts
        };
        self.drive.commanded_v = volts;
        self.drive_sine(volts, dir);
    }

    /// The drive voltage from the inverse thrust model, after this period's load observation:
    /// the model's voltage for the commanded speed against the load estimate and the profile's
    /// inertia (F = M·a) along the drive `dir`.
    fn feedforward_v(&mut self, err_nm: f32, v_ref: f32, v_cmd: f32, dir: i8) -> f32 {
        let stall = self.cached_limits().map_or(0.0, |(stall, _)| stall);
        let sample = self.load_sample(err_nm, stall);
        self.load.update(&sample);
        let mass = self.moving_mass_kg();
        let braking = self.motion.accel_ref_nm_s2() * v_ref < 0.0;
        let counted = self.load.counted_along_n(f32::from(dir), braking);
        let load_along = counted + f32::from(dir) * mass * self.motion.accel_ref_nm_s2() * 1e-9;
        self.model
            .table()
            .map_or(0.0, |t| t.voltage_for(v_cmd.abs() * 1e-6, load_along, self.drive.commanded_v))
    }

    /// This period's evidence for the load observer (the thrust model run forwards: what the
    /// applied drive pushes at the measured speed, less what accelerated the mass, is what the
    /// load took); the same thrust times the move's speed-up ([`super::mass`]).
    fn load_sample(&mut self, err_nm: f32, stall: f32) -> LoadSample {
        let d = f32::from(self.drive.generator.direction());
        // Observe only while the drive pushes the way the slider moves at a fair speed: the
        // model is least certain when braking and near standstill (stick).
        let backslide = self.state() == State::Moving && d * self.feedback.speed_nm_s() < -50_000.0;
        let observe = (d * self.feedback.speed_nm_s() > 200_000.0 || backslide)
            && self.drive.commanded_v > 0.2 * self.cfg.max_drive_v;
        let applied = if observe || self.mass.timing() {
            self.model
                .table()
                .map_or(0.0, |t| t.thrust_n(self.swing_v(), d * self.feedback.speed_nm_s() * 1e-6))
        } else {
            0.0
        };
        self.time_speedup(d * applied);
        let observed_n = observe.then(|| {
            let mass = self.moving_mass_kg();
            let accel = (self.feedback.speed_nm_s() - self.feedback.prev_speed_nm_s()) / self.dt_s * 1e-9;
            d * applied - mass * accel
        });
        let push_n_s = self.approach_push_n_s(err_nm, d, stall);
        LoadSample { observed_n, backslide, err_nm, push_n_s, dt_s: self.dt_s, stall_n: stall }
    }

    /// Final approach and the slider does not move: near the foot's slip threshold the model's
    /// crawl is least certain. At 5 N preload a 0.3 kg carriage stopped 550 nm short of a 10 µm
    /// step at 13 V, where the model has it moving at 0.2 mm/s, and the integral alone took 89 ms
    /// to settle it (now 18 ms; its 1 mm move 1.51 → 1.24× the limit). So push harder (N/s added
    /// to the integral's rate), reaching the stall force within [`APPROACH_RAMP_S`], or slower for
    /// a heavy carriage: under a push rising at F/T it reaches the approach speed v after
    /// √(2·τ·T), τ = M·v/F, when the push has risen by F·√(2·τ/T). A tenth of F at most asks
    /// T ≥ 200·τ (50 kg: 0.5 s; at 20 ms the 50 kg carriage overshot 1 mm against an unknown 2 N
    /// by 322 nm).
    fn approach_push_n_s(&self, err_nm: f32, d: f32, stall: f32) -> Option<f32> {
        let stuck = d * self.feedback.speed_nm_s() < APPROACH_STUCK_SHARE * self.cfg.approach_speed_nm_s;
        if !(self.motion.profile().done() && stuck) {
            return None;
        }
        let answer_s = self.moving_mass_kg() * self.cfg.approach_speed_nm_s * 1e-9 / stall.max(1e-3);
        let ramp_s = APPROACH_RAMP_S.max(APPROACH_RAMP_ANSWER_TIMES * answer_s);
        Some(err_nm.signum() * stall / ramp_s)
    }

    /// No model: PI from position error straight to signed volts; the volts and the drive's sign.
    fn plain_pi_v(&mut self, err_nm: f32) -> (f32, i8) {
        let signed = self.pi.update(err_nm, self.dt_s);
        let dir = if signed >= 0.0 { 1 } else { -1 };
        (signed.abs().min(self.cfg.max_drive_v), dir)
    }

    /// The generator's writes for a coarse period: the sine at `volts` along `dir`, the static
    /// offset on its way back to centre.
    fn drive_sine(&mut self, volts: f32, dir: i8) {
        // While the sine runs the foot slides anyway: bring the static offset back to centre,
        // within a few milliseconds. Until it is, the sine has less room in the amplifier's range:
        // at the old 45 ms for a ±23 V hold offset, a move started from a hold lost thrust over
        // its whole speed-up (1 mm: 0.9–2.8 µm peak following error against 0.55 from rest).
        let offset = self.fine.recentre(self.dt_s);
        self.drive.generator.ramp_static_offsets_v([offset; 2], DAC_SAMPLES_PER_STEP as u32);
        self.drive.generator.set_direction(dir);
        self.drive.generator.set_frequency_hz(self.coarse_frequency_hz());
        self.drive.generator.set_amplitude_v(volts);
    }
}
