//! Motion and servo handlers: `SVO`, `RON`, `FRF`, `FNL`/`FPL`, `POS`, `MOV`, `MVR`, `STP`, `HLT` and the
//! open-loop extension `XOS`, with the check they share (whether a move may start) and the
//! mapping of the controller's [`CommandError`] to GCS error numbers (the preload window is the
//! controller's one check, [`Controller::check_preload`]).

use super::args::{axis, flag, no_args, number, pairs, position_nm, to_f32, within_travel};
use super::call::{Call, GcsResult};
use super::num::parse_int;
use super::state::limit_switches;
use super::{error, Board, Gcs};
use crate::controller::{CommandError, Controller, ReferenceSignal};

fn command_error(e: CommandError) -> i32 {
    match e {
        CommandError::Faulted(_) => error::MOTION_ERROR,
        CommandError::ServoOff => error::MOVE_WITHOUT_REF_OR_SERVO_OFF,
        CommandError::OutOfTravel => error::POS_OUT_OF_LIMITS,
        CommandError::PreloadInvalid => error::SENSOR_SIGNAL_INVALID,
        CommandError::PreloadOutOfWindow => error::MOTION_ERROR,
        CommandError::InvalidValue => error::PARAM_OUT_OF_RANGE,
        CommandError::ServoOn => error::OPEN_LOOP_WITH_SERVO_ON,
        CommandError::Busy => error::CONTROLLER_BUSY,
    }
}

impl Gcs {
    /// Whether a closed-loop move may start: servo on, referenced (with reference mode on),
    /// not referencing.
    fn move_allowed(&self, ctl: &Controller) -> GcsResult {
        if ctl.referencing() {
            return Err(error::CONTROLLER_BUSY);
        }
        if !ctl.servo() || (self.reference_mode && !ctl.referenced()) {
            return Err(error::MOVE_WITHOUT_REF_OR_SERVO_OFF);
        }
        Ok(())
    }
}

pub(super) fn svo(_gcs: &mut Gcs, c: Call) -> GcsResult {
    let Call { args, ctl, .. } = c;
    let on = pairs(args, flag)?;
    if ctl.referencing() {
        return Err(error::CONTROLLER_BUSY);
    }
    if ctl.fault().is_none() && ctl.servo() == on {
        // Already so: nothing to do (servo on again must not re-anchor a moving
        // slider's reference where it stands).
        return Ok(());
    }
    if ctl.fault().is_some() {
        // As on PI controllers after a motion error: switching the servo (on or off)
        // again is the recovery. Check what servo-on needs before clearing.
        if on {
            ctl.check_preload().map_err(command_error)?;
        }
        ctl.clear_fault();
    }
    ctl.set_servo(on).map_err(command_error)?;
    Ok(())
}

pub(super) fn ron(gcs: &mut Gcs, c: Call) -> GcsResult {
    let Call { args, .. } = c;
    gcs.reference_mode = pairs(args, flag)?;
    Ok(())
}

pub(super) fn frf(gcs: &mut Gcs, c: Call) -> GcsResult {
    let Call { args, ctl, .. } = c;
    for a in args {
        axis(a)?;
    }
    if !gcs.reference_mode {
        return Err(error::REF_WITH_REF_DISABLED);
    }
    ctl.start_referencing().map_err(command_error)?;
    Ok(())
}

/// `FNL`, `FPL`: reference on the negative / positive limit switch (PI's commands for stages
/// without a reference switch). Without limit switches ([`limit_switches`]) both latch 32 (PI:
/// stage has no limit switch). With them, `FNL` runs the core's search when the negative switch
/// is the reference signal (0x1016 = 1), as `FRF` does; the core references on no other switch,
/// so `FPL`, and `FNL` with the index as the signal, latch 34.
fn limit_reference(gcs: &mut Gcs, c: Call, negative: bool) -> GcsResult {
    let Call { args, ctl, .. } = c;
    for a in args {
        axis(a)?;
    }
    if !limit_switches(&ctl.limit_switches()).wired {
        return Err(error::NO_LIMIT_SWITCH);
    }
    if !negative || ctl.config().reference_signal != ReferenceSignal::NegativeLimit {
        return Err(error::NOT_ALLOWED);
    }
    if !gcs.reference_mode {
        return Err(error::REF_WITH_REF_DISABLED);
    }
    ctl.start_referencing().map_err(command_error)?;
    Ok(())
}

