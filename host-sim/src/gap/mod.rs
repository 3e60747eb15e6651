//! The model-gap workflow: calibrate the base model to measured steady speeds, detect structure
//! the noise cannot explain, name the missing effect(s) from the library of `crate::motor::effects`, add
//! them one at a time, and show how much of the gap they explain.
//!
//! Statistics (all in weighted units, weights `|v| + 0.25·v̄`, noise scale `s` from
//! difference-based pseudo-residuals along load within each measured curve):
//! - consistency: `R = (SSR/(n − p))/s²`; below its noise limit ([`Thresholds`]) and with no
//!   condition's structure above noise the residuals are noise and nothing is missing;
//! - score: Rao's score statistic of each candidate's strength at zero, after projecting out what
//!   the current parameters can explain (one-sided where the strength is one-sided);
//! - likelihood ratio `LR = (SSR₀ − SSR₁)/s²`, `ΔBIC = LR − k·ln n`;
//! - cross-validation: K folds of held-out operating curves (preload, voltage, frequency,
//!   direction); improvement = 1 − RMS_cv(with)/RMS_cv(without);
//! - residual structure along a condition: `χ² = Σ_levels n_l·r̄_l²/s²` of the level means `r̄_l`
//!   of the weighted residuals; pure noise gives χ² with `levels − 1` degrees of freedom (the
//!   calibrated level absorbs one). An accepted effect is *named* only when, after the final
//!   fit, this χ² is below its `1 − α` quantile along every condition of the effect's signature
//!   ([`crate::motor::effects::Effect::signature`]); otherwise it is a *partial candidate*.

pub mod base;
pub mod chi2;
pub mod fit;
pub mod measure;
pub mod measured_csv;
mod refits;
pub mod report;
mod stages;
pub mod surrogate;

use crate::gap::measured_csv::MeasuredRow;
use crate::motor::effects::{Axis, Condition, Effect, EFFECT_NAMES};
use crate::motor::params::Params;
use anyhow::Result;
use fit::{covariance, fit as lm_fit, named_values, Data, Fit, Model, BASE_NAMES, BASE_PARAMS};
use nalgebra::DMatrix;
use serde::Serialize;
use std::path::PathBuf;

/// Decision settings of the workflow. The thresholds themselves are not set here: they follow
/// from each data set's row count and noise estimate ([`Thresholds`]).
#[derive(Debug, Clone)]
pub struct Options {
    pub max_effects: usize,
    pub folds: usize,
    /// Significance level of every test against the noise: the consistency ratio R, the
    /// residual structure along each condition, and (shared among a round's candidates) the
    /// likelihood ratio behind ΔBIC. An accepted effect whose refit leaves residual structure
    /// along one of its signature conditions that pure noise would exceed with probability below
    /// `signature_alpha` is a partial candidate, not a named effect.
    pub signature_alpha: f64,
    /// Minimum relative improvement of the cross-validated RMS ([`Thresholds::cv_improvement`]).
    pub min_cv_improvement: f64,
    /// ΔBIC margin within which candidates form an ambiguity group (candidates whose refits both
    /// leave residuals consistent with noise are grouped whatever their ΔBIC).
    pub ambiguity_bic: f64,
    /// Which effects the library offers (default: all); a name that is not in
    /// [`EFFECT_NAMES`] makes [`analyze`] fail.
    pub library: Vec<&'static str>,
}

impl Default for Options {
    fn default() -> Self {
        Options {
            max_effects: 3,
            folds: 5,
            // 0.1 % per test: over the ≤ 3 signature conditions of each of the ≤ 3 accepted
            // effects, noise alone demotes a correct effect with probability < 1 %; over the five
            // conditions and R of the verdict, noise alone denies "nothing missing" with
            // probability < 0.6 %.
            signature_alpha: 1e-3,
            min_cv_improvement: 0.15,
            ambiguity_bic: 10.0,
            library: EFFECT_NAMES.to_vec(),
        }
    }
}

