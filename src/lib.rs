//! Control core of the piezo-drive firmware: `no_std`, no HAL, no allocation.
//!
//! The firmware (`src/main.rs`) and the simulator (`host-sim`) run this very code:
//! - [`generator`]: quadrature sine (and static) DAC words for the two stacks;
//! - [`sensors`]: encoder unwrapping, preload force cell;
//! - [`model`]: fixed-point steady-state thrust model and its inverse (the feedforward);
//! - [`inertia`]: the same model for a carriage whose speed ripples within a period (f32);
//! - [`normal_motion`], [`contact_orbit`]: the stator's normal motion and the carriage's orbit
//!   under its contact force (f32, issue 28; not yet in the board's table build);
//! - [`profile`]: online trapezoidal motion profile;
//! - [`controller`]: state machine, position control, supervision; one entry point `step`;
//! - [`settings`]: every controller setting declared once (id, unit, range, default, storage);
//! - [`storage`]: the flash parameter record (encode/decode with version and CRC);
//! - [`param_store`]: that record in two flash pages, so a power cut never loses the last one;
//! - [`recorder`]: the data recorder (`DRC`/`DRT`/`RTR`/`DRR?`): record tables filled each tick;
//! - [`gcs`]: the PI GCS 2.0 command protocol (UART on the board, TCP or a pty in `host-sim serve`);
//! - [`defaults`]: the firmware's default settings, with the baked motor table [`motor_table`].
#![no_std]
#![deny(clippy::unwrap_used, clippy::expect_used, clippy::panic, clippy::indexing_slicing)]

pub mod config;
pub mod contact_motor;
pub mod contact_orbit;
pub mod controller;
pub mod defaults;
pub mod fastmath;
pub mod gcs;
pub mod generator;
pub mod hardware;
pub mod inertia;
pub mod model;
pub mod motor_table;
pub mod normal_motion;
pub mod param_store;
pub mod pil_wire;
pub mod profile;
pub mod recorder;
pub mod safety;
pub mod sensors;
pub mod settings;
pub mod storage;
pub mod trig;

/// The core's fixed-point number: 16 integer bits, 16 fraction bits (resolution 1.5e-5).
pub type Fx = fixed::types::I16F16;
