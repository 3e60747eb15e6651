//! The model table from the contact model ([`crate::contact_motor`]): per drive row the
//! stator's normal motion gives the contact force over a period ([`crate::normal_motion`]), and
//! the carriage's periodic motion on it ([`crate::contact_orbit`]) gives its mean speed against a
//! set of loads. A row's thrust at each φp column is the load at which the carriage runs at that
//! column's speed, read off those (speed, load) pairs.
//!
//! Why loads and not speeds: the orbit answers "how fast against this load"; the table asks
//! "what thrust at this speed". The pairs span the whole row: at the foot's peak speed forward
//! the foot never outruns the carriage and friction holds it back with μ·F̄ (F̄ the mean contact
//! force, eq. 12), at the peak speed backward it always does and pushes with μ·F̄; between, the
//! orbits at [`ROW_LOADS`] loads spread over ±μ·F̄. The speed against the load has kinks where the
//! impact pattern changes (docs/simulator.md), so the loads are spread evenly, not fitted.

use super::model_cache::{
    constant_speed_row, less_guide_friction, load_at_speed, row_volts, thrust_at_zero_speed,
    with_guide_friction, ModelRequest, LOAD_POINTS, PHASE_POINTS,
};
use crate::contact_motor::{Calibration, ContactMotor};
use crate::contact_orbit::Orbits;
use crate::normal_motion::contact_force;
use crate::trig::cos;
use crate::Fx;

/// Loads of a row's orbits, as shares of μ·F̄: denser toward the ends, where the speed turns
/// fastest with the load (the foot's reach), and across zero and the stall force.
pub const ROW_LOADS: [f32; 16] =
    [-0.95, -0.7, -0.45, -0.25, -0.1, 0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 0.97];

/// What a request needs for a contact build: the motor's constants and the calibrated ρ, λ, μ.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactInputs {
    pub motor: ContactMotor,
    pub calibration: Calibration,
}

/// One drive of the contact model at the request's preload and frequency: its (speed mm/s,
/// load N) pairs over the row's loads, ascending in load.
struct RowPairs {
    pairs: [(f32, f32); ROW_LOADS.len() + 2],
    n: usize,
}

/// The contact model's pairs at `volts`; None where the normal motion does not settle into one
/// period (a subharmonic or chaotic bouncing: the row then stays the constant-speed model's).
fn row_pairs(request: &ModelRequest, c: &ContactInputs, volts: f32) -> Option<RowPairs> {
    let point =
        c.motor.point(&c.calibration, request.preload_n, volts, request.frequency_hz, request.moving_mass_kg);
    let profile = contact_force(&point.stator, &point.drive).ok()?;
    let orbits = Orbits::new(&profile.force, point.carriage);
    let mu_f = c.calibration.mu * profile.force.mean_n();
    let foot_mm_s = point.carriage.foot_peak_m_s * 1e3;
    let loads = ROW_LOADS.map(|s| s * mu_f);
    let speeds = orbits.speeds_along(&loads);
    let mut pairs = [(0.0f32, 0.0f32); ROW_LOADS.len() + 2];
    // The ends: at the foot's peak speed forward friction only brakes, backward it only drives.
    pairs[0] = (foot_mm_s, -mu_f);
    let mut n = 1;
    for (speed, load) in speeds.iter().zip(loads) {
        if let (Some(v), Some(slot)) = (speed, pairs.get_mut(n)) {
            *slot = (v * 1e3, load);
            n += 1;
        }
    }
    if let Some(slot) = pairs.get_mut(n) {
        *slot = (-foot_mm_s, mu_f);
        n += 1;
    }
    Some(RowPairs { pairs, n })
}

