//! The data recorder's commands (`DRC`, `DRC?`, `DRL?`, `DRR?`, `DRT`, `DRT?`, `HDR?`, `RTR`,
//! `RTR?`, `TNR?`), one handler each, on the board's [`Recorder`] ([`Board::recorder`]; a board
//! without one answers them as unknown commands). Formats as PIPython reads them: `DRC?` →
//! `1=1 2` (table=source option), `DRT?` → `1=6 0`, `DRL?` → `1=1024`, `RTR?`/`TNR?` → a number,
//! `HDR?` → `#RecordOptions`, `#TriggerOptions` and `#Additional information` sections of
//! `<number>=<text>` lines, `DRR?` → PI's GCS array: `# KEY = value` header lines up to
//! `# END_HEADER`, then one line per point with one column per table.
//!
//! `DRR?` can be far longer than one reply buffer: its handler writes the header and the rows
//! that fit and leaves a [`DrrCursor`]; the board sends that and asks for the rest with
//! [`Gcs::continue_reply`] until [`Gcs::reply_pending`] is false.

use super::args::{axis, no_args};
use super::call::{Call, GcsResult, Query};
use super::framing::Out;
use super::{error, Board, Gcs, Reply};
use crate::gcs::num::{parse_int, write_scaled};
use crate::recorder::{self, Recorder, RecorderError, DEPTH, OPTIONS, TABLES, TRIGGERS};

/// Longest row: [`TABLES`] columns of at most `-2147.483648` and a space, and the line end.
const ROW_MAX: usize = TABLES * 13 + 2;

/// Where a `DRR?` reply goes on: the columns (table id, record option) and the rows left.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DrrCursor {
    columns: heapless::Vec<(usize, u32), TABLES>,
    /// Next point (0-based) and one past the last.
    next: usize,
    end: usize,
}

fn recorder_error(e: RecorderError) -> i32 {
    match e {
        RecorderError::UnknownTable => error::INVALID_RECORD_TABLE,
        RecorderError::UnknownOption => error::INVALID_RECORD_OPTION,
        RecorderError::OutOfRange => error::PARAM_OUT_OF_RANGE,
    }
}

fn recorder(board: &dyn Board) -> Result<&Recorder, i32> {
    board.recorder().ok_or(error::UNKNOWN_COMMAND)
}

/// A non-negative integer argument (decimal or `0x` hex); beyond `usize` it is out of range.
fn count(t: &[u8]) -> Result<usize, i32> {
    let v = parse_int(t).ok_or(error::PARAM_SYNTAX)?;
    usize::try_from(v).map_err(|_| error::PARAM_OUT_OF_RANGE)
}

/// A record table id, 1..=[`TABLES`] (`zero_ok`: 0 too, meaning every table).
fn table(t: &[u8], zero_ok: bool) -> Result<usize, i32> {
    let id = parse_int(t).ok_or(error::PARAM_SYNTAX)?;
    match usize::try_from(id) {
        Ok(0) if zero_ok => Ok(0),
        Ok(id) => Recorder::check_table(id).map(|_| id).map_err(recorder_error),
        Err(_) => Err(error::INVALID_RECORD_TABLE),
    }
}

/// The tables a query names, or every table when it names none; each checked first.
fn query_tables(args: &[&[u8]]) -> Result<heapless::Vec<usize, TABLES>, i32> {
    let mut ids = heapless::Vec::new();
    if args.is_empty() {
        for id in 1..=TABLES {
            ids.push(id).map_err(|_| error::WRONG_PARAM_COUNT)?;
        }
    }
    for a in args {
        ids.push(table(a, false)?).map_err(|_| error::WRONG_PARAM_COUNT)?;
    }
    Ok(ids)
}

/// `{<first> <second> <third>}` triples: the count checked.
fn triples<'a, 'c>(args: &'a [&'c [u8]]) -> Result<core::slice::ChunksExact<'a, &'c [u8]>, i32> {
    if args.is_empty() {
        return Err(error::MISSING_PARAM);
    }
    if args.len() % 3 != 0 {
        return Err(error::WRONG_PARAM_COUNT);
    }
    Ok(args.chunks_exact(3))
}

