//! The carriage's periodic motion under the stator's own contact force, in the core (f32): the
//! copy of host-sim's `steady_contact` orbit (`ContactModel::period` and its search), issue 28
//! item 3. The contact force comes in as a [`ContactForce`], made by the core's copy of the
//! stator's normal motion ([`crate::normal_motion`]) or, in host-sim's tests, from the f64
//! model's. The board's contact table calls both (`controller/contact_build.rs`; its cost on the
//! M4 in docs/firmware.md).
//!
//! The carriage takes [`BASE_STEPS`] steps per period, each halved (down to 1/[`FINE`] of it)
//! where the contact starts, ends or changes by more than [`SPLIT_FORCE_N`] within it, and while
//! it sticks to the foot with its oscillation on the friction layer, `√(kt/M)`, turning by more
//! than [`SPLIT_LAYER_TURN_RAD`] in a step. Between the foot and the carriage: Coulomb friction
//! with εc (eq. 16) in series with the friction layer (shear spring `kt`, dashpot `ct`), the law
//! of host-sim's `contact_friction::Layer::kelvin_voigt`.
//!
//! Memory: the force of a base step is a straight line between its ends unless it holds a
//! contact switch or an impact, whose [`FINE`] sub-step means are kept (at most [`MAX_EVENTS`]
//! such steps): about 4 KB for a period.

use heapless::Vec;

/// Base steps per drive period.
pub const BASE_STEPS: usize = 256;
/// Sub-steps of a base step where the contact's events are resolved.
pub const FINE: usize = 16;
/// Base steps per period whose force is kept on its sub-steps (landing, impacts, take-off).
pub const MAX_EVENTS: usize = 48;
/// A step is halved where the contact force changes by more than this within it (N).
pub const SPLIT_FORCE_N: f32 = 0.25;
/// A sticking step is halved while the carriage on the friction layer turns more than this (rad).
pub const SPLIT_LAYER_TURN_RAD: f32 = 0.05;
/// A base step is kept on its sub-steps where a straight line between its ends misses a sub-step
/// mean by more than this (N).
const LINE_TOLERANCE_N: f32 = 0.1;

/// The contact force over one drive period, φ from −π (the bottom of the foot's ellipse).
#[derive(Debug, Clone)]
pub struct ContactForce {
    /// The force at the start of base step i (N); entry BASE_STEPS closes the period.
    edge_n: [f32; BASE_STEPS + 1],
    /// Per base step, the index into `events` of its sub-step means, or `u8::MAX`.
    event_at: [u8; BASE_STEPS],
    events: Vec<[f32; FINE], MAX_EVENTS>,
}

/// Why a force profile could not be taken.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ForceError {
    /// More than [`MAX_EVENTS`] base steps need their sub-steps.
    TooManyEvents,
    /// Not exactly [`BASE_STEPS`] base steps were given.
    Incomplete,
}

/// The force at a base-step edge from the sub-step means either side: their mean while the foot
/// presses on both sides; a contact that starts or ends at the edge puts the edge at zero.
fn edge_force_n(before: f32, after: f32) -> f32 {
    if before > 0.0 && after > 0.0 {
        0.5 * (before + after)
    } else {
        0.0
    }
}

/// A [`ContactForce`] taken one base step at a time, as the stator's normal motion makes it
/// (`crate::normal_motion`): only the first and the last base step's sub-steps are held.
pub struct ForceBuilder {
    force: ContactForce,
    first: [f32; FINE],
    last: [f32; FINE],
    pushed: usize,
    error: Option<ForceError>,
}

impl Default for ForceBuilder {
    fn default() -> Self {
        Self::new()
    }
}

impl ForceBuilder {
    pub fn new() -> Self {
        ForceBuilder {
            force: ContactForce {
                edge_n: [0.0; BASE_STEPS + 1],
                event_at: [u8::MAX; BASE_STEPS],
                events: Vec::new(),
            },
            first: [0.0; FINE],
            last: [0.0; FINE],
            pushed: 0,
            error: None,
        }
    }

