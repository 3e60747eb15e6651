//! `host-sim calibrate`'s flags ([`CalibrateOptions`]); the fitted file is the global `--params`.

use host_sim::virtual_controller::calibrate::CalibrateOptions;
use std::path::PathBuf;

#[derive(clap::Args, Debug, Clone)]
pub struct CalibrateArgs {
    /// The controller's GCS over TCP (e.g. `host-sim serve --tcp 127.0.0.1:50000`).
    #[arg(long, value_name = "ADDR:PORT", required_unless_present = "serial", conflicts_with = "serial")]
    pub tcp: Option<String>,
    /// The controller's GCS over a serial port (a board's ST-LINK port, or `host-sim serve --pty`).
    #[arg(long, value_name = "DEV")]
    pub serial: Option<PathBuf>,
    /// Baud rate of `--serial`.
    #[arg(long, default_value_t = 115_200)]
    pub baud: u32,
    /// Store the calibration in the controller's flash (`WPA`) after reading it back.
    #[arg(long)]
    pub save: bool,
    /// Print one JSON object instead of the table.
    #[arg(long)]
    pub json: bool,
}

impl From<CalibrateArgs> for CalibrateOptions {
    fn from(a: CalibrateArgs) -> Self {
        CalibrateOptions { tcp: a.tcp, serial: a.serial, baud: a.baud, save: a.save, json: a.json }
    }
}
