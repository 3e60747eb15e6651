//! Queries of the controller's state: `ERR?`, `SVO?`, `RON?`, `FRF?`, `ONT?`, `POS?`, `MOV?` and
//! the extensions `XPF?` (preload), `XDA?`/`XDF?` (drive), `XFT?` (fault), `XTM?` (thrust limits).

use super::args::no_args;
use super::call::{GcsResult, Query};
use super::{error, Gcs};

pub(super) fn err_query(gcs: &mut Gcs, c: Query) -> GcsResult {
    let Query { args, out, .. } = c;
    no_args(args)?;
    out.line();
    out.i(i64::from(gcs.error));
    gcs.error = error::NONE;
    Ok(())
}

pub(super) fn svo_query(gcs: &mut Gcs, c: Query) -> GcsResult {
    let Query { args, ctl, out, .. } = c;
    gcs.axis_query(args, out, |out| out.u(u64::from(ctl.servo())))?;
    Ok(())
}

pub(super) fn ron_query(gcs: &mut Gcs, c: Query) -> GcsResult {
    let Query { args, out, .. } = c;
    let ron = gcs.reference_mode;
    gcs.axis_query(args, out, |out| out.u(u64::from(ron)))?;
    Ok(())
}

pub(super) fn frf_query(gcs: &mut Gcs, c: Query) -> GcsResult {
    let Query { args, ctl, out, .. } = c;
    gcs.axis_query(args, out, |out| out.u(u64::from(ctl.referenced())))?;
    Ok(())
}

pub(super) fn ont_query(gcs: &mut Gcs, c: Query) -> GcsResult {
    let Query { args, ctl, out, .. } = c;
    gcs.axis_query(args, out, |out| out.u(u64::from(ctl.on_target())))?;
    Ok(())
}

pub(super) fn pos_query(gcs: &mut Gcs, c: Query) -> GcsResult {
    let Query { args, ctl, out, .. } = c;
    gcs.axis_query(args, out, |out| out.mm(ctl.position_nm()))?;
    Ok(())
}

pub(super) fn mov_query(gcs: &mut Gcs, c: Query) -> GcsResult {
    let Query { args, ctl, out, .. } = c;
    gcs.axis_query(args, out, |out| out.mm(ctl.target_nm()))?;
    Ok(())
}

pub(super) fn xpf_query(gcs: &mut Gcs, c: Query) -> GcsResult {
    let Query { args, ctl, out, .. } = c;
    let f = ctl.preload_n().ok_or(error::SENSOR_SIGNAL_INVALID)?;
    gcs.axis_query(args, out, |out| out.fixed(f64::from(f), 3))?;
    Ok(())
}

pub(super) fn xda_query(gcs: &mut Gcs, c: Query) -> GcsResult {
    let Query { args, ctl, out, .. } = c;
    let v = f64::from(ctl.drive_voltage_v());
    gcs.axis_query(args, out, |out| out.fixed(v, 3))?;
    Ok(())
}

pub(super) fn xdf_query(gcs: &mut Gcs, c: Query) -> GcsResult {
    let Query { args, ctl, out, .. } = c;
    let f = f64::from(ctl.drive_frequency_hz());
    gcs.axis_query(args, out, |out| out.fixed(f, 1))?;
    Ok(())
}

pub(super) fn xft_query(gcs: &mut Gcs, c: Query) -> GcsResult {
    let Query { args, ctl, out, .. } = c;
    let fault = ctl.fault();
    gcs.axis_query(args, out, |out| match fault {
        Some(code) => {
            out.u(code as u64);
            out.s(" ");
            out.s(code.text());
        }
        None => out.s("0 no fault"),
    })?;
    Ok(())
}

pub(super) fn xtm_query(gcs: &mut Gcs, c: Query) -> GcsResult {
    let Query { args, ctl, out, .. } = c;
    let (stall, speed) = ctl.thrust_limits().ok_or(error::SENSOR_SIGNAL_INVALID)?;
    gcs.axis_query(args, out, |out| {
        out.fixed(f64::from(stall), 3);
        out.s(" ");
        out.fixed(f64::from(speed), 3);
    })?;
    Ok(())
}
