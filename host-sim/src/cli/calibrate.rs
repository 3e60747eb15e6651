//! `host-sim calibrate`'s flags ([`CalibrateOptions`]); the fitted file is the global `--params`.

use host_sim::virtual_controller::calibrate::CalibrateOptions;

#[derive(clap::Args, Debug, Clone)]
pub struct CalibrateArgs {
    /// How to reach the controller.
    #[command(flatten)]
    pub link: super::LinkArgs,
    /// Store the calibration in the controller's flash (`WPA`) after reading it back.
    #[arg(long)]
    pub save: bool,
    /// Print one JSON object instead of the table.
    #[arg(long)]
    pub json: bool,
    /// Choose the λ to upload by simulating the board on the fitted model (`--params`) first:
    /// the λ of a grid about the fitted one whose moves peak lowest. Needs the file the board's
    /// firmware was built for.
    #[arg(long, value_name = "FIRMWARE.toml")]
    pub tune: Option<std::path::PathBuf>,
    /// The board's preload in the tuning's simulation (N).
    #[arg(long, default_value_t = 16.0, requires = "tune")]
    pub tune_preload_n: f64,
}

impl From<CalibrateArgs> for CalibrateOptions {
    fn from(a: CalibrateArgs) -> Self {
        CalibrateOptions {
            tcp: a.link.tcp,
            serial: a.link.serial,
            baud: a.link.baud,
            save: a.save,
            json: a.json,
            tune: a.tune.map(|f| (f, a.tune_preload_n)),
        }
    }
}
