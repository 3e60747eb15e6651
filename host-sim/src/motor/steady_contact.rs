//! Steady-state thrust with the contact's timing (issue 28): the thrust integral of eq. (19) with
//! the contact force the stator really makes, on a carriage that rides the foot.
//!
//! The constant-speed model (eqs. 13–22) takes the contact force as the linear contact-stage
//! response cut at zero, `kc·Yc·(cos φ − cos θc/2)` (eq. 15), centred on the foot's peak speed. On
//! the paper's stator with physical masses the contact force differs from that cap in three ways
//! the plant shows (`host-sim trace`): it leads the foot's speed through the stator's damping, the
//! foot lands late with an impact, and at low preload the foot swings free and the landing impact
//! carries most of the period's normal impulse before the foot's peak speed. All three come from
//! the stator's normal equations (4) and (6) with the unilateral contact (10) and their dashpots,
//! so here they are solved rather than approximated:
//!
//! 1. **Normal periodic motion.** The 2-DOF stator under the stacks' normal force `F̂·cos φ`
//!    (eq. 3; φ = ωt from the foot's peak forward speed, where the normal force peaks too: the
//!    tangential speed is the sum of the stack strokes' rates, the normal force their difference,
//!    both ∝ cos φ for the quadrature drive), with the preload through the preload spring and the
//!    contact spring–dashpot of the parameter file (its damping from the restitution) switched on
//!    while the foot presses. Each contact state is linear, so every step is its exact transition
//!    (matrix exponential of the state augmented with the drive's cos/sin, so the sine enters
//!    exactly), and a step in which the state changes is halved until the switch is located to
//!    `1/2^20` of the period. It is run on [`STEPS`] steps per period from the static equilibrium
//!    until its contact impulses repeat, then once more on [`FINE`]× finer steps, whose contact
//!    force the carriage runs on. Where the foot lands with an impact, the impulses may repeat
//!    only every few periods: the landing is located to that 1/2^20, and on the sourced
//!    prototype at 5–17 N the impulses then alternate in a pattern of 2–4 periods whose periods
//!    differ by 2e-5 to 2e-4 of the preload (a step's mean), while the one-period test asks 1e-5. A pattern of up to
//!    [`MAX_PATTERN`] periods is then looked for: one whose periods differ by less than
//!    [`ROUNDING_SHARE`] is the rounding and is kept as its mean period; a larger one (a real
//!    subharmonic) is kept whole, and the carriage's orbit runs over all of it. Where the
//!    foot repeats nothing within [`MAX_PERIODS`] (chaotic bouncing: 5 and 8 N at 100 V and
//!    2.1 kHz) [`UNSETTLED_PERIODS`] more periods are kept as they come
//!    ([`ContactProfile::settled`] says which). Holds wherever the stator's equations do: the
//!    whole band, every preload, impacts of any length.
//! 2. **The carriage's periodic motion** under that contact force and the foot's harmonic
//!    tangential speed `ω·Xc·cos φ` (eqs. 1, 8), with the carriage's inertia, the load, Coulomb
//!    friction with εc (eq. 16) and the friction layer between foot and slider — the same step
//!    the plant takes (`contact_friction`), on steps halved where the contact or the interface
//!    changes (see [`ContactModel::period`]). The periodic speed `v(T) = v(0)` is found by
//!    regula falsi on `v(0)`, the layer carried over from a first period. The thrust model's
//!    speed is its mean.
//!
//! The parameter file's effects enter as the plant applies them: the drive gain of
//! `amplifier_rolloff` / `stator_resonance` on the voltage, `hertz_contact` in `kc`, the foot's
//! speed × the drive sense's `assembly_asymmetry` factor, μ × the preload's and (Coulomb laws)
//! the slip's factor, the guide's `rail_friction` on the carriage at its own speed, and the
//! `slider_inertia` mass.
//!
//! What it leaves out of the plant: the DAC's 200 kS/s staircase and the amplifier's transient
//! (its gain is in `Yc`, `Xc`; its phase lag is the same on both channels, so it moves nothing),
//! and LuGre (the Coulomb laws only; LuGre runs as Coulomb with μd).

