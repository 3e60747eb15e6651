//! host-sim: the physical plant of the shaking-beam piezo motor, its steady-state thrust model,
//! and the command-line tools around them. One folder per job:
//! - [`motor`]: the motor models (parameters, time-domain plant, steady-state models, effects);
//! - [`harness`]: the loops that run the firmware's control core against the plant (SIL, the
//!   moves and the demo, PIL on the emulated Cortex-M4F);
//! - [`virtual_controller`]: the board over GCS (`serve`), its client and the characterisation
//!   that drives a board over it;
//! - [`gap`]: the model-gap workflow (measured data, calibration, named effects);
//! - and beside them the figures and command-line checks (`curve`, `paper`, `trace`, `plot`, …).
pub mod gap;
pub mod harness;
pub mod motor;
pub mod virtual_controller;

pub mod check;
pub mod curve;
pub mod model_grid;
pub mod paper;
pub mod plant_figures;
pub mod plot;
pub mod readme_figures;
pub mod trace;
