//! Queries of the controller's state: `ERR?`, `SVO?`, `RON?`, `FRF?`, `ONT?`, `POS?`, `MOV?`,
//! what the axis has to reference on (`LIM?`, `TRS?`, `HAR?`), the status register (`#4`,
//! `SRG?`) and the extensions `XPF?` (preload), `XDA?`/`XDF?` (drive), `XFT?` (fault), `XTM?`
//! (thrust limits).

use super::args::{axis, no_args};
use super::call::{GcsResult, Query};
use super::framing::Out;
use super::snapshot::Snapshot;
use super::{error, Gcs};

/// The limit switches as the protocol reports them: whether the axis has them (`LIM?`) and
/// whether each is active now (bits 0 and 2 of the status register).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct LimitSwitches {
    pub wired: bool,
    pub negative_active: bool,
    pub positive_active: bool,
}

/// The one place the protocol learns about limit switches: the controller's own view
/// ([`crate::controller::Controller::limit_switches`]): the axis has them (`LIM?` → 1, `FNL`
/// allowed) when the board reads their pins and the setting `0x1025` has them read; bits 0 and 2
/// of the status register are their debounced states then.
pub fn limit_switches(lim: &crate::controller::LimitSwitches) -> LimitSwitches {
    let wired = lim.wired && lim.enabled;
    LimitSwitches { wired, negative_active: wired && lim.negative, positive_active: wired && lim.positive }
}

/// PI's status register (`#4`, `SRG? 1 1`; C-863/C-867 layout): bit 0 negative limit switch,
/// 2 positive limit switch, 8 error (an error number latched for `ERR?`), 12 servo on, 13 in
/// motion (moving, referencing or stepping), 14 referencing, 15 on target. Bit 1 (reference
/// switch) and the digital inputs (4–7) stay 0: the board has no such inputs.
pub(super) fn status_register(latched_error: i32, ctl: &Snapshot) -> u16 {
    let lim = limit_switches(&ctl.limit_switches());
    let mut r = 0u16;
    for (on, bit) in [
        (lim.negative_active, 0x0001),
        (lim.positive_active, 0x0004),
        (latched_error != error::NONE, 0x0100),
        (ctl.servo(), 0x1000),
        (ctl.in_motion(), 0x2000),
        (ctl.referencing(), 0x4000),
        (ctl.on_target(), 0x8000),
    ] {
        if on {
            r |= bit;
        }
    }
    r
}

/// `0x` and four upper-case hex digits: the register as `#4` sends it and EPICS motorPIGCS2
/// reads it (four digits from the third character on).
pub(super) fn write_register(out: &mut Out, r: u16) {
    out.s("0x");
    for shift in [12u32, 8, 4, 0] {
        let d = ((r >> shift) & 0xF) as usize;
        if let Some(c) = b"0123456789ABCDEF".get(d) {
            out.b(&[*c]);
        }
    }
}

/// `LIM?`: whether the axis has limit switches (0 or 1).
pub(super) fn lim_query(gcs: &mut Gcs, c: Query) -> GcsResult {
    let Query { args, ctl, out, .. } = c;
    let wired = limit_switches(&ctl.limit_switches()).wired;
    gcs.axis_query(args, out, |out| out.u(u64::from(wired)))?;
    Ok(())
}

/// `TRS?`: whether the axis has a reference signal `FRF` references on: always 1, the encoder
/// index or, by parameter 0x1016, the negative limit switch.
pub(super) fn trs_query(gcs: &mut Gcs, c: Query) -> GcsResult {
    let Query { args, out, .. } = c;
    gcs.axis_query(args, out, |out| out.u(1))?;
    Ok(())
}

/// `HAR?`: whether the axis can reference on a hard stop: 0, the search turns round at the
/// limit switches or fails by timeout, it never drives into a stop on purpose.
pub(super) fn har_query(gcs: &mut Gcs, c: Query) -> GcsResult {
    let Query { args, out, .. } = c;
    gcs.axis_query(args, out, |out| out.u(0))?;
    Ok(())
}

/// `SRG? [{<AxisID> <RegisterID>}]`: the status register (register 1) as `#4` answers it, one
/// `1 1=0x9000` line per pair (none: axis 1's).
pub(super) fn srg_query(gcs: &mut Gcs, c: Query) -> GcsResult {
    let Query { args, ctl, out, .. } = c;
    if args.len() % 2 != 0 {
        return Err(error::WRONG_PARAM_COUNT);
    }
    for pair in args.chunks(2) {
        let [a, id] = pair else { return Err(error::WRONG_PARAM_COUNT) };
        axis(a)?;
        if *id != b"1" {
            return Err(error::PARAM_OUT_OF_RANGE);
        }
    }
    let r = status_register(gcs.error, ctl);
    for _ in 0..(args.len() / 2).max(1) {
        out.line();
        out.s("1 1=");
        write_register(out, r);
    }
    Ok(())
}

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
