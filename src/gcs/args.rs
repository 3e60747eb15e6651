//! Argument checks shared by the handlers: the axis (`1`), numbers, flags, `{<AxisID> <Value>}`
//! pairs, positions within the travel, and [`Gcs::axis_query`] for the one-line-per-axis queries.

use super::call::GcsResult;
use super::error;
use super::framing::Out;
use super::num::{parse_decimal, Decimal};
use super::Gcs;
use crate::controller::Controller;

pub(super) fn axis(t: &[u8]) -> GcsResult {
    if t == b"1" {
        Ok(())
    } else {
        Err(error::INVALID_AXIS)
    }
}

pub(super) fn number(t: &[u8]) -> Result<Decimal, i32> {
    parse_decimal(t).ok_or(error::PARAM_SYNTAX)
}

/// Axes of a query: none means all (axis 1 once); each given axis is answered in turn.
pub(super) fn query_axes(args: &[&[u8]]) -> Result<usize, i32> {
    for a in args {
        axis(a)?;
    }
    Ok(args.len().max(1))
}

/// `{<AxisID> <Value>}` pairs: every pair is checked (axis, then `check` on the value), and the
/// value of the last pair is the one that counts (one axis). A line with any bad pair executes
/// nothing, so the same checks must pass for every pair, not only the last.
pub(super) fn pairs<T>(args: &[&[u8]], mut check: impl FnMut(&[u8]) -> Result<T, i32>) -> Result<T, i32> {
    if args.is_empty() {
        return Err(error::MISSING_PARAM);
    }
    if args.len() % 2 != 0 {
        return Err(error::WRONG_PARAM_COUNT);
    }
    let mut last = Err(error::MISSING_PARAM);
    for pair in args.chunks(2) {
        if let [a, v] = pair {
            axis(a)?;
            last = Ok(check(v)?);
        }
    }
    last
}

/// A position or distance in mm as nanometres; beyond i64 it is out of limits.
pub(super) fn position_nm(t: &[u8]) -> Result<i64, i32> {
    number(t)?.scaled_i64(6).ok_or(error::POS_OUT_OF_LIMITS)
}

/// `nm` within the travel limits (`TMN?`..`TMX?`), else error 7.
pub(super) fn within_travel(ctl: &Controller, nm: i64) -> Result<i64, i32> {
    let c = ctl.config();
    if nm < c.travel_min_nm || nm > c.travel_max_nm {
        return Err(error::POS_OUT_OF_LIMITS);
    }
    Ok(nm)
}

pub(super) fn no_args(args: &[&[u8]]) -> GcsResult {
    if args.is_empty() {
        Ok(())
    } else {
        Err(error::WRONG_PARAM_COUNT)
    }
}

/// A boolean argument: exactly `0` or `1`.
pub(super) fn flag(t: &[u8]) -> Result<bool, i32> {
    match parse_decimal(t).ok_or(error::PARAM_SYNTAX)?.integer() {
        Some(0) => Ok(false),
        Some(1) => Ok(true),
        _ => Err(error::PARAM_OUT_OF_RANGE),
    }
}

pub(super) fn to_f32(d: &Decimal) -> Option<f32> {
    let v = d.to_f64()? as f32;
    v.is_finite().then_some(v)
}

impl Gcs {
    /// `XYZ? [{<AxisID>}]`: one `1=value` line per requested axis.
    pub(super) fn axis_query(
        &self,
        args: &[&[u8]],
        out: &mut Out,
        mut value: impl FnMut(&mut Out),
    ) -> GcsResult {
        let n = query_axes(args)?;
        for _ in 0..n {
            out.line();
            out.s("1=");
            value(out);
        }
        Ok(())
    }
}