pub(super) fn fnl(gcs: &mut Gcs, c: Call) -> GcsResult {
    limit_reference(gcs, c, true)
}

pub(super) fn fpl(gcs: &mut Gcs, c: Call) -> GcsResult {
    limit_reference(gcs, c, false)
}

pub(super) fn pos(gcs: &mut Gcs, c: Call) -> GcsResult {
    let Call { args, ctl, .. } = c;
    // Within the travel limits: beyond them the distance to a later target could
    // overflow, and the stage cannot be there anyway.
    let nm = pairs(args, |t| within_travel(ctl, position_nm(t)?))?;
    if gcs.reference_mode {
        return Err(error::NOT_ALLOWED);
    }
    if ctl.in_motion() {
        return Err(error::CONTROLLER_BUSY);
    }
    ctl.set_reference_here(nm);
    Ok(())
}

/// A command that changes the target was accepted: the recorder's move trigger.
fn moved(ctl: &Controller, board: &dyn Board) {
    if let Some(rec) = board.recorder() {
        rec.on_move(ctl);
    }
}

pub(super) fn mov(gcs: &mut Gcs, c: Call) -> GcsResult {
    let Call { args, ctl, board, .. } = c;
    // Syntax of every pair, then whether a move is allowed at all, then the limits
    // of every pair.
    pairs(args, position_nm)?;
    gcs.move_allowed(ctl)?;
    let target = pairs(args, |t| within_travel(ctl, position_nm(t)?))?;
    ctl.move_to(target).map_err(command_error)?;
    moved(ctl, board);
    Ok(())
}

pub(super) fn mvr(gcs: &mut Gcs, c: Call) -> GcsResult {
    let Call { args, ctl, board, .. } = c;
    pairs(args, position_nm)?;
    gcs.move_allowed(ctl)?;
    let base = ctl.target_nm();
    let target = pairs(args, |t| {
        let target = base.checked_add(position_nm(t)?).ok_or(error::POS_OUT_OF_LIMITS)?;
        within_travel(ctl, target)
    })?;
    ctl.move_to(target).map_err(command_error)?;
    moved(ctl, board);
    Ok(())
}

pub(super) fn stp(_gcs: &mut Gcs, c: Call) -> GcsResult {
    let Call { args, ctl, .. } = c;
    no_args(args)?;
    ctl.stop();
    Err(error::STOPPED)
}

pub(super) fn hlt(_gcs: &mut Gcs, c: Call) -> GcsResult {
    let Call { args, ctl, .. } = c;
    for a in args {
        axis(a)?;
    }
    ctl.halt();
    Err(error::STOPPED)
}

pub(super) fn xos(_gcs: &mut Gcs, c: Call) -> GcsResult {
    let Call { args, ctl, board, .. } = c;
    let [a, cycles, amplitude, frequency] = args else {
        return Err(if args.is_empty() { error::MISSING_PARAM } else { error::WRONG_PARAM_COUNT });
    };
    axis(a)?;
    let cycles = parse_int(cycles).ok_or(error::PARAM_SYNTAX)?;
    let amplitude = number(amplitude)?;
    let frequency = number(frequency)?;
    let cycles = i32::try_from(cycles)
        .ok()
        .filter(|c| *c != 0 && c.unsigned_abs() <= 1_000_000)
        .ok_or(error::PARAM_OUT_OF_RANGE)?;
    let amplitude = to_f32(&amplitude).ok_or(error::PARAM_OUT_OF_RANGE)?;
    let frequency = to_f32(&frequency).ok_or(error::PARAM_OUT_OF_RANGE)?;
    ctl.open_loop_step(cycles, amplitude, frequency).map_err(command_error)?;
    moved(ctl, board);
    Ok(())
}
