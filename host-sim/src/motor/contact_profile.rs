//! The stator's normal periodic motion under the drive (issue 28), whose contact force the
//! steady model with the contact's timing (`steady_contact.rs`) runs the carriage on.
//!
//! The 2-DOF stator under the stacks' normal force `F̂·cos φ`
//! (eq. 3; φ = ωt from the foot's peak forward speed, where the normal force peaks too: the
//! tangential speed is the sum of the stack strokes' rates, the normal force their difference,
//! both ∝ cos φ for the quadrature drive), with the preload through the preload spring and the
//! contact spring–dashpot of the parameter file (its damping from the restitution) switched on
//! while the foot presses. Each contact state is linear, so every step is its exact transition
//! (matrix exponential of the state augmented with the drive's cos/sin, so the sine enters
//! exactly), and a step in which the state changes is halved until the switch is located to
//! `1/2^20` of the period. It is run on [`STEPS`] steps per period from the static equilibrium
//! until its contact impulses repeat, then once more on [`FINE`]× finer steps, whose contact
//! force the carriage runs on. Where the foot lands with an impact, the impulses may repeat
//! only every few periods: the landing is located to that 1/2^20, and on the sourced
//! prototype at 5–17 N the impulses then alternate in a pattern of 2–4 periods whose periods
//! differ by 2e-5 to 2e-4 of the preload (a step's mean), while the one-period test asks 1e-5. A pattern of up to
//! [`MAX_PATTERN`] periods is then looked for: one whose periods differ by less than
//! [`ROUNDING_SHARE`] is the rounding and is kept as its mean period; a larger one (a real
//! subharmonic) is kept whole, and the carriage's orbit runs over all of it. Where the
//! foot repeats nothing within [`MAX_PERIODS`] (chaotic bouncing: 5 and 8 N at 100 V and
//! 2.1 kHz) [`UNSETTLED_PERIODS`] more periods are kept as they come
//! ([`ContactProfile::settled`] says which). Holds wherever the stator's equations do: the
//! whole band, every preload, impacts of any length.

use crate::motor::params::Params;
use crate::motor::plant::{contact_spring, state_matrix, stator_dashpots};
use crate::motor::steady::{amplitudes, OperatingPoint};
use nalgebra::SMatrix;
use std::collections::VecDeque;
use std::f64::consts::TAU;

/// Base steps per drive period: the normal motion settles on these, and the carriage's orbit
/// takes them where nothing changes within one.
pub const STEPS: usize = 256;
/// A base step is this many fine steps (2^[`FINE_LEVEL`]). The settled normal motion is run once
/// more on the fine steps and its contact force kept on them, and the orbit halves a base step
/// down to them where the contact or the interface changes within it (see
/// `ContactModel::period`).
pub const FINE: usize = 16;
pub(crate) const FINE_LEVEL: usize = 4;
/// Fine steps per drive period.
pub const FINE_STEPS: usize = STEPS * FINE;
/// The drive's amplitude ramps up over this time, as `steady_speed_m_s` drives the plant.
const RAMP_S: f64 = 0.01;
/// Halvings of a base step that locate a contact switch inside it: to 1/2^20 of the period, as
/// 1024 steps halved ten times did.
const LEVELS: usize = 12;
/// An orbit's step is halved where the contact force changes by more than this within it (the
/// landing's impact, the foot's take-off): the friction layer passes a short, high force
/// differently from its mean.
const SPLIT_FORCE_N: f64 = 0.25;
/// Periods the normal motion may take to settle before it is averaged instead.
const MAX_PERIODS: usize = 600;
/// Periods kept when the normal motion does not repeat: the carriage's orbit then runs over all
/// of them. (Averaging the contact force over them instead would smear the impacts, and the
/// friction layer passes a short, high impact differently from a low, long one.) Eight, not
/// 32: the grid and band tests move by under 0.1 % of the plant's speed, and each orbit there
/// costs a quarter; the gap workflow, which solves thousands of them, ran 1.5–3× faster (1 kg,
/// 192 rows).
pub const UNSETTLED_PERIODS: usize = 8;
/// The longest repeating pattern of the normal motion looked for, in periods: the orbit over one
/// whole pattern is the carriage's periodic motion (a physical subharmonic as much as the
/// landing's rounding, see the module's notes). The sourced prototype's paper grid (5–17 N,
/// 60 and 100 V, 0.9–2.1 kHz) shows patterns of 2–4 periods, found after 43–405 periods where
/// the one-period test ran to [`MAX_PERIODS`]; the profiles of that grid took half the periods.
pub const MAX_PATTERN: usize = 16;
/// A pattern whose periods differ from their mean by less than this share of the preload (a
/// step's mean) is the landing's rounding (2e-5 to 2e-4 on the sourced prototype's paper grid)
/// and is solved as its mean period.
pub const ROUNDING_SHARE: f64 = 1e-3;

