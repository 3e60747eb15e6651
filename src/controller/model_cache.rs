//! The thrust model as the control tick uses it: prepared off the tick, read in it.
//!
//! Building a model point (contact angle, eq. 14 exact form, and the speed-independent parts of
//! eq. 22) and finding a speed-at-load root cost thousands of instructions on the Cortex-M4, and
//! their inputs (the preload, the configuration) change slowly. So a lower-priority context (the
//! board's thread-mode task, or the host right after each step) builds a [`ModelTable`] for the
//! measured preload: the mean thrust of eq. (22) on a grid of [`VOLT_POINTS`] drive voltages ×
//! [`PHASE_POINTS`] values of φp = acos(v / ω·Xc) (the phase at which the foot's tangential speed
//! equals the slider's, physics.md §4), and the speed at full drive against [`LOAD_POINTS`] loads.
//! The tick interpolates: the thrust at any drive and speed is one acos and a bilinear
//! interpolation (the load observer, the speed-up limit), the inverse model a search over the
//! grid's rows and one secant step, the profile's speed limit a lookup. No root finding, no point
//! building in the tick.
//!
//! Why φp and not the speed as the second coordinate: at a fixed φp the thrust changes smoothly
//! with the drive (eq. 22 scales with `kc·Yc` and the contact angle moves slowly), while at a
//! fixed speed it swings from −μF0 to +μF0 within a few volts at low drive, where the foot's speed
//! passes the slider's (interpolated in speed, the grid missed by 2.7 % of the stall force there).
//! In (voltage, φp) it stays within 1 % of the stall force of the f64 model
//! (`host-sim/tests/fixed_model.rs`).
//!
//! The hand-over: the tick never waits. [`super::Controller::model_request`] says what table the
//! controller wants (none while the installed one fits the measured preload within
//! [`PRELOAD_RESOLVE_N`]); [`ModelTable::build`] runs anywhere; [`super::Controller::install_model`]
//! takes it if it still answers the controller's configuration. Until the first table is in, the
//! profile has no speed to move at (as without a preload reading).

pub use super::contact_build::ContactInputs;
pub use super::frequency_choice::{FrequencyChoice, FREQ_CANDIDATES};
use super::{Controller, ControllerConfig};
use crate::fastmath::{acos_f32, clamp_f32, fx_from_f32};
use crate::inertia::Orbits;
use crate::model::{PerVolt, ThrustPoint};
use crate::trig::cos;
use crate::Fx;

/// Drive voltages of the grid, evenly spaced from 0 to the largest drive.
pub const VOLT_POINTS: usize = 33;
/// Values of φp of the grid, evenly spaced over [0, π].
pub const PHASE_POINTS: usize = 33;
/// Loads of the speed table, evenly spaced from 0 to the stall force at full drive.
pub const LOAD_POINTS: usize = 17;

/// Preload change (N) that asks for a new table: the model's limits change by under 0.5 % over
/// it (the stall force is about μ·F0, 16 N at the prototype's working point). At 0.02 N the force
/// cell's filtered noise crossed it every few milliseconds with a filter coefficient of 0.05
/// (`0x1015`), and each crossing rebuilt the table: 8–14 ms of thread time on the host, enough to
/// hold `host-sim serve` seconds behind the wall clock.
pub const PRELOAD_RESOLVE_N: f32 = 0.05;

/// Row 0 of the grid is built at this share of the voltage step instead of 0 V, where the foot
/// does not move and φp is undefined (the limit the row stands for).
const ROW0_SHARE: f32 = 0.05;

/// What a table is built from.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ModelRequest {
    /// The amplitudes per volt at `frequency_hz`.
    pub per_volt: PerVolt,
    pub preload_n: f32,
    pub max_drive_v: f32,
    /// Drive frequency (Hz) and the carriage's moving mass (kg): a light carriage's speed
    /// ripples within a period, and the table then comes from its periodic motion
    /// ([`crate::inertia`]). With more than one candidate in `choice`, the build chooses the
    /// frequency and the table's own request holds the one chosen.
    pub frequency_hz: f32,
    pub choice: FrequencyChoice,
    pub moving_mass_kg: f32,
    /// Guide friction of the carriage, opposing its motion (Coulomb N, viscous N·s/m): the table
    /// holds the foot's thrust net of it.
    pub rail_coulomb_n: f32,
    pub rail_viscous_n_s_per_m: f32,
    /// The contact model's inputs when the table is to come from it ([`super::contact_build`]),
    /// None for the inertial model.
    pub contact: Option<ContactInputs>,
    /// The table settings this request belongs to (bumped by every accepted settings change
    /// that changes [`TableSettings`]): a table built for an older one is refused.
    pub generation: u32,
}

impl ModelRequest {
    /// Whether a table built for `self` serves `other` as well: the same settings and frequency
    /// choice, a preload within the resolution its table asks for ([`contact_resolve_n`] for the
    /// contact model's) and a choice load within [`PRELOAD_RESOLVE_N`]. A board that builds in the background
    /// keeps its build going while the force cell's noise moves the request's preload.
    pub fn same_table_as(&self, other: &ModelRequest) -> bool {
        let resolve_n =
            if self.contact.is_some() { contact_resolve_n(self.preload_n) } else { PRELOAD_RESOLVE_N };
        let near = |a: f32, b: f32, by: f32| (a - b).abs() <= by;
        let mut choice = self.choice;
        choice.load_n = other.choice.load_n;
        near(self.preload_n, other.preload_n, resolve_n)
            && near(self.choice.load_n, other.choice.load_n, PRELOAD_RESOLVE_N)
            && ModelRequest { preload_n: other.preload_n, choice, ..*self } == *other
    }
}

