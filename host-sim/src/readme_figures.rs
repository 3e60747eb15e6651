//! `host-sim readme-figures`: every figure in `docs/` and every table of the README and the
//! `docs/*.md` pages that the simulator measures, from the code, by one command. A generated
//! table sits between `<!-- readme-figures: NAME -->` and `<!-- /readme-figures -->` in whichever
//! of `README.md` or `docs/*.md` holds it, and is rewritten in place there.
//!
//! `--check` writes nothing: it regenerates into memory and a temporary directory and fails when
//! the committed files no longer match (a table no page holds is drift too). Tolerances: a table number may differ by one unit in its
//! last printed digit or 1 %, whichever is larger; a figure must have the same SVG elements and
//! text, every number in it (coordinates in pixels, tick labels) within 2.

use crate::gap::measured_csv;
use crate::harness::moves;
use crate::motor::params::Params;
use crate::motor::steady::{OperatingPoint, ThrustModel};
use crate::motor::steady_inertia::InertialModel;
use crate::{curve, gap, model_grid, plot, trace};
use anyhow::{bail, Context, Result};
use piezo_drive::settings::{DefaultValue, Keep, Range, Setting, Ty, Value, SETTINGS};
use rayon::prelude::*;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// What `host-sim readme-figures` does.
#[derive(Debug, Clone)]
pub struct ReadmeFiguresOptions {
    /// Compare with the committed figures and the tables of README.md and docs/*.md instead of
    /// writing them (an error on drift).
    pub check: bool,
    /// Repository root: where README.md, docs/ and host-sim/ are.
    pub root: PathBuf,
}

const HEAVY_SLIDER: &str = "host-sim/params/heavy-slider.toml";
const SOURCED: &str = "host-sim/params/prototype-sourced.toml";
const EXAMPLE_CSV: &str = "host-sim/data/example-measured.csv";

/// A generated table.
struct Table {
    name: &'static str,
    text: String,
}

/// Closed-loop moves, default parameters, 16 N.
fn moves_table(p: &Params) -> Result<String> {
    let run = |to_um: f64, load_n: f64, feedforward: bool, load_known: bool| {
        moves::single_move(p, moves::MoveSpec { to_um, preload_n: 16.0, load_n, feedforward, load_known })
    };
    let cells = |r: &moves::MoveResult| -> [String; 3] {
        match (&r.fault, r.settle_time_s) {
            (None, Some(t)) => [
                format!("{t:.3} s"),
                format!("{:.1} nm", r.overshoot_nm),
                format!("{:.3} µm", r.max_following_error_um),
            ],
            (None, None) => ["did not settle".into(), "—".into(), "—".into()],
            (Some(f), _) => [
                format!("fault: {}", f.text),
                format!(
                    "{:.1} µm, then slides back {:.1} µm",
                    r.overshoot_nm * 1e-3,
                    r.slide_back_nm.unwrap_or(0.0) * 1e-3
                ),
                format!("{:.3} µm", r.max_following_error_um),
            ],
        }
    };
    let mut t = String::new();
    t.push_str("| move | settle (±1 count) | overshoot | peak following error |\n|---|---|---|---|\n");
    let row = |t: &mut String, label: &str, c: [String; 3]| {
        let _ = writeln!(t, "| {label} | {} | {} | {} |", c[0], c[1], c[2]);
    };
    // The limit as the closed-loop test measures it: on the plant.
    let limit_s = crate::harness::sweep::physical_limit_s(p, 1e-3, 16.0).0;
    let label = format!(
        "1 mm, no load (physical limit {limit_s:.3} s, measured on the plant; test asserts ≤ 1.25× = {:.3} s, < 200 nm)",
        1.25 * limit_s
    );
    row(&mut t, &label, cells(&run(1000.0, 0.0, true, false)?));
    let (demo_rows, _) = moves::demo(p, |_| {})?;
    let settle = |name: &str| -> String {
        demo_rows
            .iter()
            .find(|r| r.step == name)
            .and_then(|r| r.settle_time_s)
            .map_or("—".into(), |s| format!("{:.1} ms", s * 1e3))
    };
    row(
        &mut t,
        "100 nm and 1 µm steps (in the demo)",
        [format!("{} / {}", settle("step +100 nm"), settle("step +1 µm")), "—".into(), "—".into()],
    );
    let loaded: [(&str, f64, bool, bool); 5] = [
        ("1 mm against 2 N, load known, thrust-model feedforward", 2.0, true, true),
        ("1 mm against 2 N, load known, plain PI (`--no-feedforward`)", 2.0, false, true),
        ("1 mm against 2 N, load unknown (observer finds it), feedforward", 2.0, true, false),
        ("1 mm against 3 N (70 % of stall), load unknown, feedforward", 3.0, true, false),
        ("1 mm against 2 N, load unknown, plain PI", 2.0, false, false),
    ];
    for (label, load_n, ff, known) in loaded {
        row(&mut t, label, cells(&run(1000.0, load_n, ff, known)?));
    }
    Ok(t)
}

