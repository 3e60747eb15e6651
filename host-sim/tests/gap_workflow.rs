//! The model-gap workflow with effects hidden in plant-generated data: the base parameters given
//! to the workflow are off by ±10 % (it must recalibrate), the noise is 1 %. Expectations are the
//! hidden values, not what the code printed before.
//!
//! The fast suite (`cargo test`) runs one recovery per kind (a named effect, the carriage's
//! inertia, the negative controls, an effect named beside a partial one); the other recoveries
//! are `#[ignore]`d as heavy (60 s on 2 cores) and `.ci/run` runs them with `-- --ignored`.

use host_sim::gap::measure::{plant_speeds_mm_s, synthesize, with_noise, Grid};
use host_sim::gap::measured_csv::MeasuredRow;
use host_sim::gap::{analyze, GapReport, Options, Tier};
use host_sim::motor::effects::{Condition, EffectModel};
use host_sim::motor::params::Params;

/// The base file the workflow is given: μ +10 %, λ −10 %, ρ +10 % against the truth.
fn perturbed(truth: &Params) -> Params {
    let mut p = truth.clone();
    p.effects = Default::default();
    p.friction.mu_dynamic *= 1.1;
    p.friction.mu_static *= 1.1;
    p.stator.tangential_scale *= 0.9;
    p.stator.normal_force_ratio *= 1.1;
    p
}

fn run(truth: &Params, grid: &Grid, noise_pct: f64, seed: u64) -> GapReport {
    let rows = synthesize(truth, grid, noise_pct, seed, &|| {});
    let r = analyze(&perturbed(truth), &rows, &Options::default(), &|_, _, _| {}).expect("workflow runs");
    signature_line(&r);
    r
}

/// One line per run: what is named, what is partial, and the final residual structure along each
/// condition (χ²/dof against the noise) next to the signature test's limit.
fn signature_line(r: &GapReport) {
    let after: Vec<String> = r
        .residual_structure
        .iter()
        .map(|c| format!("{} {:.1}->{:.1}", c.condition, c.chi2_per_dof_before, c.chi2_per_dof_after))
        .collect();
    let partial: Vec<String> = r
        .partial_candidates
        .iter()
        .map(|p| {
            format!(
                "{} (share {:.2}, R {:.2}->{:.2}, gap {:.4}->{:.4}, above noise along {:?}: {})",
                p.effect,
                p.share_of_excess,
                p.consistency_without,
                p.consistency_with,
                r.gap_after,
                p.gap_with,
                p.unexplained_along,
                p.structure
                    .iter()
                    .map(|a| format!("{} {:.1}/{:.1}", a.condition, a.chi2_per_dof, a.noise_limit_per_dof))
                    .collect::<Vec<_>>()
                    .join(", ")
            )
        })
        .collect();
    let tests: Vec<String> = r
        .signature_tests
        .iter()
        .map(|t| {
            let s: Vec<String> = t
                .structure
                .iter()
                .map(|a| {
                    format!(
                        "{}{} {:.2}/{:.2}",
                        if a.signature { "*" } else { "" },
                        a.condition,
                        a.chi2_per_dof,
                        a.noise_limit_per_dof
                    )
                })
                .collect();
            format!("{} named {}: {}", t.effect, t.named, s.join(", "))
        })
        .collect();
    let sig: Vec<String> = r
        .candidates
        .iter()
        .filter(|c| c.accepted || c.partial)
        .map(|c| {
            let s: Vec<String> = c
                .structure
                .iter()
                .filter(|a| a.signature)
                .map(|a| format!("{} {:.2}/{:.2}", a.condition, a.chi2_per_dof, a.noise_limit_per_dof))
                .collect();
            format!("{} round {}: {}", c.name, c.round, s.join(", "))
        })
        .collect();
    eprintln!(
        "SIGNATURE named {:?} partial {:?}; R {:.2}->{:.2}; structure {}; candidate refits [{}]; joint fit [{}]",
        r.named_effects,
        partial,
        r.consistency_before,
        r.consistency_after,
        after.join(", "),
        sig.join("; "),
        tests.join("; ")
    );
}

