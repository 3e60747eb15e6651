//! The stages of [`super::analyze`], in the order it calls them: resolve the effect library and
//! check the data, calibrate the base model (with its noise estimate), keep the identifiable
//! effects, select effects round by round (candidates tested, the best accepted, earlier ones
//! re-tested), test the accepted effects' signatures, demote those that fail to partial
//! candidates, and build the report.

use super::base::{fit_anchored, CANDIDATE_ANCHORS, MAX_ANCHORS, SLOPE_STEP};
use super::fit::{
    self, fit as lm_fit, Data, Fit, Model, BASE_ITERATIONS, BASE_PARAMS, EFFECT_ITERATIONS, REFIT_ITERATIONS,
};
use super::refits::Refits;
use super::{
    all_rows, axis_structure, base_calibration, base_starts, candidate_starts, clears_signature, cv_rms, dof,
    effect_named_params, ratio, score, separating_experiment, structure, sub_x, Ambiguity, AxisStructure,
    Candidate, FinalEffect, GapReport, Options, Outcome, PartialCandidate, ProgressFn, Removed,
    SignatureTest, State, Structure, Thresholds, Tier, Verdict,
};
use crate::gap::measured_csv::MeasuredRow;
use crate::motor::effects::{Axis, Effect};
use crate::motor::params::Params;
use anyhow::{anyhow, bail, Result};
use rayon::prelude::*;

