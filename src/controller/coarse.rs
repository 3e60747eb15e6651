//! Coarse mode: the sine drive, its voltage from the inverse thrust model (feedforward: profile
//! speed plus position feedback, against the load observer's estimate), or plain PI without the
//! model.

use super::{Controller, State, DAC_SAMPLES_PER_STEP};
use crate::fastmath::clamp_sym_f32;

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
        let half = 0.5 * self.generator.amplitude_v();
        let room = self.fine_room_v();
        let up = half.min(room - self.fine_offset_v);
        let down = half.min(room + self.fine_offset_v);
        (up + down).max(0.0)
    }

    pub(super) fn coarse(&mut self, err_nm: f32) {
        let v_ref = self.profile.velocity_nm_s();
        let mut v_cmd = v_ref + self.cfg.kp_per_s * err_nm;
        if self.profile.done() {
            // Final approach outside the fine range: below ~0.2 mm/s the model's crawl speeds are
            // not worth trusting, so approach at a speed the motor surely makes.
            v_cmd = err_nm.signum() * v_cmd.abs().max(self.cfg.approach_speed_nm_s);
        }
        let mut dir: i8 = if v_cmd >= 0.0 { 1 } else { -1 };
        let stall = self.cached_limits().map_or(0.0, |(stall, _)| stall);
        let volts = if self.cfg.feedforward {
            // Load observer (the thrust model run forwards): what the applied drive pushes at the
            // measured speed, less what accelerated the mass, is what the load took.
            let d = f32::from(self.generator.direction());
            // Observe only while the drive pushes the way the slider moves at a fair speed: the
            // model is least certain when braking and near standstill (stick).
            let backslide = self.state() == State::Moving && d * self.speed_nm_s < -50_000.0;
            let observe =
                (d * self.speed_nm_s > 200_000.0 || backslide) && self.drive_v > 0.2 * self.cfg.max_drive_v;
            let applied = if observe || self.speedup.is_some() {
                self.model
                    .table
                    .as_ref()
                    .map_or(0.0, |t| t.thrust_n(self.swing_v(), d * self.speed_nm_s * 1e-6))
            } else {
                0.0
            };
            self.time_speedup(d * applied);
            if observe {
                let mass = self.moving_mass_kg();
                let accel = (self.speed_nm_s - self.prev_speed_nm_s) / self.dt_s * 1e-9;
                let sample = d * applied - mass * accel;
                // Sliding back under drive means the load is far above the estimate: learn faster.
                let gain = if backslide { 0.02 } else { 0.005 };
                self.observed_bias_n += gain * (sample - self.observed_bias_n);
                // What the integral built while the slider lagged is the load the observer is
                // learning now: hand it over at the observer's rate, or both push and the
                // slider runs ahead.
                self.integral_n -= gain * self.integral_n;
            }
            // The integral on the position error corrects what the model gets wrong.
            let mut integral_rate = self.cfg.ki_n_per_nm_s * err_nm;
            let stuck = d * self.speed_nm_s < APPROACH_STUCK_SHARE * self.cfg.approach_speed_nm_s;
            if self.profile.done() && stuck {
                // Final approach and the slider does not move: near the foot's slip threshold
                // the model's crawl is least certain. At 5 N preload a 0.3 kg carriage stopped
                // 550 nm short of a 10 µm step at 13 V, where the model has it moving at
                // 0.2 mm/s, and the integral alone took 89 ms to settle it (now 18 ms; its 1 mm
                // move 1.51 → 1.24× the limit). So push harder, reaching the stall force within
                // [`APPROACH_RAMP_S`], or slower for a heavy carriage: under a push rising at
                // F/T it reaches the approach speed v after √(2·τ·T), τ = M·v/F, when the push
                // has risen by F·√(2·τ/T). A tenth of F at most asks T ≥ 200·τ (50 kg: 0.5 s; at
                // 20 ms the 50 kg carriage overshot 1 mm against an unknown 2 N by 322 nm).
                let answer_s = self.moving_mass_kg() * self.cfg.approach_speed_nm_s * 1e-9 / stall.max(1e-3);
                let ramp_s = APPROACH_RAMP_S.max(APPROACH_RAMP_ANSWER_TIMES * answer_s);
                integral_rate += err_nm.signum() * stall / ramp_s;
            }
            self.integral_n = clamp_sym_f32(self.integral_n + integral_rate * self.dt_s, stall);
            self.thrust_bias_n = clamp_sym_f32(self.observed_bias_n + self.integral_n, stall);
            // Inertia of the profile's acceleration is part of the load (F = M·a).
            let mass = self.moving_mass_kg();
            // While braking, what the observer learned beyond the known load (told, or shared by
            // the moves each way) is not counted on to help when it opposes the motion: it is a
            // real load or the model's thrust error, and the error goes with the drive (at 5 N
            // preload the model's thrust at cruise was 0.9 N high; fed forward as a load that
            // would brake the slider, it kept the drive forward and the 1 kg carriage overshot
            // 1 mm by 677 nm, now 94). A real unknown load then brakes a little more than planned,
            // and the approach finishes.
            let braking = self.accel_ref_nm_s2 * v_ref < 0.0;
            let bias_along = f32::from(dir) * self.thrust_bias_n;
            let known_along = f32::from(dir) * self.known_load_n();
            let counted =
                if braking { known_along + (bias_along - known_along).min(0.0) } else { bias_along };
            let load_along = counted + f32::from(dir) * mass * self.accel_ref_nm_s2 * 1e-9;
            self.model
                .table
                .as_ref()
                .map_or(0.0, |t| t.voltage_for(v_cmd.abs() * 1e-6, load_along, self.drive_v))
        } else {
            // No model: PI from position error straight to signed volts. The integral stops
            // while the output is saturated the same way (anti-windup).
            let max_v = self.cfg.max_drive_v;
            let p_term = self.cfg.fb_kp_v_per_nm * err_nm;
            let unclamped = p_term + self.integral_v;
            let pushing_limit = unclamped.abs() >= max_v && unclamped * err_nm > 0.0;
            if !pushing_limit {
                self.integral_v =
                    clamp_sym_f32(self.integral_v + self.cfg.fb_ki_v_per_nm_s * err_nm * self.dt_s, max_v);
            }
            let signed = p_term + self.integral_v;
            dir = if signed >= 0.0 { 1 } else { -1 };
            signed.abs().min(max_v)
        };
        self.drive_v = volts;
        // While the sine runs the foot slides anyway: bring the static offset back to centre,
        // within a few milliseconds. Until it is, the sine has less room in the amplifier's range:
        // at the old 45 ms for a ±23 V hold offset, a move started from a hold lost thrust over
        // its whole speed-up (1 mm: 0.9–2.8 µm peak following error against 0.55 from rest).
        let recentre = 100.0 * self.dt_s * self.fine_room_v();
        self.fine_offset_v -= clamp_sym_f32(self.fine_offset_v, recentre);
        self.generator.ramp_static_offsets_v([self.fine_offset_v; 2], DAC_SAMPLES_PER_STEP as u32);
        self.generator.set_direction(dir);
        self.generator.set_frequency_hz(self.coarse_frequency_hz());
        self.generator.set_amplitude_v(volts);
    }
}