use crate::motor::contact_friction::{FrictionLaw, Layer, Mode, StepInput, StepScale};
use crate::motor::effects::Effects;
use crate::motor::params::{FrictionModel, Params};
use crate::motor::plant::{contact_spring, friction_law, state_matrix, stator_dashpots};
use crate::motor::roots::stall_load_n;
use crate::motor::steady::{amplitudes, OperatingPoint};
use nalgebra::SMatrix;
use std::collections::VecDeque;
use std::f64::consts::{PI, TAU};
use std::sync::{Arc, OnceLock};

/// The periodic orbit's start speed is found to this share of the foot's peak speed: the mean
/// speed then to about the same share, 1e-4 of the 1 % a speed is measured to. A caller that
/// needs less sets its own ([`ContactModel::with_root_tolerance`]).
pub const ROOT_TOLERANCE: f64 = 1e-6;

/// [`ContactModel::speed_after_one_secant`] takes its extrapolated orbit only where the secant
/// has converged: its next correction of the start speed is under this share of its first
/// (else the full search runs). On 648 five-per-cent parameter steps over the 0.3–5 kg
/// carriages, 5–17 N, 60–100 V and 0.9–2.1 kHz: 14 % searched in full, and the step's speed
/// difference off the full search's by 1.2e-4 of itself at the median, 1.6 % at the 99th
/// percentile, 4.8 % at worst (without the check: 290 %, at 5 N where impacts change pattern).
const ONE_SECANT_CONVERGED: f64 = 0.1;
/// How far from rest a period's start speed is searched, in the foot's peak speeds (first ±4×,
/// see [`ContactModel::orbit_near`]).
const WIDEST_BRACKET: f64 = 64.0;

/// Secant steps from a hint before the bracketed search takes over.
const SECANT_STEPS: usize = 4;

/// Base steps per drive period: the normal motion settles on these, and the carriage's orbit
/// takes them where nothing changes within one.
pub const STEPS: usize = 256;
/// A base step is this many fine steps (2^[`FINE_LEVEL`]). The settled normal motion is run once
/// more on the fine steps and its contact force kept on them, and the orbit halves a base step
/// down to them where the contact or the interface changes within it (see
/// [`ContactModel::period`]).
pub const FINE: usize = 16;
const FINE_LEVEL: usize = 4;
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
/// A sticking step is halved while the carriage on the friction layer, `√(kt/M)`, turns by more
/// than this (rad) in it: on a light carriage the layer's oscillation is then resolved.
const SPLIT_LAYER_TURN_RAD: f64 = 0.05;
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
    mean_contact_n: f64,
    contact_fraction: f64,
    /// Per base step (each [`FINE`] fine steps), which of its halves, quarters, ... the orbit may
    /// take whole ([`even_force`]): bit `2^level − 1 + k` for the k-th run of `FINE >> level`.
    even: Vec<u16>,
    /// The orbit's steps over the period where only the profile splits them (see
    /// [`ContactModel::period`]), with their mean contact force: laid out once, not found again
    /// step by step in each of the period's evaluations.
    leaves: Vec<Leaf>,
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
            mean_contact_n: contact_n.iter().sum::<f64>() / fine_steps,
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
    fn mean_n(&self, start: usize, len: usize) -> f64 {
        (self.prefix_n[start + len] - self.prefix_n[start]) / len as f64
    }

    /// Whether the orbit may take fine steps `start..start + len` (a run of a base step,
    /// `len` a power of two up to [`FINE`]) whole.
    fn even_run(&self, start: usize, len: usize) -> bool {
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
        self.mean_contact_n
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

/// Whether a secant's slope of the excess stays on the branch of the period map a hint's slope
/// was taken on: within a factor of two of it (the map jumps where friction weakens with speed).
fn same_branch(slope: f64, hint_slope: f64) -> bool {
    slope <= 0.5 * hint_slope && slope >= 2.0 * hint_slope
}

/// cos φ at the ends of a period's fine steps (φ from −π), computed once: a model is built for
/// every row the gap workflow evaluates, and the cosines were a fifth of an orbit's time.
fn cos_ends() -> &'static [f64] {
    static TABLE: OnceLock<Vec<f64>> = OnceLock::new();
    TABLE.get_or_init(|| (1..=FINE_STEPS).map(|i| (-PI + TAU * i as f64 / FINE_STEPS as f64).cos()).collect())
}

