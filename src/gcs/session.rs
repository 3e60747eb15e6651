//! One client's byte link, with a reply that may take seconds to send: [`LinkSession`]. The
//! board's UART task (and `host-sim serve`) hands it every received byte as it arrives and asks
//! it for the bytes to send next, so received bytes are read while a long reply (`DRR?`,
//! 27 KB, 2.4 s at 115 200 baud) is being written, and none waits in the UART's receive ring.
//!
//! What the client sees:
//! - Commands run one at a time, in the order received; a command runs once the reply before it
//!   has been handed to the link whole. Bytes received meanwhile wait in a queue of
//!   [`QUEUE_CAPACITY`] bytes, in order.
//! - `#24` (0x18) received while a reply is being sent stops the controller at once
//!   ([`Gcs::stop_now`]), and cuts the reply: it ends with the line being sent (the first line
//!   not yet handed to the link whole; the next line when only its final LF was left), that
//!   line ended by a bare LF instead of space + LF, so a client that reads up to an LF without a
//!   space before it (PIPython) sees a complete reply, shorter than announced; nothing of the
//!   rest is sent. The `#24` byte itself stays in the queue and runs in its place (it stops
//!   again whatever a command received before it started, and latches error 10, as PIPython's
//!   `StopAll` expects from its `ERR?`). `#24` with no reply in flight simply runs.
//! - `#4`, `#5` and `#7` wait in the queue like lines: their answers cannot go inside another reply.
//! - A byte that finds the queue full is lost, and so is every byte received until the queue
//!   has drained up to it (a `#24` among them still stops the controller): in its place among the
//!   commands, the line the first lost byte belonged to executes nothing and latches error 3
//!   (command buffer overrun), and the rest of the line the last lost byte belonged to is
//!   discarded up to its LF. A client that waits for each reply never fills the queue.
//!
//! A long reply is formatted [`REPLY_PART`] bytes at a time ([`Gcs::set_reply_part`]), so the
//! board's task is never long away from its receive ring.

use super::{Board, Gcs, Reply, SharedController};

/// Received bytes kept while a reply is being sent.
pub const QUEUE_CAPACITY: usize = 512;
/// The part of a long reply formatted at once.
pub const REPLY_PART: usize = 512;
/// `#24`: stop all axes.
pub const STOP_ALL: u8 = 0x18;

/// See the module.
pub struct LinkSession {
    /// The reply (or part of one) being sent, and how much of it the link has taken.
    out: Reply,
    sent: usize,
    /// `#24` came while a reply was in flight and its last line is not placed yet.
    cut: bool,
    queue: heapless::Deque<u8, QUEUE_CAPACITY>,
    /// Bytes were lost after this many of the queued bytes.
    lost_after: Option<usize>,
    /// The last lost byte was an LF.
    lost_lf: bool,
    counts: SessionCounts,
}

/// What a session did, for diagnostics and tests.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SessionCounts {
    /// `#24`s that stopped the controller while a reply was in flight.
    pub stops_in_flight: u32,
    /// Replies cut short by them.
    pub cuts: u32,
    /// Received bytes lost to a full queue.
    pub lost: u32,
}

impl Default for LinkSession {
    fn default() -> Self {
        Self::new()
    }
}

impl LinkSession {
    pub fn new() -> Self {
        LinkSession {
            out: Reply::new(),
            sent: 0,
            cut: false,
            queue: heapless::Deque::new(),
            lost_after: None,
            lost_lf: false,
            counts: SessionCounts::default(),
        }
    }

    /// Received bytes, as they arrive: a `#24` stops the controller and cuts the reply in
    /// flight; every byte is queued and commands run while no reply is in flight.
    pub fn receive(
        &mut self,
        bytes: &[u8],
        gcs: &mut Gcs,
        shared: &mut impl SharedController,
        board: &mut dyn Board,
    ) {
        gcs.set_reply_part(REPLY_PART);
        for &b in bytes {
            if b == STOP_ALL && self.replying(gcs) {
                gcs.stop_now(shared);
                self.counts.stops_in_flight = self.counts.stops_in_flight.saturating_add(1);
                if !self.cut {
                    self.cut = true;
                    self.place_cut(gcs);
                }
            }
            self.enqueue(b);
            self.advance(gcs, shared, board);
        }
    }

