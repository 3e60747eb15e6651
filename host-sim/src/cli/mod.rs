//! The command line: every clap type of `host-sim` (the library takes plain option structs and
//! enums; each argument struct here converts into its library counterpart). Used by `main.rs`
//! only.

pub mod calibrate;
pub mod characterize;
pub mod gap;
pub mod measure;
pub mod moves;
pub mod pil;
pub mod readme_figures;
pub mod serve;

use anyhow::Result;
use clap::{Parser, Subcommand};
use host_sim::check;
use host_sim::motor::params::{FrictionModel, Params};
use host_sim::motor::steady::OperatingPoint;
use std::path::PathBuf;

#[derive(Parser)]
#[command(name = "host-sim", version, about = "Simulator of the non-resonant shaking-beam piezo motor")]
pub struct Cli {
    /// Parameter file (TOML); the compiled-in prototype set when absent.
    #[arg(long, global = true, value_name = "FILE")]
    pub params: Option<PathBuf>,
    /// Moving mass of the slider and its payload (kg); overrides the file's `slider.mass_kg`.
    #[arg(long, global = true, value_name = "KG", allow_negative_numbers = true)]
    pub slider_mass_kg: Option<f64>,
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand)]
pub enum Command {
    /// Thrust–velocity characteristic: steady-state model and time-domain plant side by side.
    Curve {
        #[command(flatten)]
        point: PointArgs,
        /// Number of load points from 0 to 90 % of stall.
        #[arg(long, default_value_t = 8)]
        points: usize,
        /// Friction law of the time-domain plant.
        #[arg(long, value_enum)]
        friction: Option<FrictionArg>,
        /// Print one JSON object instead of the table.
        #[arg(long)]
        json: bool,
        /// Also draw the curve to this SVG file.
        #[arg(long, value_name = "FILE.svg")]
        plot: Option<PathBuf>,
    },
    /// The steady-state models against the plant over issue 28's grid (0.1–50 kg, 5–18 N,
    /// 1.5/2.2 kHz, loads 0/35/70 % of stall, 100 V): each model's worst error per carriage in %
    /// of the plant's no-load speed. Use `--params host-sim/params/prototype-sourced.toml` for the
    /// sourced plant. About 2 s on 2 cores.
    ModelGrid {
        /// Print every grid point as JSON instead of the table.
        #[arg(long)]
        json: bool,
    },
    /// The paper's figures (physics.md §5, in ../shared/ beside the checkout): theirs, ours, the
    /// band we hold, pass/fail.
    Paper {
        /// Print one JSON array of rows {name, paper, ours, unit, tolerance, pass, plant,
        /// plant_pass}: `paper` is the paper's figure as text, `ours` the model's value in `unit`,
        /// `tolerance` the band we hold, `plant`/`plant_pass` only where measured on the plant.
        #[arg(long)]
        json: bool,
        /// Evaluate the steady-state model and the stator's modes only (skip the plant runs).
        #[arg(long)]
        model_only: bool,
    },
    /// One drive period of the plant, sample by sample: foot normal and tangential motion, contact
    /// and friction force, foot and slider speed (after the plant has settled at the drive point).
    Trace {
        #[command(flatten)]
        point: PointArgs,
        /// Constant load opposing the motion (N), as a hanging weight.
        #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
        load_n: f64,
        /// Trace these slider masses side by side (kg, comma-separated) instead of the file's.
        #[arg(long, value_delimiter = ',', value_name = "KG,KG,...", allow_negative_numbers = true)]
        masses_kg: Vec<f64>,
        /// Print one JSON object (every sample) instead of the summary.
        #[arg(long)]
        json: bool,
        /// Also draw the period to this SVG file.
        #[arg(long, value_name = "FILE.svg")]
        plot: Option<PathBuf>,
    },
    /// One closed-loop move from 0: the firmware's controller against the plant.
    Move {
        /// Target position (µm).
        #[arg(long, allow_negative_numbers = true)]
        to_um: f64,
        /// Preload force F0 (N).
        #[arg(long, default_value_t = 16.0, allow_negative_numbers = true)]
        preload_n: f64,
        /// Constant load opposing the motion (N), as a hanging weight; a negative value pushes
        /// the slider along the move instead (an assisting load).
        #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
        load_n: f64,
        /// Switch the thrust-model feedforward off (plain feedback).
        #[arg(long)]
        no_feedforward: bool,
        /// Tell the controller the load beforehand (otherwise its observer finds it while moving).
        #[arg(long)]
        load_known: bool,
        /// Print one JSON object (settle_time_s, final_error_nm, overshoot_nm, slide_back_nm,
        /// max_following_error_um, fault, ...) instead of the summary.
        #[arg(long)]
        json: bool,
        /// Also draw position, reference and drive voltage against time to this SVG file.
        #[arg(long, value_name = "FILE.svg")]
        plot: Option<PathBuf>,
    },
    /// The main job: a scripted closed-loop sequence (long move, 10 µm / 1 µm / 100 nm steps, a
    /// move against 2 N, a preload change while holding, an out-of-window preload refused),
    /// printed as a table and drawn to demo.svg (ignored by git); then the thrust–velocity
    /// characteristic.
    Demo {
        /// Where to draw the sequence (position, reference, drive voltage against time).
        #[arg(long, value_name = "FILE.svg", default_value = "demo.svg")]
        plot: PathBuf,
    },
    /// The controller across carriages: the file's own and 0.1, 0.3, 1, 5 and 50 kg, each with
    /// seven rows: a 1 mm move; 100 nm, 1 µm and 10 µm steps; 1 mm against an unknown 2 N; 1 mm
    /// against an unknown 70 % of that plant's stall force (the highest it has over 0.5–2.2 kHz);
    /// 1 mm against a known 2 N with plain PI. Each row: load, settle time, its ratio to the
    /// plant's physical limit, overshoot, peak following error, the drive frequency chosen, fault.
    Sweep {
        /// Print one JSON array of rows instead of the table.
        #[arg(long)]
        json: bool,
        /// Preload of every case (N); the controller refuses one outside its window.
        #[arg(long, default_value_t = host_sim::harness::sweep::DEFAULT_PRELOAD_N)]
        preload_n: f64,
        /// The controller's model table: `core` (its own build, as on the board) or `contact`
        /// (host-sim's contact model of each carriage: what a model that is the motor gives the
        /// controller; too costly for the board, and slow).
        #[arg(long, value_enum, default_value_t = TableModelArg::Core)]
        model: TableModelArg,
    },
    /// Processor in the loop: one closed-loop move with the control core running on an emulated
    /// Cortex-M4F (QEMU) against the plant; instruction counts per tick and per state, and every
    /// period whose outputs differ from the host build's.
    Pil(pil::PilArgs),
    /// Regenerate every figure in docs/ and every table of the README from the code (the README's
    /// marked tables are rewritten in place); `--check` compares instead and fails on drift.
    ReadmeFigures(readme_figures::ReadmeFiguresArgs),
    /// Print the firmware's baked motor table for the parameter file, as Rust source:
    /// `host-sim firmware-table > src/motor_table.rs` after changing the motor's parameters.
    FirmwareTable,
    /// The virtual controller: the core against the plant in real time, speaking PI GCS 2.0 over
    /// TCP or a pty (see the README's UART commands section).
    Serve(serve::ServeArgs),
    /// Model-gap workflow: calibrate to measured speeds, name the missing effects, report.
    Gap(gap::GapArgs),
    /// Synthetic measured data from the plant with hidden effects (the gap workflow's input).
    Measure(measure::MeasureArgs),
    /// A board (or `serve`) measures its own thrust–speed points over GCS: open-loop bursts,
    /// written as the gap workflow's CSV.
    Characterize(characterize::CharacterizeArgs),
    /// Upload a fitted model (`--params params-fitted.toml` from `gap`) to a board or `serve`:
    /// friction coefficient, tangential scale, normal force ratio and guide friction, in one
    /// `SPA` line, read back with `SPA?`; effects the firmware does not carry are listed.
    Calibrate(calibrate::CalibrateArgs),
    /// Back-and-forth closed-loop moves on a board or `serve` over GCS, each watched by the
    /// controller's data recorder: peak following error and settle time per move.
    Moves(moves::MovesArgs),
}

