//! `host-sim moves`'s flags ([`MovesOptions`]).

use host_sim::virtual_controller::gcs_moves::MovesOptions;
use std::path::PathBuf;

#[derive(clap::Args, Debug, Clone)]
pub struct MovesArgs {
    /// The controller's GCS over TCP (e.g. `host-sim serve --tcp 127.0.0.1:50000`).
    #[arg(long, value_name = "ADDR:PORT", required_unless_present = "serial", conflicts_with = "serial")]
    pub tcp: Option<String>,
    /// The controller's GCS over a serial port (a board's ST-LINK port, or `host-sim serve --pty`).
    #[arg(long, value_name = "DEV")]
    pub serial: Option<PathBuf>,
    /// Baud rate of `--serial`.
    #[arg(long, default_value_t = 115_200)]
    pub baud: u32,
    /// Length of each move (µm): out by it, back, out, …
    #[arg(long, default_value_t = 1000.0, allow_negative_numbers = true)]
    pub distance_um: f64,
    /// Number of moves.
    #[arg(long, default_value_t = 10)]
    pub count: usize,
    /// Record one point every this many control periods (`RTR`); the recorder's 360 points must
    /// cover a move and its settling.
    #[arg(long, default_value_t = 20)]
    pub record_rate: u32,
    /// Print one JSON array instead of the table.
    #[arg(long)]
    pub json: bool,
}

impl From<MovesArgs> for MovesOptions {
    fn from(a: MovesArgs) -> Self {
        MovesOptions {
            tcp: a.tcp,
            serial: a.serial,
            baud: a.baud,
            distance_um: a.distance_um,
            count: a.count,
            record_rate: a.record_rate,
            json: a.json,
        }
    }
}
