//! `host-sim characterize`'s flags ([`CharacterizeOptions`]).

use host_sim::virtual_controller::characterize::CharacterizeOptions;
use std::path::PathBuf;

#[derive(clap::Args, Debug, Clone)]
pub struct CharacterizeArgs {
    /// How to reach the controller.
    #[command(flatten)]
    pub link: super::LinkArgs,
    /// Drive amplitudes (V peak-to-peak), comma-separated.
    #[arg(long, value_delimiter = ',', default_values_t = [60.0, 100.0], value_name = "V,V,...")]
    pub voltages_v: Vec<f64>,
    /// Drive frequencies (Hz), comma-separated.
    #[arg(long, value_delimiter = ',', default_values_t = [900.0, 1500.0, 2100.0], value_name = "HZ,HZ,...")]
    pub frequencies_hz: Vec<f64>,
    /// Drive senses, comma-separated (1, -1 or both).
    #[arg(long, value_delimiter = ',', allow_negative_numbers = true, default_values_t = [1, -1], value_name = "D,D")]
    pub directions: Vec<i8>,
    /// Weight hanging on the slider (N), pulling toward −x: it opposes the +x runs, whose rows
    /// carry it in the load column. Only the user knows it; the controller cannot measure it.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub load_n: f64,
    /// Durations of the short and the long burst (s).
    #[arg(long, value_delimiter = ',', default_values_t = [0.05, 0.2], value_name = "S,S")]
    pub burst_s: Vec<f64>,
    /// Largest change of the preload reading during the run (N); more stops the run.
    #[arg(long, default_value_t = 1.0)]
    pub preload_tolerance_n: f64,
    /// Add the rows to an existing file instead of writing a new one (e.g. after changing the
    /// preload by hand).
    #[arg(long)]
    pub append: bool,
    /// Output CSV file.
    #[arg(long, value_name = "FILE.csv")]
    pub out: PathBuf,
}

impl From<CharacterizeArgs> for CharacterizeOptions {
    fn from(a: CharacterizeArgs) -> Self {
        CharacterizeOptions {
            tcp: a.link.tcp,
            serial: a.link.serial,
            baud: a.link.baud,
            voltages_v: a.voltages_v,
            frequencies_hz: a.frequencies_hz,
            directions: a.directions,
            load_n: a.load_n,
            burst_s: a.burst_s,
            preload_tolerance_n: a.preload_tolerance_n,
            append: a.append,
            out: a.out,
        }
    }
}