/// The decision thresholds for one data set: `n` rows, noise scale estimated from `m`
/// pseudo-residuals, `L` library candidates per round, significance level α
/// ([`Options::signature_alpha`]). None is a tuned constant:
/// - **consistency ratio R** = (SSR/(n − p))/s². Under pure noise SSR/σ² is χ²(n − p) and
///   s²/σ² is χ²(m)/m, so R is F(n − p, m); "within noise" is R below its 1 − α quantile (on the
///   compact grid's 192 rows, m ≈ 35: 2.50; with the noise known, m → ∞, it would be 1.35: the
///   uncertainty of the noise estimate is most of the limit; a board's 36 rows with m = 9: 8.5).
///   With no pseudo-residuals (m = 0) the χ²(n − p)/(n − p) quantile.
/// - **ΔBIC** = LR − k·ln n with LR = (SSR₀ − SSR₁)/s², χ²(k) under noise for a candidate of k
///   parameters. A round tests L candidates, so a candidate is accepted only when its LR is above
///   the χ²(k) quantile at α/L (Bonferroni: noise alone accepts one of the L with probability
///   ≤ α); as ΔBIC that is `quantile(α/L, k) − k·ln n` (192 rows, L = 8, k = 1: 9.5; k = 2: 7.5;
///   36 rows: 11.1 and 10.8).
/// - **cross-validation gain** = 1 − RMS_cv(with)/RMS_cv(without) over the n held-out rows:
///   [`Options::min_cv_improvement`], 15 %, *not* derived. Two standard errors of a difference
///   of two independent held-out RMS (2/√n: 0.144 on 192 rows, 0.115 on 300) was tried: on a
///   board's 36 rows it is 0.33, and the guide's friction of a `mu_rail` board run passed it by
///   0.346 (the following rounds' Stribeck rise by 0.63); the two RMS are of the same held-out
///   rows, so their difference varies far less than that bound says, and a paired bound was not
///   worked out. On 300 rows 0.115 also let the carriage's inertia into round 2 of the LC-filter
///   set as a partial candidate.
#[derive(Debug, Clone, Serialize)]
pub struct Thresholds {
    pub rows: usize,
    /// Pseudo-residuals behind the base fit's noise estimate (m).
    pub noise_dof: usize,
    /// Candidates tested in a round (L).
    pub candidates_per_round: usize,
    pub alpha: f64,
    /// R below which the base model's residuals are noise (its limit for the final model is
    /// `consistency_limit_after`).
    pub consistency_ratio: f64,
    pub consistency_ratio_after: f64,
    /// R at or above which effect selection goes on: F(n − p, m)'s quantile at
    /// [`SEARCH_ALPHA`] (5 %), lower than `consistency_ratio`'s at α.
    pub search_ratio: f64,
    /// Minimum ΔBIC of a candidate of one and of two fitted parameters.
    pub delta_bic: [f64; 2],
    pub cv_improvement: f64,
}

impl Thresholds {
    pub fn new(rows: usize, noise_dof: usize, candidates_per_round: usize, opts: &Options) -> Self {
        let alpha = opts.signature_alpha;
        let each = alpha / candidates_per_round.max(1) as f64;
        let bic = |k: usize| chi2::quantile_upper(each, k) - k as f64 * (rows as f64).ln();
        Thresholds {
            rows,
            noise_dof,
            candidates_per_round,
            alpha,
            consistency_ratio: consistency_limit(rows, BASE_PARAMS, noise_dof, alpha),
            consistency_ratio_after: f64::NAN,
            search_ratio: consistency_limit(rows, BASE_PARAMS, noise_dof, SEARCH_ALPHA),
            delta_bic: [bic(1), bic(2)],
            cv_improvement: opts.min_cv_improvement,
        }
    }

    /// Minimum ΔBIC of a candidate of `k` fitted parameters.
    pub fn min_delta_bic(&self, k: usize) -> f64 {
        let n = self.rows as f64;
        match k {
            1 | 2 => self.delta_bic[k - 1],
            _ => {
                let each = self.alpha / self.candidates_per_round.max(1) as f64;
                chi2::quantile_upper(each, k) - k as f64 * n.ln()
            }
        }
    }
}

/// The significance level at which R keeps the search going ([`Thresholds::search_ratio`]):
/// searching costs a round and names nothing by itself (ΔBIC and cross-validation decide), so
/// it goes on unless noise would give such an R more often than one time in twenty.
pub const SEARCH_ALPHA: f64 = 0.05;

/// The R below which residuals of a fit of `p` parameters to `n` rows are noise, with the noise
/// estimated from `m` pseudo-residuals ([`Thresholds`]).
pub fn consistency_limit(n: usize, p: usize, m: usize, alpha: f64) -> f64 {
    let d1 = n.saturating_sub(p).max(1);
    if m > 0 {
        chi2::f_quantile_upper(alpha, d1, m)
    } else {
        chi2::quantile_upper(alpha, d1) / d1 as f64
    }
}

#[derive(Debug, Clone, Serialize)]
pub struct NamedParam {
    pub name: String,
    pub value: f64,
    pub std_dev: f64,
}

#[derive(Debug, Clone, Serialize)]
pub struct Candidate {
    pub name: String,
    /// The effect (`name` is its name).
    #[serde(skip)]
    pub effect: Effect,
    /// Round of the workflow (1 = against the calibrated base model).
    pub round: usize,
    /// Score statistic at zero strength (χ², larger = more of the residual it could explain).
    pub score: f64,
    pub score_rank: usize,
    /// Likelihood ratio of the refit with the candidate.
    pub lr: f64,
    pub delta_bic: f64,
    /// Relative improvement of the held-out (cross-validated) RMS.
    pub cv_improvement: f64,
    /// Gap (RMS/mean) of the refit.
    pub gap: f64,
    /// Residual variance / noise variance of the refit (below the threshold: explains the data).
    pub consistency: f64,
    /// Named: accepted in its round and, after the final fit, its signature is clear of structure.
    pub accepted: bool,
    /// Accepted in its round but left structure above noise along its signature after the final
    /// fit (see `partial_candidates`).
    pub partial: bool,
    /// Residual structure of this refit along every condition (its signature ones flagged).
    pub structure: Vec<AxisStructure>,
    pub params: Vec<NamedParam>,
    /// Its strength's interval the data allow: the refit's value ± 2σ (linearised), clipped to
    /// the law's range, per named parameter (`null` for an unbounded end).
    pub size_interval: Vec<SizeInterval>,
    /// Sum of squares of its refit (weighted residuals).
    #[serde(skip)]
    pub ssr: f64,
    #[serde(skip)]
    pub fit_x: Vec<f64>,
    #[serde(skip)]
    pub pred: Vec<f64>,
}

