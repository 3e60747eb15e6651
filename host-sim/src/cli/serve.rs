//! `host-sim serve`'s flags (the library's [`serve::ServeArgs`], which has no clap).

use host_sim::virtual_controller::serve;
use std::path::PathBuf;

#[derive(clap::Args, Debug, Clone)]
pub struct ServeArgs {
    /// Listen for one GCS client at a time on this TCP address (e.g. 127.0.0.1:50000).
    #[arg(long, value_name = "ADDR:PORT")]
    pub tcp: Option<String>,
    /// Open a pseudo-terminal and print its path (a serial port for clients such as PIPython's
    /// `ConnectRS232`).
    #[arg(long)]
    pub pty: bool,
    /// Log every exchange (bytes in, bytes out) to stderr.
    #[arg(long)]
    pub verbose: bool,
    /// Preload force F0 of the simulated motor (N).
    #[arg(long, default_value_t = 16.0, allow_negative_numbers = true)]
    pub preload_n: f64,
    /// A weight hanging on the simulated slider, pulling toward −x (N), for `characterize
    /// --load-n` under load.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub load_n: f64,
    /// Encoder index mark at this slider position of the plant (µm; the slider starts at 0).
    #[arg(long, default_value_t = -20.0, allow_negative_numbers = true)]
    pub index_um: f64,
    /// Limit switches this far beyond the index on either side (mm).
    #[arg(long, default_value_t = 55.0, allow_negative_numbers = true)]
    pub limit_mm: f64,
    /// File for `WPA`: the board's flash parameter record, byte for byte, loaded at start-up;
    /// in memory when absent.
    #[arg(long, value_name = "FILE")]
    pub store: Option<PathBuf>,
    /// Stop after this many seconds (for tests); runs until killed when absent.
    #[arg(long, value_name = "S")]
    pub duration_s: Option<f64>,
    /// Parameter file the board's firmware was built for (its motor table and defaults, as
    /// `firmware-table` bakes them); the `--params` file when absent. With another file the plant
    /// (`--params`) plays a motor whose truth differs from what the firmware believes.
    #[arg(long, value_name = "FILE")]
    pub firmware_params: Option<PathBuf>,
}

impl From<ServeArgs> for serve::ServeArgs {
    fn from(a: ServeArgs) -> Self {
        serve::ServeArgs {
            tcp: a.tcp,
            pty: a.pty,
            verbose: a.verbose,
            preload_n: a.preload_n,
            load_n: a.load_n,
            index_um: a.index_um,
            limit_mm: a.limit_mm,
            store: a.store,
            duration_s: a.duration_s,
            firmware_params: a.firmware_params,
        }
    }
}