/// Row `j` of the thrust grid (N, net of the guide's friction) from the contact model; row 0 (a
/// drive of a twentieth of a grid step, where the foot barely moves) is the constant-speed
/// model's. None where the normal motion does not settle into one period: a bouncing foot's
/// subharmonic or chaotic pattern (5 N at 2.2 kHz around 65-72 V), which the board's copy
/// refuses rather than averages ([`fill_unsettled_rows`] bridges it).
pub(super) fn contact_row(
    request: &ModelRequest,
    c: &ContactInputs,
    j: usize,
) -> Option<[f32; PHASE_POINTS]> {
    let (point, mut row) = constant_speed_row(request, j);
    // The columns' speeds are the table's (its foot speed per volt), whatever the contact
    // model's own rounding of the same ω·Xc.
    let foot_mm_s: f32 = point.foot_speed_mm_s.to_num();
    if j > 0 {
        let rp = row_pairs(request, c, row_volts(request, j))?;
        let pairs = rp.pairs.get(..rp.n).unwrap_or(&[]);
        for (k, t) in row.iter_mut().enumerate() {
            let phi = Fx::PI * k as i32 / (PHASE_POINTS - 1) as i32;
            *t = load_at_speed_quadratic(pairs, foot_mm_s * cos(phi).to_num::<f32>());
        }
    }
    less_guide_friction(&mut row, request, foot_mm_s);
    Some(row)
}

/// Rows whose normal motion did not settle (bit j of `unsettled`) take the straight line between
/// the nearest settled rows below and above, column by column: what the table's own
/// interpolation between those rows would read. Above the last settled row, its copy.
pub(super) fn fill_unsettled_rows(rows: &mut [[f32; PHASE_POINTS]], unsettled: u64) {
    let bad = |j: usize| j < 64 && unsettled & (1u64 << j) != 0;
    let n = rows.len();
    for j in 0..n {
        if !bad(j) {
            continue;
        }
        let below = (0..j).rev().find(|&i| !bad(i));
        let above = (j + 1..n).find(|&i| !bad(i));
        let (Some(lo), Some(lo_row)) = (below, below.and_then(|i| rows.get(i).copied())) else { continue };
        let filled = match above.and_then(|i| rows.get(i).copied().map(|r| (i, r))) {
            Some((hi, hi_row)) => {
                let t = (j - lo) as f32 / (hi - lo) as f32;
                core::array::from_fn(|k| {
                    let (a, b) =
                        (lo_row.get(k).copied().unwrap_or(0.0), hi_row.get(k).copied().unwrap_or(0.0));
                    a + (b - a) * t
                })
            }
            None => lo_row,
        };
        if let Some(slot) = rows.get_mut(j) {
            *slot = filled;
        }
    }
}

/// The full-drive speed (mm/s) against `load_n` plus the guide's friction, from the contact
/// model at `request`'s frequency: for ranking frequency candidates. 0 where it does not settle.
pub(super) fn full_drive_speed_mm_s(request: &ModelRequest, c: &ContactInputs, load_n: f32) -> f32 {
    let volts = request.max_drive_v.max(0.0);
    let point =
        c.motor.point(&c.calibration, request.preload_n, volts, request.frequency_hz, request.moving_mass_kg);
    let Ok(profile) = contact_force(&point.stator, &point.drive) else { return 0.0 };
    let orbits = Orbits::new(&profile.force, point.carriage);
    let mut hint = None;
    with_guide_friction(request, load_n, |foot_load| match orbits.orbit_near(foot_load, hint) {
        Some((speed, start)) => {
            hint = Some(start);
            speed * 1e3
        }
        None => 0.0,
    })
}

/// The speed table at full drive (mm/s against loads 0 … `stall_n`) from the top row: the table's
/// own interpolation of it, so that the speed limit and the grid agree.
pub(super) fn speed_table(top_row: &[f32; PHASE_POINTS], foot_mm_s: f32) -> [f32; LOAD_POINTS] {
    let stall_n = thrust_at_zero_speed(top_row).max(0.0);
    let mut pairs = [(0.0f32, 0.0f32); PHASE_POINTS];
    for (k, (slot, &t)) in pairs.iter_mut().zip(top_row).enumerate() {
        let phi = Fx::PI * k as i32 / (PHASE_POINTS - 1) as i32;
        *slot = (foot_mm_s * cos(phi).to_num::<f32>(), t);
    }
    core::array::from_fn(|k| {
        let load = stall_n * k as f32 / (LOAD_POINTS - 1) as f32;
        speed_at_load(&pairs, load).max(0.0)
    })
}