/// No-load speed at 16 N, 100 V on the default stator for a range of carriages: the time-domain
/// plant beside the steady-state model with the carriage's inertia (mm/s); the constant-speed
/// model's, which no mass changes, in the last row.
fn slider_mass_table(p: &Params) -> String {
    let masses = [0.05, 0.1, 0.3, 1.0, 5.0, 50.0];
    let freqs = [800.0, 1500.0, 2200.0];
    let op = |f: f64| OperatingPoint { preload_n: 16.0, voltage_v: 100.0, frequency_hz: f };
    let cells: Vec<(f64, f64)> = masses
        .iter()
        .flat_map(|&m| freqs.iter().map(move |&f| (m, f)))
        .collect::<Vec<_>>()
        .par_iter()
        .map(|&(m, f)| {
            let mut q = p.clone();
            q.slider.mass_kg = m;
            let plant = crate::motor::plant::steady_speed_m_s(&q, 16.0, 100.0, f, 1, 0.0) * 1e3;
            let model = InertialModel::new(&q, op(f)).no_load_speed_m_s() * 1e3;
            (plant, model)
        })
        .collect();
    let signed = |v: f64| if v < 0.0 { format!("**−{:.2}**", -v) } else { format!("{v:.2}") };
    let mut t = String::from("| slider | 0.8 kHz | 1.5 kHz | 2.2 kHz |\n|---|---|---|---|\n");
    for (i, m) in masses.iter().enumerate() {
        let _ = write!(t, "| {m} kg |");
        for j in 0..freqs.len() {
            let (plant, model) = cells[i * freqs.len() + j];
            let _ = write!(t, " {} / {} |", signed(plant), signed(model));
        }
        t.push('\n');
    }
    let _ = write!(t, "| constant-speed model |");
    for &f in &freqs {
        let _ = write!(t, " {:.2} |", ThrustModel::new(p, op(f)).no_load_speed_m_s() * 1e3);
    }
    t.push('\n');
    t
}

/// The gap workflow on the shipped example: what it names and how far the gap closes.
/// Worst error of each steady-state model per carriage over issue 28's grid.
fn model_grid_table(grid: &[model_grid::GridPoint]) -> String {
    let mut t = String::from(
        "| carriage | constant speed (eqs. 19–22) | with the carriage's inertia | with the contact's timing | the firmware's table |\n|---|---|---|---|---|\n",
    );
    for (m, constant, inertia, contact, firmware) in model_grid::worst_per_mass(grid) {
        let _ =
            writeln!(t, "| {m} kg | {constant:.1} % | {inertia:.1} % | {contact:.1} % | {firmware:.1} % |");
    }
    t
}

fn gap_table(r: &gap::GapReport) -> String {
    let mut t = String::from("| | result |\n|---|---|\n");
    let _ =
        writeln!(t, "| calibrated base model | gap {:.3}, R = {:.2} |", r.gap_before, r.consistency_before);
    for e in &r.final_effects {
        let params: Vec<String> =
            e.params.iter().map(|q| format!("{} {:.4} ± {:.4}", q.name, q.value, q.std_dev)).collect();
        let _ = writeln!(t, "| named: `{}` | {} |", e.name, params.join(", "));
    }
    let _ =
        writeln!(t, "| with the named effects | gap {:.3}, R = {:.2} |", r.gap_after, r.consistency_after);
    t
}