/// The steady-state model with the contact's timing at one operating point.
#[derive(Debug, Clone)]
pub struct ContactModel {
    /// The normal motion (shared: it does not depend on the carriage, μ or the tangential scale).
    pub profile: Arc<ContactProfile>,
    pub mass_kg: f64,
    /// Peak tangential foot speed along the drive sense (m/s): ω·Xc × the sense's asymmetry.
    pub foot_peak_m_s: f64,
    law: FrictionLaw,
    /// μ for sticking, with the preload's and the slip's peak factor of the effects.
    mu_stick: f64,
    /// The guide's viscous drag (`slider.damping_n_s_per_m`).
    guide_n_s_per_m: f64,
    effects: Effects,
    /// cos φ at the fine step ends ([`cos_ends`]).
    cos_end: &'static [f64],
    /// The carriage's step of each length the orbit takes, [`FINE`] fine steps down to one
    /// (index: log2 of the length).
    scales: [StepScale; FINE_LEVEL + 1],
    /// The carriage on the friction layer's shear spring, `√(kt/M)` (0 for a rigid interface).
    layer_rad_s: f64,
    /// Every step a fine step ([`Self::on_fine_steps`]).
    all_fine: bool,
    /// The orbit's start speed is found to this share of the foot's peak speed.
    root_tolerance: f64,
    /// A step in which the interface changes between stick and slip is halved (only where the
    /// friction falls with the slip speed, see [`Self::period`]).
    split_at_breakaway: bool,
    /// No effects; else μ's factor of the preload.
    plain: bool,
    preload_factor: f64,
}

/// One step of a carriage's orbit: fine steps `start..start + len` and their mean contact force.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Leaf {
    start: u32,
    len: u32,
    contact_n: f64,
}

/// A period already run: from speed `v0_m_s` and `layer`, its (end speed, mean speed, ripple,
/// end layer).
struct Known {
    v0_m_s: f64,
    layer: Layer,
    period: (f64, f64, f64, Layer),
}

impl Known {
    /// Whether a period from `v0` and `layer` is this one: the same bits.
    fn is_from(&self, v0: f64, layer: Layer) -> bool {
        let bits = |l: &Layer| (l.shear_m.to_bits(), l.shear_rate_m_s.to_bits(), l.mode);
        self.v0_m_s.to_bits() == v0.to_bits() && bits(&self.layer) == bits(&layer)
    }
}

/// A period of the carriage under way.
struct Run {
    v: f64,
    layer: Layer,
    /// Σ speed × fine steps, and the extremes of the speed.
    sum: f64,
    lo: f64,
    hi: f64,
}

/// Where a periodic motion starts: the carriage's speed and the friction layer's state at the
/// start of a period. A nearby solution's start is where the next search begins
/// ([`ContactModel::orbit_near`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OrbitStart {
    pub v0_m_s: f64,
    pub layer: Layer,
    /// Slope of the excess `v(T) − v(0)` over `v(0)` there (negative; NaN: not known).
    pub slope: f64,
}

/// The carriage's periodic motion at one load.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Orbit {
    pub mean_speed_m_s: f64,
    /// Peak-to-peak speed ripple within the period.
    pub ripple_m_s: f64,
}

impl ContactModel {
    /// The model along the positive drive sense.
    pub fn new(p: &Params, op: OperatingPoint) -> Self {
        Self::with_profile(p, Arc::new(ContactProfile::new(p, op)), 1)
    }