/// The range of one named parameter of a candidate that the data allow (± 2σ of its fitted
/// strength, mapped to the named parameter; an end at the law's zero strength, e.g. an infinite
/// corner frequency, means the data cannot tell the effect from none).
#[derive(Debug, Clone, Serialize)]
pub struct SizeInterval {
    pub name: String,
    pub value: f64,
    pub lo: Option<f64>,
    pub hi: Option<f64>,
}

/// The workflow's overall verdict.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Outcome {
    /// R and the structure along every condition within noise, nothing named or partial.
    NothingMissing,
    /// At least one effect named (its verdict says whether structure is left).
    Named,
    /// Nothing named, but structure above noise along at least one condition
    /// (`unexplained_structure`) that no library effect explains at this noise.
    StructureUnexplained,
    /// Nothing named and no condition above noise, but R above its noise limit: an excess spread
    /// over all conditions (or a partial candidate) that no library effect explains.
    ExcessUnexplained,
}

#[derive(Debug, Clone, Serialize)]
pub struct Experiment {
    pub preload_n: f64,
    pub voltage_v: f64,
    pub frequency_hz: f64,
    pub load_n: f64,
    pub direction: i8,
    /// Predicted speeds of each group member's fitted model there (mm/s), in group order.
    pub predicted_mm_s: Vec<f64>,
    /// Largest predicted difference in units of the noise there.
    pub separation_sigma: f64,
}

#[derive(Debug, Clone, Serialize)]
pub struct Ambiguity {
    pub round: usize,
    pub effects: Vec<String>,
    pub delta_bic: Vec<f64>,
    pub separating_experiment: Option<Experiment>,
}

/// A named effect with its parameters from the final refit (all accepted effects together).
#[derive(Debug, Clone, Serialize)]
pub struct FinalEffect {
    pub name: String,
    pub params: Vec<NamedParam>,
}

/// Residual structure of one fit along one condition, against the noise.
#[derive(Debug, Clone, Serialize)]
pub struct AxisStructure {
    pub condition: &'static str,
    pub levels: usize,
    /// χ² of the level means in noise units, per degree of freedom (levels − 1).
    pub chi2_per_dof: f64,
    /// The χ²/dof that pure noise exceeds with probability `signature_alpha`.
    pub noise_limit_per_dof: f64,
    /// Below the limit (or a single level: nothing to compare).
    pub consistent_with_noise: bool,
    /// In the effect's signature (the conditions its law acts on).
    pub signature: bool,
}

/// The naming decision for one accepted effect: the residual structure of the final joint fit
/// (all accepted effects together) along every condition, its signature conditions flagged.
#[derive(Debug, Clone, Serialize)]
pub struct SignatureTest {
    pub effect: String,
    /// Every signature condition consistent with noise: named; otherwise a partial candidate.
    pub named: bool,
    pub structure: Vec<AxisStructure>,
}

/// The workflow's verdict on an effect accepted in its round (ΔBIC and cross-validation), from
/// the final joint fit.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Tier {
    /// Explains most of the excess over noise and leaves its own signature conditions consistent
    /// with noise: added to the model.
    Named,
    /// Explains most of the excess over noise, and most of the base model's, but leaves
    /// structure above noise along one of its signature conditions: added to the model (the gap
    /// shrinks with it), and the structure left
    /// is reported along its conditions: something else acts there too.
    NamedWithStructureLeft,
    /// Explains less than half of the excess over noise (it soaks up part of what another cause
    /// leaves, e.g. the base model's own error): not added.
    Partial,
}

/// The verdict on one accepted effect.
#[derive(Debug, Clone, Serialize)]
pub struct Verdict {
    pub effect: String,
    pub tier: Tier,
    /// Share of the excess over noise, `SSR/s² − (n − p)`, of the final model without this
    /// effect that the effect removes (0–1).
    pub share_of_excess: f64,
    /// Conditions whose residual structure stays above noise in the final fit with it, most
    /// structured first (its own signature conditions among them decide tier 2).
    pub structure_left_along: Vec<&'static str>,
}

/// An accepted effect that explains less than half of the excess over noise: not named, not in
/// the fitted model.
#[derive(Debug, Clone, Serialize)]
pub struct PartialCandidate {
    pub effect: String,
    /// Round in which it was accepted provisionally.
    pub round: usize,
    /// Share of the excess over noise, `SSR/s² − (n − p)`, of the model with the named effects
    /// that adding this effect removes (0–1).
    pub share_of_excess: f64,
    /// R of the model with the named effects, and with this effect added.
    pub consistency_without: f64,
    pub consistency_with: f64,
    pub gap_with: f64,
    /// Its signature conditions whose structure stays above noise.
    pub unexplained_signature: Vec<&'static str>,
    /// Every condition whose structure stays above noise with it, most structured first.
    pub unexplained_along: Vec<&'static str>,
    /// Structure per condition with the effect fitted.
    pub structure: Vec<AxisStructure>,
    pub params: Vec<NamedParam>,
}

