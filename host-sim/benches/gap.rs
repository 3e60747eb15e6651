//! Wall time of the whole model-gap workflow on a 300-row file with the full effect library
//! (`cargo bench -p host-sim --bench gap`): on the heavy-slider set with the constant-speed base,
//! and on the sourced plant's 1 kg carriage with the contact base (`[model] steady =
//! "contact"`). Not a criterion bench: one run of the workflow takes seconds to minutes, and the
//! figure the issue asks for is its absolute wall time.

use host_sim::gap::measure::{synthesize, Grid};
use host_sim::gap::{analyze, Options};
use host_sim::motor::params::Params;
use std::time::Instant;

fn main() {
    // `cargo bench` passes `--bench`; anything else (e.g. a filter) is ignored.
    let mut truth = Params::heavy_slider();
    truth.effects.set("rail_coulomb_n", 0.4).expect("known parameter");
    truth.effects.set("rolloff_corner_hz", 2500.0).expect("known parameter");
    let grid = Grid::paper();
    let t = Instant::now();
    let rows = synthesize(&truth, &grid, 1.0, 7, &|| {});
    let synth_s = t.elapsed().as_secs_f64();
    let mut base = Params::heavy_slider();
    base.friction.mu_dynamic *= 1.1;
    base.friction.mu_static *= 1.1;
    base.stator.tangential_scale *= 0.9;
    base.stator.normal_force_ratio *= 1.1;
    let threads = rayon::current_num_threads();
    let t = Instant::now();
    let r = analyze(&base, &rows, &Options::default(), &|_, _, _| {}).expect("workflow runs");
    let s = t.elapsed().as_secs_f64();
    println!(
        "gap workflow: {} rows, full library ({} effects), {threads} threads: {s:.2} s wall \
         (synthetic data from the plant: {synth_s:.2} s); named {:?}, gap {:.4} -> {:.4}",
        rows.len(),
        Options::default().library.len(),
        r.named_effects,
        r.gap_before,
        r.gap_after
    );
    // The same two hidden effects on the 1 kg carriage, the contact model as the base.
    let mut truth = Params::prototype_sourced();
    truth.effects.set("rail_coulomb_n", 0.4).expect("known parameter");
    truth.effects.set("rolloff_corner_hz", 2500.0).expect("known parameter");
    let rows = synthesize(&truth, &grid, 1.0, 7, &|| {});
    let t = Instant::now();
    let r = analyze(&Params::prototype_sourced(), &rows, &Options::default(), &|_, _, _| {})
        .expect("workflow runs");
    let s = t.elapsed().as_secs_f64();
    println!(
        "gap workflow, contact base (1 kg carriage): {} rows, {threads} threads: {s:.2} s wall; named {:?}, \
         gap {:.4} -> {:.4}",
        rows.len(),
        r.named_effects,
        r.gap_before,
        r.gap_after
    );
}