    /// The model on a normal motion already solved (`profile` must be `ContactProfile::new` of a
    /// parameter set with `p`'s stator, contact, normal force ratio and drive gain), along drive
    /// sense `direction` (±1).
    pub fn with_profile(p: &Params, profile: Arc<ContactProfile>, direction: i8) -> Self {
        let (kc, c3) = contact_spring(p, profile.preload_n);
        let mu_stick = match p.friction.model {
            FrictionModel::StaticDynamic => p.friction.mu_static,
            FrictionModel::Coulomb | FrictionModel::Lugre => p.friction.mu_dynamic,
        };
        let effects = p.effects.clone();
        let stick_scale = effects.friction_factor(profile.preload_n) * effects.stribeck_peak();
        let amp = amplitudes(p, profile.voltage_v, profile.frequency_hz);
        let law = friction_law(p, kc, c3);
        let mass_kg = p.effects.slider_mass_kg(p.slider.mass_kg);
        let h_fine_s = 1.0 / (profile.frequency_hz * FINE_STEPS as f64);
        ContactModel {
            scales: std::array::from_fn(|level| {
                StepScale::new(&law, h_fine_s * (1usize << level) as f64, mass_kg)
            }),
            layer_rad_s: (law.kt_n_per_m.max(0.0) / mass_kg).sqrt(),
            all_fine: false,
            root_tolerance: ROOT_TOLERANCE,
            split_at_breakaway: p.effects.stribeck_peak() > 1.0,
            plain: p.effects.is_none(),
            preload_factor: p.effects.friction_factor(profile.preload_n),
            mass_kg,
            foot_peak_m_s: TAU * profile.frequency_hz * amp.xc_m * effects.tangential_factor(direction),
            profile,
            law,
            mu_stick: mu_stick * stick_scale,
            guide_n_s_per_m: p.slider.damping_n_s_per_m,
            effects,
            cos_end: cos_ends(),
        }
    }

    /// The same model with every step of the carriage's orbit a fine step ([`FINE_STEPS`] per
    /// period, 16× the base steps' cost): the reference the halved steps are held to.
    pub fn on_fine_steps(mut self) -> Self {
        self.all_fine = true;
        self
    }

    /// The same model with its orbits found to `share` of the foot's peak speed (instead of
    /// [`ROOT_TOLERANCE`]): for callers whose use of a speed is coarser, e.g. fits to measured
    /// speeds.
    pub fn with_root_tolerance(mut self, share: f64) -> Self {
        self.root_tolerance = share;
        self
    }

    /// One period from speed `v0` and layer state `layer`: (end speed, mean speed, ripple, end
    /// layer).
    ///
    /// The carriage's steps are the base steps, each halved (down to the fine steps) where the
    /// contact starts, ends or its force changes by more than [`SPLIT_FORCE_N`] within it, and
    /// while it sticks with the carriage on the layer turning by more than
    /// [`SPLIT_LAYER_TURN_RAD`] in a step. A contact force resolved only to whole steps at the
    /// landing, its impact or the take-off moves the friction's impulse by up to μ·F·h, and that
    /// error does not shrink steadily with more uniform steps (it depends on where the event
    /// falls in its step). Against 4096 uniform steps over issue 28's grid (in % of the no-load
    /// speed): 1024 uniform steps up to 1.34 %, these 0.91 % at 0.1 kg, 0.24 % at 0.3 kg and
    /// 0.15 % from 1 kg on. Halving also where the interface changes between stick and slip
    /// moved no point by more than 0.03 % and cost a fifth of the time, so it is done only where
    /// the sliding friction falls with the slip speed (`stribeck_friction`): there the moment of
    /// breakaway decides how long the high friction near zero slip acts, and without it the
    /// model ran 11 % fast (16 N, 100 V, 1.5 kHz, rise 1.5: 2.255 against 2.032 mm/s on fine
    /// steps; with it 2.018).
    fn period(&self, v0: f64, layer: Layer, load_n: f64) -> (f64, f64, f64, Layer) {
        let mut run = Run { v: v0, layer, sum: 0.0, lo: v0, hi: v0 };
        let n = self.profile.fine_steps();
        // Where neither the layer's turn nor a breakaway can halve a step, the steps are the
        // profile's own ([`ContactProfile::lay_out`], the same halving as `step`'s).
        let longest_s = self.scales[FINE_LEVEL].dt_s;
        if !self.all_fine && !self.split_at_breakaway && self.layer_rad_s * longest_s <= SPLIT_LAYER_TURN_RAD
        {
            for leaf in &self.profile.leaves {
                self.take(&mut run, leaf.start as usize, leaf.len as usize, leaf.contact_n, load_n, false);
            }
        } else {
            for start in (0..n).step_by(FINE) {
                self.step(&mut run, start, FINE, load_n);
            }
        }
        (run.v, run.sum / n as f64, run.hi - run.lo, run.layer)
    }

