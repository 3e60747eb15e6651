//! What a command's handler works with and returns ([`GcsResult`]): a command that acts on the
//! controller gets a [`Call`] (run with the controller locked), a query a [`Query`] (a
//! [`Snapshot`] taken under the lock, answered without it), a settings command a [`Settings`]
//! (a copy of the settings to change; the board sets them under the lock afterwards). Shared by
//! the command table (`commands.rs`) and the handler groups, which depend on this file only.

use super::framing::Out;
use super::snapshot::Snapshot;
use super::Board;
use crate::controller::{Controller, ControllerConfig};

/// What a line command that acts on the controller works with: its arguments (the tokens after
/// the name), the controller and the board. Such a command replies nothing (GCS).
pub(super) struct Call<'c> {
    pub(super) args: &'c [&'c [u8]],
    pub(super) ctl: &'c mut Controller,
    pub(super) board: &'c mut dyn Board,
}

/// What a query works with: its arguments, the controller as the snapshot shows it (it cannot
/// change the controller), the board and the reply under construction.
pub(super) struct Query<'c, 'r> {
    pub(super) args: &'c [&'c [u8]],
    pub(super) ctl: &'c Snapshot,
    pub(super) board: &'c dyn Board,
    pub(super) out: &'c mut Out<'r>,
}

/// What a settings command works with: its arguments and the settings to change (it checks
/// them with [`crate::controller::validate_settings`]; it replies nothing).
pub(super) struct Settings<'c> {
    pub(super) args: &'c [&'c [u8]],
    pub(super) cfg: &'c mut ControllerConfig,
}

pub(super) type Handler = fn(&mut super::Gcs, Call) -> GcsResult;
pub(super) type QueryHandler = fn(&mut super::Gcs, Query) -> GcsResult;
pub(super) type SettingsHandler = fn(&mut super::Gcs, Settings) -> GcsResult;

pub(super) type GcsResult = Result<(), i32>;
