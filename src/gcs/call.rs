//! What a line command's handler works with ([`Call`]) and returns ([`GcsResult`]): shared by
//! the command table (`commands.rs`) and the handler groups, which depend on this file only.

use super::framing::Out;
use super::Board;
use crate::controller::Controller;

/// What a line command works with: its arguments (the tokens after the name), the controller,
/// the board and the reply under construction.
pub(super) struct Call<'c, 'r> {
    pub(super) args: &'c [&'c [u8]],
    pub(super) ctl: &'c mut Controller,
    pub(super) board: &'c mut dyn Board,
    pub(super) out: &'c mut Out<'r>,
}

pub(super) type Handler = fn(&mut super::Gcs, Call) -> GcsResult;

pub(super) type GcsResult = Result<(), i32>;
