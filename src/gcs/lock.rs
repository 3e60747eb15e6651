//! What runs while the board holds the controller's lock (on the firmware: the control tick
//! masked) for each command: [`Gcs::execute_shared`]. The firmware's UART task, `host-sim serve`
//! (through [`Gcs::execute`]) and the processor-in-the-loop image (`tools/pil`, which counts the
//! instructions of every locked section: `host-sim pil --gcs-locks`) all run commands through
//! it, so what is measured is what the board runs.
//!
//! The line is split and its command looked up first, without the lock. Then, by command
//! (see [`Gcs::is_read_only`], [`Gcs::is_settings_only`]):
//! - a query (`…?`, #5, #7, and what only latches an error) takes a [`Snapshot`] under the
//!   lock (the settings and the state's scalars, not the 3 KiB controller) and is answered from
//!   it without the lock; `XTM?`'s snapshot also holds what its thrust limits read (they may
//!   evaluate the model, so they are evaluated from it, off the lock);
//! - a settings command (`SPA`, `VEL`, `ACC`, `DEC`) takes the same snapshot, is parsed and
//!   checked on a copy of its settings and prepared as a `ConfigChange` without the lock, and
//!   only `Controller::apply_config` (copying it in) runs under it again (when the settings
//!   changed);
//! - every other command runs under the lock (its handler: check and act; #24).

use super::commands::{Parsed, Shape};
use super::framing::Out;
use super::snapshot::Snapshot;
use super::{error, Board, Gcs, Pending, Reply};
use crate::controller::{ConfigChange, Controller};

/// The controller as a board shares it with its control tick.
pub trait SharedController {
    /// Runs `f` on the controller with the tick held off: the locked section. `None` (and `f`
    /// not run) when the controller cannot be had (not installed yet, or already locked).
    fn lock<R>(&mut self, f: impl FnOnce(&mut Controller) -> R) -> Option<R>;
}

/// A controller no tick shares (`host-sim serve`, tests): locking it is a plain borrow.
pub struct Unshared<'a>(pub &'a mut Controller);

impl SharedController for Unshared<'_> {
    fn lock<R>(&mut self, f: impl FnOnce(&mut Controller) -> R) -> Option<R> {
        Some(f(self.0))
    }
}

impl Gcs {
    /// Executes `pending` against a shared controller, locking it as little as the command
    /// allows (see the module), and appends the reply bytes (possibly none). Nothing is
    /// executed and nothing answered when the controller cannot be locked.
    pub fn execute_shared(
        &mut self,
        pending: &Pending,
        shared: &mut impl SharedController,
        board: &mut dyn Board,
        reply: &mut Reply,
    ) {
        let parsed = Parsed::of(pending);
        let thrust = parsed.needs_thrust();
        match parsed.shape() {
            Shape::Query => {
                // `XTM?`'s snapshot also copies what its thrust limits read; they are evaluated
                // from it without the lock (without a fitting table, a model point: 3 400
                // instructions on the M4).
                let Some(snap) = shared.lock(|ctl| Snapshot::take(ctl, thrust)) else { return };
                self.run_query(&parsed, &snap, board, Out::new(reply));
            }
            Shape::Settings => {
                let Some(snap) = shared.lock(|ctl| Snapshot::take(ctl, false)) else { return };
                let start = reply.len();
                if let Some(new) = self.run_settings(&parsed, &snap, board, Out::new(reply)) {
                    // Checked and prepared here, without the lock; under it only copied in. The
                    // same checks passed on the same settings (only commands change them, and
                    // they run here one at a time): neither step can fail.
                    let change = ConfigChange::prepare(snap.config(), snap.config_generation(), new);
                    let applied = match change {
                        Ok(change) => shared.lock(|ctl| ctl.apply_config(&change)).is_none_or(|r| r.is_ok()),
                        Err(_) => false,
                    };
                    if !applied {
                        reply.truncate(start);
                        self.error = error::PARAM_OUT_OF_RANGE;
                    }
                }
            }
            Shape::Locked => {
                shared.lock(|ctl| self.run_locked(&parsed, ctl, board, Out::new(reply)));
            }
        }
    }

    /// The locked sections [`Gcs::execute_shared`] runs for `pending`, by name, in order: a
    /// query's `snapshot`, a settings command's `snapshot` and
    /// `apply_config` (the second only when the settings change), any other command's `command`.
    pub fn locked_sections(pending: &Pending) -> &'static [&'static str] {
        let parsed = Parsed::of(pending);
        match parsed.shape() {
            Shape::Query => &["snapshot"],
            Shape::Settings => &["snapshot", "apply_config"],
            Shape::Locked => &["command"],
        }
    }

    /// `#24` received while a reply is being sent ([`super::LinkSession`]): stops the
    /// controller at once, in a locked section of its own that runs only
    /// [`Controller::stop`] (a part of `#24`'s `command` section), ahead of the commands received
    /// before it. The byte then runs in its place among them like any `#24` (stops again,
    /// latches error 10).
    pub fn stop_now(&mut self, shared: &mut impl SharedController) {
        shared.lock(|ctl| ctl.stop());
    }

    /// Executes `pending` against a controller no tick shares and appends the reply bytes
    /// (possibly none): [`Gcs::execute_shared`] with [`Unshared`].
    pub fn execute(
        &mut self,
        pending: &Pending,
        ctl: &mut Controller,
        board: &mut dyn Board,
        reply: &mut Reply,
    ) {
        self.execute_shared(pending, &mut Unshared(ctl), board, reply);
    }
}
