//! Weighted nonlinear least squares of the steady-state model (with effects) to measured speeds.
//!
//! Parameter vector: `[ln(μ/μ0), ln(λ/λ0), ln(ρ/ρ0)]` (friction coefficient, tangential and normal
//! amplitude scale factors of the base file) followed by each included effect's fitted
//! parameters ([`Effect::fit_params`]). Levenberg–Marquardt with box bounds, forward-difference
//! Jacobian.

use crate::gap::measured_csv::MeasuredRow;
use crate::gap::surrogate::{closed_params, new_anchor, Anchor};
use crate::motor::effects::{Condition, Effect, EffectModel, Effects};
use crate::motor::params::Params;
use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;

/// Median of |z| for a standard normal z (its 75 % quantile).
const NORMAL_MEDIAN_ABS: f64 = 0.674_489_750_196_081_7;
/// Asymptotic efficiency of the median absolute deviation against the standard deviation for
/// normal data (2/π·… = 0.3675).
const MEDIAN_EFFICIENCY: f64 = 0.3675;

/// Relative weight of a row: `|v| + 0.25·v̄` (matches the noise model of `measure`); the absolute
/// noise scale is estimated from the data.
pub const WEIGHT_FLOOR_OF_MEAN: f64 = 0.25;

/// Measured data in SI units with weights and curve membership.
#[derive(Debug, Clone)]
pub struct Data {
    pub conds: Vec<Condition>,
    /// Measured speed, m/s.
    pub y: Vec<f64>,
    /// Relative weight scale σ_i, m/s.
    pub sigma: Vec<f64>,
    /// Curve (preload level, voltage, frequency, direction) of each row.
    pub curve: Vec<usize>,
    /// Preload level of each row: measured preloads within [`PRELOAD_LEVEL_N`] of each other
    /// are one setting read through a noisy force cell (`characterize` writes each burst's
    /// reading), so they form one level of the preload condition and one curve.
    pub preload_level: Vec<usize>,
    pub n_curves: usize,
    /// The first row with each row's operating point (its preload, voltage, frequency and
    /// direction exactly; the load may differ): rows there share the closed form's model.
    pub same_point: Vec<usize>,
    /// Each row's load point: an index shared by the rows with its preload, voltage, frequency
    /// and load exactly (either sense), for [`first_alike`]; and how many there are.
    pub load_point: Vec<usize>,
    pub n_load_points: usize,
}

/// Measured preloads closer than this (N) belong to one preload setting: several times the
/// force cell's noise (0.05 N on the reference board) and well below the steps anyone sets
/// between settings.
pub const PRELOAD_LEVEL_N: f64 = 0.25;

/// Groups the rows' preloads into levels: sorted, a gap over [`PRELOAD_LEVEL_N`] starts a new one.
fn preload_levels(conds: &[Condition]) -> Vec<usize> {
    let mut order: Vec<usize> = (0..conds.len()).collect();
    order.sort_by(|&a, &b| conds[a].preload_n.total_cmp(&conds[b].preload_n));
    let mut level = vec![0usize; conds.len()];
    let mut current = 0usize;
    let mut last = f64::NAN;
    for &i in &order {
        let f = conds[i].preload_n;
        if last.is_finite() && f - last > PRELOAD_LEVEL_N {
            current += 1;
        }
        last = f;
        level[i] = current;
    }
    level
}

impl Data {
    pub fn from_rows(rows: &[MeasuredRow]) -> Self {
        let conds: Vec<Condition> = rows
            .iter()
            .map(|r| Condition {
                preload_n: r.preload_n,
                voltage_v: r.voltage_v,
                frequency_hz: r.frequency_hz,
                load_n: r.load_n,
                direction: r.direction,
            })
            .collect();
        let y: Vec<f64> = rows.iter().map(|r| r.velocity_mm_s * 1e-3).collect();
        let mean = y.iter().map(|v| v.abs()).sum::<f64>() / y.len().max(1) as f64;
        let floor = (WEIGHT_FLOOR_OF_MEAN * mean).max(1e-9);
        let sigma = y.iter().map(|v| v.abs() + floor).collect();
        let preload_level = preload_levels(&conds);
        let mut keys: Vec<[i64; 4]> = Vec::new();
        let curve = conds
            .iter()
            .zip(&preload_level)
            .map(|(c, &level)| {
                let k = [
                    level as i64,
                    (c.voltage_v * 1e6).round() as i64,
                    (c.frequency_hz * 1e3).round() as i64,
                    i64::from(c.direction),
                ];
                match keys.iter().position(|x| *x == k) {
                    Some(i) => i,
                    None => {
                        keys.push(k);
                        keys.len() - 1
                    }
                }
            })
            .collect();
        let point = |c: &Condition| {
            (c.preload_n.to_bits(), c.voltage_v.to_bits(), c.frequency_hz.to_bits(), c.direction)
        };
        let mut first = std::collections::HashMap::new();
        let same_point = conds.iter().enumerate().map(|(i, c)| *first.entry(point(c)).or_insert(i)).collect();
        let mut points = std::collections::HashMap::new();
        let load_point: Vec<usize> = conds
            .iter()
            .map(|c| {
                let key = [c.preload_n, c.voltage_v, c.frequency_hz, c.load_n].map(f64::to_bits);
                let next = points.len();
                *points.entry(key).or_insert(next)
            })
            .collect();
        let n_load_points = points.len();
        Data {
            conds,
            y,
            sigma,
            curve,
            preload_level,
            n_curves: keys.len(),
            same_point,
            load_point,
            n_load_points,
        }
    }

