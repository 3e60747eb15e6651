//! The workflow's outputs: Markdown report, SVG plots (plotters), updated parameter file.

use super::GapReport;
use crate::gap::measured_csv::MeasuredRow;
use crate::motor::params::Params;
use anyhow::{anyhow, Context, Result};
use plotters::prelude::*;
use std::fmt::Write as _;
use std::path::Path;

pub const REPORT_FILE: &str = "report.md";
pub const CURVES_SVG: &str = "curves.svg";
pub const RESIDUALS_SVG: &str = "residuals.svg";
pub const PARAMS_FILE: &str = "params-fitted.toml";

pub fn write_all(
    r: &GapReport,
    rows: &[MeasuredRow],
    base: &Params,
    measured: &Path,
    out: &Path,
) -> Result<()> {
    curves_plot(r, rows, &out.join(CURVES_SVG))?;
    residuals_plot(r, rows, &out.join(RESIDUALS_SVG))?;
    let fitted = r.fitted_params.clone().unwrap_or_else(|| base.clone());
    let mut toml = String::new();
    let _ = writeln!(toml, "# Written by `host-sim gap --measured {}`.", measured.display());
    let _ = writeln!(
        toml,
        "# Base parameters recalibrated (friction.mu_dynamic/mu_static, stator.tangential_scale, stator.normal_force_ratio);"
    );
    if r.named_effects.is_empty() && r.partial_candidates.is_empty() {
        let _ = writeln!(toml, "# no effect was missing: the base model explains the data to within noise.");
    } else if r.named_effects.is_empty() {
        let _ = writeln!(toml, "# no library effect explains the data; none added.");
    } else {
        let _ = writeln!(
            toml,
            "# effects added: {} (one-sigma uncertainties in [effects.std_dev]).",
            r.named_effects.join(", ")
        );
    }
    if !r.partial_candidates.is_empty() {
        let names: Vec<&str> = r.partial_candidates.iter().map(|p| p.effect.as_str()).collect();
        let _ = writeln!(toml, "# partial candidates, not added (see report.md): {}.", names.join(", "));
    }
    let _ = writeln!(toml, "# gap before {:.4}, after {:.4}.\n", r.gap_before, r.gap_after);
    toml.push_str(&fitted.to_toml());
    let path = out.join(PARAMS_FILE);
    std::fs::write(&path, toml).with_context(|| format!("cannot write {}", path.display()))?;
    let md = markdown(r, measured);
    let path = out.join(REPORT_FILE);
    std::fs::write(&path, md).with_context(|| format!("cannot write {}", path.display()))?;
    Ok(())
}

/// The cells of a candidate's row that the report's table and the terminal summary share (round,
/// effect, score, score rank, LR, ΔBIC, CV improvement in %, gap), each formatted once; the
/// two only pad them differently.
fn candidate_cells(c: &super::Candidate) -> [String; 8] {
    [
        c.round.to_string(),
        c.name.clone(),
        format!("{:.1}", c.score),
        c.score_rank.to_string(),
        format!("{:.1}", c.lr),
        format!("{:.1}", c.delta_bic),
        format!("{:.1}", 100.0 * c.cv_improvement),
        format!("{:.4}", c.gap),
    ]
}

fn fmt_params(c: &super::Candidate) -> String {
    c.params
        .iter()
        .map(|p| format!("{} = {:.4} ± {:.4}", p.name, p.value, p.std_dev))
        .collect::<Vec<_>>()
        .join(", ")
}

