//! `host-sim moves`'s flags ([`MovesOptions`]).

use host_sim::virtual_controller::gcs_moves::MovesOptions;

#[derive(clap::Args, Debug, Clone)]
pub struct MovesArgs {
    /// How to reach the controller.
    #[command(flatten)]
    pub link: super::LinkArgs,
    /// Length of each move (µm): out by it, back, out, …
    #[arg(long, default_value_t = 1000.0, allow_negative_numbers = true)]
    pub distance_um: f64,
    /// Number of moves.
    #[arg(long, default_value_t = 10)]
    pub count: usize,
    /// Record one point every this many control periods (`RTR`); the recorder's 1 024 points
    /// must cover a move and its settling (10: 1.02 s).
    #[arg(long, default_value_t = 10)]
    pub record_rate: u32,
    /// Print one JSON array instead of the table.
    #[arg(long)]
    pub json: bool,
}

impl From<MovesArgs> for MovesOptions {
    fn from(a: MovesArgs) -> Self {
        MovesOptions {
            tcp: a.link.tcp,
            serial: a.link.serial,
            baud: a.link.baud,
            distance_um: a.distance_um,
            count: a.count,
            record_rate: a.record_rate,
            json: a.json,
        }
    }
}
