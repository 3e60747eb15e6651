//! Online trapezoidal motion profile: every step moves the reference toward the target at the
//! highest speed from which it can still stop (v = √(2·a·distance)), within the speed and
//! acceleration limits. A new target (or new limits) mid-move is simply followed from the present
//! position and velocity, so re-planning is continuous by construction.

use crate::fastmath::sqrt_f32;

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Profile {
    pos_nm: i64,
    frac_nm: f32,
    vel_nm_s: f32,
    target_nm: i64,
    done: bool,
}

impl Profile {
    pub fn at_rest(pos_nm: i64) -> Self {
        Profile { pos_nm, frac_nm: 0.0, vel_nm_s: 0.0, target_nm: pos_nm, done: true }
    }

    pub fn set_target(&mut self, target_nm: i64) {
        self.target_nm = target_nm;
        self.done = self.target_nm == self.pos_nm && self.vel_nm_s == 0.0;
    }

    /// Replaces the profile by one at rest at `pos_nm` (used by stop and fault recovery).
    pub fn reset(&mut self, pos_nm: i64) {
        *self = Profile::at_rest(pos_nm);
    }

    pub fn target_nm(&self) -> i64 {
        self.target_nm
    }
    pub fn position_nm(&self) -> i64 {
        self.pos_nm
    }
    pub fn velocity_nm_s(&self) -> f32 {
        self.vel_nm_s
    }
    pub fn done(&self) -> bool {
        self.done
    }

    /// Where a stop at `accel` would end from the present state.
    pub fn stopping_point_nm(&self, accel_nm_s2: f32) -> i64 {
        let a = accel_nm_s2.max(1.0);
        let d = self.vel_nm_s * self.vel_nm_s.abs() / (2.0 * a);
        self.pos_nm.saturating_add(d as i64)
    }

    /// Advances one period `dt_s`: speeds up at most at `accel`, slows down at most at `decel`
    /// (a piezo motor brakes harder than it accelerates: reverse drive adds to the friction).
    pub fn step(&mut self, dt_s: f32, v_max_nm_s: f32, accel_nm_s2: impl FnOnce() -> f32, decel_nm_s2: f32) {
        if self.done {
            return;
        }
        let a_down = decel_nm_s2.max(1.0);
        let rem = (self.target_nm - self.pos_nm) as f32 - self.frac_nm;
        let dir = if rem >= 0.0 { 1.0 } else { -1.0 };
        // Discrete braking curve: from v, braking at a each step of dt covers exactly the
        // remaining distance when v = √(2·a·d + (a·dt/2)²) − a·dt/2.
        let half = 0.5 * a_down * dt_s;
        let v_stop = sqrt_f32(2.0 * a_down * rem.abs() + half * half) - half;
        let v_des = dir * v_max_nm_s.max(0.0).min(v_stop.max(0.0));
        let speeding_up = v_des * self.vel_nm_s >= 0.0 && v_des.abs() > self.vel_nm_s.abs();
        let a = if speeding_up { accel_nm_s2().max(1.0) } else { a_down };
        let dv = crate::fastmath::clamp_sym_f32(v_des - self.vel_nm_s, a * dt_s);
        self.vel_nm_s += dv;
        let step = self.vel_nm_s * dt_s;
        // Arrive when this step would reach the target and the speed is one a stop can absorb.
        if rem.abs() < 0.5 || (step * dir > 0.0 && step.abs() >= rem.abs()) {
            self.pos_nm = self.target_nm;
            self.frac_nm = 0.0;
            self.vel_nm_s = 0.0;
            self.done = true;
            return;
        }
        let total = self.frac_nm + step;
        let whole = (total as i64) as f32; // truncation toward zero
        self.pos_nm = self.pos_nm.saturating_add(total as i64);
        self.frac_nm = total - whole;
    }
}