pub fn markdown(r: &GapReport, measured: &Path) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "# Model-gap report\n");
    let _ = writeln!(
        s,
        "Measured file: `{}` ({} rows). Time: {:.1} s.\n",
        measured.display(),
        r.rows,
        r.elapsed_s
    );
    let _ = writeln!(s, "| | before | after |\n|---|---|---|");
    let _ = writeln!(s, "| gap (RMS(sim − meas)/mean meas) | {:.4} | {:.4} |", r.gap_before, r.gap_after);
    let _ = writeln!(
        s,
        "| residual variance / noise variance | {:.2} | {:.2} |",
        r.consistency_before, r.consistency_after
    );
    let _ =
        writeln!(s, "\nNoise estimate (difference-based, at the mean speed): {:.4} mm/s.\n", r.noise_mm_s);
    // The named effects have their own paragraph below.
    for line in verdict_lines(r).iter().filter(|l| !l.starts_with("named effects:")) {
        let _ = writeln!(s, "{line}\n");
    }
    if !r.named_effects.is_empty() {
        let _ = writeln!(s, "**Named effects** (in the order accepted): {}\n", r.named_effects.join(", "));
        for v in r.verdicts.iter().filter(|v| v.tier == super::Tier::NamedWithStructureLeft) {
            let _ = writeln!(
                s,
                "*{}* is named with structure left: it explains {:.0} % of the excess over noise, \
                 and residual structure above noise stays along {} (something else acts there \
                 too).\n",
                v.effect,
                100.0 * v.share_of_excess,
                v.structure_left_along.join(", ")
            );
        }
        let _ = writeln!(s, "| effect | parameter | final fit | ± 1σ |\n|---|---|---|---|");
        for e in &r.final_effects {
            for p in &e.params {
                let _ = writeln!(s, "| {} | {} | {:.5} | {:.5} |", e.name, p.name, p.value, p.std_dev);
            }
        }
        let _ = writeln!(s);
    }
    partial_section(&mut s, r);
    signature_section(&mut s, r);
    let _ = writeln!(
        s,
        "## Residual structure\n\nSpread of the mean weighted residual between the levels of each condition, \
         χ² per degree of freedom in units of the noise (≈ 1: no structure).\n\n\
         | condition | levels | before | after |\n|---|---|---|---|"
    );
    for c in &r.residual_structure {
        let _ = writeln!(
            s,
            "| {} | {} | {:.1} | {:.1} |",
            c.condition, c.levels, c.chi2_per_dof_before, c.chi2_per_dof_after
        );
    }
    let _ = writeln!(s);
    let _ = writeln!(
        s,
        "## Base calibration\n\n| parameter | file | fitted (base) | fitted (final) |\n|---|---|---|---|"
    );
    for (b, f) in r.base_calibration.iter().zip(&r.final_calibration) {
        let _ = writeln!(
            s,
            "| {} | {:.4} | {:.4} ± {:.4} | {:.4} ± {:.4} |",
            b.name, b.file_value, b.fitted, b.std_dev, f.fitted, f.std_dev
        );
    }
    let _ = writeln!(
        s,
        "\n## Candidates\n\nScore: Rao score χ² of each effect at zero strength after projecting out the \
         current parameters; LR and ΔBIC from the refit; CV: relative improvement of the held-out RMS \
         (5 folds of operating curves); R: residual/noise variance of the refit.\n"
    );
    let _ = writeln!(
        s,
        "| round | effect | score | score rank | LR | ΔBIC | CV impr. | gap | R | accepted | parameters |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|---|---|---|---|");
    for c in &r.candidates {
        let [round, name, score, rank, lr, delta_bic, cv, gap] = candidate_cells(c);
        let _ = writeln!(
            s,
            "| {round} | {name} | {score} | {rank} | {lr} | {delta_bic} | {cv} % | {gap} | {:.2} | {} | {} |",
            c.consistency,
            if c.accepted {
                "**yes**"
            } else if c.partial {
                "partial"
            } else {
                "no"
            },
            fmt_params(c)
        );
    }
    if !r.not_identifiable.is_empty() {
        let _ = writeln!(
            s,
            "\nNot tried: {}. The data hold one level of every condition their laws act on (their \
             signatures), where the recalibrated base parameters would absorb them; measure at more \
             than one level of those conditions to test them.",
            r.not_identifiable.join(", ")
        );
    }
    if !r.removed.is_empty() {
        let _ = writeln!(s, "\nRemoved on re-test:");
        for m in &r.removed {
            let _ =
                writeln!(s, "- {} (round {}, ΔBIC of keeping it {:.1})", m.name, m.round, m.delta_bic_kept);
        }
    }
    let _ = writeln!(s, "\n## Ambiguity\n");
    if r.ambiguity.is_empty() {
        let _ = writeln!(s, "None: every accepted effect beat the others by more than the ambiguity margin.");
    }
    for a in &r.ambiguity {
        let _ = writeln!(
            s,
            "- round {}: {{{}}} cannot be told apart by these data.",
            a.round,
            a.effects.join(", ")
        );
        if let Some(e) = &a.separating_experiment {
            let _ = writeln!(
                s,
                "  Separating experiment: preload {:.1} N, {:.0} V, {:.0} Hz, load {:.3} N, direction {:+}: \
                 predicted {} mm/s ({:.1} σ apart).",
                e.preload_n,
                e.voltage_v,
                e.frequency_hz,
                e.load_n,
                e.direction,
                e.predicted_mm_s.iter().map(|v| format!("{v:.4}")).collect::<Vec<_>>().join(" vs "),
                e.separation_sigma
            );
        }
    }
    let _ = writeln!(s, "\n## Plots\n\n![measured vs simulated]({CURVES_SVG})\n\n![residuals by condition]({RESIDUALS_SVG})\n");
    let _ = writeln!(s, "Updated parameter file: `{PARAMS_FILE}`.");
    s
}

