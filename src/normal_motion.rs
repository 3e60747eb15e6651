//! The stator's normal periodic motion in the core (f32): the copy of host-sim's
//! `steady_contact::ContactProfile::new` (issue 28 item 3), whose contact force feeds the
//! carriage's orbit ([`crate::contact_orbit`]).
//!
//! The two-mass stator (foot and counterweight, eqs. 4 and 6) under the stacks' normal force
//! `F̂·cos φ` (eq. 3), the preload through the preload spring and the contact spring–dashpot
//! (eq. 10 with the restitution's damping) switched on while the foot presses. Each contact state
//! is linear, so a step is its exact transition: the matrix exponential of the state augmented
//! with the drive's cos/sin and a constant, computed here once per operating point. A step in
//! which the foot lands or lifts is halved until the switch is located to 1/2^(8 + [`LEVELS`]) of
//! the period. From the static equilibrium the drive ramps up over [`RAMP_S`] as the plant's
//! does (a bouncing foot settles into another pattern without it); once the motion repeats, one
//! more period on the [`FINE`] sub-steps gives the contact force.
//!
//! Where the f64 model compares whole periods of contact impulses to see the motion repeat, this
//! copy compares the stator's state at the periods' starts (a period is a deterministic map of
//! it, so one repeats where the other does), which needs 48 states instead of 48 periods of
//! impulses: 0.8 KB instead of 48 KB. What the f64 model keeps and this copy refuses, with an
//! error: a true subharmonic (a pattern of periods that differ by more than the landing's
//! rounding) and a motion that never repeats (chaotic bouncing).

use crate::contact_orbit::{edge_phases, ContactForce, ForceBuilder, ForceError, BASE_STEPS, FINE};
use heapless::Deque;

/// Halvings of a base step that locate a contact switch: to 1/2^20 of the period.
pub const LEVELS: usize = 12;
/// The fine sub-steps' level: [`FINE`] = 2^4.
const FINE_LEVEL: usize = 4;
const _: () = assert!(FINE == 1 << FINE_LEVEL && BASE_STEPS == 256);
/// The drive's amplitude ramps up over this time, as the plant is driven.
pub const RAMP_S: f32 = 0.01;
/// Periods the normal motion may take to repeat.
pub const MAX_PERIODS: u16 = 600;
/// The longest repeating pattern looked for, in periods.
pub const MAX_PATTERN: usize = 16;
/// A pattern whose periods' base-step forces differ from the first's by less than this share of
/// the preload (mean over the period) is the landing's rounding, not a subharmonic: its last
/// period stands for it. (The f64 model's test is half this against the pattern's mean.)
const ROUNDING_SHARE: f32 = 2e-3;
/// Two periods' start states are the same motion where they differ by less than this share of
/// the preload in the forces they put on the foot (see [`Stator::distance_weights_n`]). At 1e-5
/// the landing's f32 rounding kept the bouncing foot at 5 N from ever repeating; at 1e-4 and 3e-4
/// the core's speeds over issue 28's grid stayed within 0.2 % of the f64 model's (at 3e-4 the 5 N
/// point at 2.2 kHz settles in 244 periods, at 1e-4 in 443); at 1e-3 one point was 0.54 % off.
const REPEAT_SHARE: f32 = 3e-4;
/// Positions are kept in µm, speeds in µm per base step: every entry of the transitions then
/// lies within a few units.
const LENGTH_UNIT_M: f32 = 1e-6;

/// The stator's normal dynamics (eqs. 4, 6, 10): masses, springs and their dashpots.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Stator {
    pub foot_mass_kg: f32,
    pub counterweight_mass_kg: f32,
    /// The stacks' and the frame's stiffness between foot and counterweight, `k1 = kT + kS`.
    pub stack_n_per_m: f32,
    pub preload_spring_n_per_m: f32,
    /// Dashpots of the stack (foot–counterweight) and the preload spring.
    pub stack_damping_n_s_per_m: f32,
    pub preload_damping_n_s_per_m: f32,
    /// The contact spring `kc` and its dashpot, acting while the foot presses.
    pub contact_n_per_m: f32,
    pub contact_damping_n_s_per_m: f32,
}