    pub fn len(&self) -> usize {
        self.y.len()
    }

    pub fn is_empty(&self) -> bool {
        self.y.is_empty()
    }

    pub fn mean_speed(&self) -> f64 {
        self.y.iter().sum::<f64>() / self.len().max(1) as f64
    }

    /// Gap of a prediction: RMS(simulated − measured) / mean measured speed.
    pub fn gap(&self, pred: &[f64]) -> f64 {
        let n = self.len().max(1) as f64;
        let ms = self.y.iter().zip(pred).map(|(y, p)| (p - y).powi(2)).sum::<f64>() / n;
        ms.sqrt() / self.mean_speed().abs().max(1e-12)
    }

    /// Difference-based noise estimate (Gasser et al. pseudo-residuals of the weighted residuals
    /// along load within each curve): smooth structure cancels, white noise stays. The scale is
    /// the pseudo-residuals' median absolute value over its normal quantile (1/0.6745), not their
    /// RMS: a model that misses the shape of a few curves (a carriage that stalls early under a
    /// guide's friction) puts curvature into their pseudo-residuals, and the RMS would then take
    /// the missing effect for noise. Returns the scale in weighted units and the noise's degrees
    /// of freedom: the median of normal deviates carries 0.37 of their information (its
    /// asymptotic efficiency), so `0.37 × count` (0: not estimable).
    pub fn noise_scale(&self, weighted_resid: &[f64]) -> (f64, usize) {
        let mut pseudo: Vec<f64> = Vec::new();
        for c in 0..self.n_curves {
            let mut idx: Vec<usize> = (0..self.len()).filter(|&i| self.curve[i] == c).collect();
            idx.sort_by(|&a, &b| self.conds[a].load_n.total_cmp(&self.conds[b].load_n));
            for w in idx.windows(3) {
                let (x0, x1, x2) =
                    (self.conds[w[0]].load_n, self.conds[w[1]].load_n, self.conds[w[2]].load_n);
                if x2 - x0 <= 0.0 {
                    continue;
                }
                let a = (x2 - x1) / (x2 - x0);
                let b = (x1 - x0) / (x2 - x0);
                let e = a * weighted_resid[w[0]] + b * weighted_resid[w[2]] - weighted_resid[w[1]];
                pseudo.push((e / (a * a + b * b + 1.0).sqrt()).abs());
            }
        }
        if pseudo.is_empty() {
            return (f64::NAN, 0);
        }
        pseudo.sort_by(f64::total_cmp);
        let n = pseudo.len();
        let median = if n % 2 == 1 { pseudo[n / 2] } else { 0.5 * (pseudo[n / 2 - 1] + pseudo[n / 2]) };
        (median / NORMAL_MEDIAN_ABS, ((MEDIAN_EFFICIENCY * n as f64).round() as usize).max(1))
    }
}

/// Writes an effect's fitted parameters ([`Effect::fit_params`]) into `effects`.
pub fn apply_effect(effects: &mut Effects, effect: Effect, x: &[f64]) {
    let set = |e: &mut Effects, k: &str, v: f64| {
        // Names come from the library table; `set` only fails on unknown names.
        let _ = e.set(k, v);
    };
    match effect {
        Effect::AmplifierRolloff => {
            let q = x[0];
            set(effects, "rolloff_corner_hz", if q > 0.0 { 1000.0 / q.sqrt() } else { 0.0 });
        }
        _ => {
            for (d, v) in effect.fit_params().iter().zip(x) {
                set(effects, d.name, *v);
            }
        }
    }
}