    /// The carriage over fine steps `start..start + len` of the profile, halved as
    /// [`Self::period`] says.
    fn step(&self, run: &mut Run, start: usize, len: usize, load_n: f64) {
        let scale = &self.scales[len.trailing_zeros() as usize];
        let h = scale.dt_s;
        let profile = &self.profile;
        let split = len > 1
            && (self.all_fine
                || !profile.even_run(start, len)
                || (run.layer.mode == Mode::Stick && self.layer_rad_s * h > SPLIT_LAYER_TURN_RAD));
        if split {
            self.step(run, start, len / 2, load_n);
            self.step(run, start + len / 2, len / 2, load_n);
            return;
        }
        let fc = profile.mean_n(start, len);
        if !self.take(run, start, len, fc, load_n, self.split_at_breakaway) {
            self.step(run, start, len / 2, load_n);
            self.step(run, start + len / 2, len / 2, load_n);
        }
    }

    /// The carriage over fine steps `start..start + len` whole, under mean contact force `fc`.
    /// With `at_breakaway` (and `len > 1`) a step in which the interface changes between stick
    /// and slip is not taken: returns false, `run` as it was.
    fn take(
        &self,
        run: &mut Run,
        start: usize,
        len: usize,
        fc: f64,
        load_n: f64,
        at_breakaway: bool,
    ) -> bool {
        let scale = &self.scales[len.trailing_zeros() as usize];
        let v = run.v;
        let foot_m_s = self.foot_peak_m_s * self.cos_end[(start + len - 1) % FINE_STEPS];
        // The guide's friction is symmetric in the sense, so it reads the same along the drive.
        let (rail_n, mu_scale) = if self.plain {
            (0.0, 1.0)
        } else {
            (
                self.effects.rail_force_on_slider_n(v),
                self.preload_factor * self.effects.stribeck_factor(foot_m_s - v),
            )
        };
        let external_n = -load_n - self.guide_n_s_per_m * v + rail_n;
        let input = StepInput {
            scale,
            slider_m_s: v,
            external_n,
            contact_n: fc,
            foot_m_s,
            mu_stick: self.mu_stick,
            mu_scale,
        };
        let before = run.layer;
        let friction = run.layer.step(&self.law, &input);
        if at_breakaway && len > 1 && run.layer.mode != before.mode {
            run.layer = before;
            return false;
        }
        run.v += (external_n + friction) * scale.dt_per_kg;
        run.sum += run.v * len as f64;
        run.lo = run.lo.min(run.v);
        run.hi = run.hi.max(run.v);
        true
    }

    /// The periodic motion under a constant load opposing the drive; `None` when none starts
    /// within ±[`WIDEST_BRACKET`]× the foot's peak speed.
    pub fn orbit(&self, load_n: f64) -> Option<Orbit> {
        self.orbit_near(load_n, None).map(|(orbit, _)| orbit)
    }