/// Seconds as a decimal without trailing zeros (`0.0001`, `0.002`, `1`).
fn seconds_from_ns(out: &mut Out, ns: u64) {
    let mut v = ns;
    let mut decimals = 9;
    while decimals > 0 && v % 10 == 0 {
        v /= 10;
        decimals -= 1;
    }
    write_scaled(out, i64::try_from(v).unwrap_or(i64::MAX), decimals);
}

fn option_text(opt: u32) -> (&'static str, &'static str) {
    OPTIONS.iter().find(|(o, _, _)| *o == opt).map_or(("Unknown", ""), |(_, what, unit)| (*what, *unit))
}

/// `DRC {<RecTableID> <Source> <RecOption>}`: the source is axis 1.
pub(super) fn drc(_gcs: &mut Gcs, c: Call) -> GcsResult {
    let Call { args, board, .. } = c;
    let rec = recorder(board)?;
    // Every triple checked before any is applied.
    for t in triples(args)? {
        let [id, source, opt] = t else { return Err(error::WRONG_PARAM_COUNT) };
        table(id, false)?;
        axis(source).map_err(|_| error::INVALID_RECORD_SOURCE)?;
        let opt = parse_int(opt).ok_or(error::PARAM_SYNTAX)?;
        if !u32::try_from(opt).is_ok_and(recorder::known_option) {
            return Err(error::INVALID_RECORD_OPTION);
        }
    }
    for t in triples(args)? {
        if let [id, _, opt] = t {
            let id = table(id, false)?;
            let opt = parse_int(opt).and_then(|o| u32::try_from(o).ok()).ok_or(error::PARAM_SYNTAX)?;
            rec.configure(id, opt).map_err(recorder_error)?;
        }
    }
    Ok(())
}

/// `DRC? [{<RecTableID>}]` → `1=1 2` per table.
pub(super) fn drc_query(_gcs: &mut Gcs, c: Query) -> GcsResult {
    let Query { args, board, out, .. } = c;
    let rec = recorder(board)?;
    for id in query_tables(args)? {
        let opt = rec.option(id).map_err(recorder_error)?;
        out.line();
        out.u(id as u64);
        out.s("=1 ");
        out.u(u64::from(opt));
    }
    Ok(())
}

/// `DRT {<RecTableID> <TriggerSource> <Value>}`: table 0 is every table; the value is unused
/// (an integer, as PIPython sends `0`).
pub(super) fn drt(_gcs: &mut Gcs, c: Call) -> GcsResult {
    let Call { args, ctl, board, .. } = c;
    let rec = recorder(board)?;
    for t in triples(args)? {
        let [id, trig, value] = t else { return Err(error::WRONG_PARAM_COUNT) };
        table(id, true)?;
        let trig = parse_int(trig).ok_or(error::PARAM_SYNTAX)?;
        parse_int(value).ok_or(error::PARAM_SYNTAX)?;
        if !u32::try_from(trig).is_ok_and(recorder::known_trigger) {
            return Err(error::PARAM_OUT_OF_RANGE);
        }
    }
    for t in triples(args)? {
        if let [id, trig, _] = t {
            let id = table(id, true)?;
            let trig = parse_int(trig).and_then(|o| u32::try_from(o).ok()).ok_or(error::PARAM_SYNTAX)?;
            rec.set_trigger(id, trig, ctl).map_err(recorder_error)?;
        }
    }
    Ok(())
}

/// `DRT? [{<RecTableID>}]` → `1=6 0` per table.
pub(super) fn drt_query(_gcs: &mut Gcs, c: Query) -> GcsResult {
    let Query { args, board, out, .. } = c;
    let rec = recorder(board)?;
    for id in query_tables(args)? {
        let trig = rec.trigger(id).map_err(recorder_error)?;
        out.line();
        out.u(id as u64);
        out.s("=");
        out.u(u64::from(trig));
        out.s(" 0");
    }
    Ok(())
}

/// `DRL? [{<RecTableID>}]` → `1=1024`: points recorded ([`DEPTH`] when the table is full).
pub(super) fn drl_query(_gcs: &mut Gcs, c: Query) -> GcsResult {
    let Query { args, board, out, .. } = c;
    let rec = recorder(board)?;
    for id in query_tables(args)? {
        let n = rec.points(id).map_err(recorder_error)?;
        out.line();
        out.u(id as u64);
        out.s("=");
        out.u(n as u64);
    }
    Ok(())
}