/// A value in the protocol's unit, as the parameter table prints it.
fn gcs_text(s: &Setting, v: Value) -> String {
    match (s.ty, v) {
        (Ty::I64Nm, Value::Int(nm)) => {
            let sign = if nm < 0 { "-" } else { "" };
            let (mm, frac) = (nm.unsigned_abs() / 1_000_000, nm.unsigned_abs() % 1_000_000);
            let frac = format!("{frac:06}");
            match frac.trim_end_matches('0') {
                "" => format!("{sign}{mm}"),
                f => format!("{sign}{mm}.{f}"),
            }
        }
        (_, Value::Int(x)) => format!("{x}"),
        (_, Value::F32(x)) => format!("{}", x / s.scale),
    }
}

/// A setting's range in the protocol's unit.
fn range_text(s: &Setting) -> String {
    match s.range {
        Range::Float { lo, hi, lo_open } => {
            let lo_text = gcs_text(s, Value::F32(lo));
            let hi_text = gcs_text(s, Value::F32(hi));
            match (lo == -f32::MAX, hi == f32::MAX, lo_open) {
                (true, true, _) => "any".into(),
                (false, true, true) => format!("> {lo_text}"),
                (false, true, false) => format!("≥ {lo_text}"),
                (_, _, true) => format!("> {lo_text}, ≤ {hi_text}"),
                (_, _, false) => format!("{lo_text} … {hi_text}"),
            }
        }
        Range::Int { lo, hi } => {
            format!("{} … {}", gcs_text(s, Value::Int(lo)), gcs_text(s, Value::Int(hi)))
        }
    }
}

/// The parameters, from the core's settings table ([`piezo_drive::settings::SETTINGS`]).
pub fn parameters_table() -> String {
    let defaults = piezo_drive::defaults::controller_config();
    let mut t = String::from(
        "| id | setting | unit | range | default | kept | description |\n|---|---|---|---|---|---|---|\n",
    );
    for s in SETTINGS {
        let value = gcs_text(s, (s.get)(&defaults));
        let default = match s.default {
            DefaultValue::Fixed(_) => value,
            DefaultValue::Hardware(what, _) => format!("{what} (reference board: {value})"),
        };
        let kept = match s.keep {
            Keep::Stored => "`WPA`",
            Keep::Volatile => "no",
            Keep::ReadOnly => "read-only",
        };
        let _ = writeln!(
            t,
            "| 0x{:X} | `{}` | {} | {} | {} | {} | {} |",
            s.id,
            s.name,
            s.unit,
            range_text(s),
            default,
            kept,
            s.description
        );
    }
    t
}