/// Residual structure against one condition: the spread of the mean weighted residual between
/// the condition's levels, as χ² per degree of freedom in units of the noise (≈ 1: no structure).
#[derive(Debug, Clone, Serialize)]
pub struct Structure {
    pub condition: String,
    pub levels: usize,
    pub chi2_per_dof_before: f64,
    pub chi2_per_dof_after: f64,
}

#[derive(Debug, Clone, Serialize)]
pub struct Removed {
    pub name: String,
    pub round: usize,
    pub delta_bic_kept: f64,
}

#[derive(Debug, Clone, Serialize)]
pub struct BaseFit {
    pub name: String,
    pub file_value: f64,
    pub fitted: f64,
    pub std_dev: f64,
}

#[derive(Debug, Clone, Serialize)]
pub struct GapReport {
    pub rows: usize,
    pub gap_before: f64,
    pub gap_after: f64,
    /// The effects added to the model (tiers `named` and `named_with_structure_left`).
    pub named_effects: Vec<String>,
    /// Of those, the ones that leave structure above noise along their own signature.
    pub named_with_structure_left: Vec<String>,
    /// The verdict on every effect accepted in its round, in the order accepted.
    pub verdicts: Vec<Verdict>,
    /// Effects accepted by ΔBIC and cross-validation that explain less than half of the excess
    /// over noise: not added.
    pub partial_candidates: Vec<PartialCandidate>,
    /// The signature test of every accepted effect, in the final joint fit.
    pub signature_tests: Vec<SignatureTest>,
    /// Its significance level ([`Options::signature_alpha`]).
    pub signature_alpha: f64,
    /// The named effects' parameters from the final fit (with one-sigma uncertainties).
    pub final_effects: Vec<FinalEffect>,
    pub candidates: Vec<Candidate>,
    pub ambiguity: Vec<Ambiguity>,
    /// Residual structure by condition (preload, voltage, frequency, load level, direction).
    pub residual_structure: Vec<Structure>,
    pub removed: Vec<Removed>,
    /// Library effects not tried: the data hold one level of every condition their law acts on
    /// (e.g. a preload-only law on data at one preload), so the base calibration absorbs them.
    pub not_identifiable: Vec<String>,
    /// Noise estimate, mm/s at the mean speed (difference-based, base fit).
    pub noise_mm_s: f64,
    /// Residual variance / noise variance of the calibrated base model and of the final model.
    pub consistency_before: f64,
    pub consistency_after: f64,
    /// The thresholds this data set's row count and noise give ([`Thresholds`]).
    pub thresholds: Thresholds,
    /// True only when nothing is named or partial, R is below its noise limit and the structure
    /// along every condition is within noise (`outcome` = `nothing_missing`).
    pub nothing_missing: bool,
    pub outcome: Outcome,
    /// Conditions whose residual structure in the final fit is above noise (χ²/dof above its
    /// limit at `signature_alpha`), most structured first.
    pub unexplained_structure: Vec<AxisStructure>,
    /// Where structure or an excess is left: the last round's candidates whose likelihood ratio
    /// says they explain part of it (ΔBIC at least its threshold) but which were not added
    /// (cross-validation gain below its threshold, or a partial share), each with the size
    /// interval the data allow, best ΔBIC first.
    pub unsized_candidates: Vec<Candidate>,
    pub base_calibration: Vec<BaseFit>,
    pub final_calibration: Vec<BaseFit>,
    pub elapsed_s: f64,
    #[serde(skip)]
    pub pred_before_mm_s: Vec<f64>,
    #[serde(skip)]
    pub pred_after_mm_s: Vec<f64>,
    #[serde(skip)]
    pub fitted_params: Option<Params>,
}

struct State {
    model: Model,
    fit: Fit,
    s: f64,
    /// Pseudo-residuals behind `s` (0: `s` is the residual scale, not a noise estimate).
    noise_dof: usize,
    ratio: f64,
}

impl State {
    /// Whether this fit's residuals are noise: R below its limit and no condition's structure
    /// above noise. Returns that, R's limit and the conditions above noise (most structured
    /// first).
    fn within_noise(&self, data: &Data, opts: &Options) -> (bool, f64, Vec<AxisStructure>) {
        let limit =
            consistency_limit(data.len(), self.model.n_params(), self.noise_dof, opts.signature_alpha);
        let mut above: Vec<AxisStructure> =
            axis_structure(data, &self.fit.resid, (self.s, self.noise_dof), opts.signature_alpha, &[])
                .into_iter()
                .filter(|a| !a.consistent_with_noise)
                .collect();
        above.sort_by(|a, b| {
            (b.chi2_per_dof / b.noise_limit_per_dof).total_cmp(&(a.chi2_per_dof / a.noise_limit_per_dof))
        });
        (self.ratio < limit && above.is_empty(), limit, above)
    }

    /// Whether effect selection goes on: structure above noise along a condition, or R at least
    /// its limit with the noise known ([`Thresholds::search_ratio`]).
    fn search_goes_on(&self, data: &Data, opts: &Options) -> bool {
        let limit = consistency_limit(data.len(), self.model.n_params(), self.noise_dof, SEARCH_ALPHA);
        self.ratio >= limit || !self.within_noise(data, opts).2.is_empty()
    }
}