/// Resolves [`Options::library`] into effects; fails on a name that is not an effect.
pub(super) fn resolve_library(names: &[&'static str]) -> Result<Vec<Effect>> {
    names
        .iter()
        .map(|name| name.parse::<Effect>().map_err(|e| anyhow!("effect library: {e}")))
        .collect::<Result<Vec<Effect>>>()
}

/// The measured rows as fit data; fails on fewer than 8 rows or a mean speed that is not positive
/// (the gap is relative to it).
pub(super) fn checked_data(rows: &[MeasuredRow]) -> Result<Data> {
    let data = Data::from_rows(rows);
    let n = data.len();
    if n < 8 {
        bail!("need at least 8 measured rows, got {n}");
    }
    if data.mean_speed() <= 0.0 {
        bail!("the mean measured speed must be positive (the gap is relative to it)");
    }
    Ok(data)
}

/// What the report says of the calibrated base model (before any effect is added).
pub(super) struct Before {
    /// Noise scale of the base fit (weighted units).
    pub s: f64,
    /// Weighted sum of squares of the base fit.
    pub ssr: f64,
    /// Residual variance / noise variance of the base fit.
    pub ratio: f64,
    /// Predicted speeds of the base fit (m/s) and their gap.
    pub pred: Vec<f64>,
    pub gap: f64,
    pub calibration: Vec<super::BaseFit>,
    /// χ² per condition of the base fit's residuals ([`structure`]).
    pub structure: Vec<(Axis, usize, f64)>,
}

/// Calibrates the base parameters (no effects) to the data and estimates the noise from its
/// residuals. Returns the workflow's starting state (base model, fit, noise, consistency) and
/// what the report says of the base model.
pub(super) fn calibrate_base(base: &Params, data: &Data, progress: ProgressFn) -> (State, Before) {
    let all = all_rows(data);
    progress("calibrating the base model", 0, 1);
    let (base_model, base_fit) = fit_anchored(
        &Model::new(base, data),
        data,
        &all,
        &base_starts(BASE_PARAMS),
        BASE_ITERATIONS,
        MAX_ANCHORS,
        false,
    );
    let (s0, m0) = estimate_noise(data, &base_fit);
    let pred = base_model.predict(&base_fit.x, data, &all);
    let before = Before {
        s: s0,
        ssr: base_fit.ssr,
        ratio: ratio(&base_fit, data.len(), BASE_PARAMS, s0),
        gap: data.gap(&pred),
        pred,
        calibration: base_calibration(&base_model, &base_fit, s0),
        structure: structure(data, &base_fit.resid, s0),
    };
    let state = State { model: base_model, fit: base_fit, s: s0, noise_dof: m0, ratio: before.ratio };
    (state, before)
}

/// Estimates the noise scale from the base fit's difference-based pseudo-residuals. Returns the
/// scale and the number of pseudo-residuals behind it; with no curve of three loads, the residual
/// scale and 0 (nothing can then be detected).
fn estimate_noise(data: &Data, base_fit: &Fit) -> (f64, usize) {
    let (s0, m0) = data.noise_scale(&base_fit.resid);
    if m0 == 0 || !s0.is_finite() || s0 <= 0.0 {
        ((base_fit.ssr / (data.len() - BASE_PARAMS) as f64).sqrt().max(1e-12), m0)
    } else {
        (s0, m0)
    }
}

/// Re-estimates the noise scale from a later fit's residuals. Returns it with its
/// pseudo-residual count, or `fallback` when the fit gives no usable estimate.
fn refresh_noise(data: &Data, fit: &Fit, fallback: (f64, usize)) -> (f64, usize) {
    let (s, m) = data.noise_scale(&fit.resid);
    if m == 0 || !s.is_finite() || s <= 0.0 {
        fallback
    } else {
        (s, m)
    }
}

/// Drops the effects the base parameters already have active and splits the rest by whether the
/// data can identify them: an effect whose every signature condition has one level in the data
/// cannot be told from the base calibration. Returns the effects to try and the names of those
/// left out.
pub(super) fn identifiable_library(
    library: Vec<Effect>,
    base: &Params,
    data: &Data,
) -> (Vec<Effect>, Vec<String>) {
    // On a contact base `slider_inertia` is a carriage of another mass than the file's (the
    // contact model carries the file's): a payload nobody told the file about.
    let library: Vec<Effect> = library.into_iter().filter(|e| !base.effects.is_active(*e)).collect();
    let levels = structure(data, &vec![0.0; data.len()], 1.0);
    let varied = |axis: Axis| levels.iter().any(|&(a, k, _)| a == axis && k >= 2);
    let (library, unidentifiable): (Vec<Effect>, Vec<Effect>) =
        library.into_iter().partition(|e| e.signature().iter().any(|&a| varied(a)));
    (library, unidentifiable.iter().map(|e| e.to_string()).collect())
}

/// The outcome of effect selection.
pub(super) struct Selection {
    /// The model with the accepted effects, its fit and noise.
    pub state: State,
    /// Every candidate of every round, each round's sorted by ΔBIC.
    pub candidates: Vec<Candidate>,
    pub ambiguity: Vec<Ambiguity>,
    pub removed: Vec<Removed>,
    /// The refits without some effects solved so far (the verdicts ask for the re-tests' again).
    pub refits: Refits,
}

/// Rounds of effect selection: while effects may still be added and the residuals are not
/// consistent with noise, tests every library effect not in the model, accepts the best one that
/// pays its way (ΔBIC and cross-validation), records an ambiguity group, and re-tests the earlier
/// effects. Returns the final state with every candidate, ambiguity and removal.
pub(super) fn select_effects(
    mut state: State,
    library: &[Effect],
    data: &Data,
    (opts, th): (&Options, &Thresholds),
    progress: ProgressFn,
) -> Selection {
    let mut candidates_out: Vec<Candidate> = Vec::new();
    let mut ambiguity = Vec::new();
    let mut removed = Vec::new();
    let mut refits = Refits::default();
    let mut round = 0;
    // The search starts, and goes on, on either signal: structure above noise along one
    // condition (a small effect along one condition moves R little: an amplifier 1 % slower at
    // the top frequency left R at 1.5 with χ²/dof 24 along frequency), or R above F(n − p, m)'s
    // 5 % quantile ([`Thresholds::search_ratio`]). The verdict's limit, at α = 0.001, is on a
    // board's few curves (m = 3) R 45: a search that stopped there left the guide's friction at
    // 0.22 N for 0.4, the Stribeck rise that takes up the contact model's error there untried.
    while state.model.effects.len() < opts.max_effects && state.search_goes_on(data, opts) {
        round += 1;
        let todo: Vec<Effect> =
            library.iter().copied().filter(|e| !state.model.effects.contains(e)).collect();
        if todo.is_empty() {
            break;
        }
        let mut cands = test_candidates(&state, &todo, round, data, (opts, th), progress);
        let Some((best, group)) = best_and_group(&cands, &state, data, (opts, th)) else {
            candidates_out.extend(cands);
            break;
        };
        if group.len() > 1 {
            let members: Vec<&Candidate> = group.iter().map(|&i| &cands[i]).collect();
            ambiguity.push(Ambiguity {
                round,
                effects: members.iter().map(|c| c.name.clone()).collect(),
                delta_bic: members.iter().map(|c| c.delta_bic).collect(),
                separating_experiment: separating_experiment(&members, &state.model, data, state.s),
            });
        }
        cands[best].accepted = true;
        let (effect, x) = (cands[best].effect, cands[best].fit_x.clone());
        candidates_out.extend(cands);
        state = accept_effect(&state, effect, x, round, data, th, &mut removed, &mut refits);
    }
    Selection { state, candidates: candidates_out, ambiguity, removed, refits }
}

/// Tests each effect of `todo` against the current state (in parallel): score at zero strength,
/// refit with it, likelihood ratio and ΔBIC, cross-validated improvement, residual structure.
/// Returns the candidates with their score ranks, sorted by ΔBIC (largest first).
fn test_candidates(
    state: &State,
    todo: &[Effect],
    round: usize,
    data: &Data,
    (opts, th): (&Options, &Thresholds),
    progress: ProgressFn,
) -> Vec<Candidate> {
    let all = all_rows(data);
    let label = format!("round {round}: candidates scored and refitted");
    progress(&label, 0, todo.len());
    let done = std::sync::atomic::AtomicUsize::new(0);
    let cv_without = cv_rms(&state.model, data, &state.fit.x, opts.folds);
    let (mut cands, refine_from): (Vec<Candidate>, Vec<RefineStarts>) = todo
        .par_iter()
        .map(|&effect| {
            let sc = score(state, effect, data);
            let mut m = state.model.clone();
            m.effects.push(effect);
            let starts = candidate_starts(&state.fit.x, effect, data);
            let f = lm_fit(&m, data, &all, &starts, EFFECT_ITERATIONS);
            let cheap = f.x.clone();
            let k = effect.fit_params().len();
            let pays =
                |f: &Fit| delta_bic(state.fit.ssr, f.ssr, state.s, k, data.len()) >= th.min_delta_bic(k);
            // On a contact base that fit moved the effect the way the closed form does; one
            // anchor at its end point refits it on the contact model's own slopes, and the
            // likelihood ratio is between the contact model's sums of squares.
            let (m, f, refine_from) = if m.anchor.is_some() {
                let (m1, f1) =
                    fit_anchored(&m, data, &all, &[f.x], EFFECT_ITERATIONS, CANDIDATE_ANCHORS, true);
                let (m1, f1) = match starts.first() {
                    // Not paying its way (ΔBIC below the threshold) from where the closed form
                    // led it: the closed form may have led the effect astray, so it is fitted
                    // again anchored at zero strength, on the contact model's own slopes, its
                    // surrogate from every candidate start, and the better kept. On the 0.3 kg
                    // carriage the closed form put a preload knee above every measured preload,
                    // where the contact model's slopes in the effect are zero; the base factors'
                    // own gain there made that fit look better than none.
                    Some(zero) if !pays(&f1) && zero[zero.len() - k..] != cheap[cheap.len() - k..] => {
                        let (m0, f0) =
                            fit_anchored(&m, data, &all, &starts, EFFECT_ITERATIONS, CANDIDATE_ANCHORS, true);
                        if f0.ssr < f1.ssr {
                            (m0, f0)
                        } else {
                            (m1, f1)
                        }
                    }
                    _ => (m1, f1),
                };
                // The base fit may have taken up what the effect does, and the surrogate, whose
                // closed form has the effect in its own shape, keeps it there: a Stribeck rise
                // of 1.5 on the 1 kg carriage looked like μ 2.3× its file value to the base fit,
                // and every surrogate start ended at μ 2.3×, rise 0.12. So the contact model
                // also fits from the file's base values with the effect at its largest start.
                // Where that wins after one anchor move, both are fitted to the end if the
                // candidate leads: one anchor move does not tell which valley is the deeper.
                // Not where the fit's base is within a slope step of the file's: the same start.
                let surrogate_path = cheap;
                let near_file = state.fit.x[..BASE_PARAMS].iter().all(|x| x.abs() < SLOPE_STEP);
                match starts.last().filter(|_| !near_file).map(|s| from_file_values(s)) {
                    Some(x) => {
                        let (m2, f2) =
                            fit_anchored(&m, data, &all, &[x], EFFECT_ITERATIONS, CANDIDATE_ANCHORS, false);
                        if f2.ssr < f1.ssr {
                            let from = f2.x.clone();
                            (m2, f2, RefineStarts { leading: vec![surrogate_path, from], other_valley: None })
                        } else {
                            let other_valley = Some((f2.ssr, f2.x));
                            (m1, f1, RefineStarts { leading: vec![surrogate_path], other_valley })
                        }
                    }
                    None => (m1, f1, RefineStarts { leading: vec![surrogate_path], other_valley: None }),
                }
            } else {
                (m, f, RefineStarts { leading: vec![cheap], other_valley: None })
            };
            let d = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
            progress(&label, d, todo.len());
            (candidate(state, effect, round, sc, &m, &f, cv_without, data, opts), refine_from)
        })
        .unzip();
    // On a contact base one anchor move leaves a candidate short of its optimum where the
    // contact model's slopes change along the way (a drive gain that changes the impacts): the
    // leading ones by likelihood ratio, those the decision is about, are fitted to the end.
    if state.model.anchor.is_some() {
        let mut by_lr: Vec<usize> = (0..cands.len()).collect();
        by_lr.sort_by(|&a, &b| cands[b].lr.total_cmp(&cands[a].lr));
        let lead: Vec<usize> = by_lr.into_iter().take(LEADING_CANDIDATES).collect();
        let mut runs: Vec<(usize, &RefineFrom)> =
            lead.iter().flat_map(|&i| refine_from[i].leading.iter().map(move |start| (i, start))).collect();
        // The most promising other valley is followed too: of the fits from the file's base
        // values that lost after their one anchor move, the one that got lowest. One move from
        // there need not tell the deeper valley either: on 0.3 kg with a hidden Stribeck rise a
        // calibration that took the rise up as μ 2.1× (a path chosen by a last-bit change of the
        // orbit searches) left the rise's fit from the file's values at 1.9× the sum of squares
        // of the μ valley after one move (its rise already at 1.41 for 1.5) and outside the
        // leading two; nothing was named (gap 0.31 → 0.32). Followed to its end, the rise is
        // named (gap 0.31 → 0.038).
        let alternate = refine_from
            .iter()
            .enumerate()
            .filter_map(|(i, r)| r.other_valley.as_ref().map(|(ssr, x)| (i, *ssr, x)))
            .min_by(|a, b| a.1.total_cmp(&b.1));
        if let Some((i, _, x)) = alternate {
            runs.push((i, x));
        }
        let refined: Vec<(usize, Candidate)> = runs
            .par_iter()
            .map(|&(i, x)| {
                let c = &cands[i];
                let mut m = state.model.clone();
                m.effects.push(c.effect);
                let (m, f) = fit_anchored(
                    &m,
                    data,
                    &all,
                    std::slice::from_ref(x),
                    EFFECT_ITERATIONS,
                    LEADING_ANCHORS,
                    true,
                );
                (i, candidate(state, c.effect, round, c.score, &m, &f, cv_without, data, opts))
            })
            .collect();
        for (i, c) in refined {
            if c.lr > cands[i].lr {
                cands[i] = c;
            }
        }
    }
    let mut order: Vec<usize> = (0..cands.len()).collect();
    order.sort_by(|&a, &b| cands[b].score.total_cmp(&cands[a].score));
    for (rank, &i) in order.iter().enumerate() {
        cands[i].score_rank = rank + 1;
    }
    cands.sort_by(|a, b| b.delta_bic.total_cmp(&a.delta_bic));
    cands
}

/// ΔBIC of `k` parameters that lower the sum of squares from `ssr_without` to `ssr_with` on `n`
/// rows with noise scale `s`: the likelihood ratio less the parameters' price.
fn delta_bic(ssr_without: f64, ssr_with: f64, s: f64, k: usize, n: usize) -> f64 {
    (ssr_without - ssr_with) / (s * s) - k as f64 * (n as f64).ln()
}

/// A point a leading candidate's refinement starts from.
type RefineFrom = Vec<f64>;

/// Where a candidate's fits to the end would start, from its one-move fits on a contact base:
/// `leading`, if it is among the leading candidates (the closed form's path, and the fit from
/// the file's base values where that won); `other_valley`, the fit from the file's values
/// where it lost, with its sum of squares (the lowest of those is followed too).
struct RefineStarts {
    leading: Vec<RefineFrom>,
    other_valley: Option<(f64, RefineFrom)>,
}

/// `start` with the base factors at the parameter file's values (0: the factors are logs of
/// the file's values); the effects' values kept.
fn from_file_values(start: &[f64]) -> Vec<f64> {
    let mut x = start.to_vec();
    x[..BASE_PARAMS].fill(0.0);
    x
}

/// Candidates a contact base fits to the end in each round, the leading ones by likelihood
/// ratio after one anchor move, and the anchor moves they get (from the closed-form fit's end,
/// as the first).
const LEADING_CANDIDATES: usize = 2;
const LEADING_ANCHORS: usize = 6;

/// A candidate's figures from its refit `f` of `m` (the current model plus `effect`):
/// likelihood ratio and ΔBIC against the current fit, cross-validated improvement, gap,
/// consistency, the structure along its signature and its parameters.
#[allow(clippy::too_many_arguments)]
fn candidate(
    state: &State,
    effect: Effect,
    round: usize,
    score: f64,
    m: &Model,
    f: &Fit,
    cv_without: f64,
    data: &Data,
    opts: &Options,
) -> Candidate {
    let all = all_rows(data);
    let n = data.len();
    let lr = (state.fit.ssr - f.ssr) / (state.s * state.s);
    let cv_with = cv_rms(m, data, &f.x, opts.folds);
    let pred = m.predict(&f.x, data, &all);
    let structure =
        axis_structure(data, &f.resid, (state.s, state.noise_dof), opts.signature_alpha, effect.signature());
    Candidate {
        name: effect.to_string(),
        effect,
        round,
        score,
        score_rank: 0,
        lr,
        delta_bic: delta_bic(state.fit.ssr, f.ssr, state.s, effect.fit_params().len(), n),
        cv_improvement: 1.0 - cv_with / cv_without.max(1e-300),
        gap: data.gap(&pred),
        consistency: ratio(f, n, m.n_params(), state.s),
        accepted: false,
        partial: false,
        structure,
        params: effect_named_params(m, f, effect, state.s),
        size_interval: super::size_interval(m, f, effect, state.s),
        ssr: f.ssr,
        fit_x: f.x.clone(),
        pred,
    }
}

/// The candidates (sorted by ΔBIC) that pay their way: ΔBIC and cross-validated improvement at
/// least the thresholds. Returns the best one's index and its ambiguity group (eligible
/// candidates within [`Options::ambiguity_bic`] of it, or both consistent with noise), or `None`
/// when no candidate is eligible.
fn best_and_group(
    cands: &[Candidate],
    state: &State,
    data: &Data,
    (opts, th): (&Options, &Thresholds),
) -> Option<(usize, Vec<usize>)> {
    let eligible: Vec<usize> = (0..cands.len()).filter(|&i| pays_its_way(&cands[i], th)).collect();
    // R of a refit with one more effect, against its own noise limit.
    let consistent = |c: &Candidate| {
        let p = state.model.n_params() + c.effect.fit_params().len();
        c.consistency < super::consistency_limit(data.len(), p, state.noise_dof, opts.signature_alpha)
    };
    let &best = eligible.first()?;
    let group: Vec<usize> = eligible
        .iter()
        .copied()
        .filter(|&i| {
            cands[best].delta_bic - cands[i].delta_bic < opts.ambiguity_bic
                || (consistent(&cands[best]) && consistent(&cands[i]))
        })
        .collect();
    Some((best, group))
}

/// Whether a candidate pays its way: ΔBIC and cross-validated gain at least their thresholds.
fn pays_its_way(c: &Candidate, th: &Thresholds) -> bool {
    c.delta_bic >= th.min_delta_bic(c.effect.fit_params().len()) && c.cv_improvement >= th.cv_improvement
}

/// Adds the accepted `effect` to the model, refits from its candidate fit `x`, re-tests the
/// earlier effects (each removal pushed to `removed`), and re-estimates the noise. Returns the
/// new state.
#[allow(clippy::too_many_arguments)]
fn accept_effect(
    state: &State,
    effect: Effect,
    x: Vec<f64>,
    round: usize,
    data: &Data,
    th: &Thresholds,
    removed: &mut Vec<Removed>,
    refits: &mut Refits,
) -> State {
    let mut model = state.model.clone();
    model.effects.push(effect);
    let (model, fit) =
        fit_anchored(&model, data, &all_rows(data), &[x], REFIT_ITERATIONS, MAX_ANCHORS, false);
    let (model, fit, dropped) = retest_earlier(model, fit, effect, (state.s, round), data, th, refits);
    removed.extend(dropped);
    let (s, m) = refresh_noise(data, &fit, (state.s, state.noise_dof));
    let r = ratio(&fit, data.len(), model.n_params(), s);
    State { model, fit, s, noise_dof: m, ratio: r }
}

/// Re-tests the effects accepted before `newest`: drops each and refits, and removes it if it no
/// longer pays its way, until none is removed. Returns the model, its fit and the removals.
fn retest_earlier(
    mut model: Model,
    mut fit: Fit,
    newest: Effect,
    (s, round): (f64, usize),
    data: &Data,
    th: &Thresholds,
    refits: &mut Refits,
) -> (Model, Fit, Vec<Removed>) {
    let mut removed = Vec::new();
    let n = data.len();
    let mut changed = true;
    while changed {
        changed = false;
        for e in model.effects.clone() {
            if e == newest {
                continue;
            }
            let (reduced, f) = refits.without(&model, &fit, &[e], data);
            let kept = delta_bic(f.ssr, fit.ssr, s, e.fit_params().len(), n);
            if kept < th.min_delta_bic(e.fit_params().len()) {
                removed.push(Removed { name: e.to_string(), round, delta_bic_kept: kept });
                model = reduced;
                fit = f;
                changed = true;
                break;
            }
        }
    }
    (model, fit, removed)
}

/// The signature test of every accepted effect in the final joint fit (all accepted effects
/// together, so structure one of them leaves cannot be blamed on another). Returns one test per
/// effect of the model, in model order; `named` when its signature conditions are consistent
/// with noise.
pub(super) fn signature_tests(state: &State, data: &Data, opts: &Options) -> Vec<SignatureTest> {
    state
        .model
        .effects
        .iter()
        .map(|e| {
            let structure = axis_structure(
                data,
                &state.fit.resid,
                (state.s, state.noise_dof),
                opts.signature_alpha,
                e.signature(),
            );
            SignatureTest { effect: e.to_string(), named: clears_signature(&structure), structure }
        })
        .collect()
}

/// An accepted effect stays in the model when it removes at least this share of the excess over
/// noise that the final model without it leaves: "most of the excess". A hidden effect removes
/// nearly all of what it causes (0.95–1.00 on the 1 and 5 kg carriages' recovery sets,
/// docs/model-gap.md); one that only soaks up part of another cause (the base model's own
/// error) removes a minority of it, since that cause's structure is not its shape (0.00–0.02
/// measured).
pub const MIN_SHARE_OF_EXCESS: f64 = 0.5;

/// The verdict on each accepted effect, from the final joint fit: its share of the excess over
/// noise (a refit without it) and its signature test. Effects below [`MIN_SHARE_OF_EXCESS`] are
/// partial candidates: they leave the model, which is refitted with the others (and its noise
/// re-estimated) into `selection.state`, and their candidates are marked partial. Returns the
/// verdicts (in model order) and the partial candidates, each with what it explains of the
/// kept model's excess and the structure it leaves.
pub(super) fn decide_tiers(
    selection: &mut Selection,
    tests: &[SignatureTest],
    base_ssr: f64,
    data: &Data,
    opts: &Options,
) -> (Vec<Verdict>, Vec<PartialCandidate>) {
    let (state, refits, candidates) = (&selection.state, &mut selection.refits, &selection.candidates);
    let n = data.len();
    let s = state.s;
    let excess_of = |ssr: f64, p: usize| ssr / (s * s) - n.saturating_sub(p) as f64;
    let excess = |f: &Fit, p: usize| excess_of(f.ssr, p);
    let full_excess = excess(&state.fit, state.model.n_params()).max(0.0);
    // The base model's excess from its best fit found: the calibration's, or, with one effect
    // accepted, the refit without it (the same effect-free model, started from the joint fit's
    // values). On the 0.3 kg carriage with a hidden Stribeck rise that refit took μ to 2.1× and
    // ended at 5 % of the calibration's sum of squares; measured against the calibration, the
    // rise's share of the base's excess looked like 5 %.
    let base_ssr = match state.model.effects.as_slice() {
        [only] => base_ssr.min(refits.without(&state.model, &state.fit, &[*only], data).1.ssr),
        _ => base_ssr,
    };
    let base_excess = base_ssr / (s * s) - n.saturating_sub(BASE_PARAMS) as f64;
    let verdicts: Vec<Verdict> = state
        .model
        .effects
        .iter()
        .zip(tests)
        .map(|(&e, t)| {
            let (wm, wf) = refits.without(&state.model, &state.fit, &[e], data);
            let excess_without = excess(&wf, wm.n_params());
            let share =
                if excess_without > 0.0 { (1.0 - full_excess / excess_without).clamp(0.0, 1.0) } else { 0.0 };
            let mut above: Vec<&AxisStructure> =
                t.structure.iter().filter(|a| !a.consistent_with_noise).collect();
            above.sort_by(|a, b| b.chi2_per_dof.total_cmp(&a.chi2_per_dof));
            // Structure left along its own conditions: named only as the main cause, most of
            // the base model's excess (a second effect fitted to what the first leaves, e.g. a
            // board's few curves, shares much of a small remainder and is not a cause). Most of
            // it with the other effects (the refit without it) or on its own (its first round's
            // fit, the base and it alone): a cause that later rounds joined with effects that
            // mimic part of it is still the cause. On 0.3 kg with a hidden Stribeck rise, a path
            // that accepted the rise, then a preload drop and a stator resonance, measured the
            // rise at 0.06 of the calibration's excess with the two (their refit without it
            // found better base values) and 1.00 on its own; it was left a partial candidate
            // and the gap stayed at 39 % of before (bit-level changes of the model chose that
            // path or the one that named it).
            let of_base = |removed: f64| {
                if base_excess > 0.0 {
                    (removed / base_excess).clamp(0.0, 1.0)
                } else {
                    0.0
                }
            };
            let with_others = of_base(excess_without - full_excess);
            let alone = candidates
                .iter()
                .find(|c| c.round == 1 && c.effect == e)
                .map_or(0.0, |c| of_base(base_excess - excess_of(c.ssr, BASE_PARAMS + e.fit_params().len())));
            let tier = tier_of(share, t.named, with_others, alone);
            Verdict {
                effect: e.to_string(),
                tier,
                share_of_excess: share,
                structure_left_along: above.iter().map(|a| a.condition).collect(),
            }
        })
        .collect();
    let failing: Vec<Effect> = state
        .model
        .effects
        .iter()
        .zip(&verdicts)
        .filter(|(_, v)| v.tier == Tier::Partial)
        .map(|(e, _)| *e)
        .collect();
    if failing.is_empty() {
        return (verdicts, Vec::new());
    }
    let (named, fit) = refits.without(&state.model, &state.fit, &failing, data);
    let (s, m) = refresh_noise(data, &fit, (state.s, state.noise_dof));
    let r = ratio(&fit, n, named.n_params(), s);
    let without = Without { full: state, named: &named, fit: &fit, s, ratio: r };
    let mut partial_candidates = Vec::new();
    for &e in &failing {
        let mut round = 0;
        for c in selection.candidates.iter_mut().filter(|c| c.accepted && c.effect == e) {
            c.accepted = false;
            c.partial = true;
            round = c.round;
        }
        partial_candidates.push(partial_candidate(e, round, &without, data, opts));
    }
    selection.state = State { model: named, fit, s, noise_dof: m, ratio: r };
    (verdicts, partial_candidates)
}

/// An accepted effect's tier from its share of the final model's excess, its signature test,
/// and the shares of the calibrated base model's excess it removes with the other effects and on
/// its own ([`decide_tiers`]).
fn tier_of(share: f64, signature_named: bool, of_base_with_others: f64, of_base_alone: f64) -> Tier {
    if share < MIN_SHARE_OF_EXCESS {
        Tier::Partial
    } else if signature_named {
        Tier::Named
    } else if of_base_with_others.max(of_base_alone) >= MIN_SHARE_OF_EXCESS {
        Tier::NamedWithStructureLeft
    } else {
        Tier::Partial
    }
}

/// The refit without the failing effects, against which a partial candidate is measured.
struct Without<'a> {
    /// The final joint fit (all accepted effects): its noise decided the signature test.
    full: &'a State,
    named: &'a Model,
    fit: &'a Fit,
    /// Noise scale re-estimated from `fit`, and its consistency ratio.
    s: f64,
    ratio: f64,
}