/// Parts of a table's hand-over ([`Controller::stage_model`]): the header (the request, the
/// speed table), the grid's rows in [`TABLE_PARTS`] − 3 parts, the check against the settings,
/// and the swap.
pub const TABLE_PARTS: usize = 9;
/// Grid rows per part.
const ROWS_PER_PART: usize = VOLT_POINTS.div_ceil(TABLE_PARTS - 3);

/// What a part of a table's hand-over did.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Staged {
    /// Copied beside the table in use; the next part is wanted.
    More,
    /// The last part: the new table is in use.
    Installed,
    /// Out of order, or the table no longer answers the settings: thrown away.
    Refused,
}

/// The model a table was built from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TableModelKind {
    /// Eqs. 19-22 with the carriage's periodic motion where its speed ripples.
    Inertial,
    /// The stator's normal motion and the carriage's orbit on the friction layer.
    Contact,
}

/// The controller's view of its thrust limits at one instant ([`Controller::thrust_inputs`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ThrustInputs {
    preload_n: Option<f32>,
    /// The fitting table's stall force and no-load speed, if a table fits the preload.
    table: Option<(f32, f32)>,
    per_volt: PerVolt,
    max_drive_v: f32,
    rail_coulomb_n: f32,
}

impl ThrustInputs {
    /// Stall force (N) and no-load speed (mm/s) at full drive: the table's, else a model point.
    pub fn limits(&self) -> Option<(f32, f32)> {
        let preload = self.preload_n?;
        if let Some(limits) = self.table {
            return Some(limits);
        }
        let p = self.per_volt.point(fx_from_f32(preload), fx_from_f32(self.max_drive_v));
        // Net of the guide's Coulomb friction (the table's viscous refinement is left out here).
        let guide = fx_from_f32(self.rail_coulomb_n);
        let stall = (p.stall_force_n() - guide).max(Fx::ZERO);
        Some((stall.to_num(), p.speed_at_load_mm_s(guide).to_num()))
    }
}

/// The thrust model at one preload and drive frequency, ready for the tick.
#[derive(Debug, Clone, Copy)]
pub struct ModelTable {
    request: ModelRequest,
    /// Thrust at (`max_drive_v · j / (VOLT_POINTS − 1)`, `π · k / (PHASE_POINTS − 1)`), in units of
    /// `thrust_scale_n` (16 bits: the grid's largest thrust over 32 767).
    thrust_q: [[i16; PHASE_POINTS]; VOLT_POINTS],
    thrust_scale_n: f32,
    /// Grid row per volt: (VOLT_POINTS − 1) / max_drive_v.
    index_per_v: f32,
    /// Peak foot speed per volt, ω·Xc / V (mm/s per V).
    foot_mm_s_per_v: f32,
    stall_n: f32,
    /// Forward speed at full drive against an opposing load `stall_n · k / (LOAD_POINTS − 1)`.
    speed_mm_s: [f32; LOAD_POINTS],
    swing: Swing,
}

/// How far the carriage swings about its mean line within a drive period: a carriage that sticks
/// to the foot follows its whole stroke Xc, its peak speed ω·Xc over ω (eqs. 8–9, per volt); a
/// heavier one only as
/// far as the friction impulse carries it, and friction is at most μ·Fc with Fc averaging the
/// preload over the period (eq. 12): about μ·F0/(M·ω²). On the plant at 16 and 18 N (0.05–5 kg,
/// 1.2 and 2.2 kHz, 30–100 V) the swing is 0.6–1.2× the smaller of the two
/// (`host-sim/tests/steady_inertia.rs` holds it within 0.6–1.25×; at 5 N 0.2–1.35×). M is the told
/// mass: a payload the controller measured makes the true swing smaller, the safe side.
#[derive(Debug, Clone, Copy)]
struct Swing {
    stroke_nm_per_v: f32,
    impulse_nm: f32,
}

impl Swing {
    fn of(r: &ModelRequest) -> Self {
        let omega = core::f32::consts::TAU * r.frequency_hz.max(1.0);
        let foot_mm_s_per_v: f32 = r.per_volt.foot_speed_mm_s_per_v.to_num();
        let mu: f32 = r.per_volt.mu.to_num();
        Swing {
            stroke_nm_per_v: foot_mm_s_per_v * 1e6 / omega,
            impulse_nm: mu * r.preload_n.max(0.0) / (r.moving_mass_kg.max(1e-3) * omega * omega) * 1e9,
        }
    }
}

/// Grid columns per radian of φp.
const COLUMNS_PER_RAD: f32 = (PHASE_POINTS - 1) as f32 / core::f32::consts::PI;

/// Splits a grid coordinate into its cell (at most `last − 1`) and the share into the cell.
fn cell(x: f32, last: usize) -> (usize, f32) {
    let x = clamp_f32(x, 0.0, last as f32);
    let i = (x as usize).min(last - 1);
    (i, x - i as f32)
}

/// Below this share of the constant-speed model's no-load speed at full drive, a carriage rides
/// the foot so much that the whole grid comes from its periodic motion. Above it only the speed
/// table does: the orbit model then runs a few per cent slow against the plant (1 kg at 2.2 kHz:
/// 2.88 against 2.93 mm/s, and more at part drive), and a model that underestimates the speed
/// over-drives short moves (a 10 µm step overshot 764 nm with the orbit grid, 33 nm without).
/// Measured: 0.3 kg at 2.2 kHz runs at 55 % of the constant-speed speed, 1 kg at 94 %.
pub const RIDING_SHARE: f32 = 0.8;

