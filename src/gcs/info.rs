//! Information handlers: `*IDN?`, `CSV?`, `SSN?`, `VER?`, `SAI?`, `CST?` and `XLT?` (loop
//! timing), and the identification strings they print.

use super::args::no_args;
use super::call::{GcsResult, Query};
use super::framing::Out;
use super::{error, Gcs};
use crate::controller::model_cache::TableModelKind;

/// `*IDN?` fields: maker, model, (serial), version (three dot-separated parts at most).
pub const IDN_MAKER: &str = "(c)2026 piezo-drive project";
pub const IDN_MODEL: &str = "PD-SB1";
pub const IDN_VERSION: &str = env!("CARGO_PKG_VERSION");
/// Appended to the model with parameter 0x1040 set: EPICS motorPIGCS2 picks its driver class by
/// a PI model name anywhere in `*IDN?` (this one: its C-863/C-867 motor class, whose commands
/// the board answers); PIPython matches model names exactly, so it sees no known model either way.
pub const IDN_COMPATIBLE: &str = " (C-867 compatible)";
/// `CST?`: what the axis is.
pub const STAGE_NAME: &str = "SHAKING-BEAM-PIEZO";

pub(super) fn idn_query(_gcs: &mut Gcs, c: Query) -> GcsResult {
    let Query { args, ctl, board, out } = c;
    no_args(args)?;
    out.line();
    out.s(IDN_MAKER);
    out.s(", ");
    out.s(IDN_MODEL);
    if ctl.config().idn_c867_compatible {
        out.s(IDN_COMPATIBLE);
    }
    out.s(", ");
    serial(out, board.serial_number());
    out.s(", ");
    out.s(IDN_VERSION);
    Ok(())
}

/// Six digits at least, as PI prints serial numbers.
fn serial(out: &mut Out, serial: u32) {
    let mut p = 100_000u32;
    while p > 1 && serial < p {
        out.s("0");
        p /= 10;
    }
    out.u(u64::from(serial));
}

/// `SSN?`: the serial number, as `*IDN?` prints it.
pub(super) fn ssn_query(_gcs: &mut Gcs, c: Query) -> GcsResult {
    let Query { args, board, out, .. } = c;
    no_args(args)?;
    out.line();
    serial(out, board.serial_number());
    Ok(())
}

/// `VER?`: the firmware's version, one `name: version` line as PI's controllers list theirs.
pub(super) fn ver_query(_gcs: &mut Gcs, c: Query) -> GcsResult {
    let Query { args, out, .. } = c;
    no_args(args)?;
    out.line();
    out.s("FW_ARM: V");
    out.s(IDN_VERSION);
    Ok(())
}

pub(super) fn csv_query(_gcs: &mut Gcs, c: Query) -> GcsResult {
    let Query { args, out, .. } = c;
    no_args(args)?;
    out.line();
    out.s("2.0");
    Ok(())
}

pub(super) fn sai_query(_gcs: &mut Gcs, c: Query) -> GcsResult {
    let Query { args, out, .. } = c;
    match args {
        [] => {}
        [all] if all.eq_ignore_ascii_case(b"ALL") => {}
        [_] => return Err(error::PARAM_SYNTAX),
        _ => return Err(error::WRONG_PARAM_COUNT),
    }
    out.line();
    out.s("1");
    Ok(())
}

pub(super) fn cst_query(gcs: &mut Gcs, c: Query) -> GcsResult {
    let Query { args, out, .. } = c;
    gcs.axis_query(args, out, |out| out.s(STAGE_NAME))?;
    Ok(())
}

/// `XTS?`: the model table in use (`none`, `inertial`, `contact`), whether a build runs in the
/// background, and the last build's time (µs).
pub(super) fn xts_query(_gcs: &mut Gcs, c: Query) -> GcsResult {
    let Query { args, ctl, board, out } = c;
    no_args(args)?;
    let b = board.table_build();
    out.line();
    out.s("table=");
    out.s(match ctl.table_model() {
        None => "none",
        Some(TableModelKind::Inertial) => "inertial",
        Some(TableModelKind::Contact) => "contact",
    });
    out.line();
    out.s("build=");
    out.s(if b.running { "running" } else { "idle" });
    out.line();
    out.s("last_build_us=");
    out.u(u64::from(b.last_build_us));
    Ok(())
}

pub(super) fn xlt_query(_gcs: &mut Gcs, c: Query) -> GcsResult {
    let Query { args, board, out, .. } = c;
    no_args(args)?;
    let s = board.loop_stats();
    for (key, v) in [
        ("step_cycles_last", s.step_cycles_last),
        ("step_cycles_max", s.step_cycles_max),
        ("overruns", s.overruns),
        ("core_clock_hz", s.core_clock_hz),
    ] {
        out.line();
        out.s(key);
        out.s("=");
        out.u(u64::from(v));
    }
    Ok(())
}