/// The drive and the preload the normal motion runs at.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NormalDrive {
    pub frequency_hz: f32,
    /// Amplitude of the stacks' normal force on the foot (N), eq. (3), after the drive's gain.
    pub normal_force_n: f32,
    pub preload_n: f32,
}

/// Why no contact force came out.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ProfileError {
    /// A frequency, mass, stiffness or preload that is not positive and finite.
    BadInput,
    /// The motion repeats only over this many periods, which differ by more than rounding.
    Subharmonic(u8),
    /// The motion did not repeat within [`MAX_PERIODS`].
    Unsettled,
    /// The force did not fit [`ContactForce`].
    Force(ForceError),
}

/// The settled contact force and how it was found.
#[derive(Debug, Clone)]
pub struct Profile {
    pub force: ContactForce,
    /// Periods run from the static equilibrium, and the repeating pattern's length.
    pub periods: u16,
    pub pattern: u8,
}

type M7 = [[f32; 7]; 7];
type V7 = [f32; 7];

/// The normal motion at one operating point: its exact transitions per contact state and level.
pub struct NormalMotion {
    /// `[free, pressing][level]`: exp(A·h/2^level), A over [y1, v1·h, y2, v2·h, a·cos φ, a·sin φ,
    /// 1] with lengths in [`LENGTH_UNIT_M`] and time in base steps h.
    t: [[M7; LEVELS + 1]; 2],
    /// The contact force per state unit: kc·L and c3·L/h (N).
    kc_n: f32,
    c3_n: f32,
    /// The static equilibrium's state, and the weights of [`Stator::state_distance_n`].
    rest: V7,
    weights_n: [f32; 4],
    preload_n: f32,
    ramp_steps: f32,
}

impl Stator {
    /// The state matrix per base step (dimensionless, see [`NormalMotion::t`]).
    fn state_matrix(&self, d: &NormalDrive, anchor_n: f32, contact: bool) -> Option<M7> {
        let (m1, m2) = (self.foot_mass_kg, self.counterweight_mass_kg);
        let (k1, k2, c1, c2) = (
            self.stack_n_per_m,
            self.preload_spring_n_per_m,
            self.stack_damping_n_s_per_m,
            self.preload_damping_n_s_per_m,
        );
        let (kc, c3) =
            if contact { (self.contact_n_per_m, self.contact_damping_n_s_per_m) } else { (0.0, 0.0) };
        let h = 1.0 / (d.frequency_hz * BASE_STEPS as f32);
        let (h2, l) = (h * h, LENGTH_UNIT_M);
        let turn = core::f32::consts::TAU / BASE_STEPS as f32;
        let a = [
            [0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0],
            [
                -(k1 + kc) * h2 / m1,
                -(c1 + c3) * h / m1,
                k1 * h2 / m1,
                c1 * h / m1,
                d.normal_force_n * h2 / (m1 * l),
                0.0,
                0.0,
            ],
            [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0],
            [
                k1 * h2 / m2,
                c1 * h / m2,
                -(k1 + k2) * h2 / m2,
                -(c1 + c2) * h / m2,
                -d.normal_force_n * h2 / (m2 * l),
                0.0,
                anchor_n * h2 / (m2 * l),
            ],
            [0.0, 0.0, 0.0, 0.0, 0.0, -turn, 0.0],
            [0.0, 0.0, 0.0, 0.0, turn, 0.0, 0.0],
            [0.0; 7],
        ];
        a.iter().flatten().all(|x| x.is_finite()).then_some(a)
    }

    /// How far apart two start states are, in newtons of the forces they put on the foot: the
    /// contact spring and dashpot, and the stack's spring and dashpot.
    fn distance_weights_n(&self, h: f32) -> [f32; 4] {
        let l = LENGTH_UNIT_M;
        [
            self.contact_n_per_m * l,
            self.contact_damping_n_s_per_m * l / h,
            self.stack_n_per_m * l,
            self.stack_damping_n_s_per_m * l / h,
        ]
    }
}