/// Turns a row of constant-speed thrusts (at the grid's φp columns) into the carriage's: each
/// column's constant-speed thrust is taken as a load, the periodic motion under it gives a mean
/// speed, and the row's thrust at each column's speed is read off those (speed, load) pairs
/// (the mean speed falls as the load rises; between pairs linearly, beyond them along the end
/// segment).
fn with_inertia(row: &mut [f32; PHASE_POINTS], orbits: &Orbits, foot_mm_s: f32) {
    through_speed_law(row, |load| orbits.mean_speed_mm_s(load), foot_mm_s);
}

/// [`with_inertia`] for any model of the carriage's mean speed against a load on the foot
/// (mm/s; None where it has none).
pub(super) fn through_speed_law(
    row: &mut [f32; PHASE_POINTS],
    mut speed_at_load: impl FnMut(f32) -> Option<f32>,
    foot_mm_s: f32,
) {
    let mut pairs = [(0.0f32, 0.0f32); PHASE_POINTS];
    let mut n = 0;
    for &load in row.iter() {
        if let (Some(speed), Some(slot)) = (speed_at_load(load), pairs.get_mut(n)) {
            *slot = (speed, load);
            n += 1;
        }
    }
    let Some(pairs) = pairs.get(..n).filter(|p| p.len() >= 2) else { return };
    for (k, t) in row.iter_mut().enumerate() {
        let phi = Fx::PI * k as i32 / (PHASE_POINTS - 1) as i32;
        let v: f32 = foot_mm_s * cos(phi).to_num::<f32>();
        *t = load_at_speed(pairs, v);
    }
}

/// The load at which the pairs' mean speed is `v` (pairs ordered by rising load).
pub(super) fn load_at_speed(pairs: &[(f32, f32)], v: f32) -> f32 {
    let mut seg = pairs.windows(2).last();
    for w in pairs.windows(2) {
        if let [a, b] = w {
            if (a.0 >= v && v >= b.0) || (a.0 <= v && v <= b.0) {
                seg = Some(w);
                break;
            }
        }
    }
    // Faster than the lightest load gives: extrapolate along the first segment.
    if pairs.first().is_some_and(|p| v > p.0) {
        seg = pairs.windows(2).next();
    }
    match seg {
        Some([a, b]) => {
            let d = b.0 - a.0;
            if d.abs() > 1e-9 {
                a.1 + (b.1 - a.1) * (v - a.0) / d
            } else {
                0.5 * (a.1 + b.1)
            }
        }
        _ => pairs.first().map_or(0.0, |p| p.1),
    }
}

/// Guide friction at a slider speed along the drive (N): Coulomb opposing the motion (and the
/// start of motion at standstill, so the stall force is net of it) plus viscous.
fn guide_friction_n(request: &ModelRequest, speed_mm_s: f32) -> f32 {
    let coulomb = if speed_mm_s < -1e-6 { -request.rail_coulomb_n } else { request.rail_coulomb_n };
    coulomb + request.rail_viscous_n_s_per_m * speed_mm_s * 1e-3
}

/// Takes the guide friction off a row of foot thrusts (at the grid's φp columns).
pub(super) fn less_guide_friction(row: &mut [f32; PHASE_POINTS], request: &ModelRequest, foot_mm_s: f32) {
    if request.rail_coulomb_n == 0.0 && request.rail_viscous_n_s_per_m == 0.0 {
        return;
    }
    for (k, t) in row.iter_mut().enumerate() {
        let phi = Fx::PI * k as i32 / (PHASE_POINTS - 1) as i32;
        *t -= guide_friction_n(request, foot_mm_s * cos(phi).to_num::<f32>());
    }
}

/// The speed at which the foot's thrust balances `load_n` plus the guide friction, from
/// `speed_at_foot_load` (the speed against a load on the foot alone): the viscous part depends
/// on the speed, so three passes (its share of the thrust is small; each pass shrinks the
/// error by that share).
pub fn with_guide_friction(
    request: &ModelRequest,
    load_n: f32,
    mut speed_at_foot_load: impl FnMut(f32) -> f32,
) -> f32 {
    let mut v = speed_at_foot_load(load_n + request.rail_coulomb_n);
    if request.rail_viscous_n_s_per_m != 0.0 {
        for _ in 0..3 {
            v = speed_at_foot_load(load_n + guide_friction_n(request, v.max(0.0)));
        }
    }
    v
}

/// Thrust of a row at zero slider speed: the φp = π/2 column.
pub(super) fn thrust_at_zero_speed(row: &[f32; PHASE_POINTS]) -> f32 {
    row.get((PHASE_POINTS - 1) / 2).copied().unwrap_or(0.0)
}

/// Row `j`'s drive (V) of the thrust grid.
pub(super) fn row_volts(request: &ModelRequest, j: usize) -> f32 {
    let step_v = request.max_drive_v.max(0.0) / (VOLT_POINTS - 1) as f32;
    if j == 0 {
        ROW0_SHARE * step_v
    } else {
        step_v * j as f32
    }
}

/// Row `j` of the constant-speed model's thrust grid (N, eqs. 19–22, before the guide's
/// friction), and its model point.
pub(super) fn constant_speed_row(request: &ModelRequest, j: usize) -> (ThrustPoint, [f32; PHASE_POINTS]) {
    let preload = fx_from_f32(request.preload_n);
    let point = request.per_volt.point(preload, fx_from_f32(row_volts(request, j)));
    let mut row = [0.0f32; PHASE_POINTS];
    for (k, t) in row.iter_mut().enumerate() {
        let phi = Fx::PI * k as i32 / (PHASE_POINTS - 1) as i32;
        *t = point.thrust_n(point.foot_speed_mm_s.saturating_mul(cos(phi))).to_num();
    }
    (point, row)
}