fn base_starts(n: usize) -> Vec<Vec<f64>> {
    let combos = [[0.0, 0.0, 0.0], [0.2, -0.2, 0.0], [-0.2, 0.2, 0.0], [0.0, 0.2, -0.2], [0.0, -0.2, 0.2]];
    combos
        .iter()
        .map(|c| {
            let mut v = vec![0.0; n];
            v[..BASE_PARAMS].copy_from_slice(c);
            v
        })
        .collect()
}

/// Starting points for `model + effect` from a fit of `model` (its x) and the effect's starts.
fn candidate_starts(x0: &[f64], effect: Effect, data: &Data) -> Vec<Vec<f64>> {
    let defs = effect.fit_params();
    let mut starts = Vec::new();
    if effect == Effect::PreloadDependentFriction {
        let mut pre: Vec<f64> = data.conds.iter().map(|c| c.preload_n).collect();
        pre.sort_by(f64::total_cmp);
        pre.dedup_by(|a, b| (*a - *b).abs() < 1e-9);
        let mut knees: Vec<f64> = pre.windows(2).map(|w| 0.5 * (w[0] + w[1])).collect();
        if let Some(first) = pre.first() {
            knees.push(0.5 * first);
        }
        let mut v = x0.to_vec();
        v.push(0.0);
        v.push(defs[1].zero);
        starts.push(v);
        for k in knees {
            let mut v = x0.to_vec();
            v.push(defs[0].starts[0]);
            v.push(k);
            starts.push(v);
        }
        return starts;
    }
    // The current fit with the effect at zero is always one start, so a refit never ends worse.
    for s in std::iter::once(defs[0].zero).chain(defs[0].starts.iter().copied()) {
        let mut v = x0.to_vec();
        v.push(s);
        starts.push(v);
    }
    starts
}

fn all_rows(data: &Data) -> Vec<usize> {
    (0..data.len()).collect()
}

fn ratio(fit: &Fit, n: usize, p: usize, s: f64) -> f64 {
    fit.ssr / (n.saturating_sub(p).max(1) as f64) / (s * s)
}

/// Score statistic of adding `effect` to the model at its fit.
fn score(state: &State, effect: Effect, data: &Data) -> f64 {
    let rows = all_rows(data);
    let defs = effect.fit_params();
    let jb = &state.fit.jac;
    let r = DMatrix::from_column_slice(rows.len(), 1, &state.fit.resid);
    let a = jb.transpose() * jb;
    let Some(a_inv) = a.try_inverse() else { return 0.0 };
    let mut ext = state.model.clone();
    ext.effects.push(effect);
    let knees: Vec<f64> = if effect == Effect::PreloadDependentFriction {
        candidate_starts(&state.fit.x, effect, data).iter().map(|s| s[s.len() - 1]).collect()
    } else {
        vec![0.0]
    };
    let mut best: f64 = 0.0;
    for knee in knees {
        let mut x = state.fit.x.clone();
        x.push(defs[0].zero);
        if defs.len() > 1 {
            x.push(knee);
        }
        let k = state.model.n_params();
        let span = defs[0].hi - defs[0].lo;
        let h = 1e-4 * span;
        let mut xp = x.clone();
        xp[k] += h;
        let p0 = ext.predict(&x, data, &rows);
        let p1 = ext.predict(&xp, data, &rows);
        let mut jc = DMatrix::zeros(rows.len(), 1);
        for i in 0..rows.len() {
            jc[(i, 0)] = (p1[i] - p0[i]) / h / data.sigma[i];
        }
        let proj = jb * (&a_inv * (jb.transpose() * &jc));
        let jperp = jc - proj;
        let u = (jperp.transpose() * &r)[(0, 0)];
        let info = (jperp.transpose() * &jperp)[(0, 0)];
        if info <= 0.0 {
            continue;
        }
        // d SSR/dθ = 2·J⊥ᵀr: one-sided strengths only count a decrease for θ > 0.
        let one_sided = defs[0].lo >= defs[0].zero;
        if one_sided && u > 0.0 {
            continue;
        }
        best = best.max(u * u / info / (state.s * state.s));
    }
    best
}

/// K-fold cross-validated weighted RMS over held-out curves, warm-started from `x0`.
fn cv_rms(model: &Model, data: &Data, x0: &[f64], folds: usize) -> f64 {
    let k = folds.clamp(2, data.n_curves.max(2));
    let fold_of = |c: usize| (c * 7 + 3) % k;
    let mut sum = 0.0;
    let mut count = 0usize;
    for f in 0..k {
        let train: Vec<usize> = (0..data.len()).filter(|&i| fold_of(data.curve[i]) != f).collect();
        let test: Vec<usize> = (0..data.len()).filter(|&i| fold_of(data.curve[i]) == f).collect();
        if test.is_empty() || train.len() <= model.n_params() {
            continue;
        }
        let fit = lm_fit(model, data, &train, &[x0.to_vec()], fit::REFIT_ITERATIONS);
        let pred = model.predict(&fit.x, data, &test);
        for (&i, p) in test.iter().zip(pred) {
            sum += ((p - data.y[i]) / data.sigma[i]).powi(2);
            count += 1;
        }
    }
    (sum / count.max(1) as f64).sqrt()
}