impl NormalMotion {
    /// The transitions at an operating point.
    pub fn new(s: &Stator, d: &NormalDrive) -> Result<Self, ProfileError> {
        let positive = [
            d.frequency_hz,
            d.preload_n,
            s.foot_mass_kg,
            s.counterweight_mass_kg,
            s.stack_n_per_m,
            s.preload_spring_n_per_m,
            s.contact_n_per_m,
        ];
        let damping = [s.stack_damping_n_s_per_m, s.preload_damping_n_s_per_m, s.contact_damping_n_s_per_m];
        if !positive.iter().all(|x| x.is_finite() && *x > 0.0)
            || !damping.iter().chain([&d.normal_force_n]).all(|x| x.is_finite() && *x >= 0.0)
        {
            return Err(ProfileError::BadInput);
        }
        // Static equilibrium with the preload (as the plant starts): the contact carries it, the
        // stack passes it to the counterweight, the preload spring's anchor holds it.
        let y1 = d.preload_n / s.contact_n_per_m;
        let y2 = y1 + d.preload_n / s.stack_n_per_m;
        let anchor_n = s.preload_spring_n_per_m * y2 + d.preload_n;
        let h = 1.0 / (d.frequency_hz * BASE_STEPS as f32);
        let mut t = [[[[0.0f32; 7]; 7]; LEVELS + 1]; 2];
        for (levels, contact) in t.iter_mut().zip([false, true]) {
            let a = s.state_matrix(d, anchor_n, contact).ok_or(ProfileError::BadInput)?;
            let mut scale = 1.0f32;
            for m in levels.iter_mut() {
                *m = expm(&scaled(&a, scale));
                scale *= 0.5;
            }
        }
        Ok(NormalMotion {
            t,
            kc_n: s.contact_n_per_m * LENGTH_UNIT_M,
            c3_n: s.contact_damping_n_s_per_m * LENGTH_UNIT_M / h,
            rest: [y1 / LENGTH_UNIT_M, 0.0, y2 / LENGTH_UNIT_M, 0.0, 0.0, 0.0, 1.0],
            weights_n: s.distance_weights_n(h),
            preload_n: d.preload_n,
            ramp_steps: round_half_up(RAMP_S * d.frequency_hz * BASE_STEPS as f32).max(1.0),
        })
    }

    /// The contact force of state z (N): the spring and dashpot while the foot presses.
    #[inline(always)]
    fn force_n(&self, z: &V7) -> f32 {
        if z[0] > 0.0 {
            let f = self.kc_n * z[0] + self.c3_n * z[1];
            if f > 0.0 {
                f
            } else {
                0.0
            }
        } else {
            0.0
        }
    }

    #[inline(always)]
    fn pressing(&self, z: &V7) -> bool {
        z[0] > 0.0 && self.kc_n * z[0] + self.c3_n * z[1] > 0.0
    }

    /// Advances z over a step of level `lvl`, halved where the contact state changes within it;
    /// returns the contact impulse in N·base steps (trapezoid per piece).
    fn advance(&self, z: &mut V7, lvl: usize) -> f32 {
        let contact = self.pressing(z);
        let Some(t) = self.t.get(usize::from(contact)).and_then(|levels| levels.get(lvl)) else {
            return 0.0;
        };
        let next = apply(t, z);
        if self.pressing(&next) == contact || lvl >= LEVELS {
            let share = 1.0 / (1u32 << lvl) as f32;
            let impulse = if contact { 0.5 * (self.force_n(z) + self.force_n(&next)) * share } else { 0.0 };
            *z = next;
            return impulse;
        }
        self.advance(z, lvl + 1) + self.advance(z, lvl + 1)
    }

    /// [`Self::advance`] without the impulse, for the periods before the motion repeats: one
    /// transition where the contact state holds over the step, else its two halves.
    fn advance_state(&self, z: &mut V7, lvl: usize) {
        let contact = self.pressing(z);
        let Some(t) = self.t.get(usize::from(contact)).and_then(|levels| levels.get(lvl)) else {
            return;
        };
        let next = apply(t, z);
        if self.pressing(&next) == contact || lvl >= LEVELS {
            *z = next;
            return;
        }
        self.advance_state(z, lvl + 1);
        self.advance_state(z, lvl + 1);
    }

    /// [`Self::advance`] over one base step as [`FINE`] sub-steps: each one's mean force (N).
    fn fine_step(&self, z: &mut V7) -> [f32; FINE] {
        core::array::from_fn(|_| self.advance(z, FINE_LEVEL) * FINE as f32)
    }

