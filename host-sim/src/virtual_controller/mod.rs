//! The virtual controller: the simulated board behind PI's GCS over TCP or a pty (`serve`), a GCS
//! client, and the characterisation that drives a board through it.
pub mod characterize;
pub mod gcs_client;
pub mod serve;
