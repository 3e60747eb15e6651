//! The virtual controller: the simulated board behind PI's GCS over TCP or a pty (`serve`), a GCS
//! client, the replay of EPICS motorPIGCS2's transcript, the characterisation that drives a board through it, the upload of a fitted model, and
//! the choice of λ for the board by simulating it on that model (`calibrate --tune`).
pub mod calibrate;
pub mod calibration;
pub mod characterize;
pub mod epics_replay;
pub mod gcs_client;
pub mod gcs_moves;
pub mod serve;
pub mod tune;