fn fitted(r: &GapReport, effect: &str, param: &str) -> f64 {
    let c = r
        .candidates
        .iter()
        .find(|c| c.accepted && c.name == effect)
        .unwrap_or_else(|| panic!("{effect} not accepted: {:?}", r.named_effects));
    c.params.iter().find(|p| p.name == param).unwrap_or_else(|| panic!("{param} missing")).value
}

/// Hidden effect → named first, parameter(s) within 20 %, gap down to at most 40 %.
fn recovers(name: &str, hidden: &[(&str, f64)], base: Params) -> GapReport {
    let mut truth = base;
    for (k, v) in hidden {
        truth.effects.set(k, *v).expect("known parameter");
    }
    let r = run(&truth, &Grid::paper(), 1.0, 11);
    let rank = r.candidates.iter().find(|c| c.round == 1 && c.name == name).map_or(0, |c| c.score_rank);
    let mut line = format!("RECOVERY {name}:");
    for (k, v) in hidden {
        let got = if r.named_effects.first().map(String::as_str) == Some(name) {
            fitted(&r, name, k)
        } else {
            f64::NAN
        };
        line += &format!(" {k} hidden {v} fitted {got:.4};");
    }
    let share = r.verdicts.iter().find(|v| v.effect == name).map_or(f64::NAN, |v| v.share_of_excess);
    eprintln!(
        "{line} gap_before {:.4} gap_after {:.4} score rank {rank} named {:?} share {share:.3} ({:.1} s)",
        r.gap_before, r.gap_after, r.named_effects, r.elapsed_s
    );
    assert_eq!(r.named_effects.first().map(String::as_str), Some(name), "named {:?}", r.named_effects);
    for (k, v) in hidden {
        let got = fitted(&r, name, k);
        assert!((got - v).abs() <= 0.2 * v.abs(), "{name}.{k}: hidden {v}, fitted {got}");
    }
    assert!(
        r.gap_after <= 0.4 * r.gap_before,
        "{name}: gap {:.4} -> {:.4} is not down to 40 %",
        r.gap_before,
        r.gap_after
    );
    r
}

/// The condition along which the calibrated base model's residuals are most structured.
fn most_structured(r: &GapReport) -> &str {
    let s = r
        .residual_structure
        .iter()
        .max_by(|a, b| a.chi2_per_dof_before.total_cmp(&b.chi2_per_dof_before))
        .expect("five conditions");
    &s.condition
}

#[test]
#[ignore = "heavy recovery: `.ci/run` runs it (`-- --ignored`)"]
fn rail_friction_is_named_and_recovered() {
    let _ = recovers("rail_friction", &[("rail_coulomb_n", 0.5)], Params::heavy_slider());
}

#[test]
#[ignore = "heavy recovery: `.ci/run` runs it (`-- --ignored`)"]
fn assembly_asymmetry_is_named_and_recovered() {
    let r = recovers("assembly_asymmetry", &[("asymmetry_fraction", 0.1)], Params::heavy_slider());
    // Only the drive sense tells the two strokes apart: that is where the residuals show it.
    assert_eq!(most_structured(&r), "direction");
}

#[test]
#[ignore = "heavy recovery: `.ci/run` runs it (`-- --ignored`)"]
fn preload_dependent_friction_is_named_and_recovered() {
    let _ = recovers(
        "preload_dependent_friction",
        &[("mu_drop_per_n", 0.05), ("knee_preload_n", 10.0)],
        Params::heavy_slider(),
    );
}

#[test]
fn stribeck_friction_is_named_and_recovered() {
    let _ = recovers("stribeck_friction", &[("stribeck_rise", 1.5)], Params::heavy_slider());
}

#[test]
#[ignore = "heavy recovery: `.ci/run` runs it (`-- --ignored`)"]
fn amplifier_rolloff_is_named_and_recovered() {
    let r = recovers("amplifier_rolloff", &[("rolloff_corner_hz", 2500.0)], Params::heavy_slider());
    assert_eq!(most_structured(&r), "frequency");
}

