//! The contact model as the workflow's base (`[model] steady = "contact"`), fitted through a
//! surrogate that it anchors.
//!
//! The contact model (`motor/steady_contact.rs`) is within a few per cent of the plant on every
//! carriage, but one point costs 0.5–10 ms; the fits evaluate the model tens of thousands of
//! times. So the fits run on the closed-form constant-speed model plus, per measured row, the
//! contact model's difference from it at an anchor and that difference's slopes:
//! `v(x) = v_closed(x) + Δ(x_a) + ∂Δ/∂x·(x − x_a)`. At the anchor `x_a` this is the contact model
//! in value and slope ([`fit_anchored`]); a trust region moves the anchor only where the contact
//! model's own sum of squares falls, so the fits settle at a stationary point of the contact
//! model's least squares, and every residual, gap and χ² the workflow reports is the contact
//! model's. What the closed form lends is the curvature between anchors; where it misleads, a
//! Levenberg–Marquardt step on the contact model's own slopes is tried instead.
//!
//! The normal motion does not depend on μ, the tangential scale, the carriage or the guide, so it
//! is solved once per preload, drive and normal force ratio and shared ([`ProfileCache`], in
//! `surrogate.rs` with the [`Anchor`] the fits read); each orbit search starts where the same
//! row's orbit was at the model's anchor.

use super::fit::{first_alike, fit as lm_fit, solve_once, Data, Fit, Model};
pub use super::surrogate::{closed_params, new_anchor, wants_contact, Anchor, ProfileCache};
use crate::motor::effects::{model_speed_m_s, Condition};
use crate::motor::params::Params;
use crate::motor::steady_contact::OrbitStart;
use std::sync::Arc;

/// Anchor moves at most per fit of the workflow's model: each costs `1 + n_params` contact-model evaluations of every
/// row (two when the end point is refused and the midpoint tried).
pub const MAX_ANCHORS: usize = 8;

/// Anchor moves of a candidate effect's test fit: one, from the fit on the current model's
/// anchor (a candidate's figures need the contact model's slopes, not its optimum to the last
/// digit; the accepted one is refitted with [`MAX_ANCHORS`]).
pub const CANDIDATE_ANCHORS: usize = 1;

/// Whether two anchor moves point the same way: the cosine of the steps, each parameter scaled
/// by its range, above [`SAME_WAY_COSINE`].
fn same_way(a: &[f64], b: &[f64], bounds: &[(f64, f64)]) -> bool {
    let scaled = |v: &[f64]| -> Vec<f64> {
        v.iter().zip(bounds).map(|(d, (lo, hi))| d / (hi - lo).max(1e-12)).collect()
    };
    let (a, b) = (scaled(a), scaled(b));
    let dot: f64 = a.iter().zip(&b).map(|(x, y)| x * y).sum();
    let norm = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
    dot > SAME_WAY_COSINE * norm(&a) * norm(&b)
}

/// Successive anchor moves this close in direction are a valley the surrogate falls short in.
const SAME_WAY_COSINE: f64 = 0.9;

/// The longest stretch of an anchor move's step ([`fit_anchored`]).
const MAX_STRETCH: f64 = 16.0;

/// The anchors have settled when a move lowers the contact model's sum of squares by less than
/// this share of it.
pub const ANCHOR_TOLERANCE: f64 = 1e-3;

/// Step of the anchor's forward differences: 5 % of a base factor (log scale) or of an effect
/// parameter's range. Where the foot bounces, the impacts change pattern with the drive, and the
/// contact model's speed is rough on small scales: with 1 % steps the slopes of ρ and of a drive
/// gain pointed the trust region nowhere (an amplifier pole at 2.5 kHz on the 1 kg carriage
/// stopped at 3.6 kHz, gap 48 % of before); with 5 % it reaches 2.9 kHz (gap 22 % of before).
pub const SLOPE_STEP: f64 = 0.05;

/// `v_contact − v_closed` of `model` at parameters `x` for every data row (in parallel), the
/// contact model's speed of row `i` from `speed(cache, p, condition, hint)` with whatever it
/// says besides, its orbit searched near `hints[i]`. A row that repeats an earlier one (the
/// same condition and foot speed, as both senses of a model without `assembly_asymmetry` are,
/// and the same hint) takes that row's answer: the same evaluation, not made twice.
fn minus_closed<T: Send + Clone>(
    model: &Model,
    cache: &ProfileCache,
    x: &[f64],
    data: &Data,
    hints: &[Option<OrbitStart>],
    speed: impl Fn(&ProfileCache, &Params, &Condition, Option<OrbitStart>) -> (f64, T) + Sync,
) -> Vec<(f64, T)> {
    let p = model.params_at(x);
    let q = closed_params(&p);
    let hint = |i: usize| hints.get(i).copied().flatten();
    let all: Vec<usize> = (0..data.len()).collect();
    let first = first_alike(&p, data, &all, |j, i| hint(j) == hint(i));
    solve_once(&first, |i| {
        let c = &data.conds[i];
        let (v, besides) = speed(cache, &p, c, hint(i));
        (v - model_speed_m_s(&q, c), besides)
    })
}

