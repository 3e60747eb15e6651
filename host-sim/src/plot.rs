//! SVG plots (plotters, no system fonts needed).

use crate::curve::Curve;
use anyhow::{anyhow, Result};
use plotters::prelude::*;
use std::path::Path;

pub fn thrust_velocity(curve: &Curve, path: &Path) -> Result<()> {
    let root = SVGBackend::new(path, (800, 520)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| anyhow!("plot: {e}"))?;
    let x_max = curve.stall_force_n.max(1e-6) * 1.05;
    let y_max = curve
        .points
        .iter()
        .map(|p| p.speed_mm_s_model.max(p.speed_mm_s_sim).max(p.speed_mm_s_inertia))
        .fold(curve.no_load_speed_mm_s, f64::max)
        .max(1e-6)
        * 1.1;
    // A light slider may run backwards under load: show it.
    let y_min = curve
        .points
        .iter()
        .map(|p| p.speed_mm_s_sim.min(p.speed_mm_s_inertia))
        .chain(curve.inertia_line.iter().map(|&(_, v)| v))
        .filter(|v| v.is_finite())
        .fold(0.0, f64::min)
        * 1.1;
    let title = format!(
        "Thrust–velocity, F0 {} N, {} V, {} Hz, direction {}",
        curve.preload_n, curve.voltage_v, curve.frequency_hz, curve.direction
    );
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 20))
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(60)
        .build_cartesian_2d(0.0..x_max, y_min..y_max)
        .map_err(|e| anyhow!("plot: {e}"))?;
    chart
        .configure_mesh()
        .x_desc("load opposing motion (N)")
        .y_desc("slider speed (mm/s)")
        .draw()
        .map_err(|e| anyhow!("plot: {e}"))?;
    chart
        .draw_series(LineSeries::new(curve.model_line.iter().copied(), BLUE.stroke_width(2)))
        .map_err(|e| anyhow!("plot: {e}"))?
        .label("steady-state model (eqs. 19–22)")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLUE.stroke_width(2)));
    chart
        .draw_series(LineSeries::new(curve.inertia_line.iter().copied(), GREEN.stroke_width(2)))
        .map_err(|e| anyhow!("plot: {e}"))?
        .label(format!("model with the {} kg slider's inertia", curve.slider_mass_kg))
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], GREEN.stroke_width(2)));
    chart
        .draw_series(curve.points.iter().map(|p| Circle::new((p.load_n, p.speed_mm_s_sim), 5, RED.filled())))
        .map_err(|e| anyhow!("plot: {e}"))?
        .label("time-domain plant")
        .legend(|(x, y)| Circle::new((x + 10, y), 5, RED.filled()));
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()
        .map_err(|e| anyhow!("plot: {e}"))?;
    root.present().map_err(|e| anyhow!("plot: {e}"))?;
    Ok(())
}

/// Position and reference against time (µm vs s), and the drive voltage on a second panel.
pub fn motion(trace: &[crate::harness::moves::TracePoint], title: &str, path: &Path) -> Result<()> {
    let root = SVGBackend::new(path, (900, 640)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| anyhow!("plot: {e}"))?;
    let (upper, lower) = root.split_vertically(440);
    let t_max = trace.last().map_or(1.0, |t| t.time_s).max(1e-3);
    let (mut y_min, mut y_max) = trace.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), t| {
        (lo.min(t.position_nm.min(t.reference_nm)), hi.max(t.position_nm.max(t.reference_nm)))
    });
    if !y_min.is_finite() {
        (y_min, y_max) = (0.0, 1.0);
    }
    let pad = ((y_max - y_min) * 0.05).max(50.0);
    let mut chart = ChartBuilder::on(&upper)
        .caption(title, ("sans-serif", 20))
        .margin(15)
        .x_label_area_size(35)
        .y_label_area_size(70)
        .build_cartesian_2d(0.0..t_max, (y_min - pad) * 1e-3..(y_max + pad) * 1e-3)
        .map_err(|e| anyhow!("plot: {e}"))?;
    chart.configure_mesh().y_desc("position (µm)").draw().map_err(|e| anyhow!("plot: {e}"))?;
    chart
        .draw_series(LineSeries::new(
            trace.iter().map(|t| (t.time_s, t.reference_nm * 1e-3)),
            BLUE.stroke_width(1),
        ))
        .map_err(|e| anyhow!("plot: {e}"))?
        .label("profile reference")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLUE));
    chart
        .draw_series(LineSeries::new(
            trace.iter().map(|t| (t.time_s, t.position_nm * 1e-3)),
            RED.stroke_width(2),
        ))
        .map_err(|e| anyhow!("plot: {e}"))?
        .label("slider (plant)")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], RED.stroke_width(2)));
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperLeft)
        .draw()
        .map_err(|e| anyhow!("plot: {e}"))?;
    let mut volts = ChartBuilder::on(&lower)
        .margin(15)
        .x_label_area_size(40)
        .y_label_area_size(70)
        .build_cartesian_2d(0.0..t_max, 0.0..105.0)
        .map_err(|e| anyhow!("plot: {e}"))?;
    volts
        .configure_mesh()
        .x_desc("time (s)")
        .y_desc("drive (V p-p)")
        .draw()
        .map_err(|e| anyhow!("plot: {e}"))?;
    volts
        .draw_series(LineSeries::new(trace.iter().map(|t| (t.time_s, t.drive_v)), GREEN.stroke_width(1)))
        .map_err(|e| anyhow!("plot: {e}"))?;
    root.present().map_err(|e| anyhow!("plot: {e}"))?;
    Ok(())
}