/// Row `j` of the grid from a model of the carriage's mean speed at a drive and a load on the
/// foot, `speed_at(volts, load_n)` (mm/s), net of the guide's friction: as [`thrust_row`] for a
/// riding carriage, with that model in place of the periodic motion of [`Orbits`].
pub(super) fn thrust_row_from_law(
    request: &ModelRequest,
    j: usize,
    speed_at: &mut impl FnMut(f32, f32) -> Option<f32>,
) -> [f32; PHASE_POINTS] {
    let volts = row_volts(request, j);
    let (point, mut row) = constant_speed_row(request, j);
    let foot_mm_s: f32 = point.foot_speed_mm_s.to_num();
    through_speed_law(&mut row, |load| speed_at(volts, load), foot_mm_s);
    less_guide_friction(&mut row, request, foot_mm_s);
    row
}

/// Row `j` of the thrust grid (N) at the request's preload, net of the guide's friction, from
/// the carriage's periodic motion where it rides the foot.
pub(super) fn thrust_row(request: &ModelRequest, riding: bool, j: usize) -> [f32; PHASE_POINTS] {
    let (point, mut row) = constant_speed_row(request, j);
    if riding {
        let orbits = Orbits::new(&point, request.frequency_hz, request.moving_mass_kg);
        if orbits.inertia_matters() {
            with_inertia(&mut row, &orbits, point.foot_speed_mm_s.to_num());
        }
    }
    less_guide_friction(&mut row, request, point.foot_speed_mm_s.to_num());
    row
}

impl ModelTable {
    /// The table from its grid (N, at the grid's nodes), the grid's largest thrust, the stall
    /// force and the speed table of `request` (the one chosen).
    pub(super) fn assemble(
        request: &ModelRequest,
        thrust_n: &[[f32; PHASE_POINTS]; VOLT_POINTS],
        largest: f32,
        stall_n: f32,
        speed_mm_s: [f32; LOAD_POINTS],
    ) -> Self {
        let top = request.max_drive_v.max(0.0);
        let thrust_scale_n = if largest > 0.0 { largest / 32_767.0 } else { 1.0 };
        let thrust_q = thrust_n.map(|row| {
            row.map(|t| {
                let q = t / thrust_scale_n;
                (if q >= 0.0 { q + 0.5 } else { q - 0.5 }) as i16
            })
        });
        ModelTable {
            request: *request,
            thrust_q,
            thrust_scale_n,
            index_per_v: if top > 0.0 { (VOLT_POINTS - 1) as f32 / top } else { 0.0 },
            foot_mm_s_per_v: request.per_volt.foot_speed_mm_s_per_v.to_num(),
            stall_n,
            speed_mm_s,
            swing: Swing::of(request),
        }
    }

    pub fn request(&self) -> &ModelRequest {
        &self.request
    }

    /// A table of zeros for `cfg`'s motor: what a slot holds before its first table (never read:
    /// [`ModelSlot`] says which slot is in use).
    fn placeholder(cfg: &ControllerConfig) -> Self {
        let per_volt = cfg.per_volt();
        let request = ModelRequest {
            per_volt,
            preload_n: 0.0,
            max_drive_v: cfg.max_drive_v,
            frequency_hz: cfg.drive_freq_hz,
            choice: FrequencyChoice::fixed(cfg.drive_freq_hz, per_volt, 0.0),
            moving_mass_kg: cfg.moving_mass_kg,
            rail_coulomb_n: 0.0,
            rail_viscous_n_s_per_m: 0.0,
            contact: None,
            generation: 0,
        };
        ModelTable::assemble(&request, &[[0.0; PHASE_POINTS]; VOLT_POINTS], 0.0, 0.0, [0.0; LOAD_POINTS])
    }

    /// Copies part `part` of `from` into this table: its header (part 0) or a few grid rows.
    fn copy_part(&mut self, from: &ModelTable, part: usize) {
        let Some(row_part) = part.checked_sub(1) else {
            self.request = from.request;
            self.thrust_scale_n = from.thrust_scale_n;
            self.index_per_v = from.index_per_v;
            self.foot_mm_s_per_v = from.foot_mm_s_per_v;
            self.stall_n = from.stall_n;
            self.speed_mm_s = from.speed_mm_s;
            self.swing = from.swing;
            return;
        };
        let rows =
            (row_part * ROWS_PER_PART).min(VOLT_POINTS)..((row_part + 1) * ROWS_PER_PART).min(VOLT_POINTS);
        if let (Some(to), Some(src)) = (self.thrust_q.get_mut(rows.clone()), from.thrust_q.get(rows)) {
            to.copy_from_slice(src);
        }
    }

    /// How far the carriage swings about its mean line within a drive period at `volts` of drive
    /// (nm, [`Swing`]).
    pub fn swing_nm(&self, volts: f32) -> f32 {
        (self.swing.stroke_nm_per_v * volts.max(0.0)).min(self.swing.impulse_nm)
    }

    /// Stall force at full drive (N).
    pub fn stall_n(&self) -> f32 {
        self.stall_n
    }

    /// No-load speed at full drive (mm/s).
    pub fn no_load_mm_s(&self) -> f32 {
        self.speed_mm_s[0]
    }

