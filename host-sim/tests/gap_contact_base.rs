//! The model-gap workflow on a real carriage (issue 29): the sourced plant's 1 kg carriage,
//! whose speeds the constant-speed model misses by 20–89 %, with the contact model as the base
//! (`[model] steady = "contact"` in the parameter file). The plant is the truth; its hidden
//! parameters are the independent expectation.
//!
//! CI runs the clean set and two hidden effects (the asymmetry on three noise draws; 3–15 s per
//! draw on 2 cores); the other effects and the 0.3 and 5 kg carriages are in
//! `cargo bench -p host-sim --bench gap_recovery`.

use host_sim::gap::measure::{synthesize, Grid};
use host_sim::gap::{analyze, GapReport, Options, Tier};
use host_sim::motor::params::{Params, SteadyModel};

/// The sourced plant's 1 kg carriage with `hidden` effects: 192 rows (compact grid), 1 % noise;
/// the workflow runs on the sourced file without them.
fn run(hidden: &[(&str, f64)], seed: u64) -> GapReport {
    let base = Params::prototype_sourced();
    assert_eq!(base.model.steady, SteadyModel::Contact, "the sourced file selects the contact model");
    let mut truth = base.clone();
    for (k, v) in hidden {
        truth.effects.set(k, *v).expect("a library parameter");
    }
    let rows = synthesize(&truth, &Grid::compact(), 1.0, seed, &|| {});
    let r = analyze(&base, &rows, &Options::default(), &|_, _, _| {}).expect("workflow runs");
    eprintln!(
        "{hidden:?}: gap {:.4} -> {:.4}, R {:.2} -> {:.2}, named {:?}, verdicts {:?}, {:.1} s",
        r.gap_before,
        r.gap_after,
        r.consistency_before,
        r.consistency_after,
        r.named_effects,
        r.verdicts.iter().map(|v| (&v.effect, v.tier, v.share_of_excess)).collect::<Vec<_>>(),
        r.elapsed_s
    );
    r
}

fn assert_named_first(r: &GapReport, effect: &str) {
    assert_eq!(r.named_effects.first().map(String::as_str), Some(effect), "{:?}", r.named_effects);
}

/// No hidden effect: nothing is named, and the calibrated contact model is within noise of the
/// plant (gap ≤ 3 % of the mean speed with 1 % noise on each speed plus a floor of a quarter of
/// the mean; the constant-speed base left 0.64 here). The calibration lands on the plant's own
/// μ, λ and ρ within 5 %.
#[test]
fn on_a_real_carriage_without_hidden_effects_nothing_is_named() {
    let r = run(&[], 3);
    assert!(r.named_effects.is_empty(), "named {:?}", r.named_effects);
    assert!(r.gap_before < 0.03, "gap {}", r.gap_before);
    let truth = Params::prototype_sourced();
    let expect = [truth.friction.mu_dynamic, truth.stator.tangential_scale, truth.stator.normal_force_ratio];
    for (b, want) in r.base_calibration.iter().zip(expect) {
        assert!((b.fitted - want).abs() <= 0.05 * want, "{}: fitted {}, plant {want}", b.name, b.fitted);
    }
}

/// A hidden assembly asymmetry (7 % between the drive senses) on the 1 kg carriage, three noise
/// draws: named first on each, its size within 20 %, the gap down to at most 40 % of before; and
/// named fully (tier 1) on at least two of the three. On the constant-speed base it was not named
/// at all (gap 0.50 -> 0.43).
///
/// Why not tier 1 on every draw: tier 1 asks the direction axis's χ² to stay under the noise's
/// 1 − 3e-4 quantile (12.9 per degree of freedom), while the contact model's own ≈ 1 % departure
/// from the plant leaves R ≈ 1.5–2.5 after the fit. On one draw that χ² sits near the limit, and
/// last-bit changes of the model move it across: seed 5 read 10.6 before the orbit search's
/// jump rule and 13.4 after; seed 7 read above the limit before and below after (tier 1 on
/// seven of eight seeds each time, not the same seven).
#[test]
fn on_a_real_carriage_a_hidden_asymmetry_is_named_and_recovered() {
    let mut fully = 0;
    for seed in 5..=7 {
        let r = run(&[("asymmetry_fraction", 0.07)], seed);
        assert_named_first(&r, "assembly_asymmetry");
        let fitted = r.final_effects[0].params[0].value;
        assert!((fitted - 0.07).abs() <= 0.2 * 0.07, "seed {seed}: asymmetry fitted {fitted}");
        assert!(r.gap_after <= 0.4 * r.gap_before, "seed {seed}: gap {} -> {}", r.gap_before, r.gap_after);
        if r.verdicts[0].tier == Tier::Named {
            fully += 1;
        }
    }
    assert!(fully >= 2, "tier 1 on {fully} of 3 draws");
}

/// A hidden Stribeck rise of 1.5 (μ up to 2.5× at zero slip) on the 1 kg carriage. Without the
/// effect the base fit takes it up as a larger μ (2.3× its file value), and fits with the effect
/// that start there stay in that valley (before: a partial candidate explaining 31 % of the
/// excess, gap 0.093 -> 0.087). From the file's base values the contact model finds the rise:
/// named first, its size within 20 %, the gap down to at most 40 % of before.
#[test]
fn on_a_real_carriage_a_hidden_stribeck_rise_is_named_and_recovered() {
    let r = run(&[("stribeck_rise", 1.5)], 7);
    assert_named_first(&r, "stribeck_friction");
    let fitted = r.final_effects[0].params[0].value;
    assert!((fitted - 1.5).abs() <= 0.2 * 1.5, "rise fitted {fitted}");
    assert!(r.gap_after <= 0.4 * r.gap_before, "gap {} -> {}", r.gap_before, r.gap_after);
}
