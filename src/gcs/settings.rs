//! Settings handlers: `SPA`/`SPA?` (parameters by id, see [`super::params`]), `HPA?`, the
//! closed-loop limits `VEL`/`ACC`/`DEC` and their queries, the travel limits `TMN?`/`TMX?` (the
//! PI-named commands: each its row of the table, 0xA, 0xB, 0xC, 0x30, 0x15), and `WPA` (store
//! to non-volatile memory). The settings commands change a copy of the settings
//! (a [`Settings`] call): the board hands it to the controller afterwards.

use super::args::{axis, no_args, number, pairs};
use super::call::{Call, GcsResult, Query, Settings};
use super::framing::Out;
use super::num::parse_int;
use super::snapshot::Snapshot;
use super::{error, params, Gcs};
use crate::controller::{validate_change, ControllerConfig, State};

impl Gcs {
    fn spa(&mut self, args: &[&[u8]], cfg: &mut ControllerConfig) -> GcsResult {
        if args.is_empty() {
            return Err(error::MISSING_PARAM);
        }
        if args.len() % 3 != 0 {
            return Err(error::WRONG_PARAM_COUNT);
        }
        let mut new = *cfg;
        for triple in args.chunks(3) {
            let [item, id, value] = triple else { return Err(error::WRONG_PARAM_COUNT) };
            axis(item)?;
            let p =
                params::find(parse_int(id).ok_or(error::PARAM_SYNTAX)?).ok_or(error::UNKNOWN_PARAMETER)?;
            let v = number(value)?;
            if p.read_only {
                return Err(error::READ_ONLY_PARAMETER);
            }
            let x = params::from_gcs(p, &v).ok_or(error::PARAM_OUT_OF_RANGE)?;
            if !(p.set)(&mut new, x) {
                return Err(error::PARAM_OUT_OF_RANGE);
            }
        }
        validate_change(cfg, &new).map_err(|_| error::PARAM_OUT_OF_RANGE)?;
        *cfg = new;
        Ok(())
    }

    fn spa_query(&self, args: &[&[u8]], ctl: &Snapshot, out: &mut Out) -> GcsResult {
        let cfg = ctl.config();
        if args.is_empty() {
            for p in params::PARAMS {
                param_line(out, p, cfg);
            }
            return Ok(());
        }
        if args.len() % 2 != 0 {
            return Err(error::WRONG_PARAM_COUNT);
        }
        // Check everything before answering anything.
        for pair in args.chunks(2) {
            let [item, id] = pair else { return Err(error::WRONG_PARAM_COUNT) };
            axis(item)?;
            params::find(parse_int(id).ok_or(error::PARAM_SYNTAX)?).ok_or(error::UNKNOWN_PARAMETER)?;
        }
        for pair in args.chunks(2) {
            if let [_, id] = pair {
                if let Some(p) = parse_int(id).and_then(params::find) {
                    param_line(out, p, cfg);
                }
            }
        }
        Ok(())
    }
}

pub(super) fn hpa_query(_gcs: &mut Gcs, c: Query) -> GcsResult {
    let Query { args, out, .. } = c;
    no_args(args)?;
    out.line();
    out.s("#Possible parameters of this device:");
    for p in params::PARAMS {
        out.line();
        out.s("0x");
        hex(out, p.id);
        out.s("=\t0\t1\t");
        out.s(p.kind.name());
        out.s("\t");
        out.s(p.group);
        out.s("\t");
        out.s(p.description);
        if !p.unit.is_empty() {
            out.s(" (");
            out.s(p.unit);
            out.s(")");
        }
    }
    out.line();
    out.s("end of help");
    Ok(())
}

/// The rows the PI-named commands set and show: their ids, units and scaling are the table's,
/// as for `SPA`/`SPA?`.
const VEL_ROW: &params::Param = params::row(0xA);
const ACC_ROW: &params::Param = params::row(0xB);
const DEC_ROW: &params::Param = params::row(0xC);
const TMX_ROW: &params::Param = params::row(0x15);
const TMN_ROW: &params::Param = params::row(0x30);

/// `TMN?`, `TMX?`: a length row as `SPA?` shows it (mm, six decimals).
fn travel_query(gcs: &mut Gcs, p: &params::Param, c: Query) -> GcsResult {
    let Query { args, ctl, out, .. } = c;
    let v = (p.get)(ctl.config());
    gcs.axis_query(args, out, |out| {
        params::write_gcs(out, p, v);
    })?;
    Ok(())
}

