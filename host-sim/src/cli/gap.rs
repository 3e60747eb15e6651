//! `host-sim gap`'s flags ([`GapOptions`]).

use host_sim::gap::GapOptions;
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct GapArgs {
    /// Measured steady operating points (CSV: preload_n,voltage_v,frequency_hz,load_n,direction,velocity_mm_s).
    #[arg(long, value_name = "FILE.csv")]
    pub measured: PathBuf,
    /// Directory for the report, plots and the updated parameter file.
    #[arg(long, value_name = "DIR", default_value = "gap-report")]
    pub out: PathBuf,
    /// Print one JSON object instead of the summary.
    #[arg(long)]
    pub json: bool,
}

impl From<GapArgs> for GapOptions {
    fn from(a: GapArgs) -> Self {
        GapOptions { measured: a.measured, out: a.out, json: a.json }
    }
}