/// One drive period of one or more plants (e.g. a light and a heavy carriage) in three panels:
/// foot motion, contact and friction force, foot and slider speed; one colour per trace.
pub fn period(traces: &[crate::trace::PeriodTrace], path: &Path) -> Result<()> {
    let labels: Vec<String> = traces.iter().map(|t| format!("slider {} kg", t.slider_mass_kg)).collect();
    period_labelled(traces, &labels, path)
}

/// [`period`] with a legend label per trace (e.g. two plants that differ in something else than
/// the slider); the mean speed follows each label.
pub fn period_labelled(traces: &[crate::trace::PeriodTrace], labels: &[String], path: &Path) -> Result<()> {
    use crate::trace::PeriodSample;
    let err = |e: DrawingAreaErrorKind<_>| anyhow!("plot {}: {e}", path.display());
    let root = SVGBackend::new(path, (900, 900)).into_drawing_area();
    root.fill(&WHITE).map_err(err)?;
    let panels = root.split_evenly((3, 1));
    let colours = [RED, BLUE, GREEN, MAGENTA, BLACK];
    type Pick = fn(&PeriodSample) -> f64;
    let rows: [(&str, &[(&str, Pick)]); 3] = [
        (
            "foot (µm): normal —, tangential - -",
            &[("normal", |s| s.foot_normal_um), ("tangential", |s| s.foot_tangential_um)],
        ),
        (
            "force (N): contact —, friction - -",
            &[("contact", |s| s.contact_force_n), ("friction", |s| s.friction_force_n)],
        ),
        (
            "speed (mm/s): slider —, foot - -",
            &[("slider", |s| s.slider_speed_mm_s), ("foot", |s| s.foot_speed_mm_s)],
        ),
    ];
    for (panel, (label, series)) in panels.iter().zip(rows) {
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for t in traces {
            for s in &t.samples {
                for (_, pick) in series {
                    lo = lo.min(pick(s));
                    hi = hi.max(pick(s));
                }
            }
        }
        if !lo.is_finite() {
            (lo, hi) = (0.0, 1.0);
        }
        let pad = ((hi - lo) * 0.05).max(1e-9);
        let mut chart = ChartBuilder::on(panel)
            .margin(10)
            .x_label_area_size(30)
            .y_label_area_size(60)
            .build_cartesian_2d(0.0..360.0, (lo - pad)..(hi + pad))
            .map_err(err)?;
        chart.configure_mesh().x_desc("drive phase (deg)").y_desc(label).draw().map_err(err)?;
        for ((t, colour), name) in traces.iter().zip(colours.iter().cycle()).zip(labels) {
            for (k, (_, pick)) in series.iter().enumerate() {
                let points = t.samples.iter().map(|s| (s.phase_deg, pick(s)));
                let style = colour.stroke_width(if k == 0 { 2 } else { 1 });
                if k == 0 {
                    chart
                        .draw_series(LineSeries::new(points, style))
                        .map_err(err)?
                        .label(format!("{name}: {:.3} mm/s", t.mean_speed_mm_s))
                        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], style));
                } else {
                    // Dashed: every other short segment.
                    let pts: Vec<(f64, f64)> = points.collect();
                    chart
                        .draw_series(
                            pts.chunks(4)
                                .step_by(2)
                                .map(|c| PathElement::new(c.to_vec(), colour.stroke_width(1))),
                        )
                        .map_err(err)?;
                }
            }
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .position(SeriesLabelPosition::UpperRight)
            .draw()
            .map_err(err)?;
    }
    root.present().map_err(err)?;
    Ok(())
}

