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
}

impl From<CalibrateArgs> for CalibrateOptions {
    fn from(a: CalibrateArgs) -> Self {
        CalibrateOptions {
            tcp: a.link.tcp,
            serial: a.link.serial,
            baud: a.link.baud,
            save: a.save,
            json: a.json,
        }
    }
}