/// Everything, written to `docs` (figures) and returned (tables).
fn generate(root: &Path, docs: &Path) -> Result<Vec<Table>> {
    let proto = Params::prototype();
    let heavy = Params::load(&root.join(HEAVY_SLIDER))?;
    let op = OperatingPoint { preload_n: 16.0, voltage_v: 100.0, frequency_hz: 1500.0 };

    let (demo_rows, demo_trace) = moves::demo(&proto, |_| {})?;
    plot::demo(&demo_trace, &demo_rows, &docs.join("demo.svg"))?;

    let c = curve::compute(&proto, op, 1, 8, 0.9, |_, _| {});
    plot::thrust_velocity(&c, &docs.join("thrust-velocity.svg"))?;

    let period_traces = |params: &Params, masses: &[f64]| -> Vec<trace::PeriodTrace> {
        masses
            .par_iter()
            .map(|&m| {
                let mut q = params.clone();
                q.slider.mass_kg = m;
                trace::one_period(&q, op, 0.0, 720)
            })
            .collect()
    };
    plot::period(&period_traces(&proto, &[0.3, 5.0]), &docs.join("period-prototype-1500hz.svg"))?;
    // The evidence for the preload mode's damping: the default carriage with the structural 5 %
    // on that mode (ringing, contact off the foot's peak speed) and with the file's value.
    let mut ringing = proto.clone();
    ringing.stator.preload_damping_ratio = Some(ringing.stator.damping_ratio);
    let pair =
        [period_traces(&ringing, &[proto.slider.mass_kg]), period_traces(&proto, &[proto.slider.mass_kg])];
    let labels = [
        format!("preload mode damped {}", ringing.stator.preload_mode_damping_ratio()),
        format!("preload mode damped {}", proto.stator.preload_mode_damping_ratio()),
    ];
    plot::period_labelled(&pair.concat(), &labels, &docs.join("period-preload-damping-1500hz.svg"))?;

    let sourced = Params::load(&root.join(SOURCED))?;
    let grid = model_grid::compute(&sourced);
    plot::model_grid(
        &grid,
        "Issue 28 grid, prototype-sourced: 0.1–50 kg, 5–18 N, 1.5/2.2 kHz, 0–70 % of stall",
        &docs.join("model-grid.svg"),
    )?;

    let csv = root.join(EXAMPLE_CSV);
    let rows = measured_csv::read(&csv)?;
    let report = gap::analyze(&heavy, &rows, &gap::Options::default(), &|_, _, _| {})?;
    let gap_dir = tempdir("gap")?;
    gap::report::write_all(&report, &rows, &heavy, Path::new(EXAMPLE_CSV), &gap_dir)?;
    for (from, to) in
        [(gap::report::CURVES_SVG, "gap-curves.svg"), (gap::report::RESIDUALS_SVG, "gap-residuals.svg")]
    {
        std::fs::copy(gap_dir.join(from), docs.join(to))
            .with_context(|| format!("copying {} to {}", from, docs.join(to).display()))?;
    }
    let _ = std::fs::remove_dir_all(&gap_dir);

    Ok(vec![
        Table { name: "moves", text: moves_table(&proto)? },
        Table { name: "slider-mass-speeds", text: slider_mass_table(&proto) },
        Table { name: "gap-example", text: gap_table(&report) },
        Table { name: "parameters", text: parameters_table() },
        Table { name: "model-grid", text: model_grid_table(&grid) },
    ])
}

/// The figures `generate` writes.
pub const FIGURES: [&str; 7] = [
    "model-grid.svg",
    "demo.svg",
    "thrust-velocity.svg",
    "period-prototype-1500hz.svg",
    "period-preload-damping-1500hz.svg",
    "gap-curves.svg",
    "gap-residuals.svg",
];

fn tempdir(what: &str) -> Result<PathBuf> {
    let nanos =
        std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_nanos());
    let dir = std::env::temp_dir().join(format!("host-sim-{what}-{}-{nanos}", std::process::id()));
    std::fs::create_dir_all(&dir).with_context(|| format!("cannot create {}", dir.display()))?;
    Ok(dir)
}

const BEGIN: &str = "<!-- readme-figures: ";
const END: &str = "<!-- /readme-figures -->";