fn effect_named_params(model: &Model, fit: &Fit, effect: Effect, s: f64) -> Vec<NamedParam> {
    let Some(off) = model.offset(effect) else { return Vec::new() };
    let defs = effect.fit_params();
    let k = defs.len();
    let x = &fit.x[off..off + k];
    let cov = covariance(fit, s);
    let named = named_values(effect, x);
    named
        .iter()
        .enumerate()
        .map(|(j, (pname, v))| {
            // Delta method through the internal → named map, by finite differences.
            let mut var = 0.0;
            if let Some(c) = &cov {
                let grads: Vec<f64> = (0..k)
                    .map(|m| {
                        let h = 1e-6 * (defs[m].hi - defs[m].lo);
                        let mut xp = x.to_vec();
                        xp[m] += h;
                        (named_values(effect, &xp)[j].1 - v) / h
                    })
                    .collect();
                for a in 0..k {
                    for b in 0..k {
                        var += grads[a] * grads[b] * c[(off + a, off + b)];
                    }
                }
            }
            NamedParam { name: (*pname).to_string(), value: *v, std_dev: var.max(0.0).sqrt() }
        })
        .collect()
}

/// The interval of each of `effect`'s named parameters that the fit allows: its fitted strength
/// ± 2σ (linearised, noise scale `s`), the others at their values, clipped to the law's range and
/// mapped to the named parameter.
fn size_interval(model: &Model, fit: &Fit, effect: Effect, s: f64) -> Vec<SizeInterval> {
    let Some(off) = model.offset(effect) else { return Vec::new() };
    let defs = effect.fit_params();
    let x = &fit.x[off..off + defs.len()];
    let cov = covariance(fit, s);
    named_values(effect, x)
        .iter()
        .enumerate()
        .map(|(j, (name, value))| {
            let sd = cov.as_ref().map_or(f64::NAN, |c| c[(off + j, off + j)].max(0.0).sqrt());
            let end = |sign: f64| {
                let mut xe = x.to_vec();
                xe[j] = (x[j] + sign * 2.0 * sd).clamp(defs[j].lo, defs[j].hi);
                named_values(effect, &xe)[j].1
            };
            let (a, b) = (end(-1.0), end(1.0));
            let (lo, hi) = if a <= b { (a, b) } else { (b, a) };
            SizeInterval {
                name: (*name).to_string(),
                value: *value,
                lo: lo.is_finite().then_some(lo),
                hi: hi.is_finite().then_some(hi),
            }
        })
        .collect()
}

fn base_calibration(model: &Model, fit: &Fit, s: f64) -> Vec<BaseFit> {
    let cov = covariance(fit, s);
    let file = [
        model.base.friction.mu_dynamic,
        model.base.stator.tangential_scale,
        model.base.stator.normal_force_ratio,
    ];
    (0..BASE_PARAMS)
        .map(|k| {
            let v = file[k] * fit.x[k].exp();
            let sd = cov.as_ref().map_or(f64::NAN, |c| c[(k, k)].max(0.0).sqrt() * v);
            BaseFit { name: BASE_NAMES[k].to_string(), file_value: file[k], fitted: v, std_dev: sd }
        })
        .collect()
}

/// The experiment (from a grid spanning and extending the measured ranges) where the group's
/// fitted models disagree most, in units of the expected noise there.
fn separating_experiment(group: &[&Candidate], model: &Model, data: &Data, s: f64) -> Option<Experiment> {
    let span = |f: fn(&Condition) -> f64| {
        let lo = data.conds.iter().map(f).fold(f64::INFINITY, f64::min);
        let hi = data.conds.iter().map(f).fold(f64::NEG_INFINITY, f64::max);
        (lo, hi)
    };
    let (p_lo, p_hi) = span(|c| c.preload_n);
    let (v_lo, v_hi) = span(|c| c.voltage_v);
    let (f_lo, f_hi) = span(|c| c.frequency_hz);
    let preloads = [0.5 * p_lo, p_lo, 0.5 * (p_lo + p_hi), p_hi, 1.25 * p_hi];
    let voltages = [0.5 * v_lo, v_lo, v_hi];
    let freqs = [500.0f64.min(f_lo), f_lo, 0.5 * (f_lo + f_hi), f_hi, 2200.0f64.max(f_hi)];
    let models: Vec<(Model, Vec<f64>)> = group
        .iter()
        .map(|c| {
            let mut m = model.clone();
            m.effects.push(c.effect);
            (m, c.fit_x.clone())
        })
        .collect();
    let mean = data.mean_speed().abs();
    let mut best: Option<Experiment> = None;
    for &preload_n in &preloads {
        for &voltage_v in &voltages {
            for &frequency_hz in &freqs {
                for direction in [1i8, -1] {
                    let c0 = Condition { preload_n, voltage_v, frequency_hz, load_n: 0.0, direction };
                    let p0 = models[0].0.params_at(&models[0].1);
                    let m0 = crate::motor::effects::EffectModel::new(&p0, &c0);
                    let stall = (m0.thrust_n(0.0) - m0.rail_coulomb_n).max(0.0);
                    for frac in [0.0, 0.4, 0.75] {
                        let c = Condition { load_n: frac * stall, ..c0 };
                        let speeds: Vec<f64> = models
                            .iter()
                            .map(|(m, x)| crate::motor::effects::model_speed_m_s(&m.params_at(x), &c))
                            .collect();
                        let hi = speeds.iter().copied().fold(f64::NEG_INFINITY, f64::max);
                        let lo = speeds.iter().copied().fold(f64::INFINITY, f64::min);
                        let sigma = s * (hi.abs() + fit::WEIGHT_FLOOR_OF_MEAN * mean);
                        let sep = (hi - lo) / sigma.max(1e-15);
                        if best.as_ref().is_none_or(|b| sep > b.separation_sigma) {
                            best = Some(Experiment {
                                preload_n,
                                voltage_v,
                                frequency_hz,
                                load_n: c.load_n,
                                direction,
                                predicted_mm_s: speeds.iter().map(|v| v * 1e3).collect(),
                                separation_sigma: sep,
                            });
                        }
                    }
                }
            }
        }
    }
    best
}