    /// The distance of two start states in the foot's forces (N).
    fn distance_n(&self, a: &[f32; 4], b: &[f32; 4]) -> f32 {
        a.iter().zip(b).zip(&self.weights_n).map(|((a, b), w)| (a - b).abs() * w).sum()
    }

    /// Runs the motion from the static equilibrium until it repeats, then the contact force of
    /// its settled period.
    pub fn settle(&self) -> Result<Profile, ProfileError> {
        let mut z = self.rest;
        let phases = edge_phases();
        // The last 3·MAX_PATTERN periods' start states, newest last; per pattern length k, for
        // how many periods in a row the newest has equalled the one k before it.
        let mut starts: Deque<[f32; 4], { 3 * MAX_PATTERN }> = Deque::new();
        let mut streak = [0u16; MAX_PATTERN + 1];
        let limit_n = REPEAT_SHARE * self.preload_n;
        let mut step_count = 0.0f32;
        for period in 1..=MAX_PERIODS {
            for (c, s) in phases.iter().take(BASE_STEPS) {
                // The drive's amplitude ramps as the plant's does, held over each step.
                step_count += 1.0;
                let amplitude = (step_count / self.ramp_steps).min(1.0);
                z[4] = amplitude * c;
                z[5] = amplitude * s;
                self.advance_state(&mut z, 0);
            }
            let now = [z[0], z[1], z[2], z[3]];
            if starts.is_full() {
                starts.pop_front();
            }
            // Room was made above; a full deque cannot happen here.
            let _ = starts.push_back(now);
            let n = starts.len();
            for (k, run) in streak.iter_mut().enumerate().skip(1) {
                let repeats = n
                    .checked_sub(k + 1)
                    .and_then(|i| starts.iter().nth(i))
                    .is_some_and(|before| self.distance_n(&now, before) < limit_n);
                *run = if repeats { run.saturating_add(1) } else { 0 };
            }
            // The shortest pattern that has repeated: one period that repeats the last, or k > 1
            // periods seen three times in a row (a decaying transient can pass for a shorter
            // pattern for a period or two).
            let seen = |k: usize| if k == 1 { 1 } else { 2 * k as u16 };
            let found =
                (1..=MAX_PATTERN).find(|&k| period > 3 && streak.get(k).is_some_and(|r| *r >= seen(k)));
            if let Some(k) = found {
                let force = self.pattern_force(&mut z, k)?;
                return Ok(Profile { force, periods: period.saturating_add(k as u16), pattern: k as u8 });
            }
        }
        Err(ProfileError::Unsettled)
    }

    /// The contact force over a repeating pattern of k periods, run on the fine sub-steps: its
    /// last period, where its periods differ by rounding only.
    fn pattern_force(&self, z: &mut V7, k: usize) -> Result<ContactForce, ProfileError> {
        let mut first = [0.0f32; BASE_STEPS];
        let mut spread_n = 0.0f32;
        let mut builder = ForceBuilder::new();
        for p in 0..k {
            let mut differs_n = 0.0f32;
            for first_n in first.iter_mut() {
                let sub = self.fine_step(z);
                if p + 1 == k {
                    builder.push(sub);
                }
                let base_n = sub.iter().sum::<f32>() / FINE as f32;
                if p == 0 {
                    *first_n = base_n;
                } else {
                    differs_n += (base_n - *first_n).abs();
                }
            }
            spread_n = spread_n.max(differs_n / BASE_STEPS as f32);
        }
        if spread_n >= ROUNDING_SHARE * self.preload_n {
            return Err(ProfileError::Subharmonic(k as u8));
        }
        builder.finish().map_err(ProfileError::Force)
    }
}

/// The normal motion's settled contact force at an operating point.
pub fn contact_force(s: &Stator, d: &NormalDrive) -> Result<Profile, ProfileError> {
    NormalMotion::new(s, d)?.settle()
}

/// x rounded to the nearest whole number (x ≥ 0; `f32::round` is not in `core`).
fn round_half_up(x: f32) -> f32 {
    (x + 0.5) as i32 as f32
}

fn scaled(a: &M7, by: f32) -> M7 {
    a.map(|row| row.map(|x| x * by))
}

