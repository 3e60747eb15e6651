//! What runs while the board holds the controller's lock (on the firmware: the control tick
//! masked) for each command: [`Gcs::execute_shared`]. The firmware's UART task, `host-sim serve`
//! and the processor-in-the-loop image (`tools/pil`, which counts the instructions of every
//! locked section: `host-sim pil --gcs-locks`) all run commands through it, so what is measured
//! is what the board runs.
//!
//! Three shapes, by command (see [`Gcs::is_read_only`], [`Gcs::is_settings_only`]):
//! - a query (`…?`, #5, #7) copies the controller under the lock and is answered from the copy
//!   without it;
//! - a settings command (`SPA`, `VEL`, `ACC`, `DEC`) is parsed and checked on a copy taken
//!   under the lock, and only `Controller::set_config` runs under it again;
//! - every other command runs whole under the lock.

use super::{Board, Gcs, Pending, Reply};
use crate::controller::Controller;

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
    /// allows (the module's three shapes), and appends the reply bytes (possibly none). Nothing
    /// is executed and nothing answered when the controller cannot be locked.
    pub fn execute_shared(
        &mut self,
        pending: &Pending,
        shared: &mut impl SharedController,
        board: &mut dyn Board,
        reply: &mut Reply,
    ) {
        if Self::is_read_only(pending) {
            // The copy is taken with the tick held off; the reply is formatted without.
            if let Some(mut copy) = shared.lock(|ctl| ctl.clone()) {
                self.execute(pending, &mut copy, board, reply);
            }
        } else if Self::is_settings_only(pending) {
            // Parsed and checked on a copy; the real controller only takes the new settings.
            if let Some(mut copy) = shared.lock(|ctl| ctl.clone()) {
                self.execute(pending, &mut copy, board, reply);
                let new = *copy.config();
                shared.lock(|ctl| {
                    if *ctl.config() != new {
                        // Cannot fail: the copy accepted the same settings from the same ones.
                        let _ = ctl.set_config(new);
                    }
                });
            }
        } else {
            shared.lock(|ctl| self.execute(pending, ctl, board, reply));
        }
    }
}
