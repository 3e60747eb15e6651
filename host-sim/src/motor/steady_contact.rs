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
//! 1. **Normal periodic motion** ([`ContactProfile`], `contact_profile.rs`): the stator's
//!    normal equations with the unilateral contact, solved in exact steps from the static
//!    equilibrium until the contact impulses repeat; the contact force over one settled period
//!    (or a repeating pattern, or the last periods of a chaotic one) on fine steps.
//! 2. **The carriage's periodic motion** under that contact force and the foot's harmonic
//!    tangential speed `ω·Xc·cos φ` (eqs. 1, 8), with the carriage's inertia, the load, Coulomb
//!    friction with εc (eq. 16) and the friction layer between foot and slider — the same step
//!    the plant takes (`contact_friction`), on steps halved where the contact or the interface
//!    changes (see [`ContactModel::period`]). The periodic speed `v(T) = v(0)` is found by
//!    regula falsi on `v(0)`, the layer carried over from a first period. The thrust model's
//!    speed is its mean. Where the period map jumps across `v(T) = v(0)` (a stick–slip event
//!    that moves by a step as `v(0)` changes) no start repeats: the carriage alternates
//!    between the jump's two sides, and the speed is their mix whose drifts cancel.
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
use crate::motor::contact_profile::FINE_LEVEL;
pub use crate::motor::contact_profile::{
    core_normal_motion, ContactProfile, FINE, FINE_STEPS, MAX_PATTERN, ROUNDING_SHARE, STEPS,
    UNSETTLED_PERIODS,
};
use crate::motor::effects::Effects;
use crate::motor::params::{FrictionModel, Params};
use crate::motor::plant::{contact_spring, friction_law};
use crate::motor::roots::stall_load_n;
use crate::motor::steady::{amplitudes, OperatingPoint};
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
/// The steepest the excess `v(T) − v(0)` falls with `v(0)`: a carriage that starts faster does
/// not end the period slower (its speeds cannot cross), so the slope is at least −1. A
/// bracket's last slope across a kink of the period map, within the tolerance, can read −400;
/// kept as a hint, such a slope took the next search's secant steps nowhere (10 428 of the
/// gap bench's 17 450 bracketed searches failed their first secant step).
const STEEPEST_SLOPE: f64 = -1.0;

/// A bracket across which the excess falls faster than this holds a jump of the period map (no
/// continuous excess falls faster than [`STEEPEST_SLOPE`]): a stick–slip event that moves by a
/// step as the start speed changes. The gap bench's bracketed searches met jumps of tens to
/// hundreds of tolerances across zero, where regula falsi crept to the tolerance for four to
/// eight periods more.
const JUMP_SLOPE: f64 = 2.0 * STEEPEST_SLOPE;

/// Where the excess jumps across zero, the bracket is halved down to this many tolerances.
const JUMP_BRACKET: f64 = 4.0;

/// A point of the excess evaluated in a search: the start speed, the excess, the period.
#[derive(Debug, Clone, Copy)]
struct Side {
    x: f64,
    e: f64,
    orbit: Orbit,
}

/// The orbit where the excess jumps across zero between `a` (above zero) and `b` (below): no
/// start repeats itself there, and the carriage's periods alternate between the two sides in
/// the shares whose drifts cancel (`a.e·s_a + b.e·s_b = 0`). Returns that mix's mean speed and
/// ripple (the larger) and its start speed.
fn mixed(a: &Side, b: &Side) -> (Orbit, f64) {
    let share_a = -b.e / (a.e - b.e);
    let share_b = 1.0 - share_a;
    let orbit = Orbit {
        mean_speed_m_s: share_a * a.orbit.mean_speed_m_s + share_b * b.orbit.mean_speed_m_s,
        ripple_m_s: a.orbit.ripple_m_s.max(b.orbit.ripple_m_s),
    };
    (orbit, share_a * a.x + share_b * b.x)
}

/// How far from rest a period's start speed is searched, in the foot's peak speeds (first ±4×,
/// see [`ContactModel::orbit_near`]).
const WIDEST_BRACKET: f64 = 64.0;

/// Secant steps from a hint before the bracketed search takes over.
const SECANT_STEPS: usize = 4;

