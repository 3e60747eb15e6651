//! `host-sim measure`'s flags ([`MeasureOptions`]).

use host_sim::gap::measure::MeasureOptions;
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct MeasureArgs {
    /// Hidden effect, NAME:param=value[,param=value]; repeat for several.
    #[arg(long = "effect", value_name = "NAME:param=value")]
    pub effects: Vec<String>,
    /// Measurement noise, percent of each speed (plus a floor of a quarter of the mean speed).
    #[arg(long, default_value_t = 1.0, allow_negative_numbers = true)]
    pub noise_pct: f64,
    /// Random seed of the noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Grid of operating points: `paper` (300 rows) or `compact` (192 rows).
    #[arg(long, default_value = "paper")]
    pub grid: String,
    /// Override the grid's preloads (N), comma-separated.
    #[arg(long, value_delimiter = ',', value_name = "N,N,...")]
    pub preloads_n: Option<Vec<f64>>,
    /// Override the grid's voltages (V peak-to-peak).
    #[arg(long, value_delimiter = ',', value_name = "V,V,...")]
    pub voltages_v: Option<Vec<f64>>,
    /// Override the grid's frequencies (Hz).
    #[arg(long, value_delimiter = ',', value_name = "HZ,HZ,...")]
    pub frequencies_hz: Option<Vec<f64>>,
    /// Override the loads, as fractions of the stall force at each drive point (0 to <1).
    #[arg(long, value_delimiter = ',', value_name = "F,F,...")]
    pub load_fractions: Option<Vec<f64>>,
    /// Override the drive senses (1, -1 or both).
    #[arg(long, value_delimiter = ',', allow_negative_numbers = true, value_name = "D,D")]
    pub directions: Option<Vec<i8>>,
    /// Output CSV file.
    #[arg(long, value_name = "FILE.csv")]
    pub out: PathBuf,
}

impl From<MeasureArgs> for MeasureOptions {
    fn from(a: MeasureArgs) -> Self {
        MeasureOptions {
            effects: a.effects,
            noise_pct: a.noise_pct,
            seed: a.seed,
            grid: a.grid,
            preloads_n: a.preloads_n,
            voltages_v: a.voltages_v,
            frequencies_hz: a.frequencies_hz,
            load_fractions: a.load_fractions,
            directions: a.directions,
            out: a.out,
        }
    }
}