/// Refits the named model plus the failing effect `e` (accepted in `round`). Returns its partial
/// candidate: share of the excess over noise it removes, consistency and gap with it, and the
/// conditions whose structure stays above the noise the signature test used.
fn partial_candidate(e: Effect, round: usize, w: &Without, data: &Data, opts: &Options) -> PartialCandidate {
    let all = all_rows(data);
    let n = data.len();
    let s = w.s;
    // The noise the signature test used: what a partial candidate shows of its structure is
    // measured against it, so the report says why it was not named.
    let decision_s = (w.full.s, w.full.noise_dof);
    let excess = |f: &Fit, p: usize| f.ssr / (s * s) - n.saturating_sub(p) as f64;
    let excess_without = excess(w.fit, w.named.n_params());
    let mut with = w.named.clone();
    with.effects.push(e);
    let mut starts = vec![sub_x(&w.full.model, &w.full.fit.x, &with)];
    starts.extend(candidate_starts(&w.fit.x, e, data));
    let (with, f) = fit_anchored(&with, data, &all, &starts, EFFECT_ITERATIONS, MAX_ANCHORS, false);
    let structure = axis_structure(data, &f.resid, decision_s, opts.signature_alpha, e.signature());
    let mut above: Vec<&AxisStructure> = structure.iter().filter(|a| !a.consistent_with_noise).collect();
    above.sort_by(|a, b| b.chi2_per_dof.total_cmp(&a.chi2_per_dof));
    let pred = with.predict(&f.x, data, &all);
    PartialCandidate {
        effect: e.to_string(),
        round,
        share_of_excess: if excess_without > 0.0 {
            (1.0 - excess(&f, with.n_params()) / excess_without).clamp(0.0, 1.0)
        } else {
            0.0
        },
        consistency_without: w.ratio,
        consistency_with: ratio(&f, n, with.n_params(), s),
        gap_with: data.gap(&pred),
        unexplained_signature: above.iter().filter(|a| a.signature).map(|a| a.condition).collect(),
        unexplained_along: above.iter().map(|a| a.condition).collect(),
        params: effect_named_params(&with, &f, e, s),
        structure,
    }
}