fn fmt_structure(a: &super::AxisStructure) -> String {
    format!("{} {:.1} (noise ≤ {:.1})", a.condition, a.chi2_per_dof, a.noise_limit_per_dof)
}

/// Partial candidates: what share of the excess each explains, and where the rest lies.
fn partial_section(s: &mut String, r: &GapReport) {
    if r.partial_candidates.is_empty() {
        return;
    }
    let _ = writeln!(
        s,
        "## Partial candidates\n\nAccepted by ΔBIC and cross-validation, but their fit leaves structure \
         above noise along the conditions their own law acts on: they explain part of the gap, not \
         all of it, and are not added to the fitted model. Share: the part of the excess over noise \
         (SSR/s² − (n − p)) of the model with the named effects that adding the candidate removes.\n"
    );
    let _ = writeln!(
        s,
        "| effect | round | share of the excess | R without → with | gap with | still above noise along its conditions | also above noise | parameters |\n|---|---|---|---|---|---|---|---|"
    );
    for p in &r.partial_candidates {
        let sig: Vec<String> = p
            .structure
            .iter()
            .filter(|a| a.signature && !a.consistent_with_noise)
            .map(fmt_structure)
            .collect();
        let other: Vec<String> = p
            .structure
            .iter()
            .filter(|a| !a.signature && !a.consistent_with_noise)
            .map(fmt_structure)
            .collect();
        let params: Vec<String> =
            p.params.iter().map(|q| format!("{} = {:.4} ± {:.4}", q.name, q.value, q.std_dev)).collect();
        let _ = writeln!(
            s,
            "| {} | {} | {:.0} % | {:.2} → {:.2} | {:.4} | {} | {} | {} |",
            p.effect,
            p.round,
            100.0 * p.share_of_excess,
            p.consistency_without,
            p.consistency_with,
            p.gap_with,
            sig.join(", "),
            if other.is_empty() { "—".to_string() } else { other.join(", ") },
            params.join(", ")
        );
    }
    let _ = writeln!(s);
}

/// The naming decision of each accepted effect, in the final joint fit.
fn signature_section(s: &mut String, r: &GapReport) {
    if r.signature_tests.is_empty() {
        return;
    }
    let _ = writeln!(
        s,
        "## Signature test\n\nAn accepted effect is named only when, in the final fit of all accepted \
         effects together, the residual structure (χ²/dof of the level means in noise units) along \
         each condition its law acts on stays below the quantile that noise exceeds with \
         probability {} % for that condition's levels − 1 degrees of freedom (F against the number \
         of pseudo-residuals behind the noise estimate: χ² when they are many); structure along other \
         conditions does not count against it.\n\n| effect | its conditions (χ²/dof, limit) | decision |\n|---|---|---|",
        100.0 * r.signature_alpha
    );
    for t in &r.signature_tests {
        let sig: Vec<String> = t.structure.iter().filter(|a| a.signature).map(fmt_structure).collect();
        let _ = writeln!(
            s,
            "| {} | {} | {} |",
            t.effect,
            sig.join(", "),
            if t.named { "named" } else { "partial" }
        );
    }
    let _ = writeln!(s);
}