/// The named (file) parameters of an effect from its fitted ones, for reports.
pub fn named_values(effect: Effect, x: &[f64]) -> Vec<(&'static str, f64)> {
    match effect {
        Effect::AmplifierRolloff => {
            vec![("rolloff_corner_hz", if x[0] > 0.0 { 1000.0 / x[0].sqrt() } else { f64::INFINITY })]
        }
        _ => effect.fit_params().iter().zip(x).map(|(d, v)| (d.name, *v)).collect(),
    }
}

/// A model structure: the base parameters plus a list of effects to fit.
#[derive(Debug, Clone)]
pub struct Model {
    pub base: Params,
    pub effects: Vec<Effect>,
    /// With a contact base (`[model] steady = "contact"`): the anchored surrogate's differences
    /// ([`crate::gap::base`]); `None`: the constant-speed model as it is.
    pub anchor: Option<Anchor>,
}

pub const BASE_PARAMS: usize = 3;
pub const BASE_NAMES: [&str; 3] =
    ["friction.mu_dynamic", "stator.tangential_scale", "stator.normal_force_ratio"];
const LOG_BOUND: f64 = 1.0;

impl Model {
    /// The base parameters with no effects, anchored for `data` when they select the contact model.
    pub fn new(base: &Params, data: &Data) -> Self {
        Model { base: base.clone(), effects: Vec::new(), anchor: new_anchor(base, data.len()) }
    }

    pub fn n_params(&self) -> usize {
        BASE_PARAMS + self.effects.iter().map(|e| e.fit_params().len()).sum::<usize>()
    }

    pub fn bounds(&self) -> Vec<(f64, f64)> {
        let mut b = vec![(-LOG_BOUND, LOG_BOUND); BASE_PARAMS];
        for e in &self.effects {
            b.extend(e.fit_params().iter().map(|d| (d.lo, d.hi)));
        }
        b
    }

    /// Offset of `effect` in the parameter vector.
    pub fn offset(&self, effect: Effect) -> Option<usize> {
        let mut off = BASE_PARAMS;
        for e in &self.effects {
            if *e == effect {
                return Some(off);
            }
            off += e.fit_params().len();
        }
        None
    }

    pub fn params_at(&self, x: &[f64]) -> Params {
        let mut p = self.base.clone();
        let mu = x[0].exp();
        p.friction.mu_dynamic *= mu;
        p.friction.mu_static *= mu;
        p.stator.tangential_scale *= x[1].exp();
        p.stator.normal_force_ratio *= x[2].exp();
        let mut off = BASE_PARAMS;
        for e in &self.effects {
            let k = e.fit_params().len();
            apply_effect(&mut p.effects, *e, &x[off..off + k]);
            off += k;
        }
        p
    }

    pub fn predict(&self, x: &[f64], data: &Data, rows: &[usize]) -> Vec<f64> {
        self.evaluate(x, data, rows, None).0
    }

    /// The prediction of `rows` at `x` and the closed form's constant-speed speeds under it
    /// (before the carriage's inertial part and the anchor's correction), those searched first
    /// near `near`'s (the same rows' at nearby parameters).
    fn evaluate(&self, x: &[f64], data: &Data, rows: &[usize], near: Option<&[f64]>) -> (Vec<f64>, Vec<f64>) {
        let p = self.params_at(x);
        let q = match &self.anchor {
            None => p,
            Some(_) => closed_params(&p),
        };
        // The closed form's model once per operating point (`model_speed_m_s` builds it for each
        // row; it does not depend on the load), and the rows in parallel: the fits call this for
        // every Jacobian column, and the closed form is a fifth of a contact base's time, much
        // of it outside the parallel candidate tests. A row whose closed-form speed is another's
        // ([`first_alike`], searched from the same start) takes it from that row.
        let start = |k: usize| near.and_then(|n| n.get(k)).map(|v| v.to_bits());
        let twin = first_alike(&q, data, rows, |j, k| start(j) == start(k));
        let mut points: Vec<usize> =
            (0..rows.len()).filter(|&k| twin[k] == k).map(|k| data.same_point[rows[k]]).collect();
        points.sort_unstable();
        points.dedup();
        let models: Vec<EffectModel> =
            points.par_iter().map(|&i| EffectModel::new(&q, &data.conds[i])).collect();
        let solved = solve_once(&twin, |k| {
            let i = rows[k];
            let model = &models[points.partition_point(|&j| j < data.same_point[i])];
            let load_n = data.conds[i].load_n;
            let constant = match near.and_then(|n| n.get(k)) {
                Some(&v) => model.constant_speed_near_m_s(load_n, v),
                None => model.constant_speed_at_load_m_s(load_n),
            };
            (model.speed_from_constant_m_s(load_n, constant), constant)
        });
        rows.iter()
            .zip(solved)
            .map(|(&i, (closed, constant))| {
                (self.anchor.as_ref().map_or(closed, |a| closed + a.correction_m_s(i, x)), constant)
            })
            .unzip()
    }