    /// [`Self::orbit`] searched from `hint` (a nearby solution's start, e.g. the same point with
    /// other friction), the friction layer starting from the hint's: secant steps from its start
    /// speed where it knows its slope, else (or when they leave its branch) a bracket from the
    /// points the steps evaluated on either side of the root, or 2 % of the foot's peak speed
    /// about the hint (or the one side found), widened fourfold until it holds the root. Returns the
    /// orbit and where it starts. The root is the same as from the full bracket (to
    /// [`Self::with_root_tolerance`] of the foot's peak speed); only the periods spent finding it
    /// are fewer.
    pub fn orbit_near(&self, load_n: f64, hint: Option<OrbitStart>) -> Option<(Orbit, OrbitStart)> {
        self.orbit_search(load_n, hint, &[])
    }

    /// [`Self::orbit_near`], the periods in `known` taken as evaluated (the same period from the
    /// same speed and layer gives the same to the bit).
    fn orbit_search(
        &self,
        load_n: f64,
        hint: Option<OrbitStart>,
        known: &[Known],
    ) -> Option<(Orbit, OrbitStart)> {
        let w = self.foot_peak_m_s.abs().max(1e-9);
        let hint_v0 = hint.map(|h| h.v0_m_s);
        // v(T) − v(0) and the period's mean speed and ripple, from v(0).
        // The friction layer's state at the period's start, carried from one evaluation to the
        // next: the first settles it over a period from rest (or takes a nearby solution's); a
        // later v(0) is near the last one, whose end state is then nearly its own periodic
        // start (one period, not two). The layer's own time constant, ct/kt, is microseconds.
        let carried: std::cell::Cell<Option<Layer>> = std::cell::Cell::new(hint.map(|h| h.layer));
        let excess = |v0: f64| {
            let start = carried.get().unwrap_or_else(|| self.period(v0, Layer::default(), load_n).3);
            let (end, mean, ripple, layer) = match known.iter().find(|k| k.is_from(v0, start)) {
                Some(k) => k.period,
                None => self.period(v0, start, load_n),
            };
            carried.set(Some(layer));
            (end - v0, Orbit { mean_speed_m_s: mean, ripple_m_s: ripple })
        };
        // The orbit's start: its speed, the layer at the end of the last period evaluated, and
        // the excess' slope.
        let start_at =
            |v0_m_s: f64, slope: f64| OrbitStart { v0_m_s, layer: carried.get().unwrap_or_default(), slope };
        let tol = self.root_tolerance * w;
        // With a nearby solution's slope, secant steps from its start: the excess is close to
        // linear there, and two or three periods find the root. Each step's slope must stay
        // within a factor of two of the hint's (the same branch of the period map, which jumps
        // where friction weakens with speed), else the bracketed search below runs.
        // The points the secant steps evaluated, nearest the root from each side (the excess
        // falls with v(0)): where the steps leave their branch, the bracket starts from them.
        let (mut below, mut above) = (None::<(f64, f64)>, None::<(f64, f64)>);
        let mut seen = |x: f64, e: f64| {
            if e > 0.0 && below.is_none_or(|(b, _)| x > b) {
                below = Some((x, e));
            } else if e < 0.0 && above.is_none_or(|(a, _)| x < a) {
                above = Some((x, e));
            }
        };
        if let Some(h) = hint.filter(|h| h.v0_m_s.is_finite() && h.slope < 0.0) {
            let (mut x0, (mut e0, mut orbit)) = (h.v0_m_s, excess(h.v0_m_s));
            seen(x0, e0);
            let mut slope = h.slope;
            // The last step's point is tested too: a search that ended on an orbit without
            // looking at it fell back to the bracket (a third of the gap bench's searches).
            for step in 0..=SECANT_STEPS {
                if e0.abs() < slope.abs() * tol {
                    return Some((orbit, start_at(x0, slope)));
                }
                if step == SECANT_STEPS {
                    break;
                }
                let x1 = x0 - e0 / slope;
                if !x1.is_finite() || (x1 - h.v0_m_s).abs() > 0.5 * w {
                    break;
                }
                let (e1, o1) = excess(x1);
                seen(x1, e1);
                let s1 = (e1 - e0) / (x1 - x0);
                if !same_branch(s1, h.slope) {
                    // Near the root the secant's slope is the period map's roughness, not a
                    // jump to another branch: a point whose excess puts it within the
                    // tolerance of the root by either slope is an orbit all the same.
                    if e1.abs() < s1.abs().min(slope.abs()) * tol {
                        return Some((o1, start_at(x1, slope)));
                    }
                    break;
                }
                (x0, e0, orbit, slope) = (x1, e1, o1, s1);
            }
        }
        let (lo, hi) = (-4.0 * w, 4.0 * w);
        let ((mut a, mut ea), (mut b, mut eb)) = match hint_v0.filter(|h| h.is_finite() && *h > lo && *h < hi)
        {
            Some(h) => {
                // Widened about the side the secant found, else about the hint (also where its
                // two sides are out of order: the map is not monotone there).
                let (below, above) = match (below, above) {
                    (Some(a), Some(b)) if a.0 >= b.0 => (None, None),
                    sides => sides,
                };
                let c = match (below, above) {
                    (Some((x, _)), None) | (None, Some((x, _))) => x,
                    _ => h,
                };
                let mut half = 0.02 * w;
                let (mut a, mut ea) = below.unwrap_or_else(|| {
                    let a = (c - half).max(lo);
                    (a, excess(a).0)
                });
                let (mut b, mut eb) = above.unwrap_or_else(|| {
                    let b = (c + half).min(hi);
                    (b, excess(b).0)
                });
                while (ea <= 0.0 && a > lo) || (eb >= 0.0 && b < hi) {
                    half *= 4.0;
                    if ea <= 0.0 && a > lo {
                        a = (c - half).max(lo);
                        ea = excess(a).0;
                    }
                    if eb >= 0.0 && b < hi {
                        b = (c + half).min(hi);
                        eb = excess(b).0;
                    }
                }
                ((a, ea), (b, eb))
            }
            None => ((lo, excess(lo).0), (hi, excess(hi).0)),
        };
        // A light carriage's speed ripples within a period by more than the foot's peak speed
        // (0.3 kg at 17 N, 60 V, 0.9 kHz against 4.17 N: from −5.5 to +1.5 mm/s about a mean of
        // −1.78, the foot's peak 1.1), so a period's start speed can lie beyond ±4×: the bracket
        // widens further, doubling, before there is no orbit. A bracket that held at ±4× is
        // left as it was (the same root as before).
        while ea <= 0.0 && a > -WIDEST_BRACKET * w {
            a = (2.0 * a.min(-w)).max(-WIDEST_BRACKET * w);
            ea = excess(a).0;
        }
        while eb >= 0.0 && b < WIDEST_BRACKET * w {
            b = (2.0 * b.max(w)).min(WIDEST_BRACKET * w);
            eb = excess(b).0;
        }
        if ea <= 0.0 || eb >= 0.0 {
            return None;
        }
        // Regula falsi (Illinois) on the falling excess, stopped when a step moves v(0) by less
        // than the tolerance, or when the excess at the point evaluated is so small that the
        // bracket's own slope (the excesses as evaluated, not as Illinois scales them) puts the
        // root within the tolerance of it: the last point evaluated is then the orbit.
        let mut last = f64::NAN;
        let mut side = 0i8;
        let (mut raw_a, mut raw_b) = (ea, eb);
        for i in 0..60 {
            let mut m = (a * eb - b * ea) / (eb - ea);
            if !(m > a && m < b) || i % 8 == 7 {
                m = 0.5 * (a + b);
            }
            let (em, orbit) = excess(m);
            let slope = (raw_b - raw_a) / (b - a);
            if (m - last).abs() < tol || b - a < tol || em.abs() < slope.abs() * tol {
                return Some((orbit, start_at(m, slope)));
            }
            last = m;
            if em > 0.0 {
                raw_a = em;
                (a, ea) = (m, em);
                if side == 1 {
                    eb *= 0.5;
                }
                side = 1;
            } else {
                raw_b = em;
                (b, eb) = (m, em);
                if side == -1 {
                    ea *= 0.5;
                }
                side = -1;
            }
        }
        let m = 0.5 * (a + b);
        let orbit = excess(m).1;
        Some((orbit, start_at(m, (raw_b - raw_a) / (b - a))))
    }