#[test]
#[ignore = "heavy recovery: `.ci/run` runs it (`-- --ignored`)"]
fn stator_resonance_is_named_and_recovered() {
    let r = recovers("stator_resonance", &[("resonance_strength", 0.3)], Params::heavy_slider());
    assert_eq!(most_structured(&r), "frequency");
}

/// With the ceramic contact (kc = 2e9 ≫ k1 = 2.7e7 N/m) the contact force amplitude hardly
/// depends on kc (eq. 7), so a Hertzian kc(F0) leaves no trace in speeds (see the next test).
/// On a compliant friction layer (kc = 2e7 N/m, comparable to k1) it does, and must be found.
#[test]
#[ignore = "heavy recovery: `.ci/run` runs it (`-- --ignored`)"]
fn hertz_contact_is_named_and_recovered_on_a_compliant_contact() {
    let mut soft = Params::heavy_slider();
    soft.contact.stiffness_n_per_m = 2e7;
    let _ = recovers("hertz_contact", &[("hertz_exponent", 1.0 / 3.0)], soft);
}

/// A lighter carriage on the heavy-slider stator: the data come from the plant with a 3 kg
/// carriage (`slider.mass_kg`, no effect section) instead of 50 kg; the workflow gets the
/// heavy-slider file, whose base model is the constant-speed model. It must name
/// `slider_inertia` and recover the mass.
///
/// 3 kg: at 900 Hz it runs 5 % (no load) to over 100 % (near stall, where it goes backwards)
/// slower than the constant-speed model, the gap is ≈ 9 % against 1 % noise, and the inertial
/// model still follows the plant: 1.6 % rms on 90 of the grid's rows at the true parameters,
/// weighted as the fit weighs them, against 1.1 % for the 50 kg plant and the constant-speed
/// model (mostly a calibration offset). Lighter carriages lose far more (0.5–1 kg go backwards
/// near stall at 900 Hz), but there the model's own error against the plant reaches 6–8 % at
/// some points (tests/steady_inertia.rs finds it worse still on the paper's stator) and leaves
/// frequency structure above the noise: at 2 kg the effect is only a partial candidate. Measured
/// over seeds 13–16: 3.13–3.15 kg with a reported σ of 0.35 %; the +5 % is the model's bias
/// against the plant, not noise, so the bound is 10 %, not kσ.
#[test]
fn slider_inertia_of_a_lighter_carriage_is_named_and_its_mass_recovered() {
    const CARRIAGE_KG: f64 = 3.0;
    let mut truth = Params::heavy_slider();
    truth.slider.mass_kg = CARRIAGE_KG;
    let rows = synthesize(&truth, &Grid::paper(), 1.0, 13, &|| {});
    let r = analyze(&perturbed(&Params::heavy_slider()), &rows, &Options::default(), &|_, _, _| {})
        .expect("workflow runs");
    signature_line(&r);
    let named = r.final_effects.iter().find(|e| e.name == "slider_inertia");
    let s = named.and_then(|e| e.params.iter().find(|p| p.name == "inverse_mass_per_kg"));
    let rank =
        r.candidates.iter().find(|c| c.round == 1 && c.name == "slider_inertia").map_or(0, |c| c.score_rank);
    eprintln!(
        "RECOVERY slider_inertia: mass hidden {CARRIAGE_KG} kg fitted {:?} kg (1/M {:?} ± {:?}); gap {:.4} -> {:.4}; score rank {rank} named {:?} ({:.1} s)",
        s.map(|p| 1.0 / p.value),
        s.map(|p| p.value),
        s.map(|p| p.std_dev),
        r.gap_before,
        r.gap_after,
        r.named_effects,
        r.elapsed_s
    );
    assert_eq!(r.named_effects, ["slider_inertia"]);
    let s = s.expect("fitted");
    let mass_kg = 1.0 / s.value;
    assert!((mass_kg - CARRIAGE_KG).abs() <= 0.1 * CARRIAGE_KG, "mass {mass_kg} kg");
    assert!(r.gap_after <= 0.4 * r.gap_before, "gap {:.4} -> {:.4}", r.gap_before, r.gap_after);
}