    /// The next base step's [`FINE`] sub-step means (N). Step k is classified once step k + 1
    /// has fixed its closing edge; step 0 waits for the period's end, which fixes its opening one.
    pub fn push(&mut self, sub: [f32; FINE]) {
        let k = self.pushed;
        if k >= BASE_STEPS {
            self.error = Some(ForceError::Incomplete);
            return;
        }
        if k == 0 {
            self.first = sub;
        } else {
            if let Some(e) = self.force.edge_n.get_mut(k) {
                *e = edge_force_n(self.last[FINE - 1], sub[0]);
            }
            if k > 1 {
                let last = self.last;
                self.note(k - 1, &last);
            }
        }
        self.last = sub;
        self.pushed += 1;
    }

    fn note(&mut self, k: usize, sub: &[f32; FINE]) {
        if let Err(e) = self.force.classify(k, sub) {
            self.error.get_or_insert(e);
        }
    }

    /// The force, once all [`BASE_STEPS`] steps are in.
    pub fn finish(mut self) -> Result<ContactForce, ForceError> {
        if self.pushed != BASE_STEPS {
            return Err(ForceError::Incomplete);
        }
        // The period closes on itself: edge 0 is edge BASE_STEPS.
        let wrap = edge_force_n(self.last[FINE - 1], self.first[0]);
        self.force.edge_n[0] = wrap;
        self.force.edge_n[BASE_STEPS] = wrap;
        let (first, last) = (self.first, self.last);
        self.note(BASE_STEPS - 1, &last);
        self.note(0, &first);
        match self.error {
            Some(e) => Err(e),
            None => Ok(self.force),
        }
    }
}

impl ContactForce {
    /// The force from its [`FINE`]·[`BASE_STEPS`] sub-step means (`fine_n(j)`, sub-step j from
    /// φ = −π): the edges from the means either side, and the sub-steps kept where a straight
    /// line does not carry them.
    pub fn from_fine(fine_n: impl Fn(usize) -> f32) -> Result<Self, ForceError> {
        let mut builder = ForceBuilder::new();
        for k in 0..BASE_STEPS {
            builder.push(core::array::from_fn(|i| fine_n(k * FINE + i)));
        }
        builder.finish()
    }

    /// Keeps base step k on its sub-steps where the straight line between its edges misses one.
    fn classify(&mut self, k: usize, sub: &[f32; FINE]) -> Result<(), ForceError> {
        let off_line =
            sub.iter().enumerate().any(|(i, f)| (self.line_mean(k, i, 1) - f).abs() > LINE_TOLERANCE_N);
        if off_line {
            let index = self.events.len() as u8;
            self.events.push(*sub).map_err(|_| ForceError::TooManyEvents)?;
            if let Some(slot) = self.event_at.get_mut(k) {
                *slot = index;
            }
        }
        Ok(())
    }

    /// The force at the start and the end of base step k.
    fn edges(&self, k: usize) -> (f32, f32) {
        let at = |i: usize| self.edge_n.get(i).copied().unwrap_or(0.0);
        (at(k), at(k + 1))
    }

    /// Mean of sub-steps `first..first + len` of base step k on the straight line.
    fn line_mean(&self, k: usize, first: usize, len: usize) -> f32 {
        let (a, b) = self.edges(k);
        let mid = (first as f32 + 0.5 * len as f32) / FINE as f32;
        a + (b - a) * mid
    }