    /// The mean speed of the orbit near `hint` (a nearby parameter set's orbit start with its
    /// slope) after one secant step, for finite differences: a period at the hint's start speed,
    /// the hint's slope to the next start, a period there, and the mean speed extrapolated along
    /// those two periods to where their secant puts the root. Two periods where a search takes
    /// three to five. `None` where the hint has no slope or the step leaves its branch or has not
    /// converged ([`ONE_SECANT_CONVERGED`]): then the caller searches in full.
    pub fn speed_after_one_secant(&self, load_n: f64, hint: OrbitStart) -> Option<f64> {
        self.one_secant(load_n, hint, &mut Vec::new())
    }

    /// The speed for a finite difference from `hint`: after one secant step
    /// ([`Self::speed_after_one_secant`]), else after the full search near it (that search's
    /// first periods are the secant step's, so they are not run again: a third of the gap
    /// workflow's secant steps searched on). `None` where the carriage has no orbit.
    pub fn speed_for_slope(&self, load_n: f64, hint: Option<OrbitStart>) -> Option<f64> {
        let mut known = Vec::new();
        hint.and_then(|h| self.one_secant(load_n, h, &mut known))
            .or_else(|| self.orbit_search(load_n, hint, &known).map(|(orbit, _)| orbit.mean_speed_m_s))
    }

