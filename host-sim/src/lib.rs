//! host-sim: the physical plant of the shaking-beam piezo motor, its steady-state thrust model,
//! and the command-line tools around them.
pub mod characterize;
pub mod check;
pub mod curve;
pub mod effects;
pub mod gap;
pub mod gcs_client;
pub mod measure;
pub mod measured_csv;
pub mod moves;
pub mod paper;
pub mod params;
pub mod pil;
pub mod plant;
pub mod plant_figures;
pub mod plot;
pub mod readme_figures;
pub mod roots;
pub mod serve;
pub mod sil;
pub mod steady;
pub mod steady_inertia;
pub mod trace;