    /// Forward speed at full drive against an opposing `load_n` (mm/s), interpolated; 0 at or
    /// above the stall force, the no-load speed for an assisting load.
    pub fn speed_at_load_mm_s(&self, load_n: f32) -> f32 {
        // Written so that a NaN load or stall gives 0 too.
        let stalled =
            load_n >= self.stall_n || self.stall_n <= 0.0 || load_n.is_nan() || self.stall_n.is_nan();
        if stalled {
            return 0.0;
        }
        let x = load_n / self.stall_n * (LOAD_POINTS - 1) as f32;
        let (k, t) = cell(x, LOAD_POINTS - 1);
        let a = self.speed_mm_s.get(k).copied().unwrap_or(0.0);
        if x < 0.0 {
            let b = self.speed_mm_s.get(1).copied().unwrap_or(0.0);
            return a + (a - b) * -x;
        }
        let b = self.speed_mm_s.get(k + 1).copied().unwrap_or(0.0);
        a + (b - a) * t
    }

    /// Grid column of φp for a slider at `speed_mm_s` under a foot driven at `volts`
    /// (φp = acos(v / ω·Xc); 0 or π beyond the foot's speed, π/2 for a standing foot and slider).
    fn column(&self, volts: f32, speed_mm_s: f32) -> f32 {
        let foot = self.foot_mm_s_per_v * volts;
        let ratio = if foot > 0.0 {
            clamp_f32(speed_mm_s / foot, -1.0, 1.0)
        } else if speed_mm_s > 0.0 {
            1.0
        } else if speed_mm_s < 0.0 {
            -1.0
        } else {
            0.0
        };
        acos_f32(ratio) * COLUMNS_PER_RAD
    }

    /// Row `j` of the grid at column coordinate `c` (N).
    fn row_at(&self, j: usize, c: f32) -> f32 {
        let (k, t) = cell(c, PHASE_POINTS - 1);
        let row = self.thrust_q.get(j);
        let a = f32::from(row.and_then(|r| r.get(k)).copied().unwrap_or(0));
        let b = f32::from(row.and_then(|r| r.get(k + 1)).copied().unwrap_or(0));
        (a + (b - a) * t) * self.thrust_scale_n
    }

    /// Mean thrust (N) at drive `volts` and slider speed `speed_mm_s` along the drive (eq. 22),
    /// interpolated in (voltage, φp).
    pub fn thrust_n(&self, volts: f32, speed_mm_s: f32) -> f32 {
        let (j, t) = cell(volts * self.index_per_v, VOLT_POINTS - 1);
        let c = self.column(volts, speed_mm_s);
        let a = self.row_at(j, c);
        let b = self.row_at(j + 1, c);
        a + (b - a) * t
    }

    /// The full-drive thrust at `speed_mm_s` (N).
    pub fn full_thrust_n(&self, speed_mm_s: f32) -> f32 {
        self.row_at(VOLT_POINTS - 1, self.column(self.request.max_drive_v, speed_mm_s))
    }

    /// Thrust of grid row `j` (its own voltage) at `speed_mm_s` (N).
    fn row_thrust_n(&self, j: usize, speed_mm_s: f32) -> f32 {
        let volts = j as f32 / self.index_per_v;
        self.row_at(j, self.column(volts, speed_mm_s))
    }

    /// Inverse model (the feedforward): the drive voltage at which the model runs at
    /// `speed_mm_s` against `load_n` (opposing; negative = assisting), within 0 and the largest
    /// drive. The grid's rows bracket the answer, searched from `hint_v` (the last period's
    /// answer: two rows when it moved less than a grid step; bisection over the rows
    /// otherwise, at most eight), then one secant step on the interpolated thrust.
    pub fn voltage_for(&self, speed_mm_s: f32, load_n: f32, hint_v: f32) -> f32 {
        if self.index_per_v <= 0.0 {
            return 0.0;
        }
        let last = VOLT_POINTS - 1;
        // Falling in the row: positive while the drive is not enough.
        let excess = |j: usize| load_n - self.row_thrust_n(j, speed_mm_s);
        let h = if hint_v.is_finite() { hint_v * self.index_per_v } else { 0.0 };
        let j0 = (clamp_f32(h, 0.0, last as f32) as usize).min(last - 1);
        let e0 = excess(j0);
        // Find a with excess(a) > 0 ≥ excess(a + 1).
        let (mut lo, mut e_lo, mut hi, mut e_hi);
        if e0 > 0.0 {
            let e1 = excess(j0 + 1);
            if e1 <= 0.0 {
                return self.refine(j0, e0, e1, speed_mm_s, load_n);
            }
            let e_top = if j0 + 1 == last { e1 } else { excess(last) };
            if e_top > 0.0 {
                return self.request.max_drive_v;
            }
            (lo, e_lo, hi, e_hi) = (j0 + 1, e1, last, e_top);
        } else {
            if j0 == 0 {
                return 0.0;
            }
            let e1 = excess(j0 - 1);
            if e1 > 0.0 {
                return self.refine(j0 - 1, e1, e0, speed_mm_s, load_n);
            }
            let e_bottom = if j0 == 1 { e1 } else { excess(0) };
            if e_bottom <= 0.0 {
                return 0.0;
            }
            (lo, e_lo, hi, e_hi) = (0, e_bottom, j0 - 1, e1);
        }
        while hi - lo > 1 {
            let mid = (lo + hi) / 2;
            let e = excess(mid);
            if e > 0.0 {
                (lo, e_lo) = (mid, e);
            } else {
                (hi, e_hi) = (mid, e);
            }
        }
        self.refine(lo, e_lo, e_hi, speed_mm_s, load_n)
    }