type M7 = SMatrix<f64, 7, 7>;
type V7 = SMatrix<f64, 7, 1>;

/// The normal contact force over one settled period.
#[derive(Debug, Clone, PartialEq)]
pub struct ContactProfile {
    /// Σ of the mean contact force over the fine steps before i (N·steps): any run's mean in two
    /// reads ([`Self::contact_n`] for the steps themselves). The fine steps cover one whole
    /// repeating pattern (one or more periods) when the motion settled, else
    /// [`UNSETTLED_PERIODS`] in a row. Only the sums are kept: the gap workflow holds ten
    /// thousand profiles, and fresh memory for them was a twentieth of its time.
    prefix_n: Vec<f64>,
    contact_fraction: f64,
    /// Per base step (each [`FINE`] fine steps), which of its halves, quarters, ... the orbit may
    /// take whole ([`even_force`]): bit `2^level − 1 + k` for the k-th run of `FINE >> level`.
    even: Vec<u16>,
    /// The orbit's steps over the period where only the profile splits them (see
    /// `ContactModel::period`), with their mean contact force: laid out once, not found again
    /// step by step in each of the period's evaluations.
    pub(crate) leaves: Vec<Leaf>,
    /// Peak tangential foot speed ω·Xc (m/s).
    pub foot_peak_m_s: f64,
    pub frequency_hz: f64,
    /// Drive voltage after the parameter file's drive gain (V peak-to-peak), and the preload.
    pub voltage_v: f64,
    pub preload_n: f64,
    /// Whether the impulses repeat, every period or every few (else the last periods are kept).
    pub settled: bool,
    /// Periods run from the static equilibrium.
    pub periods: usize,
}