/// The verdict in words: nothing missing (and why that may be said), the named effects, or the
/// structure or excess left that no library effect explains, with the candidates the data cannot
/// size and the intervals they allow; then the thresholds and what they follow from.
pub fn verdict_lines(r: &GapReport) -> Vec<String> {
    let t = &r.thresholds;
    let mut out = Vec::new();
    match r.outcome {
        super::Outcome::NothingMissing => out.push(format!(
            "nothing missing: R {:.2} is below its noise limit {:.2}, and the residual structure along \
             every condition is within noise",
            r.consistency_after, t.consistency_ratio_after
        )),
        super::Outcome::Named => out.push(format!("named effects: {}", r.named_effects.join(", "))),
        super::Outcome::StructureUnexplained => {
            for a in &r.unexplained_structure {
                out.push(format!(
                    "structure along {} that no library effect explains at this noise: χ²/dof {:.1} \
                     against the noise's {:.1} ({} levels; R {:.2}, its limit {:.2})",
                    a.condition,
                    a.chi2_per_dof,
                    a.noise_limit_per_dof,
                    a.levels,
                    r.consistency_after,
                    t.consistency_ratio_after
                ));
            }
        }
        super::Outcome::ExcessUnexplained => out.push(format!(
            "no library effect explains the data: residual variance {:.2}× the noise's (limit {:.2}){}",
            r.consistency_after,
            t.consistency_ratio_after,
            if r.partial_candidates.is_empty() { "" } else { "; see the partial candidates" }
        )),
    }
    if r.outcome == super::Outcome::Named {
        for a in &r.unexplained_structure {
            out.push(format!(
                "structure left along {}: χ²/dof {:.1} against the noise's {:.1}",
                a.condition, a.chi2_per_dof, a.noise_limit_per_dof
            ));
        }
    }
    for c in &r.unsized_candidates {
        let sizes: Vec<String> = c
            .size_interval
            .iter()
            .map(|i| {
                let end = |v: Option<f64>| v.map_or("∞".to_string(), |v| format!("{v:.4}"));
                format!("{} {:.4} ({} to {})", i.name, i.value, end(i.lo), end(i.hi))
            })
            .collect();
        out.push(format!(
            "candidate, not added: {} (ΔBIC {:.1}, threshold {:.1}; cross-validation gain {:.3}, threshold \
             {:.3}); the data allow {}",
            c.name,
            c.delta_bic,
            t.min_delta_bic(c.effect.fit_params().len()),
            c.cv_improvement,
            t.cv_improvement,
            sizes.join(", ")
        ));
    }
    out.push(format!(
        "thresholds from {} rows and {} noise pseudo-residuals at α = {}: R < {:.2} (the search goes on \
         above {:.2}), ΔBIC ≥ {:.1} (one parameter) / {:.1} (two), cross-validation gain ≥ {:.3}",
        t.rows,
        t.noise_dof,
        t.alpha,
        t.consistency_ratio,
        t.search_ratio,
        t.delta_bic[0],
        t.delta_bic[1],
        t.cv_improvement
    ));
    out
}

pub fn print_summary(r: &GapReport, out: &Path) {
    println!("rows {}, noise ≈ {:.4} mm/s, {:.1} s", r.rows, r.noise_mm_s, r.elapsed_s);
    println!("gap before {:.4} (residual/noise variance {:.2})", r.gap_before, r.consistency_before);
    for line in verdict_lines(r) {
        println!("{line}");
    }
    if !r.named_effects.is_empty() {
        for e in &r.final_effects {
            for p in &e.params {
                println!("  {}.{} = {:.5} ± {:.5}", e.name, p.name, p.value, p.std_dev);
            }
        }
    }
    for v in r.verdicts.iter().filter(|v| v.tier == super::Tier::NamedWithStructureLeft) {
        println!(
            "  {} explains {:.0} % of the excess over noise and is added; structure left along: {}",
            v.effect,
            100.0 * v.share_of_excess,
            v.structure_left_along.join(", ")
        );
    }
    for p in &r.partial_candidates {
        let along: Vec<String> = p
            .structure
            .iter()
            .filter(|a| !a.consistent_with_noise)
            .map(|a| format!("{} {:.1}", a.condition, a.chi2_per_dof))
            .collect();
        println!(
            "partial candidate (not named): {}, explains {:.0} % of the excess (R {:.2} -> {:.2}); \
             still above noise (χ²/dof): {}",
            p.effect,
            100.0 * p.share_of_excess,
            p.consistency_without,
            p.consistency_with,
            along.join(", ")
        );
    }
    if !r.not_identifiable.is_empty() {
        println!(
            "not tried: {} (the data vary none of the conditions their laws act on)",
            r.not_identifiable.join(", ")
        );
    }
    println!("gap after  {:.4} (residual/noise variance {:.2})", r.gap_after, r.consistency_after);
    let structure: Vec<String> = r
        .residual_structure
        .iter()
        .map(|c| format!("{} {:.1}→{:.1}", c.condition, c.chi2_per_dof_before, c.chi2_per_dof_after))
        .collect();
    println!("residual structure by condition (χ²/dof, before→after): {}", structure.join(", "));
    println!(
        "{:<6} {:<28} {:>10} {:>5} {:>10} {:>10} {:>8} {:>8}  parameters",
        "round", "effect", "score", "rank", "LR", "ΔBIC", "CV %", "gap"
    );
    for c in &r.candidates {
        let [round, name, score, rank, lr, delta_bic, cv, gap] = candidate_cells(c);
        println!(
            "{round:<6} {name:<28} {score:>10} {rank:>5} {lr:>10} {delta_bic:>10} {cv:>8} {gap:>8}  {}{}",
            fmt_params(c),
            if c.accepted {
                "  <- accepted"
            } else if c.partial {
                "  <- partial"
            } else {
                ""
            }
        );
    }
    for a in &r.ambiguity {
        println!("ambiguity (round {}): {}", a.round, a.effects.join(" | "));
    }
    println!("report, plots and {PARAMS_FILE} written to {}", out.display());
}

