//! Board-independent logic of the firmware's safety layer (issue 16), kept free of registers so
//! it is tested on the host (`tests/safety.rs`): the firmware (`src/firmware/`) only moves
//! register values in and out of these.
//!
//! - [`timing`]: control-tick lateness measured on a free-running counter of the core clock,
//!   with a leaky bucket that latches an overrun fault;
//! - [`soft_start`]: the amplifier's enable ramp from its rest level (no 0 → 50 V step);
//! - [`fault_record`]: the last fault kept in no-init RAM across a reset (magic + CRC-32);
//! - [`probe`]: a floating (unconnected) preload input, from readings after weak pulls;
//! - [`watchdog`]: window-watchdog reload values from a timeout;
//! - [`flash_ecc`]: whether a flash ECC error hit the parameter pages;
//! - [`tick`]: the control tick's order of operations over the board's peripherals.

pub mod fault_record;
pub mod flash_ecc;
pub mod probe;
pub mod soft_start;
pub mod tick;
pub mod timing;
pub mod watchdog;
