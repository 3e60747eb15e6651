//! Settings handlers: `SPA`/`SPA?` (parameters by id, see [`super::params`]), `HPA?`, the
//! closed-loop limits `VEL`/`ACC`/`DEC` and their queries, the travel limits `TMN?`/`TMX?`, and
//! `WPA` (store to non-volatile memory). The settings commands change a copy of the settings
//! (a [`Settings`] call): the board hands it to the controller afterwards.

use super::args::{axis, no_args, number, pairs, to_f32};
use super::call::{Call, GcsResult, Query, Settings};
use super::framing::Out;
use super::num::parse_int;
use super::snapshot::Snapshot;
use super::{error, params, Gcs};
use crate::controller::{validate_settings, CommandError, ControllerConfig, State};

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
        settable(cfg, &new).map_err(|_| error::PARAM_OUT_OF_RANGE)?;
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

pub(super) fn tmn_query(gcs: &mut Gcs, c: Query) -> GcsResult {
    let Query { args, ctl, out, .. } = c;
    gcs.axis_query(args, out, |out| out.mm(ctl.config().travel_min_nm))?;
    Ok(())
}

pub(super) fn tmx_query(gcs: &mut Gcs, c: Query) -> GcsResult {
    let Query { args, ctl, out, .. } = c;
    gcs.axis_query(args, out, |out| out.mm(ctl.config().travel_max_nm))?;
    Ok(())
}

pub(super) fn vel_query(gcs: &mut Gcs, c: Query) -> GcsResult {
    let Query { args, ctl, out, .. } = c;
    let v = f64::from(ctl.config().velocity_max_nm_s / 1e6);
    gcs.axis_query(args, out, |out| out.general(v))?;
    Ok(())
}

pub(super) fn acc_query(gcs: &mut Gcs, c: Query) -> GcsResult {
    let Query { args, ctl, out, .. } = c;
    let v = f64::from(ctl.config().accel_max_nm_s2 / 1e6);
    gcs.axis_query(args, out, |out| out.general(v))?;
    Ok(())
}

pub(super) fn dec_query(gcs: &mut Gcs, c: Query) -> GcsResult {
    let Query { args, ctl, out, .. } = c;
    let v = f64::from(ctl.config().decel_max_nm_s2 / 1e6);
    gcs.axis_query(args, out, |out| out.general(v))?;
    Ok(())
}

/// Whether the controller takes `new` in place of `old` (as `Controller::set_config` checks
/// them): the settings in range together, and what the hardware fixes (loop and DAC rates, DAC
/// range, encoder resolution, motor table) unchanged.
fn settable(old: &ControllerConfig, new: &ControllerConfig) -> Result<(), CommandError> {
    if new.loop_hz != old.loop_hz
        || new.dac != old.dac
        || new.encoder_nm_per_count != old.encoder_nm_per_count
        || new.motor != old.motor
    {
        return Err(CommandError::InvalidValue);
    }
    validate_settings(new)
}

/// `VEL`, `ACC`, `DEC`: one of the closed-loop motion limits, each pair checked as the whole
/// configuration it would make.
fn motion_limit(name: &str, c: Settings) -> GcsResult {
    let Settings { args, cfg } = c;
    let bad = if name == "VEL" { error::VEL_OUT_OF_LIMITS } else { error::PARAM_OUT_OF_RANGE };
    // Each pair's value is checked as the whole configuration it would make.
    let new = pairs(args, |t| {
        let x = to_f32(&number(t)?).map(|x| x * 1e6).filter(|x| x.is_finite() && *x > 0.0);
        let x = x.ok_or(bad)?;
        let mut new = *cfg;
        match name {
            "VEL" => new.velocity_max_nm_s = x,
            "ACC" => new.accel_max_nm_s2 = x,
            _ => new.decel_max_nm_s2 = x,
        }
        settable(cfg, &new).map_err(|_| bad)?;
        Ok(new)
    })?;
    *cfg = new;
    Ok(())
}

pub(super) fn vel(_gcs: &mut Gcs, c: Settings) -> GcsResult {
    motion_limit("VEL", c)
}

pub(super) fn acc(_gcs: &mut Gcs, c: Settings) -> GcsResult {
    motion_limit("ACC", c)
}

pub(super) fn dec(_gcs: &mut Gcs, c: Settings) -> GcsResult {
    motion_limit("DEC", c)
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