/// Issue 28's grid: each model's speed against the plant's at the same point (on the diagonal
/// where they agree).
pub fn model_grid(grid: &[crate::model_grid::GridPoint], title: &str, path: &Path) -> Result<()> {
    let root = SVGBackend::new(path, (760, 640)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| anyhow!("plot: {e}"))?;
    let all = grid.iter().flat_map(|g| [g.plant_mm_s, g.constant_speed_mm_s, g.inertia_mm_s, g.contact_mm_s]);
    let finite: Vec<f64> = all.filter(|v| v.is_finite()).collect();
    let lo = finite.iter().copied().fold(0.0, f64::min).floor();
    let hi = finite.iter().copied().fold(1.0, f64::max).ceil();
    let mut chart = ChartBuilder::on(&root)
        .caption(title, ("sans-serif", 18))
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(60)
        .build_cartesian_2d(lo..hi, lo..hi)
        .map_err(|e| anyhow!("plot: {e}"))?;
    chart
        .configure_mesh()
        .x_desc("time-domain plant (mm/s)")
        .y_desc("steady-state model (mm/s)")
        .draw()
        .map_err(|e| anyhow!("plot: {e}"))?;
    chart
        .draw_series(LineSeries::new([(lo, lo), (hi, hi)], BLACK.stroke_width(1)))
        .map_err(|e| anyhow!("plot: {e}"))?
        .label("model = plant")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK.stroke_width(1)));
    type Pick = fn(&crate::model_grid::GridPoint) -> f64;
    let series: [(&str, Pick, RGBColor); 3] = [
        ("constant speed (eqs. 19–22)", |g| g.constant_speed_mm_s, BLUE),
        ("with the carriage's inertia", |g| g.inertia_mm_s, GREEN),
        ("with the contact's timing (steady_contact)", |g| g.contact_mm_s, RED),
    ];
    for (label, pick, color) in series {
        chart
            .draw_series(
                grid.iter()
                    .filter(|g| pick(g).is_finite() && g.plant_mm_s.is_finite())
                    .map(|g| Circle::new((g.plant_mm_s, pick(g)), 3, color.filled())),
            )
            .map_err(|e| anyhow!("plot: {e}"))?
            .label(label)
            .legend(move |(x, y)| Circle::new((x + 10, y), 4, color.filled()));
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperLeft)
        .background_style(WHITE.mix(0.9))
        .border_style(BLACK)
        .draw()
        .map_err(|e| anyhow!("plot: {e}"))?;
    root.present().map_err(|e| anyhow!("plot: {e}"))?;
    Ok(())
}

