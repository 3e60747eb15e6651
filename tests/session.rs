//! [`LinkSession`]'s rules at their edges, byte by byte (the UART model in `tests/uart_link.rs`
//! runs the whole scenario): where a `#24` cuts a reply, a `#24` with nothing in flight, and a
//! queue that overflows. Replies from the GCS framing (space + LF between lines, LF at the end)
//! and `HLP?`'s first lines as shared/gcs-notes.md gives them.

mod common;

use common::TestBoard;
use piezo_drive::controller::{Controller, Inputs};
use piezo_drive::defaults;
use piezo_drive::gcs::session::QUEUE_CAPACITY;
use piezo_drive::gcs::{Gcs, LinkSession, Unshared};

const HLP_FIRST: &[u8] = b"The following commands are valid: \n";
const HLP_SECOND: &[u8] = b"#4 Request Status Register";

struct Rig {
    gcs: Gcs,
    ctl: Controller,
    board: TestBoard,
    link: LinkSession,
    /// Everything the link took.
    wire: Vec<u8>,
}

impl Rig {
    fn new() -> Self {
        let mut ctl = Controller::new(defaults::controller_config()).unwrap();
        for _ in 0..10 {
            ctl.step(&Inputs { preload_word: 1310, ..Default::default() });
        }
        Rig { gcs: Gcs::new(), ctl, board: TestBoard::default(), link: LinkSession::new(), wire: Vec::new() }
    }

    fn receive(&mut self, bytes: &[u8]) {
        self.link.receive(bytes, &mut self.gcs, &mut Unshared(&mut self.ctl), &mut self.board);
    }

    /// The link takes at most `n` bytes.
    fn take(&mut self, n: usize) {
        let out = self.link.output();
        let n = n.min(out.len());
        self.wire.extend_from_slice(&out[..n]);
        self.link.sent(n, &mut self.gcs, &mut Unshared(&mut self.ctl), &mut self.board);
    }

    /// The link takes everything, 7 bytes at a time.
    fn drain(&mut self) {
        while !self.link.output().is_empty() {
            self.take(7);
        }
    }

    fn wire(&mut self) -> String {
        // `#7`'s 0xB1 shows as U+FFFD.
        String::from_utf8_lossy(&std::mem::take(&mut self.wire)).into_owned()
    }
}

#[test]
fn a_stop_mid_line_ends_the_reply_with_that_line() {
    let mut rig = Rig::new();
    rig.receive(b"HLP?\n");
    rig.take(10);
    assert!(rig.link.replying(&rig.gcs));
    rig.receive(b"\x18");
    rig.drain();
    // The first line, its space + LF now a bare LF; nothing more.
    let expected = format!("{}\n", String::from_utf8_lossy(&HLP_FIRST[..HLP_FIRST.len() - 2]));
    assert_eq!(rig.wire(), expected);
    assert!(!rig.link.replying(&rig.gcs));
    // The #24 ran in its place: error 10.
    rig.receive(b"ERR?\n");
    rig.drain();
    assert_eq!(rig.wire(), "10\n");
    assert_eq!(rig.link.counts().cuts, 1);
    assert_eq!(rig.link.counts().stops_in_flight, 1);
}

#[test]
fn a_stop_when_only_the_lf_of_a_line_is_left_ends_the_reply_with_the_next_line() {
    let mut rig = Rig::new();
    rig.receive(b"HLP?\n");
    // The first line up to its space: its LF is still to go, and with it the line goes on.
    rig.take(HLP_FIRST.len() - 1);
    rig.receive(b"\x18");
    rig.drain();
    let expected = format!("{}{}\n", String::from_utf8_lossy(HLP_FIRST), String::from_utf8_lossy(HLP_SECOND));
    assert_eq!(rig.wire(), expected);
}

#[test]
fn a_stop_between_lines_ends_the_reply_with_the_next_line() {
    let mut rig = Rig::new();
    rig.receive(b"HLP?\n");
    rig.take(HLP_FIRST.len());
    rig.receive(b"\x18ERR?\n");
    rig.drain();
    let expected =
        format!("{}{}\n10\n", String::from_utf8_lossy(HLP_FIRST), String::from_utf8_lossy(HLP_SECOND));
    assert_eq!(rig.wire(), expected);
}

#[test]
fn a_stop_with_nothing_in_flight_runs_as_ever() {
    let mut rig = Rig::new();
    rig.receive(b"\x18ERR?\n");
    rig.drain();
    assert_eq!(rig.wire(), "10\n");
    assert_eq!(rig.link.counts(), Default::default());
    // A single-line reply in flight is not shortened.
    rig.receive(b"CSV?\n");
    rig.take(1);
    rig.receive(b"\x18");
    rig.drain();
    assert_eq!(rig.wire(), "2.0\n");
    assert_eq!((rig.link.counts().stops_in_flight, rig.link.counts().cuts), (1, 0));
}

#[test]
fn queued_commands_run_in_order_after_the_reply() {
    let mut rig = Rig::new();
    rig.receive(b"HLP?\n");
    rig.receive(b"CSV?\n\x07ERR?\n");
    assert_eq!(rig.link.queued(), 11);
    rig.drain();
    let wire = rig.wire();
    assert!(wire.ends_with("end of help\n2.0\n\u{fffd}\n0\n"), "{wire}");
}

#[test]
fn a_full_queue_costs_the_line_error_3_never_a_silent_loss() {
    let mut rig = Rig::new();
    rig.receive(b"HLP?\n");
    // 102 × POS? (510 bytes) and the start of an ERR?: the queue is full.
    let pos = "POS?\n".repeat(102);
    assert_eq!(pos.len() + 2, QUEUE_CAPACITY);
    rig.receive(pos.as_bytes());
    rig.receive(b"ER");
    assert_eq!(rig.link.room(), 0);
    // The rest of the ERR? line is lost, and so is what follows until the queue drains.
    rig.receive(b"R?\nCSV?\nPO");
    assert_eq!(rig.link.counts().lost, 10);
    let wire = String::from_utf8(rig.link.output().to_vec()).unwrap();
    assert!(wire.starts_with("The following"));
    rig.drain();
    let wire = rig.wire();
    let after_help = wire.split("end of help\n").nth(1).unwrap();
    // Every POS? before the loss answered, nothing for the damaged lines.
    assert_eq!(after_help, "1=0.000000\n".repeat(102));
    // The line the last lost byte belonged to ("PO…") is discarded up to its LF, not run as "S?".
    rig.receive(b"S?\nERR?\n");
    rig.drain();
    assert_eq!(rig.wire(), "3\n");
    // Then all is as before.
    rig.receive(b"CSV?\nERR?\n");
    rig.drain();
    assert_eq!(rig.wire(), "2.0\n0\n");
}

#[test]
fn a_loss_that_ends_with_an_lf_leaves_the_next_line_whole() {
    let mut rig = Rig::new();
    rig.receive(b"HLP?\n");
    rig.receive("POS?\n".repeat(102).as_bytes());
    rig.receive(b"ERR?\n");
    assert_eq!(rig.link.counts().lost, 3);
    rig.drain();
    rig.wire();
    rig.receive(b"CSV?\nERR?\n");
    rig.drain();
    assert_eq!(rig.wire(), "2.0\n3\n");
}