    /// Mean force over sub-steps `first..first + len` of base step k, and whether an orbit may
    /// take them whole (the contact neither starts nor ends in them, the force changes by at
    /// most [`SPLIT_FORCE_N`]).
    fn run(&self, k: usize, first: usize, len: usize) -> (f32, bool) {
        match self.event_at.get(k).and_then(|&i| self.events.get(usize::from(i))) {
            Some(sub) => {
                let run = sub.get(first..first + len).unwrap_or(&[]);
                let pressing = run.first().is_some_and(|f| *f > 0.0);
                let (mut lo, mut hi, mut sum) = (f32::INFINITY, f32::NEG_INFINITY, 0.0f32);
                let mut same = true;
                for &f in run {
                    lo = lo.min(f);
                    hi = hi.max(f);
                    sum += f;
                    same &= (f > 0.0) == pressing;
                }
                (sum / len as f32, same && hi - lo <= SPLIT_FORCE_N)
            }
            None => {
                let (a, b) = self.edges(k);
                let change = (b - a).abs() * len as f32 / FINE as f32;
                (self.line_mean(k, first, len), change <= SPLIT_FORCE_N)
            }
        }
    }

    /// Mean force over the period (N).
    pub fn mean_n(&self) -> f32 {
        (0..BASE_STEPS).map(|k| self.run(k, 0, FINE).0).sum::<f32>() / BASE_STEPS as f32
    }

    /// Base steps kept on their sub-steps.
    pub fn events(&self) -> usize {
        self.events.len()
    }
}

/// (cos φ, sin φ) at the base steps' edges, φ = −π + k·2π/256, by the angle-addition recurrence
/// from cos −π = −1, sin −π = 0: one rotation per edge instead of a cosine (cos and sin of
/// 2π/256). The orbit's foot speed and the normal motion's drive both step along it.
pub fn edge_phases() -> [(f32, f32); BASE_STEPS + 1] {
    const _: () = assert!(BASE_STEPS == 256);
    let (cr, sr) = (0.999_698_8_f32, 0.024_541_229_f32);
    let mut out = [(0.0f32, 0.0f32); BASE_STEPS + 1];
    let (mut co, mut si) = (-1.0f32, 0.0f32);
    for e in out.iter_mut() {
        *e = (co, si);
        (co, si) = (co * cr - si * sr, si * cr + co * sr);
    }
    out
}

/// The carriage, the interface and the drive of one orbit.
#[derive(Debug, Clone, Copy)]
pub struct Carriage {
    pub mass_kg: f32,
    /// The friction layer's shear spring and dashpot.
    pub kt_n_per_m: f32,
    pub ct_n_s_per_m: f32,
    /// Sticking limit and sliding coefficient.
    pub mu_stick: f32,
    pub mu_dynamic: f32,
    /// εc of eq. (16).
    pub viscous_n_s_per_m: f32,
    /// The guide's viscous drag on the carriage.
    pub guide_n_s_per_m: f32,
    /// The foot's peak tangential speed ω·Xc (m/s) and the drive frequency.
    pub foot_peak_m_s: f32,
    pub frequency_hz: f32,
}

/// What the interface did over the last step.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
enum Mode {
    #[default]
    Free,
    Stick,
    Slip,
}

/// The friction layer's shear and shear rate, and the interface's last mode.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
struct Layer {
    shear_m: f32,
    rate_m_s: f32,
    mode: Mode,
}

/// Where an orbit starts: the start speed, the layer there and the slope of the period's excess
/// `v(T) − v(0)` against `v(0)`. A nearby orbit's start (the next load of a table) is where
/// [`Orbits::orbit_near`] begins.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Start {
    pub v0_m_s: f32,
    layer: Layer,
    pub slope: f32,
}

/// A period under way: speed, layer, Σ speed × sub-steps.
struct Run {
    v: f32,
    layer: Layer,
    sum: f32,
}

/// The orbits of one carriage under one contact force.
pub struct Orbits<'a> {
    force: &'a ContactForce,
    c: Carriage,
    h_fine_s: f32,
    layer_rad_s: f32,
    /// cos φ at the base steps' edges, φ from −π.
    cos_edge: [f32; BASE_STEPS + 1],
}

impl<'a> Orbits<'a> {
    pub fn new(force: &'a ContactForce, c: Carriage) -> Self {
        let cos_edge = edge_phases().map(|(cos, _)| cos);
        Orbits {
            force,
            c,
            h_fine_s: 1.0 / (c.frequency_hz.max(1.0) * (BASE_STEPS * FINE) as f32),
            layer_rad_s: crate::fastmath::sqrt_f32(c.kt_n_per_m.max(0.0) / c.mass_kg.max(1e-6)),
            cos_edge,
        }
    }