/// The controller a GCS client command talks to (`characterize`, `calibrate`, `moves`).
#[derive(clap::Args, Debug, Clone)]
pub struct LinkArgs {
    /// The controller's GCS over TCP (e.g. `host-sim serve --tcp 127.0.0.1:50000`).
    #[arg(long, value_name = "ADDR:PORT", required_unless_present = "serial", conflicts_with = "serial")]
    pub tcp: Option<String>,
    /// The controller's GCS over a serial port (a board's ST-LINK port, or `host-sim serve --pty`).
    #[arg(long, value_name = "DEV")]
    pub serial: Option<std::path::PathBuf>,
    /// Baud rate of `--serial`.
    #[arg(long, default_value_t = 115_200)]
    pub baud: u32,
}

#[derive(clap::Args)]
pub struct PointArgs {
    /// Preload force F0 (N).
    #[arg(long, default_value_t = 16.0, allow_negative_numbers = true)]
    pub preload_n: f64,
    /// Peak-to-peak stack voltage (V); 100 = the full 0–100 V swing.
    #[arg(long, default_value_t = 100.0, allow_negative_numbers = true)]
    pub voltage_v: f64,
    /// Drive frequency (Hz).
    #[arg(long, default_value_t = 1500.0, allow_negative_numbers = true)]
    pub frequency_hz: f64,
    /// Drive direction: +1 or -1 (sign of the quarter-period shift).
    #[arg(long, default_value_t = 1, allow_negative_numbers = true)]
    pub direction: i8,
}