#[test]
fn hertz_contact_on_the_ceramic_contact_is_below_noise_and_nothing_is_named() {
    let mut truth = Params::heavy_slider();
    truth.effects.set("hertz_exponent", 1.0 / 3.0).unwrap();
    let r = run(&truth, &Grid::paper(), 1.0, 12);
    assert!(r.named_effects.is_empty(), "named {:?}", r.named_effects);
}

#[test]
fn negative_control_without_hidden_effects_names_nothing() {
    for (noise, seed) in [(1.0, 21), (2.0, 22)] {
        let r = run(&Params::heavy_slider(), &Grid::paper(), noise, seed);
        eprintln!(
            "NEGATIVE noise {noise} %: gap {:.4}, residual/noise variance {:.2}, named {:?}",
            r.gap_before, r.consistency_before, r.named_effects
        );
        assert!(r.named_effects.is_empty(), "noise {noise} %: named {:?}", r.named_effects);
        assert!(r.nothing_missing);
        // The recalibration alone must bring the ±10 % base back to the noise level.
        assert!(r.gap_before < 0.03, "gap {:.4}", r.gap_before);
        assert!(r.consistency_before < 2.0, "R {:.2}", r.consistency_before);
    }
}

#[test]
#[ignore = "heavy recovery: `.ci/run` runs it (`-- --ignored`)"]
fn two_hidden_effects_are_both_named() {
    let mut truth = Params::heavy_slider();
    truth.effects.set("rail_coulomb_n", 0.5).unwrap();
    truth.effects.set("rolloff_corner_hz", 2500.0).unwrap();
    let r = run(&truth, &Grid::paper(), 1.0, 31);
    eprintln!("TWO named {:?}, gap {:.4} -> {:.4}", r.named_effects, r.gap_before, r.gap_after);
    let mut named = r.named_effects.clone();
    named.sort();
    assert_eq!(named, ["amplifier_rolloff", "rail_friction"]);
    assert!((fitted(&r, "rail_friction", "rail_coulomb_n") - 0.5).abs() < 0.1);
    assert!((fitted(&r, "amplifier_rolloff", "rolloff_corner_hz") - 2500.0).abs() < 500.0);
}

/// Near no load, at one voltage and two frequencies, a Stribeck rise and an amplifier roll-off
/// both just bend the speed between the two frequencies: the grid cannot separate them.
#[test]
#[ignore = "heavy recovery: `.ci/run` runs it (`-- --ignored`)"]
fn an_inseparable_pair_is_reported_as_one_ambiguity_group_with_the_true_effect() {
    let mut truth = Params::heavy_slider();
    truth.effects.set("stribeck_rise", 1.5).unwrap();
    let grid = Grid {
        preloads_n: vec![8.0, 11.0, 14.0],
        voltages_v: vec![100.0],
        frequencies_hz: vec![1200.0, 2000.0],
        load_fractions: vec![0.0, 0.05, 0.1, 0.15, 0.2, 0.25, 0.3],
        directions: vec![1, -1],
    };
    let r = run(&truth, &grid, 1.0, 7);
    eprintln!(
        "AMBIGUITY {:?} named {:?}",
        r.ambiguity.iter().map(|a| &a.effects).collect::<Vec<_>>(),
        r.named_effects
    );
    let group = r
        .ambiguity
        .iter()
        .find(|a| a.effects.iter().any(|e| e == "stribeck_friction"))
        .expect("an ambiguity group with the true effect");
    assert!(group.effects.iter().any(|e| e == "amplifier_rolloff"), "group {:?}", group.effects);
    let exp = group.separating_experiment.as_ref().expect("a separating experiment");
    assert!(exp.separation_sigma > 3.0, "the proposed experiment must separate them: {exp:?}");
    // On the full paper grid (several voltages, loads to near stall) the same effect is no longer
    // ambiguous.
    let full = run(&truth, &Grid::paper(), 1.0, 7);
    assert_eq!(full.named_effects.first().map(String::as_str), Some("stribeck_friction"));
    assert!(full.ambiguity.iter().all(|a| !a.effects.iter().any(|e| e == "stribeck_friction")));
}