    /// Weighted residuals at `x` and the constant-speed speeds under them ([`Self::evaluate`]).
    fn weighted_resid(
        &self,
        x: &[f64],
        data: &Data,
        rows: &[usize],
        near: Option<&[f64]>,
    ) -> (Vec<f64>, Vec<f64>) {
        let (pred, constant) = self.evaluate(x, data, rows, near);
        (rows.iter().zip(pred).map(|(&i, p)| (p - data.y[i]) / data.sigma[i]).collect(), constant)
    }

    /// Weighted Jacobian of the residuals (rows × params), forward differences inside the bounds,
    /// each column's speeds searched near `constant` (the constant-speed speeds at `x`).
    fn jacobian(&self, x: &[f64], data: &Data, rows: &[usize], r0: &[f64], constant: &[f64]) -> DMatrix<f64> {
        let b = self.bounds();
        let n = x.len();
        let mut j = DMatrix::zeros(rows.len(), n);
        for k in 0..n {
            let span = if k < BASE_PARAMS { 1.0 } else { b[k].1 - b[k].0 };
            let mut h = 1e-6 * span.max(1e-9);
            if x[k] + h > b[k].1 {
                h = -h;
            }
            let mut xp = x.to_vec();
            xp[k] += h;
            let (rp, _) = self.weighted_resid(&xp, data, rows, Some(constant));
            for i in 0..rows.len() {
                j[(i, k)] = (rp[i] - r0[i]) / h;
            }
        }
        j
    }
}

/// For each of `rows` (by position), the first position whose row is evaluated as this one is
/// under `p`: the same preload, voltage, frequency and load, the same foot speed factor of its
/// sense (the only way the sense enters the closed form and the contact model: both senses of a
/// model without `assembly_asymmetry` are one), and `same(first, this)` (the same start of the
/// search, by position).
pub(super) fn first_alike(
    p: &Params,
    data: &Data,
    rows: &[usize],
    same: impl Fn(usize, usize) -> bool,
) -> Vec<usize> {
    // The key is the row's load point and which of the senses' foot speed factors (−1, 0, +1)
    // its own equals first, as a number: no hashing (this runs for every evaluation of a fit).
    let senses = [-1i8, 0, 1];
    let factor = |d: i8| p.effects.tangential_factor(d).to_bits();
    let class: Vec<usize> =
        senses.iter().map(|&d| senses.iter().position(|&e| factor(e) == factor(d)).unwrap_or(0)).collect();
    let key = |i: usize| {
        let sense = usize::try_from(data.conds[i].direction.signum() + 1).unwrap_or(1);
        data.load_point[i] * 3 + class[sense]
    };
    // Per key, the positions that lead a group, in the order they came: a list through `next`.
    const NONE: usize = usize::MAX;
    let mut head = vec![NONE; data.n_load_points * 3];
    let mut tail = vec![NONE; data.n_load_points * 3];
    let mut next = vec![NONE; rows.len()];
    rows.iter()
        .enumerate()
        .map(|(k, &i)| {
            let key = key(i);
            let mut j = head[key];
            while j != NONE {
                if same(j, k) {
                    return j;
                }
                j = next[j];
            }
            match tail[key] {
                NONE => head[key] = k,
                last => next[last] = k,
            }
            tail[key] = k;
            k
        })
        .collect()
}

/// `solve` at each position `first` names as its own first (in parallel), and each position
/// given the answer of its first ([`first_alike`]): every distinct evaluation made once.
pub(super) fn solve_once<T: Send + Clone>(first: &[usize], solve: impl Fn(usize) -> T + Sync) -> Vec<T> {
    let lead: Vec<usize> = (0..first.len()).filter(|&k| first[k] == k).collect();
    let solved: Vec<T> = lead.par_iter().map(|&k| solve(k)).collect();
    let mut slot = vec![0; first.len()];
    for (n, &k) in lead.iter().enumerate() {
        slot[k] = n;
    }
    first.iter().map(|&j| solved[slot[j]].clone()).collect()
}