type Key = (i64, i64, i64, i8);

fn key(r: &MeasuredRow) -> Key {
    (
        (r.preload_n * 1e3).round() as i64,
        (r.voltage_v * 1e3).round() as i64,
        r.frequency_hz.round() as i64,
        r.direction,
    )
}

/// Up to four measured curves (those with the largest before-residuals) with the model before
/// and after, against load.
fn curves_plot(r: &GapReport, rows: &[MeasuredRow], path: &Path) -> Result<()> {
    let e = |e: Box<dyn std::error::Error>| anyhow!("plot: {e}");
    let mut keys: Vec<(Key, f64)> = Vec::new();
    for (i, row) in rows.iter().enumerate() {
        let k = key(row);
        let d = (r.pred_before_mm_s[i] - row.velocity_mm_s).powi(2);
        match keys.iter_mut().find(|(x, _)| *x == k) {
            Some(entry) => entry.1 += d,
            None => keys.push((k, d)),
        }
    }
    keys.sort_by(|a, b| b.1.total_cmp(&a.1));
    keys.truncate(4);
    let root = SVGBackend::new(path, (1000, 760)).into_drawing_area();
    root.fill(&WHITE).map_err(|x| e(Box::new(x)))?;
    let panels = root.split_evenly((2, 2));
    for (panel, (k, _)) in panels.iter().zip(&keys) {
        let idx: Vec<usize> = (0..rows.len()).filter(|&i| key(&rows[i]) == *k).collect();
        let mut pts: Vec<(f64, f64, f64, f64)> = idx
            .iter()
            .map(|&i| (rows[i].load_n, rows[i].velocity_mm_s, r.pred_before_mm_s[i], r.pred_after_mm_s[i]))
            .collect();
        pts.sort_by(|a, b| a.0.total_cmp(&b.0));
        let x_max = pts.iter().map(|p| p.0).fold(0.0, f64::max).max(1e-3) * 1.1;
        let y_max = pts.iter().map(|p| p.1.max(p.2).max(p.3)).fold(0.0, f64::max).max(1e-3) * 1.15;
        let y_min = pts.iter().map(|p| p.1.min(p.2).min(p.3)).fold(0.0, f64::min);
        let first = rows[idx[0]];
        let title = format!(
            "F0 {} N, {} V, {} Hz, dir {:+}",
            first.preload_n, first.voltage_v, first.frequency_hz, first.direction
        );
        let mut chart = ChartBuilder::on(panel)
            .caption(title, ("sans-serif", 16))
            .margin(10)
            .x_label_area_size(35)
            .y_label_area_size(50)
            .build_cartesian_2d(0.0..x_max, y_min..y_max)
            .map_err(|x| e(Box::new(x)))?;
        chart
            .configure_mesh()
            .x_desc("load (N)")
            .y_desc("speed (mm/s)")
            .draw()
            .map_err(|x| e(Box::new(x)))?;
        chart
            .draw_series(LineSeries::new(pts.iter().map(|p| (p.0, p.2)), BLUE.stroke_width(2)))
            .map_err(|x| e(Box::new(x)))?
            .label("base model (calibrated)")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLUE.stroke_width(2)));
        chart
            .draw_series(LineSeries::new(pts.iter().map(|p| (p.0, p.3)), GREEN.stroke_width(2)))
            .map_err(|x| e(Box::new(x)))?
            .label("with named effects")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], GREEN.stroke_width(2)));
        chart
            .draw_series(pts.iter().map(|p| Circle::new((p.0, p.1), 4, RED.filled())))
            .map_err(|x| e(Box::new(x)))?
            .label("measured")
            .legend(|(x, y)| Circle::new((x + 10, y), 4, RED.filled()));
        // Speeds fall with load: the lower left of each panel is empty, the upper right is not
        // always (a near-flat curve), so the legend goes lower left, clear of the measured points.
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::LowerLeft)
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .label_font(("sans-serif", 12))
            .draw()
            .map_err(|x| e(Box::new(x)))?;
    }
    root.present().map_err(|x| e(Box::new(x)))?;
    Ok(())
}