/// An effect name the library does not know is an error naming it and the known ones, before any
/// work (it used to be fitted silently as `rail_friction`).
#[test]
fn an_unknown_effect_in_the_library_is_an_error() {
    let opts = Options { library: vec!["rail_friction", "rail_fricton"], ..Options::default() };
    // Rows the workflow would accept (eight, positive mean speed): the name is what it refuses.
    let rows: Vec<MeasuredRow> = (0..8)
        .map(|i| MeasuredRow {
            line: i + 2,
            preload_n: 16.0,
            voltage_v: 100.0,
            frequency_hz: 1500.0,
            load_n: f64::from(i as u8),
            direction: 1,
            velocity_mm_s: 40.0 - 4.0 * i as f64,
        })
        .collect();
    let e =
        analyze(&Params::heavy_slider(), &rows, &opts, &|_, _, _| {}).expect_err("unknown effect refused");
    let text = format!("{e:#}");
    assert_eq!(
        text,
        "effect library: unknown effect 'rail_fricton' (known: rail_friction, assembly_asymmetry, \
         preload_dependent_friction, stribeck_friction, amplifier_rolloff, stator_resonance, hertz_contact, \
         slider_inertia)"
    );
    // Every known name is accepted.
    assert!(host_sim::motor::effects::EFFECT_NAMES
        .iter()
        .all(|n| host_sim::motor::effects::effect_name(n).ok() == Some(*n)));
}

/// Plant data whose drive chain is not in the library: a switching amplifier's second-order LC
/// output filter (corner `f0`, quality `q`) in front of the stacks, gain
/// `1/√((1 − x²)² + (x/q)²)` with `x = f/f0`. The library knows one pole (`amplifier_rolloff`,
/// −20 dB/decade, no flat part) and a mode that raises the drive (`stator_resonance`); neither
/// makes a gain that stays flat to 1.5 kHz and then falls steeply. Loads are fractions of the
/// true (filtered) stall force, as `measure` does for library effects.
fn synthesize_behind_lc_filter(
    truth: &Params,
    grid: &Grid,
    f0_hz: f64,
    q: f64,
    seed: u64,
) -> Vec<MeasuredRow> {
    let gain = |f: f64| {
        let x = f / f0_hz;
        1.0 / ((1.0 - x * x).powi(2) + (x / q).powi(2)).sqrt()
    };
    let (mut nominal, mut driven) = (Vec::new(), Vec::new());
    for &preload_n in &grid.preloads_n {
        for &voltage_v in &grid.voltages_v {
            for &frequency_hz in &grid.frequencies_hz {
                for &direction in &grid.directions {
                    let c0 = Condition { preload_n, voltage_v, frequency_hz, load_n: 0.0, direction };
                    let d0 = Condition { voltage_v: voltage_v * gain(frequency_hz), ..c0 };
                    let m = EffectModel::new(truth, &d0);
                    let stall = (m.thrust_n(0.0) - m.rail_coulomb_n).max(0.0);
                    for &fr in &grid.load_fractions {
                        nominal.push(Condition { load_n: fr * stall, ..c0 });
                        driven.push(Condition { load_n: fr * stall, ..d0 });
                    }
                }
            }
        }
    }
    let speeds = plant_speeds_mm_s(truth, &driven, &|| {});
    with_noise(&nominal, &speeds, 1.0, seed)
}