/// `RTR <RecordTableRate>`: one point every that many control ticks (1..=65535).
pub(super) fn rtr(_gcs: &mut Gcs, c: Call) -> GcsResult {
    let Call { args, board, .. } = c;
    let rec = recorder(board)?;
    let [rate] = args else {
        return Err(if args.is_empty() { error::MISSING_PARAM } else { error::WRONG_PARAM_COUNT });
    };
    let rate = parse_int(rate).ok_or(error::PARAM_SYNTAX)?;
    let rate = u32::try_from(rate).map_err(|_| error::PARAM_OUT_OF_RANGE)?;
    rec.set_rate(rate).map_err(recorder_error)
}

/// `RTR?` → the rate.
pub(super) fn rtr_query(_gcs: &mut Gcs, c: Query) -> GcsResult {
    let Query { args, board, out, .. } = c;
    let rec = recorder(board)?;
    no_args(args)?;
    out.line();
    out.u(u64::from(rec.rate()));
    Ok(())
}

/// `TNR?` → the number of record tables.
pub(super) fn tnr_query(_gcs: &mut Gcs, c: Query) -> GcsResult {
    let Query { args, board, out, .. } = c;
    recorder(board)?;
    no_args(args)?;
    out.line();
    out.u(TABLES as u64);
    Ok(())
}

/// `HDR?`: the record and trigger options and the table depth, as PIPython's
/// `datarectools.get_hdr_options` reads them (its `getmaxnumvalues` takes the depth from the
/// line `<n> datapoints per table`).
pub(super) fn hdr_query(_gcs: &mut Gcs, c: Query) -> GcsResult {
    let Query { args, board, out, .. } = c;
    recorder(board)?;
    no_args(args)?;
    out.line();
    out.s("#RecordOptions");
    for (opt, what, unit) in OPTIONS {
        out.line();
        out.u(u64::from(*opt));
        out.s("=");
        out.s(what);
        if *opt != recorder::option::NOTHING {
            out.s(" of axis");
        }
        if !unit.is_empty() {
            out.s(" (");
            out.s(unit);
            out.s(")");
        }
    }
    out.line();
    out.s("#TriggerOptions");
    for (trig, what) in TRIGGERS {
        out.line();
        out.u(u64::from(*trig));
        out.s("=");
        out.s(what);
    }
    out.line();
    out.s("#Additional information");
    out.line();
    out.u(DEPTH as u64);
    out.s(" datapoints per table");
    out.line();
    out.u(TABLES as u64);
    out.s(" record tables; record rate RTR in control ticks (servo update time: parameter 0x0E000200)");
    out.line();
    out.s("end of help");
    Ok(())
}