/// χ² (not per dof) of the level means of the weighted residuals and the number of levels, per
/// condition of [`Axis::ALL`]. The load level is a row's rank in load within its curve (the load
/// fraction of a measured curve).
fn structure(data: &Data, resid: &[f64], s: f64) -> Vec<(Axis, usize, f64)> {
    let n = data.len();
    let mut load_rank = vec![0i64; n];
    for c in 0..data.n_curves {
        let mut idx: Vec<usize> = (0..n).filter(|&i| data.curve[i] == c).collect();
        idx.sort_by(|&a, &b| data.conds[a].load_n.total_cmp(&data.conds[b].load_n));
        for (r, &i) in idx.iter().enumerate() {
            load_rank[i] = r as i64;
        }
    }
    let key = |axis: Axis, i: usize| -> i64 {
        let c = &data.conds[i];
        match axis {
            Axis::Preload => data.preload_level[i] as i64,
            Axis::Voltage => (c.voltage_v * 1e3).round() as i64,
            Axis::Frequency => (c.frequency_hz * 1e3).round() as i64,
            Axis::Load => load_rank[i],
            Axis::Direction => i64::from(c.direction),
        }
    };
    Axis::ALL
        .iter()
        .map(|&axis| {
            let mut groups: Vec<(i64, usize, f64)> = Vec::new();
            for (i, r) in resid.iter().enumerate().take(n) {
                let k = key(axis, i);
                match groups.iter_mut().find(|g| g.0 == k) {
                    Some(g) => {
                        g.1 += 1;
                        g.2 += r;
                    }
                    None => groups.push((k, 1, *r)),
                }
            }
            // Σ n_l·(r̄_l − r̄)²: the spread between the levels about the overall mean r̄, which
            // has levels − 1 degrees of freedom under noise whether or not the fit's parameters
            // absorb the overall level. An offset common to all rows is not structure along any
            // condition (R measures it); counted in, a model 1 % off everywhere showed χ²/dof 24
            // along the two drive senses of a symmetric plant.
            let total: f64 = resid.iter().take(n).sum();
            let between =
                groups.iter().map(|g| g.2 * g.2 / g.1 as f64).sum::<f64>() - total * total / n as f64;
            let chi2 = between.max(0.0) / (s * s);
            (axis, groups.len(), chi2)
        })
        .collect()
}

fn dof(levels: usize) -> usize {
    levels.saturating_sub(1).max(1)
}

/// [`structure`] tested against the noise at level `alpha`, with `sig`'s conditions flagged.
fn axis_structure(
    data: &Data,
    resid: &[f64],
    (s, noise_dof): (f64, usize),
    alpha: f64,
    sig: &[Axis],
) -> Vec<AxisStructure> {
    structure(data, resid, s)
        .into_iter()
        .map(|(axis, levels, chi2)| {
            let k = dof(levels);
            // χ²/dof over an estimated noise variance is F(k, m) with m pseudo-residuals behind
            // the estimate (→ χ²(k)/k for many); a few leave the noise itself uncertain.
            let limit_per_dof = if noise_dof > 0 {
                chi2::f_quantile_upper(alpha, k, noise_dof)
            } else {
                chi2::quantile_upper(alpha, k) / k as f64
            };
            AxisStructure {
                condition: axis.label(),
                levels,
                chi2_per_dof: chi2 / k as f64,
                noise_limit_per_dof: limit_per_dof,
                consistent_with_noise: levels < 2 || chi2 / k as f64 <= limit_per_dof,
                signature: sig.contains(&axis),
            }
        })
        .collect()
}

/// Whether a fit leaves its effect's signature conditions consistent with noise.
fn clears_signature(st: &[AxisStructure]) -> bool {
    st.iter().filter(|a| a.signature).all(|a| a.consistent_with_noise)
}

/// The parameter vector of `to` (a sub-model of `from`) taken from `x` of `from`.
fn sub_x(from: &Model, x: &[f64], to: &Model) -> Vec<f64> {
    let mut out: Vec<f64> = x[..BASE_PARAMS].to_vec();
    for e in &to.effects {
        let off = from.offset(*e).unwrap_or(BASE_PARAMS);
        out.extend_from_slice(&x[off..off + e.fit_params().len()]);
    }
    out
}

/// Progress of the workflow: a stage label and (done, total) steps within it.
pub type ProgressFn<'a> = &'a (dyn Fn(&str, usize, usize) + Sync);