    /// The foot's speed at the end of sub-step `first + len − 1` of base step k (the cosine
    /// between the base edges on a straight line: within 8e-5 of the foot's peak speed).
    fn foot_m_s(&self, k: usize, end: usize) -> f32 {
        let at = |i: usize| self.cos_edge.get(i).copied().unwrap_or(0.0);
        let (a, b) = (at(k), at(k + 1));
        self.c.foot_peak_m_s * (a + (b - a) * end as f32 / FINE as f32)
    }

    /// One period from `v0_m_s` with the layer as given: the end speed, mean speed and layer.
    fn period(&self, v0_m_s: f32, layer: Layer, load_n: f32) -> (f32, f32, Layer) {
        let mut run = Run { v: v0_m_s, layer, sum: 0.0 };
        for k in 0..BASE_STEPS {
            self.step(&mut run, k, 0, FINE, load_n);
        }
        (run.v, run.sum / (BASE_STEPS * FINE) as f32, run.layer)
    }

    /// The carriage over sub-steps `first..first + len` of base step k, halved where needed.
    fn step(&self, run: &mut Run, k: usize, first: usize, len: usize, load_n: f32) {
        let h = self.h_fine_s * len as f32;
        let (fc, even) = self.force.run(k, first, len);
        let sticking = run.layer.mode == Mode::Stick;
        if len > 1 && (!even || (sticking && self.layer_rad_s * h > SPLIT_LAYER_TURN_RAD)) {
            self.step(run, k, first, len / 2, load_n);
            self.step(run, k, first + len / 2, len / 2, load_n);
            return;
        }
        let foot = self.foot_m_s(k, first + len);
        let external_n = -load_n - self.c.guide_n_s_per_m * run.v;
        let friction = self.layer_step(&mut run.layer, h, run.v, external_n, fc, foot);
        run.v += (external_n + friction) * h / self.c.mass_kg;
        run.sum += run.v * len as f32;
    }

    /// The interface over a step (host-sim's `Layer::kelvin_voigt`): the layer sticks by the
    /// trapezoidal rule while the force it needs is within μ·Fc, else the interface slides at
    /// μd·Fc (with εc's viscous part) and the layer relaxes toward that force (implicit).
    fn layer_step(&self, l: &mut Layer, dt: f32, v: f32, external_n: f32, fc: f32, foot: f32) -> f32 {
        let (mass, kt, ct) = (self.c.mass_kg, self.c.kt_n_per_m, self.c.ct_n_s_per_m);
        let u0 = l.rate_m_s;
        let a = 0.25 * kt * dt + 0.5 * ct;
        let g = dt / mass;
        let v_stick = (v + g * (external_n + kt * l.shear_m + a * (u0 + foot))) / (1.0 + g * a);
        let u = foot - v_stick;
        let trial = kt * l.shear_m + a * (u0 + u);
        if fc > 0.0 && trial.abs() <= self.c.mu_stick * fc {
            l.shear_m += 0.5 * dt * (u0 + u);
            l.rate_m_s = u;
            l.mode = Mode::Stick;
            return trial;
        }
        let slide = if fc > 0.0 { self.c.mu_dynamic * fc * trial.signum() } else { 0.0 };
        let s_new = (slide + ct / dt * l.shear_m) / (kt + ct / dt);
        l.rate_m_s = (s_new - l.shear_m) / dt;
        l.shear_m = s_new;
        if fc > 0.0 {
            l.mode = Mode::Slip;
            // εc·(foot − v_new), implicit in v_new.
            let kv = self.c.viscous_n_s_per_m * g;
            let v_new = (v + g * (external_n + slide) + kv * foot) / (1.0 + kv);
            slide + self.c.viscous_n_s_per_m * (foot - v_new)
        } else {
            l.mode = Mode::Free;
            0.0
        }
    }