/// `DRR? [<StartPoint> [<NumberOfPoints> [{<RecTableID>}]]]`: points from `StartPoint`
/// (1-based) on, at most `NumberOfPoints` (all when absent) and no more than every named table
/// holds; the tables with a record option when none is named. `SAMPLE_TIME` is the first
/// column's (tables triggered under different `RTR`s differ). Refused: a start or count of 0
/// (17), a table without a record option (78), a start past the recorded points (77).
pub(super) fn drr_query(gcs: &mut Gcs, c: Query) -> GcsResult {
    let Query { args, ctl, board, out } = c;
    let rec = recorder(board)?;
    let (start, wanted, named) = match args {
        [] => (1, None, &[][..]),
        [s] => (count(s)?, None, &[][..]),
        [s, n, rest @ ..] => (count(s)?, Some(count(n)?), rest),
    };
    if start == 0 || wanted == Some(0) {
        return Err(error::PARAM_OUT_OF_RANGE);
    }
    let mut columns: heapless::Vec<(usize, u32), TABLES> = heapless::Vec::new();
    if named.is_empty() {
        for id in 1..=TABLES {
            let opt = rec.option(id).map_err(recorder_error)?;
            if opt != recorder::option::NOTHING {
                columns.push((id, opt)).map_err(|_| error::WRONG_PARAM_COUNT)?;
            }
        }
        if columns.is_empty() {
            return Err(error::TABLE_NOT_CONFIGURED);
        }
    } else {
        for t in named {
            let id = table(t, false)?;
            let opt = rec.option(id).map_err(recorder_error)?;
            if opt == recorder::option::NOTHING {
                return Err(error::TABLE_NOT_CONFIGURED);
            }
            columns.push((id, opt)).map_err(|_| error::WRONG_PARAM_COUNT)?;
        }
    }
    let mut held = DEPTH;
    for (id, _) in &columns {
        held = held.min(rec.points(*id).map_err(recorder_error)?);
    }
    if start > held {
        return Err(error::NOT_ENOUGH_RECORDED_DATA);
    }
    let first = start - 1;
    let rows = wanted.unwrap_or(held).min(held - first);
    let rate = columns.first().map_or(Ok(1), |(id, _)| rec.table_rate(*id)).map_err(recorder_error)?;
    let loop_hz = u64::from(ctl.config().loop_hz.max(1));

    for (key, value) in [("VERSION", 1), ("TYPE", 1), ("SEPARATOR", 32), ("DIM", columns.len() as u64)] {
        out.line();
        out.s("# ");
        out.s(key);
        out.s(" = ");
        out.u(value);
    }
    out.line();
    out.s("# SAMPLE_TIME = ");
    seconds_from_ns(out, u64::from(rate) * 1_000_000_000 / loop_hz);
    out.line();
    out.s("# NDATA = ");
    out.u(rows as u64);
    for (k, (_, opt)) in columns.iter().enumerate() {
        let (what, unit) = option_text(*opt);
        out.line();
        out.s("# NAME");
        out.u(k as u64);
        out.s(" = ");
        out.s(what);
        out.s(" of axis 1");
        if !unit.is_empty() {
            out.s(" (");
            out.s(unit);
            out.s(")");
        }
    }
    out.line();
    out.s("# END_HEADER");
    let mut cursor = DrrCursor { columns, next: first, end: first + rows };
    if write_rows(&mut cursor, rec, out, gcs.part_bytes) {
        out.open_end();
        gcs.drr = Some(cursor);
    }
    Ok(())
}

/// Writes the cursor's rows while they fit in `out` and leave it at most `part` bytes long;
/// whether rows remain.
pub(super) fn write_rows(cursor: &mut DrrCursor, rec: &Recorder, out: &mut Out, part: usize) -> bool {
    while cursor.next < cursor.end {
        if out.room() < ROW_MAX || out.buf.len().saturating_add(ROW_MAX) > part {
            break;
        }
        out.line();
        for (k, (id, opt)) in cursor.columns.iter().enumerate() {
            if k > 0 {
                out.s(" ");
            }
            let v = rec.point(*id, cursor.next).unwrap_or(0);
            write_point(out, *opt, v);
        }
        cursor.next += 1;
    }
    cursor.next < cursor.end
}

impl DrrCursor {
    /// Rows left.
    pub fn rows_left(&self) -> usize {
        self.end.saturating_sub(self.next)
    }
}

/// The shortest part [`Gcs::set_reply_part`] takes: two of the longest rows.
pub const PART_MIN: usize = 2 * ROW_MAX;

/// The long `DRR?` reply's continuation, beside the rows it writes.
impl Gcs {
    /// The next part of a reply that goes on (see [`Gcs::reply_pending`]), appended to `reply`
    /// (give it an empty one: a part is as long as the buffer takes, or as
    /// [`Gcs::set_reply_part`] allows).
    pub fn continue_reply(&mut self, board: &dyn Board, reply: &mut Reply) {
        let Some(mut cursor) = self.drr.take() else { return };
        let Some(rec) = board.recorder() else { return };
        let mut out = Out { buf: reply, lines: 0, ok: true };
        let before = cursor.rows_left();
        if write_rows(&mut cursor, rec, &mut out, self.part_bytes) {
            if cursor.rows_left() == before {
                // No room for a single row: the caller's buffer was not empty. Give up.
                return;
            }
            out.open_end();
            self.drr = Some(cursor);
        } else {
            out.finish();
        }
    }
}

/// Writes point `v` of option `opt` in the protocol's unit (`1.000050`, `98.250`, `nan`, `2`).
pub fn write_point(out: &mut dyn crate::gcs::num::Sink, opt: u32, v: i32) -> bool {
    if v == recorder::NO_VALUE {
        return out.put(b"nan");
    }
    write_scaled(out, i64::from(v), recorder::decimals(opt))
}