    /// The crossing between rows `j` (excess > 0) and `j + 1` (≤ 0): linear in the voltage first,
    /// then one secant step on the interpolated thrust at that voltage, kept inside the rows.
    fn refine(&self, j: usize, e_j: f32, e_next: f32, speed_mm_s: f32, load_n: f32) -> f32 {
        let (v_j, v_next) = (j as f32 / self.index_per_v, (j + 1) as f32 / self.index_per_v);
        let span = e_j - e_next;
        let t = if span > 0.0 { clamp_f32(e_j / span, 0.0, 1.0) } else { 1.0 };
        let v1 = v_j + (v_next - v_j) * t;
        let e1 = load_n - self.thrust_n(v1, speed_mm_s);
        // Secant with the row on the other side of the crossing.
        let (v_other, e_other) = if e1 > 0.0 { (v_next, e_next) } else { (v_j, e_j) };
        let d = e1 - e_other;
        let v2 = if d != 0.0 { v1 - e1 * (v1 - v_other) / d } else { v1 };
        clamp_f32(v2, v_j, v_next)
    }
}

/// The settings a model table is built from: the motor and its calibration, the drive's
/// frequencies and voltage, the carriage's mass and its guide's friction. A change of any other
/// setting (`VEL`, `ACC`, `DEC`, gains, limits, windows) leaves the table as it is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TableSettings {
    motor: crate::model::MotorConstants,
    drive_freq_hz: f32,
    drive_freq_min_hz: f32,
    max_drive_v: f32,
    moving_mass_kg: f32,
    mu_dynamic: f32,
    tangential_scale: f32,
    normal_force_ratio: f32,
    rail_coulomb_n: f32,
    rail_viscous_n_s_per_m: f32,
    contact_table: bool,
}

impl TableSettings {
    pub fn of(c: &ControllerConfig) -> Self {
        TableSettings {
            motor: c.motor,
            drive_freq_hz: c.drive_freq_hz,
            drive_freq_min_hz: c.drive_freq_min_hz,
            max_drive_v: c.max_drive_v,
            moving_mass_kg: c.moving_mass_kg,
            mu_dynamic: c.mu_dynamic,
            tangential_scale: c.tangential_scale,
            normal_force_ratio: c.normal_force_ratio,
            rail_coulomb_n: c.rail_coulomb_n,
            rail_viscous_n_s_per_m: c.rail_viscous_n_s_per_m,
            contact_table: c.contact_table,
        }
    }
}

/// The preload with the drive quiet: what the contact model is solved at. Under drive the force
/// cell reads the stator's mean contact force, which the contact model itself puts above the
/// static preload where the foot bounces (5.55 N at 5 N, 1.5 kHz, full drive), and which moves
/// with the drive: a contact table asked for at that reading is solved at the wrong preload, and
/// asked for anew at every move (26-45 builds of seconds in one PIL move at 5 N).
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct RestPreload {
    quiet_periods: u32,
    preload_n: Option<f32>,
}

impl RestPreload {
    /// Quiet periods before the reading counts as static: five of the force-cell filter's time
    /// constants at its default coefficient 0.01 per period.
    const SETTLED_PERIODS: u32 = 500;

    /// One period: whether the drive was quiet, and the preload read.
    pub(super) fn note(&mut self, quiet: bool, reading_n: Option<f32>) {
        self.quiet_periods = if quiet { self.quiet_periods.saturating_add(1) } else { 0 };
        if quiet && (self.preload_n.is_none() || self.quiet_periods >= Self::SETTLED_PERIODS) {
            self.preload_n = reading_n.or(self.preload_n);
        }
    }

    pub(super) fn preload_n(&self) -> Option<f32> {
        self.preload_n
    }
}

/// The preload change (N) that asks for a new contact table at `preload_n`: where the table's
/// thrust would move by 0.5 % of the stall force. The stall force scales with the preload (μ·F̄,
/// eq. 12), so that is 0.5 % of the preload; never finer than [`PRELOAD_RESOLVE_N`].
pub fn contact_resolve_n(preload_n: f32) -> f32 {
    (0.005 * preload_n.abs()).max(PRELOAD_RESOLVE_N)
}

/// The controller's copy of the model table (see this module) and what it asks for.
#[derive(Debug, Clone, Copy)]
pub(super) struct ModelSlot {
    pub(super) per_volt: PerVolt,
    /// Static foot displacement per volt of common offset (nm/V), calibrated.
    pub(super) fine_nm_per_v: f32,
    /// Counts accepted configurations: a settings change prepared from an older one is refused.
    pub(super) generation: u32,
    /// Counts the configurations that changed [`TableSettings`]: a table built for an older one
    /// is refused.
    pub(super) table_generation: u32,
    /// Two tables: the one in use (`active`) and the one a board fills beside it, a part per
    /// tick lock ([`Controller::stage_model`]), swapped in by an index change.
    tables: [ModelTable; 2],
    /// The table in use, if any.
    active: Option<usize>,
    /// The other table holds a complete copy of a finished build's parts up to this one.
    staged_parts: usize,
    /// The preload with the drive quiet, for the contact table.
    pub(super) rest_preload: RestPreload,
}

impl ModelSlot {
    pub(super) fn new(cfg: &ControllerConfig, generation: u32) -> Self {
        ModelSlot {
            per_volt: cfg.per_volt(),
            fine_nm_per_v: cfg.fine_nm_per_v(),
            generation,
            table_generation: generation,
            tables: [ModelTable::placeholder(cfg), ModelTable::placeholder(cfg)],
            active: None,
            staged_parts: 0,
            rest_preload: RestPreload::default(),
        }
    }

