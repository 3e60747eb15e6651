//! Refits of a fitted model without some of its effects, each solved once per analysis: the
//! re-test of the earlier effects after an acceptance and the verdicts on the final model ask
//! for the same ones, and on a contact base each costs tens of contact-model evaluations of
//! every row (a fit is deterministic in its model, start and anchor, so the answer is the same).

use super::base::{fit_anchored, MAX_ANCHORS};
use super::fit::{Data, Fit, Model, EFFECT_ITERATIONS};
use super::{all_rows, sub_x};
use crate::motor::effects::Effect;
use std::sync::Arc;

/// The refits solved so far, by the model they were taken from and the effects kept.
#[derive(Default)]
pub(super) struct Refits {
    done: Vec<Done>,
}

struct Done {
    /// The model refitted from (held, so that its anchor's address stays its own).
    from: Model,
    from_x: Vec<u64>,
    kept: Vec<Effect>,
    result: (Model, Fit),
}

/// Whether two models are the same fit's: the same effects and the same anchor (shared, not
/// equal: an anchor is only ever shared by the models of one fit).
fn same_model(a: &Model, b: &Model) -> bool {
    a.effects == b.effects
        && match (&a.anchor, &b.anchor) {
            (None, None) => true,
            (Some(a), Some(b)) => Arc::ptr_eq(&a.delta_m_s, &b.delta_m_s) && Arc::ptr_eq(&a.x, &b.x),
            _ => false,
        }
}

impl Refits {
    /// `model` (fitted at `fit`) without the effects in `drop`, refitted from `fit`'s values of
    /// what stays: its anchors move up to [`MAX_ANCHORS`] times.
    pub(super) fn without(&mut self, model: &Model, fit: &Fit, drop: &[Effect], data: &Data) -> (Model, Fit) {
        let kept: Vec<Effect> = model.effects.iter().copied().filter(|e| !drop.contains(e)).collect();
        let from_x: Vec<u64> = fit.x.iter().map(|v| v.to_bits()).collect();
        if let Some(d) =
            self.done.iter().find(|d| d.kept == kept && d.from_x == from_x && same_model(&d.from, model))
        {
            return d.result.clone();
        }
        let mut reduced = model.clone();
        reduced.effects.clone_from(&kept);
        let start = sub_x(model, &fit.x, &reduced);
        let result =
            fit_anchored(&reduced, data, &all_rows(data), &[start], EFFECT_ITERATIONS, MAX_ANCHORS, false);
        self.done.push(Done { from: model.clone(), from_x, kept, result: result.clone() });
        result
    }
}