/// The pages that may hold generated tables: `README.md`, then every `docs/*.md` in name order.
fn pages(root: &Path, docs: &Path) -> Result<Vec<PathBuf>> {
    let mut md: Vec<PathBuf> = std::fs::read_dir(docs)
        .with_context(|| format!("cannot read {}", docs.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_file() && p.extension().is_some_and(|x| x == "md"))
        .collect();
    md.sort();
    let mut out = vec![root.join("README.md")];
    out.extend(md);
    Ok(out)
}

/// A page with its marked blocks.
struct Page {
    path: PathBuf,
    /// The path as the messages name it (`README.md`, `docs/controller.md`).
    label: String,
    text: String,
    blocks: Vec<(String, std::ops::Range<usize>)>,
}

/// A page's marked blocks: (name, byte range of the content between the markers). A block's
/// end marker also starts a line.
fn marked_blocks(readme: &str) -> Result<Vec<(String, std::ops::Range<usize>)>> {
    let mut out = Vec::new();
    let mut from = 0;
    // A marker starts a line (the README also mentions the marker syntax in running text).
    while let Some(i) = readme[from..].find(&format!("\n{BEGIN}")) {
        let start = from + i + 1;
        let name_end = readme[start..].find("-->").map(|j| start + j).context("unterminated marker")?;
        let name = readme[start + BEGIN.len()..name_end].trim().to_string();
        let content_start = readme[name_end..].find('\n').map_or(readme.len(), |j| name_end + j + 1);
        let end = readme[content_start - 1..]
            .find(&format!("\n{END}"))
            .map(|j| content_start + j)
            .with_context(|| format!("block '{name}' has no {END}"))?;
        out.push((name, content_start..end));
        from = end + END.len();
    }
    Ok(out)
}

/// Numbers in a text (a '−' counts as a minus; digits that follow a letter, as in `F0` or `x1`,
/// belong to the word), each with the size of one unit in its last printed digit, and the text
/// with each number replaced by `#` and its count of decimals: what must match exactly.
fn scan(text: &str) -> (Vec<(f64, f64)>, String) {
    let chars: Vec<char> = text.chars().collect();
    let mut numbers = Vec::new();
    let mut skeleton = String::new();
    let mut i = 0;
    while i < chars.len() {
        let after_word = i > 0 && chars[i - 1].is_alphanumeric();
        let neg = matches!(chars[i], '-' | '−')
            && chars.get(i + 1).is_some_and(|c| c.is_ascii_digit())
            && !after_word;
        let start = if neg { i + 1 } else { i };
        if !(chars.get(start).is_some_and(|c| c.is_ascii_digit()) && (neg || !after_word)) {
            skeleton.push(chars[i]);
            i += 1;
            continue;
        }
        let mut j = start;
        let mut decimals: Option<i32> = None;
        while j < chars.len() {
            let c = chars[j];
            if c.is_ascii_digit() {
                if let Some(d) = decimals.as_mut() {
                    *d += 1;
                }
            } else if c == '.' && decimals.is_none() && chars.get(j + 1).is_some_and(|c| c.is_ascii_digit()) {
                decimals = Some(0);
            } else {
                break;
            }
            j += 1;
        }
        let digits: String = chars[start..j].iter().collect();
        let value: f64 = digits.parse().unwrap_or(f64::NAN);
        let places = decimals.unwrap_or(0);
        numbers.push((if neg { -value } else { value }, 10f64.powi(-places)));
        let _ = write!(skeleton, "#{places}");
        i = j;
    }
    (numbers, skeleton)
}

/// The numbers of a text with the unit of their last printed digit (see `scan`).
pub fn numbers(text: &str) -> Vec<(f64, f64)> {
    scan(text).0
}

/// Differences between a committed table and the generated one, within the table tolerance.
pub fn table_drift(committed: &str, generated: &str) -> Option<String> {
    let (a, layout_a) = scan(committed);
    let (b, layout_b) = scan(generated);
    if layout_a != layout_b {
        return Some("layout, text or printed precision differs".into());
    }
    for ((x, ux), (y, _)) in a.iter().zip(&b) {
        let tol = ux.max(0.01 * x.abs().max(y.abs())) * (1.0 + 1e-9);
        if (x - y).abs() > tol {
            return Some(format!("{x} is now {y}"));
        }
    }
    None
}

/// Differences between a committed SVG and the generated one, within the figure tolerance.
pub fn figure_drift(committed: &str, generated: &str) -> Option<String> {
    let (a, layout_a) = scan(committed);
    let (b, layout_b) = scan(generated);
    if layout_a != layout_b {
        return Some(format!("elements or text differ ({} numbers committed, {} now)", a.len(), b.len()));
    }
    for ((x, _), (y, _)) in a.iter().zip(&b) {
        if (x - y).abs() > 2.0 {
            return Some(format!("{x} is now {y}"));
        }
    }
    None
}

pub fn run(args: &ReadmeFiguresOptions) -> Result<()> {
    let root = &args.root;
    let readme_path = root.join("README.md");
    if !readme_path.is_file() {
        bail!("--root {}: cannot read {}", root.display(), readme_path.display());
    }
    let docs = root.join("docs");
    if !docs.is_dir() {
        bail!("--root {}: no docs/ directory there", root.display());
    }
    let mut pages_read = Vec::new();
    for path in pages(root, &docs)? {
        let text = std::fs::read_to_string(&path)
            .with_context(|| format!("--root {}: cannot read {}", root.display(), path.display()))?;
        let label = path.strip_prefix(root).unwrap_or(&path).display().to_string();
        let blocks = marked_blocks(&text).with_context(|| label.clone())?;
        pages_read.push(Page { path, label, text, blocks });
    }
    let out_dir = if args.check { tempdir("readme-figures")? } else { docs.clone() };
    let tables = generate(root, &out_dir)?;
    for t in &tables {
        println!("{}:\n{}", t.name, t.text);
    }
    if args.check {
        let mut drift = Vec::new();
        for f in FIGURES {
            let committed = std::fs::read_to_string(docs.join(f)).unwrap_or_default();
            let generated = std::fs::read_to_string(out_dir.join(f))?;
            if let Some(d) = figure_drift(&committed, &generated) {
                drift.push(format!("docs/{f}: {d}"));
            }
        }
        let _ = std::fs::remove_dir_all(&out_dir);
        for t in &tables {
            // Every block of that name is checked, wherever it is.
            let mut found = false;
            for page in &pages_read {
                for (_, range) in page.blocks.iter().filter(|(name, _)| name == t.name) {
                    found = true;
                    if let Some(d) = table_drift(&page.text[range.clone()], &t.text) {
                        drift.push(format!("{} table '{}': {d}", page.label, t.name));
                    }
                }
            }
            if !found {
                drift.push(format!("README.md and docs/*.md: no block '{}'", t.name));
            }
        }
        if !drift.is_empty() {
            for d in &drift {
                println!("drift: {d}");
            }
            bail!(
                "{} of the README's and docs' figures and tables no longer match the code ({}); \
                 regenerate them with `cargo run --release -p host-sim -- readme-figures`",
                drift.len(),
                drift.join("; ")
            );
        }
        println!("README and docs figures and tables match the code");
        return Ok(());
    }
    let mut missing: Vec<&str> = tables.iter().map(|t| t.name).collect();
    for page in pages_read {
        let mut text = page.text.clone();
        // Replace from the last block back so earlier ranges stay valid.
        let mut blocks = page.blocks;
        blocks.sort_by_key(|(_, r)| std::cmp::Reverse(r.start));
        for (name, range) in blocks {
            if let Some(t) = tables.iter().find(|t| t.name == name) {
                text.replace_range(range, &t.text);
                missing.retain(|m| *m != name);
            }
        }
        if text != page.text {
            std::fs::write(&page.path, text)
                .with_context(|| format!("cannot write {}", page.path.display()))?;
        }
    }
    println!("figures written to {}; tables in README.md and docs/*.md updated", docs.display());
    for m in missing {
        println!("no block '{m}' in README.md or docs/*.md: that table was printed only");
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_carry_the_unit_of_their_last_digit() {
        assert_eq!(
            numbers("| **−0.40** / 2.22 | 28.0 nm | x2 |"),
            vec![(-0.40, 0.01), (2.22, 0.01), (28.0, 0.1)]
        );
        assert_eq!(numbers("F0 16 N, x1=\"-3\""), vec![(16.0, 1.0), (-3.0, 1.0)]);
    }

    #[test]
    fn tables_pass_within_the_last_digit_or_one_percent_and_fail_beyond() {
        assert!(table_drift("| 0.424 s | 28.0 nm |", "| 0.425 s | 28.1 nm |").is_none());
        assert!(table_drift("| 540.0 nm |", "| 545.0 nm |").is_none(), "within 1 %");
        assert!(table_drift("| 0.424 s |", "| 0.430 s |").is_some());
        assert!(table_drift("| 29 nm |", "| 28.0 nm |").is_some(), "a changed layout is drift");
        assert!(table_drift("| a | 1 |", "| b | 1 |").is_some());
    }

    #[test]
    fn figures_pass_within_two_and_fail_beyond() {
        let a = r#"<circle cx="100" cy="200" r="5"/><text>1.5</text>"#;
        assert!(figure_drift(a, r#"<circle cx="101" cy="198" r="5"/><text>1.5</text>"#).is_none());
        assert!(figure_drift(a, r#"<circle cx="104" cy="200" r="5"/><text>1.5</text>"#).is_some());
        assert!(figure_drift(a, r#"<rect cx="100" cy="200" r="5"/><text>1.5</text>"#).is_some());
    }
}