    /// The table in use.
    pub(super) fn table(&self) -> Option<&ModelTable> {
        self.active.and_then(|i| self.tables.get(i))
    }

    /// The slot beside the table in use, and its index.
    fn spare(&mut self) -> (usize, Option<&mut ModelTable>) {
        let i = self.active.map_or(0, |a| 1 - a);
        (i, self.tables.get_mut(i))
    }

    /// New settings, with these amplitudes per volt and fine stroke. Where they change what the
    /// table is built from (`table_changed`), the table goes and a new one is asked for; else
    /// the table stays (a build of seconds on the board must not restart on a `VEL`). In place,
    /// because a whole slot moved by value copies the table's kilobytes under the tick lock.
    pub(super) fn reconfigure_with(&mut self, per_volt: PerVolt, fine_nm_per_v: f32, table_changed: bool) {
        self.per_volt = per_volt;
        self.fine_nm_per_v = fine_nm_per_v;
        self.generation = self.generation.wrapping_add(1);
        if table_changed {
            self.table_generation = self.table_generation.wrapping_add(1);
            self.active = None;
            self.staged_parts = 0;
        }
    }
}

impl Controller {
    /// Stall force (N) and no-load speed (mm/s) at full drive and the measured preload: from the
    /// model table when it fits the preload, else computed here (for queries, off the tick).
    pub fn thrust_limits(&self) -> Option<(f32, f32)> {
        self.thrust_inputs().limits()
    }

    /// What [`Self::thrust_limits`] reads, copied out (a few words), so that a board can evaluate
    /// them without holding the tick off: without a fitting table they cost a model point.
    pub fn thrust_inputs(&self) -> ThrustInputs {
        let preload_n = self.preload_n();
        ThrustInputs {
            preload_n,
            table: preload_n.and_then(|f| self.fitting_table(f)).map(|t| (t.stall_n(), t.no_load_mm_s())),
            per_volt: self.model.per_volt,
            max_drive_v: self.cfg.max_drive_v,
            rail_coulomb_n: self.cfg.rail_coulomb_n,
        }
    }

    /// The installed table, if it was built for this preload (within [`PRELOAD_RESOLVE_N`]).
    pub(super) fn fitting_table(&self, preload_n: f32) -> Option<&ModelTable> {
        self.model.table().filter(|t| (preload_n - t.request().preload_n).abs() <= PRELOAD_RESOLVE_N)
    }

    /// The drive frequency of coarse motion (Hz): the installed table's (chosen with it), the
    /// highest allowed before there is one.
    pub fn coarse_frequency_hz(&self) -> f32 {
        self.model.table().map_or(self.cfg.drive_freq_hz, |t| t.request().frequency_hz)
    }

    /// The cached limits for the control path: (stall N, no-load mm/s), None before a table.
    pub(super) fn cached_limits(&self) -> Option<(f32, f32)> {
        self.model.table().map(|t| (t.stall_n(), t.no_load_mm_s()))
    }

    /// The model table the controller wants built, if the installed one does not fit the
    /// measured preload or the configuration (see [`model_cache`]); None without a valid preload.
    /// Cheap: a board calls it under its lock, builds the table outside, then installs it.
    pub fn model_request(&self) -> Option<ModelRequest> {
        let live_n = self.preload_n()?;
        // The frequency is chosen anew when there is no table or the load it was chosen for has
        // moved ([`super::frequency`]); else a table for a new preload keeps it.
        let load_n = self.choice_load_n();
        // The contact model's table is built once an inertial one serves (it takes the board
        // seconds; the inertial one milliseconds) and replaces it. It is solved at the preload
        // read with the drive quiet ([`RestPreload`]), asked for anew when its thrust would move
        // by 0.5 % of the stall force ([`contact_resolve_n`]), and its frequency is chosen
        // between moves only: a build of seconds started mid-move would land after it.
        let contact = self.contact_inputs().filter(|_| self.model.table().is_some());
        let upgrade = contact.is_some() && self.model.table().is_some_and(|t| t.request().contact.is_none());
        let (preload_n, resolve_n) = match contact {
            Some(_) => {
                let rest_n = self.model.rest_preload.preload_n().unwrap_or(live_n);
                (rest_n, contact_resolve_n(rest_n))
            }
            None => (live_n, PRELOAD_RESOLVE_N),
        };
        let hold_choice = contact.is_some() && self.state() == super::State::Moving;
        let kept = self.model.table().filter(|t| hold_choice || self.keeps_frequency(t, load_n));
        let pinned =
            self.frequency.pinned_hz().filter(|&f| kept.is_some_and(|t| t.request().frequency_hz != f));
        let choice = match (kept, pinned) {
            // Back to the frequency a failed trial left ([`super::frequency`]).
            (_, Some(f)) => FrequencyChoice::fixed(f, self.cfg.per_volt_at(f), load_n),
            (Some(t), _) if !upgrade && (preload_n - t.request().preload_n).abs() <= resolve_n => {
                return None
            }
            (Some(t), _) => t.request().choice,
            (None, _) => {
                let (lowest, highest) = (self.cfg.drive_freq_min_hz, self.cfg.drive_freq_hz);
                FrequencyChoice::between(lowest, highest, load_n, |f| self.cfg.per_volt_at(f))
            }
        };
        // The request's own frequency is where the build stays when the model can rank no
        // candidate ([`ModelRequest::chosen`]): the one in use, else the highest.
        let (frequency_hz, per_volt) = match self.model.table() {
            Some(t) if choice.len > 1 && t.request().generation == self.model.table_generation => {
                (t.request().frequency_hz, t.request().per_volt)
            }
            _ => (choice.frequency_hz[0], choice.per_volt[0]),
        };
        Some(ModelRequest {
            per_volt,
            preload_n,
            max_drive_v: self.cfg.max_drive_v,
            frequency_hz,
            choice,
            moving_mass_kg: self.cfg.moving_mass_kg,
            rail_coulomb_n: self.cfg.rail_coulomb_n,
            rail_viscous_n_s_per_m: self.cfg.rail_viscous_n_s_per_m,
            contact,
            generation: self.model.table_generation,
        })
    }