    /// [`Self::speed_after_one_secant`], the periods it ran pushed to `known`.
    fn one_secant(&self, load_n: f64, hint: OrbitStart, known: &mut Vec<Known>) -> Option<f64> {
        let w = self.foot_peak_m_s.abs().max(1e-9);
        if !(hint.v0_m_s.is_finite() && hint.slope < 0.0) {
            return None;
        }
        let mut period = |v0: f64, layer: Layer| {
            let p = self.period(v0, layer, load_n);
            known.push(Known { v0_m_s: v0, layer, period: p });
            p
        };
        let x0 = hint.v0_m_s;
        let (end0, mean0, _, layer) = period(x0, hint.layer);
        let e0 = end0 - x0;
        let x1 = x0 - e0 / hint.slope;
        if !x1.is_finite() || (x1 - x0).abs() > 0.5 * w {
            return None;
        }
        if e0.abs() < hint.slope.abs() * self.root_tolerance * w {
            return Some(mean0);
        }
        let (end1, mean1, _, _) = period(x1, layer);
        let e1 = end1 - x1;
        let s1 = (e1 - e0) / (x1 - x0);
        if !same_branch(s1, hint.slope) {
            return None;
        }
        let root = x1 - e1 / s1;
        if (root - x1).abs() > ONE_SECANT_CONVERGED * (x1 - x0).abs() {
            return None;
        }
        Some(mean1 + (mean1 - mean0) / (x1 - x0) * (root - x1))
    }

    pub fn speed_at_load_m_s(&self, load_n: f64) -> Option<f64> {
        self.orbit(load_n).map(|o| o.mean_speed_m_s)
    }

    pub fn no_load_speed_m_s(&self) -> f64 {
        self.speed_at_load_m_s(0.0).unwrap_or(0.0)
    }

    /// The load at which the mean speed falls to zero: bisection to 1e-4 of μ·F0.
    pub fn stall_force_n(&self) -> f64 {
        let forward = |load: f64| self.speed_at_load_m_s(load).is_some_and(|v| v > 0.0);
        let top = self.mu_stick * self.profile.mean_contact_n().max(1e-9);
        stall_load_n(forward, top, 1e-4 * top)
    }
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
