//! The virtual controller: the simulated board behind PI's GCS over TCP or a pty (`serve`), a GCS
//! client, the characterisation that drives a board through it, and the upload of a fitted model.
pub mod calibrate;
pub mod characterize;
pub mod gcs_client;
pub mod gcs_moves;
pub mod serve;