    /// The contact model's inputs when the settings ask for its table and the motor table has
    /// the constants ([`crate::contact_motor`]).
    fn contact_inputs(&self) -> Option<ContactInputs> {
        let motor = self.cfg.motor.contact;
        (self.cfg.contact_table && motor.is_present()).then_some(ContactInputs {
            motor,
            calibration: crate::contact_motor::Calibration {
                normal_force_ratio: self.cfg.normal_force_ratio,
                tangential_scale: self.cfg.tangential_scale,
                mu: self.cfg.mu_dynamic,
            },
        })
    }

    /// The preload read with the drive quiet ([`RestPreload`]): what a contact model is solved
    /// at (hosts that build the table from another contact model read it here).
    pub fn rest_preload_n(&self) -> Option<f32> {
        self.model.rest_preload.preload_n()
    }

    /// Which model the installed table comes from: None before the first table.
    pub fn table_model(&self) -> Option<TableModelKind> {
        self.model.table().map(|t| {
            if t.request().contact.is_some() {
                TableModelKind::Contact
            } else {
                TableModelKind::Inertial
            }
        })
    }

    /// Takes a table built from [`Self::model_request`]; false (and the table dropped) when the
    /// configuration changed since the request.
    pub fn install_model(&mut self, table: ModelTable) -> bool {
        self.install_model_from(&table)
    }

    /// [`Self::install_model`] from where the table was built, at once: every part staged, then
    /// swapped in.
    pub fn install_model_from(&mut self, table: &ModelTable) -> bool {
        let r = table.request();
        // A request made by hand (tests, hosts) may name amplitudes per volt that the settings
        // would not give: checked here in full. A board's requests come from
        // [`Self::model_request`], whose generation ties them to the settings.
        if r.per_volt != self.cfg.per_volt_at(r.frequency_hz) {
            return false;
        }
        let mut part = 0;
        loop {
            match self.stage_model(table, part) {
                Staged::More => part += 1,
                Staged::Installed => return true,
                Staged::Refused => return false,
            }
        }
    }

    /// One part of a table's hand-over, for a board that holds the tick off for each part alone
    /// ([`TABLE_PARTS`] parts: the header, then a few rows each; the whole copy took 5 800
    /// instructions on the M4): part `k` is copied beside the table in use, and the last part
    /// swaps it in by an index change. Parts go in order from 0; a part out of order, or a table
    /// that no longer answers the settings (checked at the last part), is refused and the table
    /// in use stays.
    pub fn stage_model(&mut self, table: &ModelTable, part: usize) -> Staged {
        if part != self.model.staged_parts || part >= TABLE_PARTS {
            self.model.staged_parts = 0;
            return Staged::Refused;
        }
        let check = TABLE_PARTS - 2;
        // The whole check against the settings, in a part of its own; the swap then needs only
        // the generation to be the same (a settings change in between bumps it).
        let answers = match part {
            p if p == check => self.answers_settings(table.request()),
            p if p > check => table.request().generation == self.model.table_generation,
            _ => true,
        };
        if !answers {
            self.model.staged_parts = 0;
            return Staged::Refused;
        }
        let (spare_index, spare) = self.model.spare();
        let Some(spare) = spare else { return Staged::Refused };
        if part + 1 < TABLE_PARTS {
            if part < check {
                spare.copy_part(table, part);
            }
            self.model.staged_parts = part + 1;
            return Staged::More;
        }
        let old_hz = self.coarse_frequency_hz();
        self.model.active = Some(spare_index);
        self.model.staged_parts = 0;
        self.frequency_switched(old_hz, table.request().frequency_hz);
        Staged::Installed
    }

    /// Whether a table built for `r` fits the settings now. Its amplitudes per volt follow from
    /// the settings its generation names (the motor table, the calibration and the frequency
    /// are [`TableSettings`]); recomputing them here cost 3 100 instructions on the M4, more
    /// than a tick lock may hold.
    fn answers_settings(&self, r: &ModelRequest) -> bool {
        let lowest = self.cfg.drive_freq_min_hz.min(self.cfg.drive_freq_hz);
        r.generation == self.model.table_generation
            && r.max_drive_v == self.cfg.max_drive_v
            && (lowest..=self.cfg.drive_freq_hz).contains(&r.frequency_hz)
            && r.moving_mass_kg == self.cfg.moving_mass_kg
            && r.rail_coulomb_n == self.cfg.rail_coulomb_n
            && r.rail_viscous_n_s_per_m == self.cfg.rail_viscous_n_s_per_m
            && (r.contact.is_none() || r.contact == self.contact_inputs())
    }

    /// The lower-rate work done at once: builds and installs the model table if one is wanted.
    /// For hosts that run the controller synchronously (simulator, tests); the board splits it
    /// into [`Self::model_request`], [`ModelTable::build`] outside its lock, [`Self::install_model`].
    pub fn background(&mut self) {
        if let Some(r) = self.model_request() {
            self.install_model(ModelTable::build(&r));
        }
    }
}