/// The naming decision: every accepted effect's signature test and the partial candidates.
pub(super) struct Naming {
    pub signature_tests: Vec<SignatureTest>,
    pub verdicts: Vec<Verdict>,
    pub partial_candidates: Vec<PartialCandidate>,
}

/// Builds the report from the stages' results: gaps and predictions before and after, the fitted
/// parameter file with the named effects' uncertainties, residual structure before and after per
/// condition, and the time since `t0`.
pub(super) fn build_report(
    data: &Data,
    (opts, mut thresholds): (&Options, Thresholds),
    before: Before,
    selection: Selection,
    naming: Naming,
    not_identifiable: Vec<String>,
    t0: std::time::Instant,
) -> GapReport {
    let state = selection.state;
    let all = all_rows(data);
    let pred_after = state.model.predict(&state.fit.x, data, &all);
    let gap_after = data.gap(&pred_after);
    let (fitted, final_effects) = final_effects(&state);
    let mean_mm_s = data.mean_speed() * 1e3;
    let residual_structure = residual_structure(before.structure, structure(data, &state.fit.resid, state.s));
    let (within_noise, limit_after, unexplained_structure) = state.within_noise(data, opts);
    thresholds.consistency_ratio_after = limit_after;
    let nothing_named = state.model.effects.is_empty();
    let nothing_missing = nothing_named && naming.partial_candidates.is_empty() && within_noise;
    let outcome = if nothing_missing {
        Outcome::NothingMissing
    } else if !nothing_named {
        Outcome::Named
    } else if !unexplained_structure.is_empty() {
        Outcome::StructureUnexplained
    } else {
        Outcome::ExcessUnexplained
    };
    // What the last round tested and did not add, where its likelihood ratio says it explains
    // part of what is left: a candidate the data cannot yet size or tell from the base model's
    // own error, reported with the interval they allow.
    let last_round = selection.candidates.iter().map(|c| c.round).max().unwrap_or(0);
    let unsized_candidates: Vec<Candidate> = if within_noise {
        Vec::new()
    } else {
        selection
            .candidates
            .iter()
            .filter(|c| {
                c.round == last_round
                    && !c.accepted
                    && !c.partial
                    && c.delta_bic >= thresholds.min_delta_bic(c.effect.fit_params().len())
            })
            .cloned()
            .collect()
    };
    GapReport {
        rows: data.len(),
        gap_before: before.gap,
        gap_after,
        named_effects: state.model.effects.iter().map(|e| e.to_string()).collect(),
        named_with_structure_left: naming
            .verdicts
            .iter()
            .filter(|v| v.tier == Tier::NamedWithStructureLeft)
            .map(|v| v.effect.clone())
            .collect(),
        verdicts: naming.verdicts,
        nothing_missing,
        outcome,
        unexplained_structure,
        unsized_candidates,
        thresholds,
        partial_candidates: naming.partial_candidates,
        signature_tests: naming.signature_tests,
        signature_alpha: opts.signature_alpha,
        final_effects,
        candidates: selection.candidates,
        ambiguity: selection.ambiguity,
        residual_structure,
        removed: selection.removed,
        not_identifiable,
        noise_mm_s: before.s * (1.0 + fit::WEIGHT_FLOOR_OF_MEAN) * mean_mm_s,
        consistency_before: before.ratio,
        consistency_after: state.ratio,
        base_calibration: before.calibration,
        final_calibration: base_calibration(&state.model, &state.fit, state.s),
        elapsed_s: t0.elapsed().as_secs_f64(),
        pred_before_mm_s: before.pred.iter().map(|v| v * 1e3).collect(),
        pred_after_mm_s: pred_after.iter().map(|v| v * 1e3).collect(),
        fitted_params: Some(fitted),
    }
}