/// Levenberg–Marquardt iterations of a fit (on a contact base, of each anchor's surrogate fit):
/// the base calibration from the file's values, which may be far off.
pub const BASE_ITERATIONS: usize = 100;
/// ... a fit with an effect added or dropped: a candidate's, a refit without some effects, a
/// partial candidate's.
pub const EFFECT_ITERATIONS: usize = 60;
/// ... the refit of an accepted effect from its candidate's fit, and each cross-validation fold's.
pub const REFIT_ITERATIONS: usize = 40;

/// The Levenberg–Marquardt damping at which a fit stops looking for a smaller step: there the
/// step is a millionth of the Gauss–Newton one along each parameter's curvature. Up to 1e12
/// half the fits of the gap bench's contact base ended by failing their last thirty dampings,
/// 80 % of their trial evaluations; stopping at 1e6 left that bench's report the same to 1e-9
/// (one cross-validated figure to 1e-6).
const MAX_DAMPING: f64 = 1e6;

/// Result of one fit.
#[derive(Debug, Clone)]
pub struct Fit {
    pub x: Vec<f64>,
    /// Weighted sum of squared residuals.
    pub ssr: f64,
    pub resid: Vec<f64>,
    pub jac: DMatrix<f64>,
}

/// Levenberg–Marquardt from each start; the best end point wins.
pub fn fit(model: &Model, data: &Data, rows: &[usize], starts: &[Vec<f64>], max_iter: usize) -> Fit {
    let mut best: Option<Fit> = None;
    for s in starts {
        let f = lm(model, data, rows, s, max_iter);
        if best.as_ref().is_none_or(|b| f.ssr < b.ssr) {
            best = Some(f);
        }
    }
    best.unwrap_or_else(|| lm(model, data, rows, &vec![0.0; model.n_params()], max_iter))
}

fn lm(model: &Model, data: &Data, rows: &[usize], start: &[f64], max_iter: usize) -> Fit {
    let bounds = model.bounds();
    let clamp = |x: &mut Vec<f64>| {
        for (v, (lo, hi)) in x.iter_mut().zip(&bounds) {
            *v = v.clamp(*lo, *hi);
        }
    };
    let mut x = start.to_vec();
    clamp(&mut x);
    let (mut r, mut constant) = model.weighted_resid(&x, data, rows, None);
    let mut ssr: f64 = r.iter().map(|v| v * v).sum();
    let mut lambda = 1e-3;
    let n = x.len();
    let mut j = model.jacobian(&x, data, rows, &r, &constant);
    for _ in 0..max_iter {
        let jt = j.transpose();
        let a = &jt * &j;
        let g = &jt * DVector::from_vec(r.clone());
        let mut improved = false;
        let mut tiny_step = false;
        while lambda < MAX_DAMPING {
            let mut m = a.clone();
            for k in 0..n {
                m[(k, k)] += lambda * a[(k, k)].max(1e-12) + 1e-15;
            }
            let Some(step) = m.lu().solve(&(-&g)) else {
                lambda *= 10.0;
                continue;
            };
            let mut xn: Vec<f64> = x.iter().zip(step.iter()).map(|(a, b)| a + b).collect();
            clamp(&mut xn);
            let moved: f64 = xn.iter().zip(&x).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
            let (rn, cn) = model.weighted_resid(&xn, data, rows, None);
            let sn: f64 = rn.iter().map(|v| v * v).sum();
            if sn < ssr {
                let rel = (ssr - sn) / ssr.max(1e-300);
                x = xn;
                r = rn;
                constant = cn;
                ssr = sn;
                lambda = (lambda / 4.0).max(1e-9);
                improved = true;
                tiny_step = rel < 1e-10 || moved < 1e-12;
                break;
            }
            lambda *= 5.0;
        }
        if !improved {
            break;
        }
        j = model.jacobian(&x, data, rows, &r, &constant);
        if tiny_step {
            break;
        }
    }
    // `j` is the Jacobian at `x`: taken at the start and after every step.
    Fit { x, ssr, resid: r, jac: j }
}

/// Covariance of the parameters at a fit for a noise scale `s` (weighted units).
pub fn covariance(fit: &Fit, s: f64) -> Option<DMatrix<f64>> {
    let a = fit.jac.transpose() * &fit.jac;
    a.try_inverse().map(|inv| inv * (s * s))
}