/// The speed at which the (speed, thrust) pairs (ascending in thrust along φp) reach `load_n`.
fn speed_at_load(pairs: &[(f32, f32)], load_n: f32) -> f32 {
    for w in pairs.windows(2) {
        if let [a, b] = w {
            if (a.1 <= load_n && load_n <= b.1) || (a.1 >= load_n && load_n >= b.1) {
                let d = b.1 - a.1;
                return if d.abs() > 1e-9 {
                    a.0 + (b.0 - a.0) * (load_n - a.1) / d
                } else {
                    0.5 * (a.0 + b.0)
                };
            }
        }
    }
    0.0
}

/// Candidate `i` of the request's frequency choice, ranked by the contact model's speed at full
/// drive against the choice's load: it becomes `best` when faster (as
/// `ModelRequest::rank_candidate` does with the inertial model).
pub(super) fn rank_candidate(
    request: &ModelRequest,
    c: &ContactInputs,
    i: usize,
    best: &mut (f32, ModelRequest),
) {
    let choice = &request.choice;
    let (Some(&f), Some(pv)) = (choice.frequency_hz.get(i), choice.per_volt.get(i)) else { return };
    let candidate = ModelRequest { per_volt: *pv, frequency_hz: f, ..*request };
    let speed = full_drive_speed_mm_s(&candidate, c, choice.load_n.max(0.0));
    if speed > best.0 {
        *best = (speed, candidate);
    }
}

/// The load at which the pairs (speed, load; speeds falling as loads rise) run at `v`: the
/// parabola through the segment that holds `v` and its nearer neighbour, held inside the
/// segment's loads (the speed against the load bends smoothly between impact-pattern changes;
/// a straight line between pairs 0.1 μ·F̄ apart missed the heavy carriage's curve by 3 % of its
/// stall force).
fn load_at_speed_quadratic(pairs: &[(f32, f32)], v: f32) -> f32 {
    let within = |w: &[(f32, f32)]| match w {
        [a, b] => (a.0 >= v && v >= b.0) || (a.0 <= v && v <= b.0),
        _ => false,
    };
    let Some(i) = pairs.windows(2).position(within) else {
        return load_at_speed(pairs, v);
    };
    let (Some(&a), Some(&b)) = (pairs.get(i), pairs.get(i + 1)) else {
        return load_at_speed(pairs, v);
    };
    let linear = load_at_speed(&[a, b], v);
    // The third point: the neighbour on the side nearer to v.
    let t = if (b.0 - a.0).abs() > 1e-9 { (v - a.0) / (b.0 - a.0) } else { 0.5 };
    let before = i.checked_sub(1).and_then(|k| pairs.get(k)).copied();
    let after = pairs.get(i + 2).copied();
    let Some(c) = (if t < 0.5 { before.or(after) } else { after.or(before) }) else { return linear };
    let (x0, x1, x2) = (a.0, b.0, c.0);
    let (d01, d02, d12) = (x0 - x1, x0 - x2, x1 - x2);
    if d01.abs() < 1e-9 || d02.abs() < 1e-9 || d12.abs() < 1e-9 {
        return linear;
    }
    let l0 = (v - x1) * (v - x2) / (d01 * d02);
    let l1 = (v - x0) * (v - x2) / (-d01 * d12);
    let l2 = (v - x0) * (v - x1) / (d02 * d12);
    let q = a.1 * l0 + b.1 * l1 + c.1 * l2;
    let (lo, hi) = if a.1 <= b.1 { (a.1, b.1) } else { (b.1, a.1) };
    crate::fastmath::clamp_f32(q, lo, hi)
}
