//! The workflow's detection limits: for each library effect, the smallest size that it names
//! first with its size within 20 % on every noise seed, on the sourced plant's compact grid
//! (192 rows) at 1 % noise with `measure`'s noise model, for the 0.3, 1 and 5 kg carriages
//! (`cargo bench -p host-sim --bench gap_limits`). The size is bisected on a log scale between a
//! size too small to see and one the recovery bench names; each step runs the workflow once per
//! seed. Arguments: a filter on the row label (`-- "1 kg amplifier"`), `--seeds=N` (the first N
//! of [`SEEDS`], default 3), `--steps=N` (bisection steps, default 5: a factor of
//! (hi/lo)^(1/32) at the end), `--write` (rewrite the marked table of docs/model-gap.md with the
//! rows run). Cost: (steps + 1) × seeds workflow runs a row, 3–10 s each on two idle cores; the
//! full table (7 effects × 3 carriages, 3 seeds, 5 steps) is 378 runs, about 40 minutes.

use host_sim::gap::measure::{synthesize, Grid};
use host_sim::gap::measured_csv::{parse, to_csv_string};
use host_sim::gap::{analyze, Options};
use host_sim::motor::params::Params;
use std::time::Instant;

/// The noise seeds, in the order used.
const SEEDS: [u64; 5] = [101, 102, 103, 104, 105];

/// An effect's size knob: the parameter set in the truth (with any fixed companions), the range
/// bisected (the size at `weakest` is assumed too small to be named, `strongest` is checked), and
/// whether a larger value of the parameter is a weaker effect (a corner frequency).
struct Knob {
    effect: &'static str,
    param: &'static str,
    fixed: &'static [(&'static str, f64)],
    weakest: f64,
    strongest: f64,
}

const KNOBS: [Knob; 7] = [
    Knob { effect: "rail_friction", param: "rail_coulomb_n", fixed: &[], weakest: 0.002, strongest: 0.8 },
    Knob {
        effect: "assembly_asymmetry",
        param: "asymmetry_fraction",
        fixed: &[],
        weakest: 5e-4,
        strongest: 0.14,
    },
    Knob {
        effect: "preload_dependent_friction",
        param: "mu_drop_per_n",
        fixed: &[("knee_preload_n", 10.0)],
        weakest: 5e-4,
        strongest: 0.1,
    },
    Knob { effect: "stribeck_friction", param: "stribeck_rise", fixed: &[], weakest: 0.01, strongest: 3.0 },
    // The corner: 200 kHz is a 0.01 % loss at 2.1 kHz, 1.5 kHz more than half.
    Knob {
        effect: "amplifier_rolloff",
        param: "rolloff_corner_hz",
        fixed: &[],
        weakest: 200e3,
        strongest: 1500.0,
    },
    Knob {
        effect: "stator_resonance",
        param: "resonance_strength",
        fixed: &[],
        weakest: 0.003,
        strongest: 0.6,
    },
    Knob { effect: "hertz_contact", param: "hertz_exponent", fixed: &[], weakest: 0.003, strongest: 1.0 },
];

/// Whether every seed's run at `size` names the effect first with every hidden parameter fitted
/// within 20 %. Returns that and the runs' wall time.
fn named_at(knob: &Knob, mass_kg: f64, size: f64, seeds: &[u64]) -> (bool, f64) {
    let mut base = Params::prototype_sourced();
    base.slider.mass_kg = mass_kg;
    let mut truth = base.clone();
    let mut hidden: Vec<(&str, f64)> = vec![(knob.param, size)];
    hidden.extend(knob.fixed.iter().copied());
    for (k, v) in &hidden {
        truth.effects.set(k, *v).expect("a library parameter");
    }
    let t = Instant::now();
    let ok = seeds.iter().all(|&seed| {
        // Through the CSV `host-sim measure` writes, as a user's file would be.
        let rows = synthesize(&truth, &Grid::compact(), 1.0, seed, &|| {});
        let rows = parse(&to_csv_string(&rows)).expect("measure's CSV reads back");
        let r = analyze(&base, &rows, &Options::default(), &|_, _, _| {}).expect("workflow runs");
        r.named_effects.first().is_some_and(|e| e == knob.effect)
            && r.final_effects.iter().filter(|e| e.name == knob.effect).flat_map(|e| e.params.iter()).all(
                |p| {
                    hidden
                        .iter()
                        .find(|(k, _)| *k == p.name)
                        .is_none_or(|(_, v)| (p.value - v).abs() <= 0.2 * v.abs())
                },
            )
    });
    (ok, t.elapsed().as_secs_f64())
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let flag =
        |name: &str| args.iter().find_map(|a| a.strip_prefix(name)).and_then(|v| v.parse::<usize>().ok());
    let n_seeds = flag("--seeds=").unwrap_or(3).clamp(1, SEEDS.len());
    let steps = flag("--steps=").unwrap_or(5);
    let write = args.iter().any(|a| a == "--write");
    let filter = args.iter().find(|a| !a.starts_with("--"));
    let seeds = &SEEDS[..n_seeds];
    let mut table = String::from(
        "| carriage | effect | parameter | smallest size named first within 20 % | not named at | runs | s |\n\
         |---|---|---|---|---|---|---|\n",
    );
    for mass_kg in [0.3, 1.0, 5.0] {
        for knob in &KNOBS {
            let label = format!("{mass_kg} kg {}", knob.effect);
            if filter.is_some_and(|f| !label.contains(f.as_str())) {
                continue;
            }
            let (mut runs, mut secs) = (0, 0.0);
            let mut probe = |size: f64| {
                let (ok, s) = named_at(knob, mass_kg, size, seeds);
                runs += seeds.len();
                secs += s;
                eprintln!("{label}: {} = {size:.5}: {}", knob.param, if ok { "named" } else { "not named" });
                ok
            };
            // Bisection on the log of the size between a failing weak end and a passing strong
            // end (on a corner frequency "weaker" is higher).
            let (mut weak, mut strong) = (knob.weakest, knob.strongest);
            let row = if !probe(strong) {
                format!("not named at {strong}", strong = fmt(strong))
            } else {
                for _ in 0..steps {
                    let mid = (weak * strong).sqrt();
                    if probe(mid) {
                        strong = mid;
                    } else {
                        weak = mid;
                    }
                }
                fmt(strong)
            };
            let line = format!(
                "| {mass_kg} kg | `{}` | `{}` | {row} | {} | {runs} | {secs:.0} |\n",
                knob.effect,
                knob.param,
                if row.starts_with("not") { "—".to_string() } else { fmt(weak) }
            );
            print!("{line}");
            table.push_str(&line);
        }
    }
    let note = format!(
        "\nSeeds {:?}, {steps} bisection steps, the compact grid, 1 % noise (`measure`'s model).\n",
        seeds
    );
    println!("{note}");
    if write {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/model-gap.md");
        let doc = std::fs::read_to_string(path).expect("docs/model-gap.md");
        let (open, close) = ("<!-- gap-limits -->\n", "<!-- /gap-limits -->");
        let (Some(a), Some(b)) = (doc.find(open), doc.find(close)) else {
            panic!("docs/model-gap.md has no {open:?} … {close:?} block");
        };
        let new = format!("{}{open}{table}{note}{}", &doc[..a], &doc[b..]);
        std::fs::write(path, new).expect("write docs/model-gap.md");
    }
}

/// A size with three significant digits.
fn fmt(v: f64) -> String {
    let decimals = (2 - v.abs().log10().floor() as i32).max(0) as usize;
    format!("{v:.decimals$}")
}