impl ContactProfile {
    /// Solves the stator's normal periodic motion at an operating point.
    pub fn new(p: &Params, op: OperatingPoint) -> Self {
        let op = OperatingPoint { voltage_v: op.voltage_v * p.effects.drive_gain(op.frequency_hz), ..op };
        let amp = amplitudes(p, op.voltage_v, op.frequency_hz);
        let w = TAU * op.frequency_hz;
        let k1 = p.k1_n_per_m();
        let k2 = p.stator.preload_spring_n_per_m;
        let (kc, c3) = contact_spring(p, op.preload_n);
        // Static equilibrium with the preload (as the plant starts).
        let y1 = op.preload_n / kc;
        let y2 = y1 + op.preload_n / k1;
        let anchor_force_n = k2 * (y2 + op.preload_n / k2);
        let h = 1.0 / (op.frequency_hz * STEPS as f64);
        let h_fine = h / FINE as f64;
        let transitions = Transitions::new(p, (kc, c3), amp.normal_force_n, anchor_force_n, w, h);
        let force = |x: &V7| if x[0] > 0.0 { (kc * x[0] + c3 * x[1]).max(0.0) } else { 0.0 };
        let pressing = |x: &V7| x[0] > 0.0 && kc * x[0] + c3 * x[1] > 0.0;
        // φ = −π at the start: cos = −1, sin = 0.
        let mut x = V7::from_column_slice(&[y1, 0.0, y2, 0.0, -1e-9, 0.0, 1.0]);
        // The last 3·MAX_PATTERN periods' impulses, newest last; and per pattern length k, for
        // how many periods in a row each has repeated the one k before it.
        let mut recent: VecDeque<Vec<f64>> = VecDeque::with_capacity(3 * MAX_PATTERN + 1);
        let mut streak = [0usize; MAX_PATTERN + 1];
        let scale = op.preload_n.max(1e-3);
        let ramp_steps = (RAMP_S / h).round().max(1.0);
        let mut step_count = 0.0;
        // Periods on the fine steps from where the base steps left the motion (the ramp is over
        // before anything repeats): the contact force the orbit runs on.
        let fine_periods = |periods: usize, x: &mut V7| -> Vec<Vec<f64>> {
            (0..periods)
                .map(|_| {
                    (0..FINE_STEPS)
                        .map(|_| advance(x, FINE_LEVEL, &transitions, &force, &pressing, h) / h_fine)
                        .collect()
                })
                .collect()
        };
        for period in 1..=MAX_PERIODS {
            let mut now = vec![0.0; STEPS];
            for slot in now.iter_mut() {
                // The drive's amplitude ramps up as the plant's does (a bouncing foot may settle
                // into another pattern after a shock), held over each step. After the ramp the
                // transitions turn the drive's cos/sin without changing their amplitude (to
                // rounding, 1e-11 over a thousand periods).
                if step_count < ramp_steps {
                    step_count += 1.0;
                    let r = (x[4] * x[4] + x[5] * x[5]).sqrt();
                    let target = (step_count / ramp_steps).min(1.0);
                    x[4] *= target / r;
                    x[5] *= target / r;
                }
                *slot = advance(&mut x, 0, &transitions, &force, &pressing, h) / h;
            }
            recent.push_back(now);
            if recent.len() > 3 * MAX_PATTERN {
                recent.pop_front();
            }
            // Whether this period repeated the one k before it (k = 1: the last one).
            let repeats = |k: usize| {
                let n = recent.len();
                match (recent.get(n - 1), n.checked_sub(k + 1).and_then(|i| recent.get(i))) {
                    (Some(a), Some(b)) => {
                        let limit = 1e-5 * scale * STEPS as f64;
                        a.iter()
                            .zip(b)
                            .try_fold(0.0, |sum, (a, b)| Some(sum + (a - b).abs()).filter(|s| *s < limit))
                            .is_some()
                    }
                    _ => false,
                }
            };
            for (k, run) in streak.iter_mut().enumerate().skip(1) {
                *run = if repeats(k) { *run + 1 } else { 0 };
            }
            // The shortest pattern that has repeated: one period that repeats the last (as
            // before patterns were looked for), or k > 1 periods seen three times in a row (a
            // decaying transient can pass for a shorter pattern for a period or two).
            let seen = |k: usize| if k == 1 { 1 } else { 2 * k };
            if let Some(k) = (1..=MAX_PATTERN).find(|&k| period > 3 && streak[k] >= seen(k)) {
                let pattern = fine_periods(k, &mut x);
                let pattern: Vec<&Vec<f64>> = pattern.iter().collect();
                return ContactProfile::with_blocks(
                    one_period_if_rounding(&pattern, scale),
                    w * amp.xc_m,
                    op,
                    true,
                    period + k,
                );
            }
        }
        let kept = fine_periods(UNSETTLED_PERIODS, &mut x);
        ContactProfile::with_blocks(
            kept.into_iter().flatten().collect(),
            w * amp.xc_m,
            op,
            false,
            MAX_PERIODS + UNSETTLED_PERIODS,
        )
    }