/// Residuals (% of the mean measured speed) against each condition, before (grey) and after (red).
fn residuals_plot(r: &GapReport, rows: &[MeasuredRow], path: &Path) -> Result<()> {
    let e = |e: Box<dyn std::error::Error>| anyhow!("plot: {e}");
    let mean = rows.iter().map(|r| r.velocity_mm_s).sum::<f64>() / rows.len().max(1) as f64;
    let scale = 100.0 / mean.abs().max(1e-12);
    let before: Vec<f64> =
        rows.iter().zip(&r.pred_before_mm_s).map(|(m, p)| (p - m.velocity_mm_s) * scale).collect();
    let after: Vec<f64> =
        rows.iter().zip(&r.pred_after_mm_s).map(|(m, p)| (p - m.velocity_mm_s) * scale).collect();
    let lim = before.iter().chain(&after).fold(1.0f64, |a, v| a.max(v.abs())) * 1.1;
    type Get = fn(&MeasuredRow) -> f64;
    let conds: [(&str, Get); 5] = [
        ("preload (N)", |r| r.preload_n),
        ("voltage (V)", |r| r.voltage_v),
        ("frequency (Hz)", |r| r.frequency_hz),
        ("load (N)", |r| r.load_n),
        ("direction", |r| f64::from(r.direction)),
    ];
    let root = SVGBackend::new(path, (1200, 720)).into_drawing_area();
    root.fill(&WHITE).map_err(|x| e(Box::new(x)))?;
    let root = root
        .titled(
            "residuals (simulated − measured, % of mean speed): grey before, red after",
            ("sans-serif", 18),
        )
        .map_err(|x| e(Box::new(x)))?;
    let panels = root.split_evenly((2, 3));
    for (panel, (label, get)) in panels.iter().zip(conds) {
        let xs: Vec<f64> = rows.iter().map(get).collect();
        let (lo, hi) = xs.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(*v), b.max(*v)));
        let pad = ((hi - lo) * 0.08).max(0.5);
        let mut chart = ChartBuilder::on(panel)
            .margin(10)
            .x_label_area_size(35)
            .y_label_area_size(45)
            .build_cartesian_2d(lo - pad..hi + pad, -lim..lim)
            .map_err(|x| e(Box::new(x)))?;
        chart.configure_mesh().x_desc(label).y_desc("residual (%)").draw().map_err(|x| e(Box::new(x)))?;
        // Jitter the discrete conditions a little so the points do not hide each other.
        let jit = |i: usize| ((i * 37 % 11) as f64 / 10.0 - 0.5) * pad * 0.6;
        chart
            .draw_series(
                xs.iter()
                    .zip(&before)
                    .enumerate()
                    .map(|(i, (x, y))| Circle::new((x + jit(i), *y), 2, RGBColor(150, 150, 150).filled())),
            )
            .map_err(|x| e(Box::new(x)))?;
        chart
            .draw_series(
                xs.iter()
                    .zip(&after)
                    .enumerate()
                    .map(|(i, (x, y))| Circle::new((x + jit(i), *y), 2, RED.filled())),
            )
            .map_err(|x| e(Box::new(x)))?;
    }
    root.present().map_err(|x| e(Box::new(x)))?;
    Ok(())
}
