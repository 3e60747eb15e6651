//! Framing: collecting received bytes into commands ([`Pending`], [`Gcs::push_byte`]) and
//! building replies ([`Out`]: lines separated by space + LF, closed by LF), including a reply
//! that goes on over several buffers (the `DRR?` cursor: [`Gcs::reply_pending`],
//! [`Gcs::continue_reply`]).

use super::num::{self, write_fixed, write_i64, write_scaled, write_u64};
use super::{Gcs, Reply, LINE_CAPACITY};

pub(super) type Line = heapless::Vec<u8, LINE_CAPACITY>;

/// A complete command, ready for [`Gcs::execute`].
// No allocation: the line travels by value (264 bytes), which is what the firmware queues.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Pending {
    /// A command line without its LF.
    Line(Line),
    /// A line longer than [`LINE_CAPACITY`], discarded up to its LF.
    TooLong,
    /// A single-byte command (0x04, 0x05, 0x07, 0x18) or another control byte.
    Byte(u8),
}

pub(super) fn is_space(b: u8) -> bool {
    b == b' ' || b == b'\t' || b == b'\r'
}

/// Reply under construction: lines separated by space + LF, closed by LF; tracks overflow.
pub(super) struct Out<'a> {
    pub(super) buf: &'a mut Reply,
    pub(super) lines: u32,
    pub(super) ok: bool,
}

impl num::Sink for Out<'_> {
    fn put(&mut self, bytes: &[u8]) -> bool {
        self.ok &= self.buf.extend_from_slice(bytes).is_ok();
        self.ok
    }
}

impl<'a> Out<'a> {
    /// A reply appended to `buf`.
    pub(super) fn new(buf: &'a mut Reply) -> Self {
        Out { buf, lines: 0, ok: true }
    }
    pub(super) fn line(&mut self) {
        if self.lines > 0 {
            self.s(" \n");
        }
        self.lines = self.lines.saturating_add(1);
    }
    #[inline(never)]
    pub(super) fn s(&mut self, text: &str) {
        num::Sink::put(self, text.as_bytes());
    }
    pub(super) fn b(&mut self, bytes: &[u8]) {
        num::Sink::put(self, bytes);
    }
    pub(super) fn u(&mut self, v: u64) {
        write_u64(self, v);
    }
    pub(super) fn i(&mut self, v: i64) {
        write_i64(self, v);
    }
    /// Nanometres as millimetres with six decimals (`1=2.500000`).
    pub(super) fn mm(&mut self, nm: i64) {
        write_scaled(self, nm, 6);
    }
    pub(super) fn fixed(&mut self, v: f64, decimals: u32) {
        write_fixed(self, v, decimals);
    }
    /// Bytes the reply buffer still takes.
    pub(super) fn room(&self) -> usize {
        self.buf.capacity().saturating_sub(self.buf.len())
    }
    /// Ends the last line as one more follows in the next reply (space + LF), so that
    /// [`Out::finish`] adds nothing.
    pub(super) fn open_end(&mut self) {
        if self.lines > 0 {
            self.s(" \n");
        }
        self.lines = 0;
    }
    pub(super) fn finish(&mut self) {
        if self.lines > 0 {
            self.s("\n");
        }
    }
}

impl Gcs {
    /// Cheap: collect one received byte. Some(..) once a complete command (a line, or a
    /// single-byte command) is ready.
    pub fn push_byte(&mut self, byte: u8) -> Option<Pending> {
        match byte {
            b'\n' => {
                let pending = if self.overflow {
                    Pending::TooLong
                } else {
                    Pending::Line(core::mem::take(&mut self.line))
                };
                self.line.clear();
                self.overflow = false;
                Some(pending)
            }
            // A NUL between lines is line noise (a port opening), not a command.
            0x00 if self.line.is_empty() && !self.overflow => None,
            // Control bytes other than tab and CR are commands of their own (#5, #7, #24; any
            // other is an unknown command), wherever they arrive.
            0x00..=0x08 | 0x0b | 0x0c | 0x0e..=0x1f => Some(Pending::Byte(byte)),
            _ => {
                if self.line.push(byte).is_err() {
                    self.overflow = true;
                }
                None
            }
        }
    }

    /// Received bytes were lost (a board's queue of received bytes was full:
    /// [`super::LinkSession`]): the line they belonged to executes nothing and latches error 3
    /// (GCS: command too long or command buffer overrun). `line_ended`: the lost bytes ended
    /// with an LF; otherwise the rest of the line, up to its LF, is discarded too.
    pub fn receive_overrun(&mut self, line_ended: bool) {
        self.line.clear();
        self.overflow = !line_ended;
        self.error = super::error::COMMAND_TOO_LONG;
    }

    /// Forgets a partly received line (e.g. when a client disconnects mid-line).
    pub fn discard_partial_line(&mut self) {
        self.line.clear();
        self.overflow = false;
    }

    /// Whether the last command's reply goes on (a `DRR?` longer than one reply buffer): call
    /// [`Gcs::continue_reply`] with an empty buffer and send what it adds until this is false.
    /// A new command drops what is left.
    pub fn reply_pending(&self) -> bool {
        self.drr.is_some()
    }
}