    /// The profile of `contact_n` (fine steps) with its base steps' means and evenness.
    fn with_blocks(
        contact_n: Vec<f64>,
        foot_peak_m_s: f64,
        op: OperatingPoint,
        settled: bool,
        periods: usize,
    ) -> Self {
        let mut prefix_n = Vec::with_capacity(contact_n.len() + 1);
        prefix_n.push(0.0);
        for f in &contact_n {
            prefix_n.push(prefix_n.last().copied().unwrap_or(0.0) + f);
        }
        let even = contact_n
            .chunks(FINE)
            .map(|base| {
                let mut bits = 0u16;
                let (mut level, mut len) = (0, FINE);
                while len > 1 {
                    for (k, run) in base.chunks(len).enumerate() {
                        if even_force(run) {
                            bits |= 1 << ((1 << level) - 1 + k);
                        }
                    }
                    level += 1;
                    len /= 2;
                }
                bits
            })
            .collect();
        let fine_steps = contact_n.len() as f64;
        let mut profile = ContactProfile {
            contact_fraction: contact_n.iter().filter(|f| **f > 0.0).count() as f64 / fine_steps,
            prefix_n,
            even,
            leaves: Vec::new(),
            foot_peak_m_s,
            frequency_hz: op.frequency_hz,
            voltage_v: op.voltage_v,
            preload_n: op.preload_n,
            settled,
            periods,
        };
        let mut leaves = Vec::new();
        for start in (0..profile.fine_steps()).step_by(FINE) {
            profile.lay_out(start, FINE, &mut leaves);
        }
        profile.leaves = leaves;
        profile
    }

    /// The leaves of fine steps `start..start + len` (a run of a base step), halved where the
    /// run is not even.
    fn lay_out(&self, start: usize, len: usize, leaves: &mut Vec<Leaf>) {
        if len > 1 && !self.even_run(start, len) {
            self.lay_out(start, len / 2, leaves);
            self.lay_out(start + len / 2, len / 2, leaves);
        } else {
            // Runs of a base step within a few thousand fine steps: both fit in 32 bits.
            let (start_u32, len_u32) = (start as u32, len as u32);
            leaves.push(Leaf { start: start_u32, len: len_u32, contact_n: self.mean_n(start, len) });
        }
    }

    /// The mean contact force over fine steps `start..start + len`.
    pub(crate) fn mean_n(&self, start: usize, len: usize) -> f64 {
        (self.prefix_n[start + len] - self.prefix_n[start]) / len as f64
    }

    /// Whether the orbit may take fine steps `start..start + len` (a run of a base step,
    /// `len` a power of two up to [`FINE`]) whole.
    pub(crate) fn even_run(&self, start: usize, len: usize) -> bool {
        // Shifts, not divisions (`len` is a power of two): this is asked at every step.
        let shift = len.trailing_zeros();
        let level = FINE_LEVEL as u32 - shift;
        let bit = (1usize << level) - 1 + ((start % FINE) >> shift);
        self.even.get(start / FINE).is_some_and(|bits| bits & (1 << bit) != 0)
    }

    /// Fine steps the profile covers ([`FINE_STEPS`] a period).
    pub fn fine_steps(&self) -> usize {
        self.prefix_n.len().saturating_sub(1)
    }

    /// Mean contact force over fine step i (N); step i spans φ from −π + i·2π/FINE_STEPS (modulo
    /// one period). From the kept sums: to their rounding (1e-13 N at 40 N).
    pub fn contact_n(&self) -> Vec<f64> {
        self.prefix_n.windows(2).map(|w| w[1] - w[0]).collect()
    }

    /// Mean contact force over the period: equals the preload's mean force (eq. 12).
    pub fn mean_contact_n(&self) -> f64 {
        self.prefix_n.last().copied().unwrap_or(0.0) / self.fine_steps().max(1) as f64
    }

    /// Share of the period in which the foot presses.
    pub fn contact_fraction(&self) -> f64 {
        self.contact_fraction
    }
}