impl PointArgs {
    pub fn validate(&self, p: &Params) -> Result<OperatingPoint> {
        let range = p.amplifier.output_max_v - p.amplifier.output_min_v;
        let op = OperatingPoint {
            preload_n: check::preload_n("--preload-n", self.preload_n)?,
            voltage_v: check::voltage_v("--voltage-v", self.voltage_v, range)?,
            frequency_hz: check::frequency_hz("--frequency-hz", self.frequency_hz, p.amplifier.dac_rate_hz)?,
        };
        check::direction("--direction", i64::from(self.direction))?;
        Ok(op)
    }
}

/// `sweep --model`: where the controller's model table comes from
/// ([`host_sim::harness::contact_table::TableModel`], whose contact variant carries a file).
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum TableModelArg {
    /// The core's own build, as on the board.
    Core,
    /// Host-sim's contact model of each carriage.
    Contact,
    /// The core's own build from its contact model (setting 0x1024 = 1), as on a board told to.
    CoreContact,
}

/// `--friction`: the friction law of the time-domain plant ([`FrictionModel`], which has no clap
/// in the library).
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum FrictionArg {
    /// Seed eq. (16): Coulomb with μd and a viscous part εc; stick solved exactly.
    Coulomb,
    /// Stick holds up to μs·Fc, slip at μd·Fc (interface paper, Fig. 1b).
    StaticDynamic,
    /// LuGre bristle model (interface paper, Fig. 1d).
    Lugre,
}

impl From<FrictionArg> for FrictionModel {
    fn from(a: FrictionArg) -> Self {
        match a {
            FrictionArg::Coulomb => FrictionModel::Coulomb,
            FrictionArg::StaticDynamic => FrictionModel::StaticDynamic,
            FrictionArg::Lugre => FrictionModel::Lugre,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::pil::FaultArg;
    use super::*;
    use clap::ValueEnum;
    use host_sim::harness::pil::FaultCase;

    /// Each mirror has one flag value per library value: its `From` is one-to-one, and the
    /// matches below (exhaustive over the library's enums) stop compiling when the library gains a
    /// value the CLI cannot name.
    #[test]
    fn every_library_value_has_one_flag_value() {
        let friction = |m: FrictionModel| match m {
            FrictionModel::Coulomb => FrictionArg::Coulomb,
            FrictionModel::StaticDynamic => FrictionArg::StaticDynamic,
            FrictionModel::Lugre => FrictionArg::Lugre,
        };
        for a in FrictionArg::value_variants() {
            assert_eq!(friction(FrictionModel::from(*a)), *a);
        }
        let fault = |f: FaultCase| match f {
            FaultCase::EncoderJump => FaultArg::EncoderJump,
            FaultCase::EncoderLoss => FaultArg::EncoderLoss,
            FaultCase::PreloadLoss => FaultArg::PreloadLoss,
            FaultCase::Stall => FaultArg::Stall,
            FaultCase::FrfIntoStop => FaultArg::FrfIntoStop,
            FaultCase::EncoderJitter => FaultArg::EncoderJitter,
            FaultCase::LimitHit => FaultArg::LimitHit,
        };
        for a in FaultArg::value_variants() {
            assert_eq!(fault(FaultCase::from(*a)), *a);
        }
    }
}