/// The final model's parameters as a parameter file, with each named effect's one-sigma
/// uncertainties recorded in it. Returns the file and the named effects with their parameters.
fn final_effects(state: &State) -> (Params, Vec<FinalEffect>) {
    let mut fitted = state.model.params_at(&state.fit.x);
    let mut final_effects = Vec::new();
    for e in &state.model.effects {
        let params = effect_named_params(&state.model, &state.fit, *e, state.s);
        for np in &params {
            fitted.effects.std_dev.insert(np.name.clone(), np.std_dev);
        }
        final_effects.push(FinalEffect { name: e.to_string(), params });
    }
    (fitted, final_effects)
}

/// Pairs the χ² per condition of the base fit and of the final fit. Returns them per degree of
/// freedom, one entry per condition.
fn residual_structure(before: Vec<(Axis, usize, f64)>, after: Vec<(Axis, usize, f64)>) -> Vec<Structure> {
    before
        .into_iter()
        .zip(after)
        .map(|((axis, levels, before), (_, _, after))| Structure {
            condition: axis.label().to_string(),
            levels,
            chi2_per_dof_before: before / dof(levels) as f64,
            chi2_per_dof_after: after / dof(levels) as f64,
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_cause_joined_by_effects_that_mimic_it_is_still_named() {
        // The figures of the 0.3 kg carriage's hidden Stribeck rise on the path that accepted the
        // rise, a preload drop and a stator resonance: the rise 0.997 of the final excess, 0.06
        // of the calibration's with the other two and 1.00 on its own; the two 0.31 and 0.47.
        assert_eq!(tier_of(0.997, false, 0.06, 1.00), Tier::NamedWithStructureLeft);
        assert_eq!(tier_of(0.31, false, 0.0, 0.11), Tier::Partial);
        assert_eq!(tier_of(0.47, false, 0.0, 0.01), Tier::Partial);
    }

    #[test]
    fn a_second_effect_fitted_to_a_remainder_is_not_named_with_structure_left() {
        // Most of the final excess but little of the base's, with the others or alone: partial.
        assert_eq!(tier_of(0.9, false, 0.1, 0.2), Tier::Partial);
        // Its signature test passed: named whatever the base's share.
        assert_eq!(tier_of(0.9, true, 0.1, 0.2), Tier::Named);
        // Under half of the final excess: partial whatever else.
        assert_eq!(tier_of(0.4, true, 1.0, 1.0), Tier::Partial);
    }
}