/// The core's copy of [`ContactProfile::new`]'s inputs (`piezo_drive::normal_motion`): the
/// stator and the drive at an operating point, the parameter file's drive gain applied.
pub fn core_normal_motion(
    p: &Params,
    op: OperatingPoint,
) -> (piezo_drive::normal_motion::Stator, piezo_drive::normal_motion::NormalDrive) {
    let voltage_v = op.voltage_v * p.effects.drive_gain(op.frequency_hz);
    let amp = amplitudes(p, voltage_v, op.frequency_hz);
    let (kc, c3) = contact_spring(p, op.preload_n);
    let (c1, c2) = stator_dashpots(p);
    let stator = piezo_drive::normal_motion::Stator {
        foot_mass_kg: p.stator.foot_mass_kg as f32,
        counterweight_mass_kg: p.stator.counterweight_mass_kg as f32,
        stack_n_per_m: p.k1_n_per_m() as f32,
        preload_spring_n_per_m: p.stator.preload_spring_n_per_m as f32,
        stack_damping_n_s_per_m: c1 as f32,
        preload_damping_n_s_per_m: c2 as f32,
        contact_n_per_m: kc as f32,
        contact_damping_n_s_per_m: c3 as f32,
    };
    let drive = piezo_drive::normal_motion::NormalDrive {
        frequency_hz: op.frequency_hz as f32,
        normal_force_n: amp.normal_force_n as f32,
        preload_n: op.preload_n as f32,
    };
    (stator, drive)
}

/// A repeating pattern's impulses: their mean over the pattern as one period where its periods
/// differ from that mean by less than [`ROUNDING_SHARE`] of the preload (a step's mean): the
/// landing's rounding, not a subharmonic, and the orbit over one period costs 1/k of it;
/// else the whole pattern.
fn one_period_if_rounding(pattern: &[&Vec<f64>], scale: f64) -> Vec<f64> {
    let k = pattern.len() as f64;
    let mean: Vec<f64> = (0..FINE_STEPS).map(|i| pattern.iter().map(|p| p[i]).sum::<f64>() / k).collect();
    let spread = pattern
        .iter()
        .map(|p| p.iter().zip(&mean).map(|(a, b)| (a - b).abs()).sum::<f64>() / FINE_STEPS as f64)
        .fold(0.0, f64::max);
    if spread < ROUNDING_SHARE * scale {
        mean
    } else {
        pattern.iter().flat_map(|p| p.iter().copied()).collect()
    }
}

/// Whether an orbit may step over these fine steps whole: the contact neither starts nor ends in
/// them and its force changes by at most [`SPLIT_FORCE_N`].
fn even_force(fine_n: &[f64]) -> bool {
    let pressing = fine_n.first().is_some_and(|f| *f > 0.0);
    let (lo, hi) =
        fine_n.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), f| (lo.min(*f), hi.max(*f)));
    fine_n.iter().all(|f| (*f > 0.0) == pressing) && hi - lo <= SPLIT_FORCE_N
}

/// Advances the normal state over a step of level `lvl`, halving where the contact state changes;
/// returns the contact impulse over the step (trapezoid per piece).
fn advance(
    x: &mut V7,
    lvl: usize,
    t: &Transitions,
    force: &impl Fn(&V7) -> f64,
    pressing: &impl Fn(&V7) -> bool,
    h: f64,
) -> f64 {
    let contact = pressing(x);
    let m = &t.by_contact[usize::from(contact)][lvl];
    let next = if t.drive_only { transition(m, x) } else { m * *x };
    if pressing(&next) == contact || lvl == LEVELS {
        let hl = h / f64::from(1u32 << lvl);
        let impulse = if contact { 0.5 * (force(x) + force(&next)) * hl } else { 0.0 };
        *x = next;
        return impulse;
    }
    advance(x, lvl + 1, t, force, pressing, h) + advance(x, lvl + 1, t, force, pressing, h)
}

/// The exact transitions of the augmented normal state over a base step and its halvings
/// (index: level), without and with the foot pressing.
struct Transitions {
    by_contact: [Vec<M7>; 2],
    /// Every one has in its drive rows only the drive's rotation and the anchor's constant
    /// ([`drive_only`]): stepped by [`transition`].
    drive_only: bool,
}