/// The demo sequence as a motion-control user reads it: position against the reference with each
/// step labelled (and the drive frequency and preload it ran at), the following error on a log
/// scale that shows the 1 mm move and the 100 nm step alike, and one panel per small step.
pub fn demo(
    trace: &[crate::harness::moves::TracePoint],
    rows: &[crate::harness::moves::DemoRow],
    path: &Path,
) -> Result<()> {
    let e = |err: DrawingAreaErrorKind<_>| anyhow!("plot: {err}");
    let root = SVGBackend::new(path, (1000, 980)).into_drawing_area();
    root.fill(&WHITE).map_err(e)?;
    let (top, rest) = root.split_vertically(360);
    let (middle, bottom) = rest.split_vertically(300);
    let t_max = trace.last().map_or(1.0, |t| t.time_s).max(1e-3);
    let um = |nm: f64| nm * 1e-3;
    let (lo, hi) = trace
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), t| (a.min(t.position_nm), b.max(t.position_nm)));
    let (lo, hi) = if lo.is_finite() { (lo, hi) } else { (0.0, 1.0) };
    let pad = (hi - lo).max(1.0) * 0.08;
    let mut pos = ChartBuilder::on(&top)
        .caption("demo: the firmware's controller against the plant (1 kg carriage)", ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(30)
        .y_label_area_size(70)
        .build_cartesian_2d(0.0..t_max, um(lo - pad)..um(hi + 2.0 * pad))
        .map_err(e)?;
    pos.configure_mesh().y_desc("position (µm)").draw().map_err(e)?;
    pos.draw_series(LineSeries::new(
        trace.iter().map(|t| (t.time_s, um(t.reference_nm))),
        BLUE.stroke_width(1),
    ))
    .map_err(e)?
    .label("reference (profile)")
    .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLUE));
    pos.draw_series(LineSeries::new(
        trace.iter().map(|t| (t.time_s, um(t.position_nm))),
        RED.mix(0.7).stroke_width(2),
    ))
    .map_err(e)?
    .label("slider (plant, true position)")
    .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], RED.stroke_width(2)));
    // Each traced step: a numbered line at its start, and the list of steps with the drive
    // frequency and preload each ran at.
    let at = |s: f64| trace.iter().find(|t| t.time_s >= s);
    let traced: Vec<_> = rows.iter().filter(|r| r.trace_span_s.1 > r.trace_span_s.0).collect();
    let x_text = t_max * 0.42;
    for (i, r) in traced.iter().enumerate() {
        let (s0, _) = r.trace_span_s;
        let Some(p) = at(s0) else { continue };
        pos.draw_series(LineSeries::new([(s0, um(lo - pad)), (s0, um(hi + pad))], BLACK.mix(0.3)))
            .map_err(e)?;
        pos.draw_series(std::iter::once(Text::new(
            format!("{}", i + 1),
            (s0, um(hi + 1.3 * pad)),
            ("sans-serif", 13),
        )))
        .map_err(e)?;
        let line = format!(
            "{}  {}: {:.1} kHz, preload {:.1} N",
            i + 1,
            r.step,
            p.drive_frequency_hz * 1e-3,
            p.preload_n
        );
        let y = um(lo + (hi - lo) * (0.78 - 0.06 * i as f64));
        pos.draw_series(std::iter::once(Text::new(line, (x_text, y), ("sans-serif", 12)))).map_err(e)?;
    }
    pos.configure_series_labels()
        .position(SeriesLabelPosition::LowerRight)
        .background_style(WHITE.mix(0.9))
        .border_style(BLACK)
        .draw()
        .map_err(e)?;

    // Following error |slider − reference| on a log scale: 1 nm to the move's largest.
    let err_max = trace.iter().map(|t| (t.position_nm - t.reference_nm).abs()).fold(100.0, f64::max) * 2.0;
    let mut ferr = ChartBuilder::on(&middle)
        .margin(12)
        .x_label_area_size(35)
        .y_label_area_size(70)
        .build_cartesian_2d(0.0..t_max, (1.0..err_max).log_scale())
        .map_err(e)?;
    ferr.configure_mesh().x_desc("time (s)").y_desc("|following error| (nm)").draw().map_err(e)?;
    ferr.draw_series(LineSeries::new(
        trace.iter().map(|t| (t.time_s, (t.position_nm - t.reference_nm).abs().max(1.0))),
        MAGENTA.stroke_width(1),
    ))
    .map_err(e)?
    .label("following error")
    .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], MAGENTA));
    ferr.draw_series(LineSeries::new([(0.0, 50.0), (t_max, 50.0)], BLACK.stroke_width(2)))
        .map_err(e)?
        .label("one encoder count (50 nm)")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK.stroke_width(2)));
    ferr.configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .background_style(WHITE.mix(0.9))
        .border_style(BLACK)
        .draw()
        .map_err(e)?;

    // The small steps, each in its own panel: position and reference from the step's start (nm)
    // over its first 20 ms, with the ±1 count band around the target.
    let steps: Vec<&crate::harness::moves::DemoRow> =
        rows.iter().filter(|r| r.step.starts_with("step ")).collect();
    let panels = bottom.split_evenly((1, steps.len().max(1)));
    for (panel, r) in panels.iter().zip(&steps) {
        let (s0, s1) = r.trace_span_s;
        let window = (s1 - s0).min(0.02);
        let pts: Vec<_> = trace.iter().filter(|t| t.time_s >= s0 && t.time_s <= s0 + window).collect();
        let Some(first) = pts.first() else { continue };
        let base = first.reference_nm;
        let target = r.target_um * 1e3 - base;
        let (a, b) = pts.iter().fold((0.0f64, target), |(a, b), t| {
            (a.min(t.position_nm - base).min(t.reference_nm - base), b.max(t.position_nm - base))
        });
        let span = (b - a).max(1.0);
        let mut c = ChartBuilder::on(panel)
            .caption(r.step, ("sans-serif", 14))
            .margin(10)
            .x_label_area_size(35)
            .y_label_area_size(55)
            .build_cartesian_2d(0.0..window * 1e3, (a - 0.1 * span)..(b + 0.15 * span))
            .map_err(e)?;
        c.configure_mesh()
            .x_desc("ms from the step")
            .y_desc("nm from the start")
            .x_labels(5)
            .draw()
            .map_err(e)?;
        c.draw_series(LineSeries::new(
            pts.iter().map(|t| ((t.time_s - s0) * 1e3, t.reference_nm - base)),
            BLUE,
        ))
        .map_err(e)?;
        c.draw_series(LineSeries::new(
            pts.iter().map(|t| ((t.time_s - s0) * 1e3, t.position_nm - base)),
            RED.mix(0.7).stroke_width(2),
        ))
        .map_err(e)?;
        for band in [target - 50.0, target + 50.0] {
            c.draw_series(LineSeries::new([(0.0, band), (window * 1e3, band)], BLACK.mix(0.3))).map_err(e)?;
        }
    }
    root.present().map_err(e)?;
    Ok(())
}