/// a·b. The state matrices' rows 4–6 (drive and constant) are zero but for their own block,
/// so zero entries of `a` are skipped: about half the products.
fn mul(a: &M7, b: &M7) -> M7 {
    let mut out = [[0.0f32; 7]; 7];
    for (o, ar) in out.iter_mut().zip(a) {
        for (aik, br) in ar.iter().zip(b) {
            if *aik == 0.0 {
                continue;
            }
            for (oj, bkj) in o.iter_mut().zip(br) {
                *oj += aik * bkj;
            }
        }
    }
    out
}

/// t·z for a transition: rows 0–3 the stator, rows 4–5 the drive's rotation (its other entries
/// are zero), row 6 the constant. Written out: this is the normal motion's inner loop.
#[inline(always)]
fn apply(t: &M7, z: &V7) -> V7 {
    let row = |r: &[f32; 7]| {
        r[0] * z[0] + r[1] * z[1] + r[2] * z[2] + r[3] * z[3] + r[4] * z[4] + r[5] * z[5] + r[6] * z[6]
    };
    [
        row(&t[0]),
        row(&t[1]),
        row(&t[2]),
        row(&t[3]),
        t[4][4] * z[4] + t[4][5] * z[5],
        t[5][4] * z[4] + t[5][5] * z[5],
        z[6],
    ]
}

/// exp(a) by scaling and squaring: a/2^s with a row-sum norm under 1/2, its Taylor series to
/// the power whose remainder falls under 1e-8 (at most the 8th), squared s times.
fn expm(a: &M7) -> M7 {
    let norm = a.iter().map(|row| row.iter().map(|x| x.abs()).sum::<f32>()).fold(0.0f32, f32::max);
    let mut squarings = 0u32;
    let mut scale = 1.0f32;
    while norm * scale > 0.5 && squarings < 30 {
        scale *= 0.5;
        squarings += 1;
    }
    let m = scaled(a, scale);
    // Terms: the first n whose next one, ‖m‖^(n+1)/(n+1)!, is under 1e-8.
    let (mut terms, mut next) = (1u8, norm * scale);
    while next > 1e-8 && terms < 8 {
        terms += 1;
        next *= norm * scale / f32::from(terms);
    }
    let identity: M7 = core::array::from_fn(|i| core::array::from_fn(|j| if i == j { 1.0 } else { 0.0 }));
    // Horner: I + m(I + m/2(I + m/3(...))).
    let mut e = identity;
    for k in (1..=terms).rev() {
        let me = scaled(&mul(&m, &e), 1.0 / f32::from(k));
        e = identity;
        for (er, mr) in e.iter_mut().zip(me) {
            for (x, y) in er.iter_mut().zip(mr) {
                *x += y;
            }
        }
    }
    for _ in 0..squarings {
        e = mul(&e, &e);
    }
    e
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_exponential_of_a_rotation_turns_by_its_angle() {
        // exp([[0, −θ], [θ, 0]]) is the rotation by θ: cos θ, sin θ (θ = 2 rad needs squarings).
        let mut a = [[0.0f32; 7]; 7];
        a[4][5] = -2.0;
        a[5][4] = 2.0;
        let e = expm(&a);
        assert!((e[4][4] - 2f32.cos()).abs() < 1e-6 && (e[5][4] - 2f32.sin()).abs() < 1e-6, "{:?}", e[4]);
        assert!((e[0][0] - 1.0).abs() < 1e-7 && e[0][1] == 0.0);
    }

    #[test]
    fn bad_input_is_refused() {
        let s = Stator {
            foot_mass_kg: 0.06,
            counterweight_mass_kg: 1.0,
            stack_n_per_m: 2.7e7,
            preload_spring_n_per_m: 1e5,
            stack_damping_n_s_per_m: 10.0,
            preload_damping_n_s_per_m: 10.0,
            contact_n_per_m: 2e9,
            contact_damping_n_s_per_m: 2e4,
        };
        let d = NormalDrive { frequency_hz: 0.0, normal_force_n: 30.0, preload_n: 16.0 };
        assert_eq!(contact_force(&s, &d).err(), Some(ProfileError::BadInput));
        let d = NormalDrive { frequency_hz: 1500.0, normal_force_n: f32::NAN, preload_n: 16.0 };
        assert_eq!(contact_force(&s, &d).err(), Some(ProfileError::BadInput));
    }
}