    /// The bytes to send next (empty: nothing to send until more is received). Hand them to
    /// the link and report how many it took with [`LinkSession::sent`].
    pub fn output(&self) -> &[u8] {
        self.out.get(self.sent..).unwrap_or_default()
    }

    /// The link took `n` bytes of [`LinkSession::output`]: the next part of a long reply is
    /// formatted, or the next queued commands run.
    pub fn sent(
        &mut self,
        n: usize,
        gcs: &mut Gcs,
        shared: &mut impl SharedController,
        board: &mut dyn Board,
    ) {
        self.sent = self.sent.saturating_add(n).min(self.out.len());
        self.advance(gcs, shared, board);
    }

    /// Whether a reply is in flight (bytes of it not yet taken by the link, or parts of it not
    /// yet formatted).
    pub fn replying(&self, gcs: &Gcs) -> bool {
        self.sent < self.out.len() || gcs.reply_pending()
    }

    /// Bytes the queue still takes.
    pub fn room(&self) -> usize {
        QUEUE_CAPACITY - self.queue.len()
    }

    /// Bytes received and not yet run.
    pub fn queued(&self) -> usize {
        self.queue.len()
    }

    pub fn counts(&self) -> SessionCounts {
        self.counts
    }

    fn enqueue(&mut self, b: u8) {
        if self.lost_after.is_none() && self.queue.push_back(b).is_ok() {
            return;
        }
        if self.lost_after.is_none() {
            self.lost_after = Some(self.queue.len());
        }
        self.lost_lf = b == b'\n';
        self.counts.lost = self.counts.lost.saturating_add(1);
    }

    /// Until there is something to send or nothing left to run: the next part of the reply,
    /// or the next queued byte.
    fn advance(&mut self, gcs: &mut Gcs, shared: &mut impl SharedController, board: &mut dyn Board) {
        loop {
            if self.sent < self.out.len() {
                return;
            }
            if gcs.reply_pending() {
                // Each part either adds bytes or ends the reply: this loop ends.
                self.out.clear();
                self.sent = 0;
                gcs.continue_reply(board, &mut self.out);
                if self.cut {
                    self.place_cut(gcs);
                }
                continue;
            }
            self.cut = false;
            if self.lost_after == Some(0) {
                self.lost_after = None;
                gcs.receive_overrun(self.lost_lf);
            }
            let Some(b) = self.queue.pop_front() else { return };
            if let Some(n) = self.lost_after.as_mut() {
                *n = n.saturating_sub(1);
            }
            if let Some(pending) = gcs.push_byte(b) {
                self.out.clear();
                self.sent = 0;
                gcs.execute_shared(&pending, shared, board, &mut self.out);
            }
        }
    }

    /// Ends the reply in flight with the line being sent (see the module), if that line is in
    /// the buffer; otherwise the next part places it.
    fn place_cut(&mut self, gcs: &mut Gcs) {
        let rest = self.out.get(self.sent..).unwrap_or_default();
        // Only the LF of the line's space + LF is left: the line after it ends the reply.
        let space_sent =
            self.sent > 0 && self.out.get(self.sent - 1) == Some(&b' ') && rest.first() == Some(&b'\n');
        let from = self.sent + usize::from(space_sent);
        let rest = self.out.get(from..).unwrap_or_default();
        match rest.windows(2).position(|w| w == b" \n") {
            Some(i) => {
                self.out.truncate(from + i);
                // Room: one byte was just truncated away.
                let _ = self.out.push(b'\n');
                gcs.abandon_reply();
                self.cut = false;
                self.counts.cuts = self.counts.cuts.saturating_add(1);
            }
            // The reply's last line is being sent: it ends as it would have.
            None if !gcs.reply_pending() => self.cut = false,
            None => {}
        }
    }
}