/// A sticking step is halved while the carriage on the friction layer, `√(kt/M)`, turns by more
/// than this (rad) in it: on a light carriage the layer's oscillation is then resolved.
const SPLIT_LAYER_TURN_RAD: f64 = 0.05;
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
        // μ's factor only where the foot presses: no step reads it without contact, and the
        // Stribeck factor's exp is a step's dearest part.
        let (rail_n, mu_scale) = if self.plain {
            (0.0, 1.0)
        } else {
            let mu_scale =
                if fc > 0.0 { self.preload_factor * self.effects.stribeck_factor(foot_m_s - v) } else { 1.0 };
            (self.effects.rail_force_on_slider_n(v), mu_scale)
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
    /// points the steps evaluated on either side of the root, or about the one side found (twice
    /// its excess over the hint's slope) or the hint (2 % of the foot's peak speed), widened
    /// fourfold until it holds the root. Returns the orbit and where it starts. The root is the
    /// same as from the full bracket (to [`Self::with_root_tolerance`] of the foot's peak speed,
    /// or, where the excess jumps across zero, the jump to [`JUMP_BRACKET`] tolerances); only
    /// the periods spent finding it are fewer.
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
        let start_at = |v0_m_s: f64, slope: f64| OrbitStart {
            v0_m_s,
            layer: carried.get().unwrap_or_default(),
            // Bounded, a NaN (not known) kept as it is.
            slope: if slope < STEEPEST_SLOPE { STEEPEST_SLOPE } else { slope },
        };
        let tol = self.root_tolerance * w;
        // With a nearby solution's slope, secant steps from its start: the excess is close to
        // linear there, and two or three periods find the root. Each step's slope must stay
        // within a factor of two of the hint's (the same branch of the period map, which jumps
        // where friction weakens with speed), else the bracketed search below runs.
        // The points the secant steps evaluated, nearest the root from each side (the excess
        // falls with v(0)): where the steps leave their branch, the bracket starts from them.
        let (mut below, mut above) = (None::<Side>, None::<Side>);
        let mut seen = |x: f64, e: f64, orbit: Orbit| {
            if e > 0.0 && below.is_none_or(|b| x > b.x) {
                below = Some(Side { x, e, orbit });
            } else if e < 0.0 && above.is_none_or(|a| x < a.x) {
                above = Some(Side { x, e, orbit });
            }
        };
        if let Some(h) = hint.filter(|h| h.v0_m_s.is_finite() && h.slope < 0.0) {
            let (mut x0, (mut e0, mut orbit)) = (h.v0_m_s, excess(h.v0_m_s));
            seen(x0, e0, orbit);
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
                seen(x1, e1, o1);
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
        let side = |x: f64| {
            let (e, orbit) = excess(x);
            Side { x, e, orbit }
        };
        let (mut a, mut b) = match hint_v0.filter(|h| h.is_finite() && *h > lo && *h < hi) {
            Some(h) => {
                // Widened about the side the secant found, else about the hint (also where its
                // two sides are out of order: the map is not monotone there).
                let (below, above) = match (below, above) {
                    (Some(a), Some(b)) if a.x >= b.x => (None, None),
                    sides => sides,
                };
                let c = match (below, above) {
                    (Some(known), None) | (None, Some(known)) => known.x,
                    _ => h,
                };
                // One side known: the root is about its excess over the hint's slope away (twice
                // that, then widened fourfold), not a fixed 2 % of the foot's speed away.
                let mut half = 0.02 * w;
                if let ((Some(known), None) | (None, Some(known)), Some(s)) =
                    ((below, above), hint.map(|h| h.slope).filter(|s| *s < 0.0))
                {
                    half = (2.0 * known.e.abs() / s.max(STEEPEST_SLOPE).abs()).clamp(4.0 * tol, half);
                }
                let mut a = below.unwrap_or_else(|| side((c - half).max(lo)));
                let mut b = above.unwrap_or_else(|| side((c + half).min(hi)));
                while (a.e <= 0.0 && a.x > lo) || (b.e >= 0.0 && b.x < hi) {
                    half *= 4.0;
                    if a.e <= 0.0 && a.x > lo {
                        a = side((c - half).max(lo));
                    }
                    if b.e >= 0.0 && b.x < hi {
                        b = side((c + half).min(hi));
                    }
                }
                (a, b)
            }
            None => (side(lo), side(hi)),
        };
        // A light carriage's speed ripples within a period by more than the foot's peak speed
        // (0.3 kg at 17 N, 60 V, 0.9 kHz against 4.17 N: from −5.5 to +1.5 mm/s about a mean of
        // −1.78, the foot's peak 1.1), so a period's start speed can lie beyond ±4×: the bracket
        // widens further, doubling, before there is no orbit. A bracket that held at ±4× is
        // left as it was (the same root as before).
        while a.e <= 0.0 && a.x > -WIDEST_BRACKET * w {
            a = side((2.0 * a.x.min(-w)).max(-WIDEST_BRACKET * w));
        }
        while b.e >= 0.0 && b.x < WIDEST_BRACKET * w {
            b = side((2.0 * b.x.max(w)).min(WIDEST_BRACKET * w));
        }
        if a.e <= 0.0 || b.e >= 0.0 {
            return None;
        }
        // Regula falsi (Illinois) on the falling excess, stopped when a step moves v(0) by less
        // than the tolerance, or when the excess at the point evaluated is so small that the
        // bracket's own slope (the excesses as evaluated, not as Illinois scales them) puts the
        // root within the tolerance of it: the last point evaluated is then the orbit. Where
        // the excess falls across the bracket faster than any continuous excess can
        // ([`JUMP_SLOPE`]), it jumps across zero inside: halved down to [`JUMP_BRACKET`]
        // tolerances, the orbit is the mix of its ends ([`mixed`]).
        let mut last = f64::NAN;
        let mut illinois = 0i8;
        let (mut scaled_a, mut scaled_b) = (a.e, b.e);
        for i in 0..60 {
            let slope = (b.e - a.e) / (b.x - a.x);
            let jump = slope < JUMP_SLOPE;
            if jump && b.x - a.x < JUMP_BRACKET * tol {
                let (orbit, v0_m_s) = mixed(&a, &b);
                return Some((orbit, start_at(v0_m_s, slope)));
            }
            let mut m = (a.x * scaled_b - b.x * scaled_a) / (scaled_b - scaled_a);
            if jump || !(m > a.x && m < b.x) || i % 8 == 7 {
                m = 0.5 * (a.x + b.x);
            }
            let (em, orbit) = excess(m);
            if (m - last).abs() < tol || b.x - a.x < tol || em.abs() < slope.abs() * tol {
                return Some((orbit, start_at(m, slope)));
            }
            last = m;
            if em > 0.0 {
                a = Side { x: m, e: em, orbit };
                scaled_a = em;
                if illinois == 1 {
                    scaled_b *= 0.5;
                }
                illinois = 1;
            } else {
                b = Side { x: m, e: em, orbit };
                scaled_b = em;
                if illinois == -1 {
                    scaled_a *= 0.5;
                }
                illinois = -1;
            }
        }
        let m = 0.5 * (a.x + b.x);
        let orbit = excess(m).1;
        Some((orbit, start_at(m, (b.e - a.e) / (b.x - a.x))))
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
