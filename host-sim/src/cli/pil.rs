//! `host-sim pil`'s flags: the run's options ([`PilOptions`]) plus where the ELF comes from, the
//! instruction budget and the output.

use host_sim::harness::pil::{FaultCase, PilOptions};
use std::path::PathBuf;

// No doc comment: the `Pil` variant's is the subcommand's about text.
#[derive(clap::Args, Debug, Clone)]
pub struct PilArgs {
    /// Target position (µm).
    #[arg(long, allow_negative_numbers = true, required_unless_present = "gcs_locks")]
    pub to_um: Option<f64>,
    /// Preload force F0 (N).
    #[arg(long, default_value_t = 16.0, allow_negative_numbers = true)]
    pub preload_n: f64,
    /// Constant load opposing the motion (N), as a hanging weight; not told to the controller.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub load_n: f64,
    /// Provoke a fault during the move and check the drive goes safe on the target.
    #[arg(long, value_enum)]
    pub fault: Option<FaultArg>,
    /// The target program (default: build `tools/pil` of this checkout and use its ELF).
    #[arg(long, value_name = "ELF")]
    pub elf: Option<PathBuf>,
    /// Exit with an error when the tick's instructions exceed these (mean, max).
    #[arg(long, num_args = 2, value_names = ["MEAN", "MAX"])]
    pub budget: Option<Vec<u32>>,
    /// After the move has settled, also reference on an encoder index 50 µm behind the start
    /// (GCS `FRF`) and, servo off, step 300 drive cycles open loop back (GCS `XOS`, 80 V,
    /// 1.5 kHz), so that every state of the tick runs on the target against the plant.
    #[arg(long)]
    pub all_states: bool,
    /// Build the controller's model table from the contact model (setting 0x1024 = 1, sent to
    /// the target over GCS before the move): the JSON's `table_model` and
    /// `table_build_instructions` then give the board's contact build on the M4.
    #[arg(long)]
    pub contact_table: bool,
    /// Instead of the move: send every GCS command the firmware knows to the core on the
    /// emulated M4, between control periods against the plant, and print the instructions of
    /// each section it runs with the controller locked (the tick held off on the board).
    #[arg(long, conflicts_with_all = ["to_um", "fault", "budget", "all_states"])]
    pub gcs_locks: bool,
    /// With --gcs-locks: exit with an error when a locked section exceeds this many
    /// instructions [default: 3000].
    #[arg(long)]
    pub lock_budget: Option<u32>,
    /// Print one JSON object instead of the summary.
    #[arg(long)]
    pub json: bool,
}

impl PilArgs {
    /// The library's options of the run.
    pub fn options(&self) -> PilOptions {
        PilOptions {
            to_um: self.to_um.unwrap_or(0.0),
            preload_n: self.preload_n,
            load_n: self.load_n,
            fault: self.fault.map(FaultCase::from),
            all_states: self.all_states,
            contact_table: self.contact_table,
        }
    }
}

/// `--fault`: [`FaultCase`] as a flag value.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum FaultArg {
    /// The encoder count jumps by 5000 counts (250 µm) 20 ms into the move.
    EncoderJump,
    /// The encoder stops counting 20 ms into the move (the coarse mode's encoder-loss watch).
    EncoderLoss,
    /// The preload falls to 2 N (below the window) 20 ms into the move.
    PreloadLoss,
    /// A load of twice the stall force opposes the move from the start.
    Stall,
    /// Referencing toward a hard end stop 100 µm on the −x side (the index 1 mm on the +x side,
    /// no limit switches): the drive must go safe.
    FrfIntoStop,
    /// One encoder channel lost 20 ms into the move, the other toggling (the count flickers).
    EncoderJitter,
    /// Open-loop stepping toward a limit switch at 100 µm: the run ends at the switch.
    LimitHit,
}

impl From<FaultArg> for FaultCase {
    fn from(a: FaultArg) -> Self {
        match a {
            FaultArg::EncoderJump => FaultCase::EncoderJump,
            FaultArg::EncoderLoss => FaultCase::EncoderLoss,
            FaultArg::PreloadLoss => FaultCase::PreloadLoss,
            FaultArg::Stall => FaultCase::Stall,
            FaultArg::FrfIntoStop => FaultCase::FrfIntoStop,
            FaultArg::EncoderJitter => FaultCase::EncoderJitter,
            FaultArg::LimitHit => FaultCase::LimitHit,
        }
    }
}