/// A drive chain outside the library (an LC filter: flat, then steep above 2 kHz): the one-pole
/// roll-off fits its mean slope, explains most of the excess over noise and is added, but leaves
/// structure along its own condition, the frequency: named with structure left (tier 2), the gap
/// shown shrinking and the rest reported where it lies.
#[test]
#[ignore = "heavy recovery: `.ci/run` runs it (`-- --ignored`)"]
fn a_drive_chain_outside_the_library_is_named_with_structure_left() {
    let truth = Params::heavy_slider();
    let rows = synthesize_behind_lc_filter(&truth, &Grid::paper(), 2000.0, 0.8, 41);
    let r = analyze(&perturbed(&truth), &rows, &Options::default(), &|_, _, _| {}).expect("workflow runs");
    signature_line(&r);
    assert_eq!(r.named_effects, ["amplifier_rolloff"]);
    assert_eq!(r.named_with_structure_left, ["amplifier_rolloff"]);
    let v = r.verdicts.iter().find(|v| v.effect == "amplifier_rolloff").expect("a verdict");
    assert_eq!(v.tier, Tier::NamedWithStructureLeft);
    // One pole fits the mean slope over 0.9–2.1 kHz but not the flat-then-steep shape: most of
    // the excess, not all of it, and what is left lies along the frequency.
    assert!(v.share_of_excess >= 0.5 && v.share_of_excess < 0.99, "share {}", v.share_of_excess);
    assert_eq!(v.structure_left_along.first(), Some(&"frequency"), "{:?}", v.structure_left_along);
    let test = r.signature_tests.iter().find(|t| t.effect == "amplifier_rolloff").unwrap();
    assert!(!test.named, "the frequency's structure stays above noise");
    assert!(r.partial_candidates.is_empty(), "{:?}", r.partial_candidates);
    // Added, so the gap shrinks with it; the report says what is left and where.
    assert!(r.gap_after < 0.6 * r.gap_before, "{} vs {}", r.gap_after, r.gap_before);
    let md = host_sim::gap::report::markdown(&r, std::path::Path::new("lc.csv"));
    assert!(md.contains("named with structure left") && md.contains("along frequency"), "{md}");
}

/// Structure left along conditions outside an effect's signature does not demote it: with the
/// same LC filter and a hidden assembly asymmetry, the asymmetry clears its own condition (the
/// drive sense) and is named while the frequency structure stays, with the roll-off named beside
/// it with that structure left.
#[test]
fn an_effect_that_clears_its_own_signature_is_named_beside_one_with_structure_left() {
    let mut truth = Params::heavy_slider();
    truth.effects.set("asymmetry_fraction", 0.1).unwrap();
    let rows = synthesize_behind_lc_filter(&truth, &Grid::compact(), 2000.0, 0.8, 43);
    let r = analyze(&perturbed(&truth), &rows, &Options::default(), &|_, _, _| {}).expect("workflow runs");
    signature_line(&r);
    let mut named = r.named_effects.clone();
    named.sort();
    assert_eq!(named, ["amplifier_rolloff", "assembly_asymmetry"]);
    assert!((fitted(&r, "assembly_asymmetry", "asymmetry_fraction") - 0.1).abs() <= 0.02);
    let tier = |e: &str| r.verdicts.iter().find(|v| v.effect == e).map(|v| v.tier);
    assert_eq!(tier("assembly_asymmetry"), Some(Tier::Named));
    assert_eq!(tier("amplifier_rolloff"), Some(Tier::NamedWithStructureLeft));
    // The decision, in the joint fit of both accepted effects: the drive sense is consistent with
    // noise (χ² limit 10.8 for one degree of freedom at α = 0.001), the frequency is not (13.8
    // for two), and the asymmetry is named all the same.
    let test = r.signature_tests.iter().find(|t| t.effect == "assembly_asymmetry").expect("tested");
    assert!(test.named);
    let along = |c: &str| test.structure.iter().find(|a| a.condition == c).unwrap();
    assert!(
        along("direction").signature && along("direction").chi2_per_dof < 10.8,
        "{:?}",
        along("direction")
    );
    assert!(
        !along("frequency").signature && along("frequency").chi2_per_dof > 13.8 / 2.0,
        "{:?}",
        along("frequency")
    );
}
