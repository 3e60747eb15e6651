//! Loop harnesses: the firmware's control core against the plant, on the host (SIL, the moves
//! and the demo, the sweep over carriages) and on QEMU's Cortex-M4F (PIL).
pub mod contact_table;
pub mod moves;
pub mod pil;
pub mod pil_locks;
pub mod sil;
pub mod sweep;