/// The differences at `x`: one contact-model evaluation of each row, its orbit searched near
/// `hints` (per row, None: none). Returns the differences and where each row's orbit starts.
fn differences(
    model: &Model,
    cache: &ProfileCache,
    x: &[f64],
    data: &Data,
    hints: &[Option<OrbitStart>],
) -> (Vec<f64>, Vec<Option<OrbitStart>>) {
    minus_closed(model, cache, x, data, hints, |cache, p, c, hint| cache.speed_near(p, c, hint))
        .into_iter()
        .unzip()
}

/// The differences at `x`, each row's orbit after one secant step from its orbit `starts` at a
/// point a slope step away (`ProfileCache::speed_for_slope`): a forward difference's other end.
fn slope_ends(
    model: &Model,
    cache: &ProfileCache,
    x: &[f64],
    data: &Data,
    starts: &[Option<OrbitStart>],
) -> Vec<f64> {
    minus_closed(model, cache, x, data, starts, |cache, p, c, start| (cache.speed_for_slope(p, c, start), ()))
        .into_iter()
        .map(|(d, ())| d)
        .collect()
}

/// The differences at an anchor's point and where each row's orbit starts there.
type AtPoint = (Vec<f64>, Vec<Option<OrbitStart>>);

/// The anchor of `model` at `x`: the differences there (`at_x` where the caller has them) and
/// their slopes. Slopes for the first parameters are taken from `reuse` where it has them (an
/// anchor at a nearby point: the slopes change slowly), the others by forward differences, one
/// evaluation of every row each.
fn anchored(
    model: &Model,
    cache: &Arc<ProfileCache>,
    x: &[f64],
    data: &Data,
    reuse: Option<&Anchor>,
    hints: &[Option<OrbitStart>],
    at_x: Option<AtPoint>,
) -> Anchor {
    let (delta, starts) = at_x.unwrap_or_else(|| differences(model, cache, x, data, hints));
    let known = reuse.filter(|r| r.slope.len() == data.len()).map_or(0, |r| r.x.len().min(x.len()));
    let mut slope: Vec<Vec<f64>> = match reuse {
        Some(r) if known > 0 => r.slope.iter().map(|g| g[..known].to_vec()).collect(),
        _ => vec![Vec::new(); data.len()],
    };
    for row in slope.iter_mut() {
        row.resize(x.len(), 0.0);
    }
    let bounds = model.bounds();
    for (k, &(lo, hi)) in bounds.iter().enumerate().take(x.len()).skip(known) {
        let span = if k < super::fit::BASE_PARAMS { 1.0 } else { hi - lo };
        let mut h = SLOPE_STEP * span.max(1e-9);
        if x[k] + h > hi {
            h = -h;
        }
        let mut xp = x.to_vec();
        xp[k] += h;
        let moved = slope_ends(model, cache, &xp, data, &starts);
        for (row, (a, b)) in slope.iter_mut().zip(moved.iter().zip(&delta)) {
            row[k] = (a - b) / h;
        }
    }
    Anchor {
        cache: cache.clone(),
        x: Arc::new(x.to_vec()),
        delta_m_s: Arc::new(delta),
        slope: Arc::new(slope),
        starts: Arc::new(starts),
    }
}

/// `model` anchored at `x` with `anchor`'s slopes (the differences fresh: one evaluation of every
/// row) and the contact model's fit there.
fn moved_anchor(model: &Model, anchor: &Anchor, x: &[f64], data: &Data, rows: &[usize]) -> (Model, Fit) {
    let mut m = model.clone();
    let (delta, starts) = differences(model, &anchor.cache, x, data, &anchor.starts);
    m.anchor = Some(Anchor {
        delta_m_s: Arc::new(delta),
        x: Arc::new(x.to_vec()),
        starts: Arc::new(starts),
        ..anchor.clone()
    });
    let f = lm_fit(&m, data, rows, &[x.to_vec()], 0);
    (m, f)
}