impl Transitions {
    /// For the stator of `p` with contact spring and dashpot `contact`, under the stacks'
    /// normal force amplitude (N) and the preload spring's anchor force (N), at drive frequency
    /// `w` (rad/s), base step `h` (s).
    fn new(
        p: &Params,
        contact: (f64, f64),
        normal_force_n: f64,
        anchor_force_n: f64,
        w: f64,
        h: f64,
    ) -> Self {
        // The state [y1, ẏ1, y2, ẏ2] augmented with the drive's cos/sin and a constant, so that
        // the sine and the anchor enter exactly.
        let augmented = |pressing: bool| -> M7 {
            let a6 = state_matrix(p, pressing.then_some(contact));
            let mut a = M7::zeros();
            for i in 0..4 {
                for j in 0..4 {
                    a[(i, j)] = a6[(i, j)];
                }
                a[(i, 4)] = a6[(i, 4)] * normal_force_n;
                a[(i, 6)] = a6[(i, 5)] * anchor_force_n;
            }
            a[(4, 5)] = -w;
            a[(5, 4)] = w;
            a
        };
        let levels = |pressing: bool| -> Vec<M7> {
            let a = augmented(pressing);
            (0..=LEVELS).map(|l| (a * (h / f64::from(1u32 << l))).exp()).collect()
        };
        let by_contact = [levels(false), levels(true)];
        Transitions { drive_only: by_contact.iter().flatten().all(drive_only), by_contact }
    }
}

/// Whether a transition's last three rows are the drive's cos/sin turned by their rotation and
/// the anchor's constant kept, all their other entries exact zeros: what the exponential of
/// [`ContactProfile::new`]'s augmented matrix has there.
fn drive_only(m: &M7) -> bool {
    (4..7).all(|i| (0..4).all(|j| m[(i, j)] == 0.0))
        && m[(4, 6)] == 0.0
        && m[(5, 6)] == 0.0
        && m[(6, 4)] == 0.0
        && m[(6, 5)] == 0.0
}

/// `m·x` for a [`drive_only`] transition: the stator's four rows in full, the drive's two by
/// their rotation and the constant by itself. The terms are summed in the order of nalgebra's
/// product, so the result is the same to the bit for a third of the work.
#[inline]
fn transition(m: &M7, x: &V7) -> V7 {
    let mut y = V7::zeros();
    for i in 0..4 {
        let mut sum = m[(i, 0)] * x[0];
        for j in 1..7 {
            sum += m[(i, j)] * x[j];
        }
        y[i] = sum;
    }
    y[4] = m[(4, 4)] * x[4] + m[(4, 5)] * x[5];
    y[5] = m[(5, 4)] * x[4] + m[(5, 5)] * x[5];
    y[6] = m[(6, 6)] * x[6];
    y
}

/// One step of a carriage's orbit: fine steps `start..start + len` and their mean contact force.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Leaf {
    pub(crate) start: u32,
    pub(crate) len: u32,
    pub(crate) contact_n: f64,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_short_product_is_nalgebras_to_the_bit() {
        // The exponentials of the sourced prototype's augmented matrices have exact zeros
        // wherever `transition` skips a term, and its sums run in nalgebra's order.
        let p = Params::prototype_sourced();
        let (kc, c3) = contact_spring(&p, 10.0);
        for frequency_hz in [500.0, 1500.0, 2200.0] {
            let w = TAU * frequency_hz;
            let t = Transitions::new(&p, (kc, c3), 7.0, 12.0, w, 1.0 / (frequency_hz * STEPS as f64));
            assert!(t.drive_only, "{frequency_hz} Hz");
            let mut seed = 0x9e37_79b9_7f4a_7c15_u64;
            let mut next = || {
                seed ^= seed << 13;
                seed ^= seed >> 7;
                seed ^= seed << 17;
                (seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
            };
            for m in t.by_contact.iter().flatten() {
                for _ in 0..50 {
                    let x = V7::from_fn(|i, _| if i == 6 { 1.0 } else { next() * 1e-5 });
                    let (fast, full) = (transition(m, &x), m * x);
                    assert!(
                        fast.iter().zip(full.iter()).all(|(a, b)| a.to_bits() == b.to_bits()),
                        "{fast} {full}"
                    );
                }
            }
        }
    }
}