    /// Mean speed of the periodic motion against `load_n` (m/s along the drive), found by regula
    /// falsi (Illinois) on the period's start speed to 1e-4 of the foot's peak speed, the layer
    /// carried from one period to the next; `None` where no orbit starts within ±16 foot speeds.
    pub fn mean_speed_m_s(&self, load_n: f32) -> Option<f32> {
        self.orbit_near(load_n, None).map(|(mean, _)| mean)
    }

    /// Mean speeds against `loads` in a row (a speed table: ascending loads), each search started
    /// where the last two orbits' starts point: their start speed extrapolated linearly in the
    /// load, the last one's layer and slope ([`Self::orbit_near`]). About two periods a load
    /// where one hint alone took three or four. None where a load has no orbit.
    pub fn speeds_along<const N: usize>(&self, loads: &[f32; N]) -> [Option<f32>; N] {
        let mut out = [None; N];
        let mut last: Option<(f32, Start)> = None;
        let mut before: Option<(f32, Start)> = None;
        for (slot, &load_n) in out.iter_mut().zip(loads) {
            let hint = match (last, before) {
                (Some((l1, s1)), Some((l0, s0))) if (l1 - l0).abs() > 0.0 => {
                    let v0_m_s = s1.v0_m_s + (s1.v0_m_s - s0.v0_m_s) * (load_n - l1) / (l1 - l0);
                    Some(Start { v0_m_s, ..s1 })
                }
                (Some((_, s1)), _) => Some(s1),
                _ => None,
            };
            match self.orbit_near(load_n, hint) {
                Some((speed, start)) => {
                    *slot = Some(speed);
                    before = last;
                    last = Some((load_n, start));
                }
                None => (before, last) = (None, None),
            }
        }
        out
    }

    /// [`Self::mean_speed_m_s`] from a nearby orbit's start: secant steps from it while the
    /// excess' slope stays within a factor of two of the hint's (the same branch of the period
    /// map), else the bracketed search. Returns the mean speed and this orbit's start.
    pub fn orbit_near(&self, load_n: f32, hint: Option<Start>) -> Option<(f32, Start)> {
        let w = self.c.foot_peak_m_s.abs().max(1e-9);
        let tol = 1e-4 * w;
        if let Some(h) = hint.filter(|h| h.v0_m_s.is_finite() && h.slope < 0.0) {
            let mut layer = h.layer;
            let mut excess = |v0: f32| {
                let (end, mean, l) = self.period(v0, layer, load_n);
                layer = l;
                (end - v0, mean)
            };
            let (mut x0, (mut e0, mut mean)) = (h.v0_m_s, excess(h.v0_m_s));
            let mut slope = h.slope;
            for _ in 0..4 {
                if e0.abs() < slope.abs() * tol {
                    return Some((mean, Start { v0_m_s: x0, layer, slope }));
                }
                let x1 = x0 - e0 / slope;
                if !x1.is_finite() || (x1 - h.v0_m_s).abs() > 0.5 * w {
                    break;
                }
                let (e1, m1) = excess(x1);
                let s1 = (e1 - e0) / (x1 - x0);
                if !(s1 <= 0.5 * h.slope && s1 >= 2.0 * h.slope) {
                    break;
                }
                (x0, e0, mean, slope) = (x1, e1, m1, s1);
            }
        }
        self.bracketed(load_n)
    }