/// Fits `model` from `starts`; with a contact base, as a trust region around anchors: anchored
/// at the first start, the surrogate is fitted, and the anchor moves to the fit's end point if
/// the contact model's own sum of squares is lower there (else to the midpoint, else it stays;
/// a move along the last one's direction stretched while it keeps falling), its slopes taken
/// afresh before the next fit, until the sum of squares stops falling
/// ([`ANCHOR_TOLERANCE`] of it, at most `max_anchors` moves). The surrogate matches the contact
/// model's value and slope at each anchor, so this settles at a stationary point of the contact
/// model's own least squares. With `reuse_slopes`, the first anchor takes the slopes of the
/// parameters `model`'s own anchor has (a candidate effect appended to an anchored model: only
/// the effect's are new). Returns the model with its final anchor (exact value, the slopes of
/// the last point they were taken at) and the fit there, whose residuals are the contact model's.
pub fn fit_anchored(
    model: &Model,
    data: &Data,
    rows: &[usize],
    starts: &[Vec<f64>],
    max_iter: usize,
    max_anchors: usize,
    reuse_slopes: bool,
) -> (Model, Fit) {
    let Some(prior) = &model.anchor else {
        return (model.clone(), lm_fit(model, data, rows, starts, max_iter));
    };
    let cache = prior.cache.clone();
    let x0 = starts.first().cloned().unwrap_or_else(|| vec![0.0; model.n_params()]);
    let mut m = model.clone();
    m.anchor = Some(anchored(model, &cache, &x0, data, reuse_slopes.then_some(prior), &prior.starts, None));
    let mut here = lm_fit(&m, data, rows, &[x0], 0);
    let mut starts: Vec<Vec<f64>> = starts.to_vec();
    let mut last_step: Option<Vec<f64>> = None;
    for round in 1..=max_anchors {
        let Some(anchor) = m.anchor.clone() else { break };
        let end = lm_fit(&m, data, rows, &starts, max_iter).x;
        // Steps tried in turn until the contact model agrees one is an improvement: the
        // surrogate's optimum (the closed form's curvature on the contact model's slopes), a
        // Levenberg–Marquardt step on the contact model's own linearisation (its slopes at the
        // anchor), and each again shorter: halved, and more damped.
        let step: Vec<f64> = end.iter().zip(&here.x).map(|(a, b)| a - b).collect();
        let bounds = m.bounds();
        let clamp = |x: Vec<f64>| -> Vec<f64> {
            x.into_iter().zip(&bounds).map(|(v, (lo, hi))| v.clamp(*lo, *hi)).collect()
        };
        let surrogate = |share: f64| clamp(here.x.iter().zip(&step).map(|(x, d)| x + share * d).collect());
        let linearised = |damping: f64| -> Option<Vec<f64>> {
            let j = &here.jac;
            let a = j.transpose() * j;
            let g = j.transpose() * nalgebra::DVector::from_column_slice(&here.resid);
            let mut lhs = a.clone();
            for k in 0..a.nrows() {
                lhs[(k, k)] += damping * a[(k, k)].max(1e-12);
            }
            let dx = lhs.lu().solve(&(-g))?;
            Some(clamp(here.x.iter().zip(dx.iter()).map(|(x, d)| x + d).collect()))
        };
        let tries: Vec<Vec<f64>> = [
            Some(surrogate(1.0)),
            linearised(1e-2),
            Some(surrogate(0.5)),
            linearised(1.0),
            Some(surrogate(0.25)),
            linearised(100.0),
        ]
        .into_iter()
        .flatten()
        .collect();
        let Some(mut next) =
            tries.iter().map(|x| moved_anchor(&m, &anchor, x, data, rows)).find(|(_, f)| f.ssr < here.ssr)
        else {
            break;
        };
        // Where the contact model's valley is longer than the closed form's curvature says, the
        // surrogate's steps fall short by the same factor round after round (a hidden amplifier
        // pole on the 1 kg carriage: eight anchor moves, each lowering the sum of squares by
        // 15–20 %, left it at five times the optimum's). So where this move points the way the
        // last one did, its step is doubled, up to 16×, while the contact model's sum of squares
        // keeps falling: one evaluation each. Not on a first move: stretched there, the base fit
        // of the 0.3 kg carriage with a hidden Stribeck rise ran μ to its bound (2.7×).
        let taken: Vec<f64> = next.1.x.iter().zip(&here.x).map(|(a, b)| a - b).collect();
        let along = last_step.as_ref().is_some_and(|last| same_way(last, &taken, &bounds));
        last_step = Some(taken.clone());
        let mut stretch = 2.0;
        while along && stretch <= MAX_STRETCH {
            let x = clamp(here.x.iter().zip(&taken).map(|(x, d)| x + stretch * d).collect());
            let further = moved_anchor(&m, &anchor, &x, data, rows);
            if further.1.ssr >= next.1.ssr {
                break;
            }
            next = further;
            stretch *= 2.0;
        }
        let (next_m, next) = next;
        let gain = (here.ssr - next.ssr) / here.ssr.max(1e-300);
        (m, here) = (next_m, next);
        if gain < ANCHOR_TOLERANCE || round == max_anchors {
            break;
        }
        // The differences at the new point are the ones its step was judged by.
        let at_x = m.anchor.as_ref().map(|a| (a.delta_m_s.to_vec(), a.starts.to_vec()));
        m.anchor = Some(anchored(&m, &cache, &here.x, data, None, &[], at_x));
        starts = vec![here.x.clone()];
    }
    (m, here)
}