pub(super) fn tmn_query(gcs: &mut Gcs, c: Query) -> GcsResult {
    travel_query(gcs, TMN_ROW, c)
}

pub(super) fn tmx_query(gcs: &mut Gcs, c: Query) -> GcsResult {
    travel_query(gcs, TMX_ROW, c)
}

/// `VEL?`, `ACC?`, `DEC?`: a motion-limit row in the protocol's unit, about seven digits.
fn motion_limit_query(gcs: &mut Gcs, p: &params::Param, c: Query) -> GcsResult {
    let Query { args, ctl, out, .. } = c;
    let v = (p.get)(ctl.config());
    gcs.axis_query(args, out, |out| {
        params::write_short(out, p, v);
    })?;
    Ok(())
}

pub(super) fn vel_query(gcs: &mut Gcs, c: Query) -> GcsResult {
    motion_limit_query(gcs, VEL_ROW, c)
}

pub(super) fn acc_query(gcs: &mut Gcs, c: Query) -> GcsResult {
    motion_limit_query(gcs, ACC_ROW, c)
}

pub(super) fn dec_query(gcs: &mut Gcs, c: Query) -> GcsResult {
    motion_limit_query(gcs, DEC_ROW, c)
}

/// `VEL`, `ACC`, `DEC`: one of the closed-loop motion limits, as `SPA` sets its row (the
/// table's scaling and range), with the command's own error code; each pair checked as the
/// whole configuration it would make.
fn motion_limit(p: &params::Param, bad: i32, c: Settings) -> GcsResult {
    let Settings { args, cfg } = c;
    let new = pairs(args, |t| {
        let x = params::from_gcs(p, &number(t)?).ok_or(bad)?;
        let mut new = *cfg;
        if !(p.set)(&mut new, x) {
            return Err(bad);
        }
        validate_change(cfg, &new).map_err(|_| bad)?;
        Ok(new)
    })?;
    *cfg = new;
    Ok(())
}

pub(super) fn vel(_gcs: &mut Gcs, c: Settings) -> GcsResult {
    motion_limit(VEL_ROW, error::VEL_OUT_OF_LIMITS, c)
}

pub(super) fn acc(_gcs: &mut Gcs, c: Settings) -> GcsResult {
    motion_limit(ACC_ROW, error::PARAM_OUT_OF_RANGE, c)
}

pub(super) fn dec(_gcs: &mut Gcs, c: Settings) -> GcsResult {
    motion_limit(DEC_ROW, error::PARAM_OUT_OF_RANGE, c)
}

pub(super) fn spa(gcs: &mut Gcs, c: Settings) -> GcsResult {
    let Settings { args, cfg } = c;
    gcs.spa(args, cfg)
}

pub(super) fn spa_query(gcs: &mut Gcs, c: Query) -> GcsResult {
    let Query { args, ctl, out, .. } = c;
    gcs.spa_query(args, ctl, out)?;
    Ok(())
}

pub(super) fn wpa(_gcs: &mut Gcs, c: Call) -> GcsResult {
    let Call { args, ctl, board, .. } = c;
    match args {
        [] => {}
        [pw] if *pw == b"100" => {}
        [_] => return Err(error::INVALID_PASSWORD),
        _ => return Err(error::WRONG_PARAM_COUNT),
    }
    // Writing the flash stalls the CPU (about 20 ms on the board): only with the
    // drive quiet, servo off and nothing moving.
    if ctl.state() != State::Idle || ctl.servo() || ctl.in_motion() || ctl.referencing() {
        return Err(error::NOT_ALLOWED);
    }
    if !board.store_parameters(ctl.config()) {
        return Err(error::FLASH_PROGRAM_FAILED);
    }
    Ok(())
}

fn hex(out: &mut Out, v: u32) {
    let digits = b"0123456789ABCDEF";
    let mut started = false;
    for shift in (0..8).rev() {
        let d = ((v >> (shift * 4)) & 0xF) as usize;
        if d != 0 || started || shift == 0 {
            started = true;
            if let Some(c) = digits.get(d) {
                out.b(&[*c]);
            }
        }
    }
}

fn param_line(out: &mut Out, p: &params::Param, cfg: &ControllerConfig) {
    out.line();
    out.s("1 0x");
    hex(out, p.id);
    out.s("=");
    params::write_gcs(out, p, (p.get)(cfg));
}