    /// The bracketed search of [`Self::orbit_near`].
    fn bracketed(&self, load_n: f32) -> Option<(f32, Start)> {
        let w = self.c.foot_peak_m_s.abs().max(1e-9);
        let mut layer = self.period(0.0, Layer::default(), load_n).2;
        let mut excess = |v0: f32| {
            let (end, mean, l) = self.period(v0, layer, load_n);
            layer = l;
            (end - v0, mean)
        };
        let (mut lo, mut hi) = (-4.0 * w, 4.0 * w);
        let (mut e_lo, mut e_hi) = (excess(lo).0, excess(hi).0);
        while e_lo <= 0.0 && lo > -16.0 * w {
            lo *= 2.0;
            e_lo = excess(lo).0;
        }
        while e_hi >= 0.0 && hi < 16.0 * w {
            hi *= 2.0;
            e_hi = excess(hi).0;
        }
        if !(e_lo > 0.0 && e_hi < 0.0) {
            return None;
        }
        let tol = 1e-4 * w;
        let (mut side, mut mean, mut at) = (0i8, f32::NAN, 0.0f32);
        let (mut raw_lo, mut raw_hi) = (e_lo, e_hi);
        for i in 0..40 {
            let mut m = (lo * e_hi - hi * e_lo) / (e_hi - e_lo);
            if !(m > lo && m < hi) || i % 8 == 7 {
                m = 0.5 * (lo + hi);
            }
            let (e, mm) = excess(m);
            (mean, at) = (mm, m);
            if hi - lo < tol || e.abs() < 1e-6 * w {
                break;
            }
            if e > 0.0 {
                raw_lo = e;
                (lo, e_lo) = (m, e);
                if side == 1 {
                    e_hi *= 0.5;
                }
                side = 1;
            } else {
                raw_hi = e;
                (hi, e_hi) = (m, e);
                if side == -1 {
                    e_lo *= 0.5;
                }
                side = -1;
            }
        }
        Some((mean, Start { v0_m_s: at, layer, slope: (raw_hi - raw_lo) / (hi - lo) }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_force_with_more_events_than_room_is_refused_not_cut() {
        // A foot that lands in every other base step: 128 steps off a straight line.
        let chattering = |j: usize| if (j / FINE) % 2 == 0 && j % FINE == FINE / 2 { 50.0 } else { 0.0 };
        assert_eq!(ContactForce::from_fine(chattering).err(), Some(ForceError::TooManyEvents));
        // Within room: one impact in a smooth arc.
        let arc = |j: usize| if j == 100 { 80.0 } else { 10.0 };
        assert_eq!(ContactForce::from_fine(arc).map(|f| f.events()), Ok(1));
    }

    #[test]
    fn a_force_taken_step_by_step_needs_exactly_one_period() {
        // The normal motion streams a period's base steps into the builder: one short or one
        // over is an error, not a force with a hole or a wrapped step.
        let mut short = ForceBuilder::new();
        for _ in 1..BASE_STEPS {
            short.push([10.0; FINE]);
        }
        assert_eq!(short.finish().err(), Some(ForceError::Incomplete));
        let mut over = ForceBuilder::new();
        for _ in 0..=BASE_STEPS {
            over.push([10.0; FINE]);
        }
        assert_eq!(over.finish().err(), Some(ForceError::Incomplete));
        let mut whole = ForceBuilder::new();
        for _ in 0..BASE_STEPS {
            whole.push([10.0; FINE]);
        }
        let mean = whole.finish().map(|f| f.mean_n());
        assert!(mean.is_ok_and(|m| (m - 10.0).abs() < 1e-4), "{mean:?}");
    }

    #[test]
    fn a_straight_force_is_carried_by_its_edges_and_its_runs_mean_what_they_hold() {
        // A force rising and falling linearly over the period (a tent, periodic): no events, and
        // the mean of any run is the force at its middle (the line's own mean), e.g. base step
        // 10's second half.
        let n = (BASE_STEPS * FINE) as f32;
        let tent = |j: usize| 1.0 + 40.0 * (0.5 - ((j as f32 + 0.5) / n - 0.5).abs());
        let force = ContactForce::from_fine(tent);
        assert_eq!(force.as_ref().map(ContactForce::events), Ok(0));
        let Ok(force) = force else { return };
        let (mean, even) = force.run(10, 8, 8);
        let middle = 1.0 + 40.0 * (10.0 * FINE as f32 + 12.0) / n;
        assert!((mean - middle).abs() < 1e-4, "{mean} against {middle}");
        assert!(even, "a change of 20 N over 2048 sub-steps is even in 8");
    }
}