/// The whole workflow on measured rows. `progress` is told each stage and step.
pub fn analyze(
    base: &Params,
    rows: &[MeasuredRow],
    opts: &Options,
    progress: ProgressFn,
) -> Result<GapReport> {
    let t0 = std::time::Instant::now();
    let library = stages::resolve_library(&opts.library)?;
    let data = stages::checked_data(rows)?;
    let (start, before) = stages::calibrate_base(base, &data, progress);
    let (library, not_identifiable) = stages::identifiable_library(library, base, &data);
    let thresholds = Thresholds::new(data.len(), start.noise_dof, library.len(), opts);
    let mut selection = stages::select_effects(start, &library, &data, (opts, &thresholds), progress);
    // Name only the effects whose own signature conditions are consistent with noise in the final
    // fit; the others are partial candidates and leave the model, which is refitted.
    let signature_tests = stages::signature_tests(&selection.state, &data, opts);
    let (verdicts, partial_candidates) =
        stages::decide_tiers(&mut selection, &signature_tests, before.ssr, &data, opts);
    let naming = stages::Naming { signature_tests, verdicts, partial_candidates };
    Ok(stages::build_report(&data, (opts, thresholds), before, selection, naming, not_identifiable, t0))
}

/// What `host-sim gap` is asked for (the workflow's thresholds are [`Options`]).
#[derive(Debug, Clone)]
pub struct GapOptions {
    /// Measured steady operating points (CSV: preload_n,voltage_v,frequency_hz,load_n,direction,velocity_mm_s).
    pub measured: PathBuf,
    /// Directory for the report, plots and the updated parameter file.
    pub out: PathBuf,
    /// Print one JSON object instead of the summary.
    pub json: bool,
}

pub fn run(args: GapOptions, params: &Params) -> Result<()> {
    let rows = crate::gap::measured_csv::read(&args.measured)?;
    // The report directory before the work, so a bad path costs nothing.
    crate::check::output_dir("--out", &args.out)?;
    let bar = if crate::check::show_progress() {
        indicatif::ProgressBar::new(1)
    } else {
        indicatif::ProgressBar::hidden()
    };
    bar.set_style(
        indicatif::ProgressStyle::with_template("gap {spinner} [{elapsed}] {bar:30} {pos}/{len} {msg}")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    bar.enable_steady_tick(std::time::Duration::from_millis(120));
    let report = analyze(params, &rows, &Options::default(), &|msg: &str, done: usize, total: usize| {
        bar.set_message(msg.to_string());
        bar.set_length(total as u64);
        bar.set_position(done as u64);
    })?;
    bar.finish_and_clear();
    report::write_all(&report, &rows, params, &args.measured, &args.out)?;
    if args.json {
        use std::io::Write;
        // A closed pipe (e.g. `| head`) is not an error of the workflow.
        let _ = writeln!(std::io::stdout(), "{}", serde_json::to_string_pretty(&report)?);
    } else {
        report::print_summary(&report, &args.out);
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The thresholds against their closed forms: the χ²(1) quantile at α/L is z² with z the
    /// normal quantile (P(|Z| > 3.836107) = 1.25e-4), χ²(2)'s is −2·ln(α/L), and 2/√n.
    #[test]
    fn thresholds_follow_from_rows_and_noise() {
        let opts = Options::default();
        let t = Thresholds::new(192, 35, 8, &opts);
        let ln_n = 192f64.ln();
        assert!((t.delta_bic[0] - (3.836_107f64.powi(2) - ln_n)).abs() < 1e-4, "{}", t.delta_bic[0]);
        assert!(
            (t.delta_bic[1] - (-2.0 * (1e-3f64 / 8.0).ln() - 2.0 * ln_n)).abs() < 1e-6,
            "{}",
            t.delta_bic[1]
        );
        assert!(t.search_ratio > 1.0 && t.search_ratio < t.consistency_ratio);
        assert!((chi2::f_upper_tail(t.search_ratio, 189, 35) - SEARCH_ALPHA).abs() < 1e-3);
        // R's limit is F(n − p, m)'s 1 − α quantile: above the known-noise χ² limit, below the
        // ratio a handful of pseudo-residuals would allow, and falling as m grows.
        let known = consistency_limit(192, BASE_PARAMS, 0, 1e-3);
        let r = t.consistency_ratio;
        let many = consistency_limit(192, BASE_PARAMS, 100_000, 1e-3);
        eprintln!(
            "R limits: m = 35 {r:.3}, m → ∞ {many:.3}, χ² {known:.3}; board (36 rows, m = 3) {:.2}; search: \
             192 rows {:.2}, 300 rows (m 66) {:.2}, board {:.2}",
            consistency_limit(36, 3, 3, 1e-3),
            t.search_ratio,
            consistency_limit(300, 3, 66, SEARCH_ALPHA),
            consistency_limit(36, 3, 3, SEARCH_ALPHA)
        );
        assert!(t.search_ratio > 1.0 && t.search_ratio < t.consistency_ratio);
        assert!((chi2::f_upper_tail(t.search_ratio, 189, 35) - SEARCH_ALPHA).abs() < 1e-3);
        assert!((many - known).abs() < 0.01 * known, "{many} vs {known}");
        assert!(r > known && r < consistency_limit(192, BASE_PARAMS, 10, 1e-3));
        assert!(chi2::f_upper_tail(r, 189, 35) > 0.9e-3 && chi2::f_upper_tail(r, 189, 35) < 1.1e-3);
    }
}
