//! `host-sim characterize`'s flags ([`CharacterizeOptions`]).

use host_sim::virtual_controller::characterize::CharacterizeOptions;
use std::path::PathBuf;

#[derive(clap::Args, Debug, Clone)]
pub struct CharacterizeArgs {
    /// The controller's GCS over TCP (e.g. `host-sim serve --tcp 127.0.0.1:50000`).
    #[arg(long, value_name = "ADDR:PORT", required_unless_present = "serial", conflicts_with = "serial")]
    pub tcp: Option<String>,
    /// The controller's GCS over a serial port (a board's ST-LINK port, or `host-sim serve --pty`).
    #[arg(long, value_name = "DEV")]
    pub serial: Option<PathBuf>,
    /// Baud rate of `--serial`.
    #[arg(long, default_value_t = 115_200)]
    pub baud: u32,
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
            tcp: a.tcp,
            serial: a.serial,
            baud: a.baud,
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
