//! `host-sim serve`: the virtual controller. The firmware's control core runs against the plant
//! paced to the wall clock, and speaks PI GCS 2.0 through the very protocol module the firmware
//! uses ([`piezo_drive::gcs`]), over TCP (`--tcp 127.0.0.1:PORT`) or a pseudo-terminal (`--pty`).
//! One client at a time; a client that disconnects mid-line leaves nothing behind. The link
//! runs through the board's [`LinkSession`]: a `#24` received while a reply is being written
//! stops at once and cuts the reply, as on the board's UART.

use crate::harness::sil::{controller_config, Sil};
use crate::motor::params::Params;
use crate::motor::plant::ExternalLoad;
use anyhow::{bail, Context, Result};
use piezo_drive::controller::ControllerConfig;
use piezo_drive::gcs::{Board, Gcs, LinkSession, LoopStats, Pending, Reply, Unshared};
use piezo_drive::recorder::Recorder;
use piezo_drive::storage;
use std::fmt::Write as _;
use std::io::{ErrorKind, Read, Write};
use std::net::{TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

/// What `host-sim serve` runs (the CLI's flags of the same names build it).
#[derive(Debug, Clone)]
pub struct ServeArgs {
    /// Listen for one GCS client at a time on this TCP address (e.g. 127.0.0.1:50000).
    pub tcp: Option<String>,
    /// Open a pseudo-terminal and print its path (a serial port for clients such as PIPython's
    /// `ConnectRS232`).
    pub pty: bool,
    /// Log every exchange (bytes in, bytes out) to stderr.
    pub verbose: bool,
    /// Preload force F0 of the simulated motor (N).
    pub preload_n: f64,
    /// A weight hanging on the simulated slider, pulling toward −x (N): what a user hangs on a
    /// stage to characterise it under load.
    pub load_n: f64,
    /// Encoder index mark at this slider position of the plant (µm; the slider starts at 0).
    pub index_um: f64,
    /// Limit switches this far beyond the index on either side (mm).
    pub limit_mm: f64,
    /// File for `WPA`: the board's flash parameter record, byte for byte, loaded at start-up;
    /// in memory when absent.
    pub store: Option<PathBuf>,
    /// Stop after this many seconds (for tests); runs until killed when absent.
    pub duration_s: Option<f64>,
    /// The parameter file the board's firmware was built for (its motor table and hardware
    /// defaults, as `host-sim firmware-table` bakes them); the plant's own file when absent.
    /// Another file here plays a motor whose truth differs from what its firmware believes.
    pub firmware_params: Option<PathBuf>,
}

/// The simulated board's side of the protocol.
pub struct SimBoard {
    store: Option<PathBuf>,
    /// Last `WPA` record when there is no file.
    pub stored: Option<Vec<u8>>,
    pub stats: LoopStats,
    /// The data recorder, filled after every control period as on the board.
    pub recorder: Box<Recorder>,
}

impl Board for SimBoard {
    /// As the board's flash task: the core's record ([`storage::encode`]) of a configuration
    /// the core accepts, byte for byte, into the `--store` file (or memory).
    fn store_parameters(&mut self, cfg: &ControllerConfig) -> bool {
        if storage::validate(cfg).is_err() {
            return false;
        }
        let record = storage::encode(cfg);
        match &self.store {
            Some(path) => std::fs::write(path, record).is_ok(),
            None => {
                self.stored = Some(record.to_vec());
                true
            }
        }
    }
    fn serial_number(&self) -> u32 {
        1
    }
    fn loop_stats(&self) -> LoopStats {
        self.stats
    }
    fn recorder(&self) -> Option<&Recorder> {
        Some(&self.recorder)
    }
}

/// The configuration the board boots with: the record in `store` decoded over the defaults,
/// as the firmware loads its flash page; the defaults when there is no file yet.
pub fn boot_config(p: &Params, store: Option<&Path>) -> Result<ControllerConfig> {
    let defaults = controller_config(p);
    let Some(path) = store.filter(|path| path.exists()) else { return Ok(defaults) };
    let bytes = std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
    storage::decode(&bytes, &defaults).map_err(|e| {
        anyhow::anyhow!(
            "{}: not a parameter record this controller loads ({e:?}); `WPA` writes one, \
             remove the file to start from the defaults",
            path.display()
        )
    })
}

/// Printable form of protocol bytes for the log.
fn escape(bytes: &[u8]) -> String {
    let mut s = String::new();
    for &b in bytes {
        match b {
            b'\n' => s.push_str("\\n"),
            b'\r' => s.push_str("\\r"),
            b'\t' => s.push_str("\\t"),
            0x20..=0x7e => s.push(char::from(b)),
            _ => {
                let _ = write!(s, "\\x{b:02x}");
            }
        }
    }
    s
}

/// A byte stream to one client.
trait Link {
    /// Bytes now available (empty when none); Err when the client went away.
    fn poll_read(&mut self, buf: &mut [u8]) -> std::io::Result<usize>;
    fn write_all_bytes(&mut self, bytes: &[u8]) -> std::io::Result<()>;
}

impl Link for TcpStream {
    fn poll_read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        match self.read(buf) {
            Ok(0) => Err(std::io::Error::new(ErrorKind::UnexpectedEof, "client closed the connection")),
            Ok(n) => Ok(n),
            Err(e) if e.kind() == ErrorKind::WouldBlock || e.kind() == ErrorKind::Interrupted => Ok(0),
            Err(e) => Err(e),
        }
    }
    fn write_all_bytes(&mut self, bytes: &[u8]) -> std::io::Result<()> {
        self.set_nonblocking(false)?;
        let r = self.write_all(bytes).and_then(|_| self.flush());
        self.set_nonblocking(true)?;
        r
    }
}

/// The virtual controller: the board (controller + plant), the protocol, the pacing.
pub struct VirtualController {
    pub sil: Sil,
    pub gcs: Gcs,
    pub board: SimBoard,
    verbose: bool,
    start: Instant,
    sim_start_s: f64,
}

impl VirtualController {
    pub fn new(p: &Params, args: &ServeArgs) -> Result<Self> {
        crate::check::preload_n("--preload-n", args.preload_n)?;
        crate::check::position_um("--index-um", args.index_um)?;
        crate::check::in_range("--limit-mm", args.limit_mm, 0.0, false, 1000.0, "mm")?;
        if let Some(store) = &args.store {
            crate::check::output_file("--store", store)?;
        }
        // Parameters stored by an earlier WPA, loaded as the firmware loads them from flash.
        let firmware = match &args.firmware_params {
            Some(path) => {
                Params::load(path).with_context(|| format!("--firmware-params {}", path.display()))?
            }
            None => p.clone(),
        };
        let cfg = boot_config(&firmware, args.store.as_deref())?;
        crate::check::in_range("--load-n", args.load_n, 0.0, true, 100.0, "N")?;
        let mut sil = Sil::new(p, cfg, args.preload_n, 1)?;
        sil.set_load(ExternalLoad::opposing(args.load_n, 1));
        let index_m = args.index_um * 1e-6;
        sil.index_position_m = Some(index_m);
        sil.limits_m = Some((index_m - args.limit_mm * 1e-3, index_m + args.limit_mm * 1e-3));
        let mut vc = VirtualController {
            sil,
            gcs: Gcs::new(),
            board: SimBoard {
                store: args.store.clone(),
                stored: None,
                stats: LoopStats::default(),
                recorder: Box::default(),
            },
            verbose: args.verbose,
            start: Instant::now(),
            sim_start_s: 0.0,
        };
        // "Cycles" are nanoseconds on the host.
        vc.board.stats.core_clock_hz = 1_000_000_000;
        // Settle the force-cell filter before anyone talks to us.
        vc.sil.run_until(0.05, |_| false);
        vc.sim_start_s = vc.sil.time_s();
        vc.start = Instant::now();
        Ok(vc)
    }

    /// Runs the plant up to the wall clock (at most 0.1 s of catching up per call).
    pub fn advance(&mut self) {
        let wall = self.start.elapsed().as_secs_f64();
        let behind = wall - (self.sil.time_s() - self.sim_start_s);
        if behind > 0.1 {
            // Fell behind (a stalled host): skip ahead rather than race.
            self.board.stats.overruns = self.board.stats.overruns.saturating_add(1);
            self.sim_start_s += behind - 0.1;
        }
        while self.sil.time_s() - self.sim_start_s < wall {
            self.period();
            let ns = u32::try_from(self.sil.last_step_ns).unwrap_or(u32::MAX);
            self.board.stats.step_cycles_last = ns;
            self.board.stats.step_cycles_max = self.board.stats.step_cycles_max.max(ns);
        }
    }

    /// One control period, then the recorder's point (as the board's tick does).
    pub fn period(&mut self) {
        self.sil.period();
        self.board.recorder.sample(&self.sil.controller);
    }

    /// Feeds `text` through the protocol and returns the replies as text: for callers that drive
    /// the simulated board directly (tests, `calibrate --tune`), not a link.
    pub fn exchange(&mut self, text: &str) -> String {
        let mut out = Reply::new();
        self.feed(text.as_bytes(), &mut out);
        String::from_utf8_lossy(&out).into_owned()
    }

    /// Feeds received bytes through the protocol; replies are appended to `out` (which must
    /// have room for them all: tests only; a `DRR?` goes on only while it has room).
    pub fn feed(&mut self, bytes: &[u8], out: &mut Reply) {
        for &b in bytes {
            if let Some(p) = self.gcs.push_byte(b) {
                self.execute(&p, out);
                while self.gcs.reply_pending() {
                    self.gcs.continue_reply(&self.board, out);
                }
            }
        }
    }

    /// Runs one command; its reply is appended to `out`.
    fn execute(&mut self, p: &Pending, out: &mut Reply) {
        let before = out.len();
        self.gcs.execute(p, &mut self.sil.controller, &mut self.board, out);
        if self.verbose {
            let cmd = match p {
                Pending::Line(l) => escape(l),
                Pending::TooLong => "<line too long>".into(),
                Pending::Byte(b) => escape(&[*b]),
            };
            let reply = out.get(before..).map(escape).unwrap_or_default();
            eprintln!(
                "[{:9.4} s] > {cmd}  < {}{}",
                self.sil.time_s() - self.sim_start_s,
                if reply.is_empty() { "(nothing)" } else { &reply },
                match self.gcs.latched_error() {
                    0 => String::new(),
                    e => format!("  [error {e} latched]"),
                }
            );
        }
    }

    /// Serves one client until it goes away (or `deadline` passes), through the board's
    /// [`LinkSession`]: received bytes are read between the parts of a reply as the board's
    /// UART task reads them, so a `#24` stops at once and cuts a long reply the same way. Only
    /// as many bytes are read as the session's queue takes: TCP and the pty hold the rest back,
    /// so nothing is ever lost here.
    fn serve_client(&mut self, link: &mut dyn Link, deadline: Option<Instant>) -> Result<()> {
        let mut session = LinkSession::new();
        let mut buf = [0u8; 512];
        // The client stopped sending (or went away): what it sent is still answered, as far as
        // it takes the replies.
        let mut eof = false;
        loop {
            if deadline.is_some_and(|d| Instant::now() >= d) {
                return Ok(());
            }
            self.advance();
            let room = if eof { 0 } else { session.room().min(buf.len()) };
            let n = if room == 0 {
                0
            } else {
                match link.poll_read(buf.get_mut(..room).unwrap_or_default()) {
                    Ok(n) => n,
                    Err(e) => {
                        if self.verbose {
                            eprintln!("client stopped sending: {e}");
                        }
                        eof = true;
                        0
                    }
                }
            };
            if n > 0 {
                let chunk = buf.get(..n).unwrap_or_default();
                if self.verbose {
                    eprintln!("[{:9.4} s] > {}", self.sil.time_s() - self.sim_start_s, escape(chunk));
                }
                let mut ctl = Unshared(&mut self.sil.controller);
                session.receive(chunk, &mut self.gcs, &mut ctl, &mut self.board);
            }
            let out = session.output();
            if out.is_empty() && eof {
                self.gcs.discard_partial_line();
                self.gcs.abandon_reply();
                return Ok(());
            }
            if out.is_empty() {
                if n == 0 {
                    std::thread::sleep(Duration::from_micros(500));
                }
                continue;
            }
            // One part at a time, reading in between.
            let part = out.get(..out.len().min(WRITE_PART)).unwrap_or_default();
            if self.verbose {
                eprintln!(
                    "[{:9.4} s] < {}{}",
                    self.sil.time_s() - self.sim_start_s,
                    escape(part),
                    match self.gcs.latched_error() {
                        0 => String::new(),
                        e => format!("  [error {e} latched]"),
                    }
                );
            }
            if let Err(e) = link.write_all_bytes(part) {
                if self.verbose {
                    eprintln!("client gone while replying: {e}");
                }
                self.gcs.discard_partial_line();
                self.gcs.abandon_reply();
                return Ok(());
            }
            let sent = part.len();
            let mut ctl = Unshared(&mut self.sil.controller);
            session.sent(sent, &mut self.gcs, &mut ctl, &mut self.board);
        }
    }
}

/// Bytes written to the client at once: what the board's 512-byte transmit ring takes.
const WRITE_PART: usize = 512;

#[cfg(unix)]
mod pty {
    use anyhow::{bail, Result};
    use std::ffi::CStr;
    use std::fs::File;
    use std::io::{ErrorKind, Read, Write};
    use std::os::fd::FromRawFd;

    /// Master side of a raw-mode pseudo-terminal; the slave stays open so the master never
    /// sees a hang-up between clients.
    pub struct Pty {
        master: File,
        _slave: File,
        pub path: String,
    }

    impl Pty {
        pub fn open() -> Result<Self> {
            // SAFETY: plain libc calls on descriptors we own; every result is checked.
            unsafe {
                let fd = libc::posix_openpt(libc::O_RDWR | libc::O_NOCTTY);
                if fd < 0 {
                    bail!("posix_openpt failed: {}", std::io::Error::last_os_error());
                }
                let master = File::from_raw_fd(fd);
                if libc::grantpt(fd) != 0 || libc::unlockpt(fd) != 0 {
                    bail!("grantpt/unlockpt failed: {}", std::io::Error::last_os_error());
                }
                let mut name = [0 as libc::c_char; 256];
                if libc::ptsname_r(fd, name.as_mut_ptr(), name.len()) != 0 {
                    bail!("ptsname_r failed: {}", std::io::Error::last_os_error());
                }
                let path = CStr::from_ptr(name.as_ptr()).to_string_lossy().into_owned();
                let sfd = libc::open(name.as_ptr(), libc::O_RDWR | libc::O_NOCTTY);
                if sfd < 0 {
                    bail!("opening {path} failed: {}", std::io::Error::last_os_error());
                }
                let slave = File::from_raw_fd(sfd);
                // Raw mode: no echo, no line editing, no CR/LF translation either way.
                let mut t: libc::termios = std::mem::zeroed();
                if libc::tcgetattr(sfd, &mut t) != 0 {
                    bail!("tcgetattr failed: {}", std::io::Error::last_os_error());
                }
                libc::cfmakeraw(&mut t);
                if libc::tcsetattr(sfd, libc::TCSANOW, &t) != 0 {
                    bail!("tcsetattr failed: {}", std::io::Error::last_os_error());
                }
                let flags = libc::fcntl(fd, libc::F_GETFL);
                if flags < 0 || libc::fcntl(fd, libc::F_SETFL, flags | libc::O_NONBLOCK) != 0 {
                    bail!("fcntl failed: {}", std::io::Error::last_os_error());
                }
                Ok(Pty { master, _slave: slave, path })
            }
        }
    }

    impl super::Link for Pty {
        fn poll_read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
            match self.master.read(buf) {
                Ok(n) => Ok(n),
                Err(e) if e.kind() == ErrorKind::WouldBlock || e.kind() == ErrorKind::Interrupted => Ok(0),
                Err(e) => Err(e),
            }
        }
        fn write_all_bytes(&mut self, mut bytes: &[u8]) -> std::io::Result<()> {
            while !bytes.is_empty() {
                match self.master.write(bytes) {
                    Ok(n) => bytes = bytes.get(n..).unwrap_or_default(),
                    Err(e) if e.kind() == ErrorKind::WouldBlock || e.kind() == ErrorKind::Interrupted => {
                        std::thread::sleep(std::time::Duration::from_micros(200));
                    }
                    Err(e) => return Err(e),
                }
            }
            Ok(())
        }
    }
}

/// `host-sim serve`.
pub fn run(p: &Params, args: &ServeArgs) -> Result<()> {
    if args.tcp.is_some() == args.pty {
        bail!("give exactly one of --tcp ADDR:PORT and --pty");
    }
    if let Some(d) = args.duration_s {
        if !(d.is_finite() && d > 0.0) {
            bail!("--duration-s must be a positive number of seconds, got {d}");
        }
    }
    let mut vc = VirtualController::new(p, args)?;
    let deadline = args.duration_s.map(|d| Instant::now() + Duration::from_secs_f64(d));
    if let Some(addr) = &args.tcp {
        let listener = TcpListener::bind(addr).with_context(|| format!("binding {addr}"))?;
        listener.set_nonblocking(true)?;
        println!("listening on {}", listener.local_addr()?);
        std::io::stdout().flush()?;
        loop {
            if deadline.is_some_and(|d| Instant::now() >= d) {
                return Ok(());
            }
            vc.advance();
            match listener.accept() {
                Ok((mut stream, peer)) => {
                    stream.set_nonblocking(true)?;
                    let _ = stream.set_nodelay(true);
                    if args.verbose {
                        eprintln!("client {peer} connected");
                    }
                    vc.serve_client(&mut stream, deadline)?;
                    if args.verbose {
                        eprintln!("client {peer} done");
                    }
                }
                Err(e) if e.kind() == ErrorKind::WouldBlock => std::thread::sleep(Duration::from_millis(1)),
                Err(e) => return Err(e).context("accepting a client"),
            }
        }
    }
    #[cfg(unix)]
    {
        let mut link = pty::Pty::open()?;
        println!("pty {}", link.path);
        std::io::stdout().flush()?;
        vc.serve_client(&mut link, deadline)
    }
    #[cfg(not(unix))]
    bail!("--pty needs a Unix host")
}

/// The virtual controller's defaults for the crate's tests: no link, 16 N, the index 20 µm
/// below the start, travel ±55 mm.
#[cfg(test)]
pub(crate) fn test_args() -> ServeArgs {
    ServeArgs {
        tcp: None,
        pty: false,
        verbose: false,
        preload_n: 16.0,
        load_n: 0.0,
        index_um: -20.0,
        limit_mm: 55.0,
        store: None,
        duration_s: None,
        firmware_params: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use piezo_drive::controller::State;
    use piezo_drive::gcs::{params::PARAMS, REPLY_CAPACITY};

    fn args() -> ServeArgs {
        super::test_args()
    }

    /// Runs the plant (not paced) until `done` or `max_s` of plant time.
    fn run_until(vc: &mut VirtualController, max_s: f64, done: impl Fn(&Sil) -> bool) -> bool {
        vc.sil.run_until(max_s, done)
    }

    fn number(reply: &str) -> f64 {
        reply.trim_end().split('=').nth(1).unwrap().parse().unwrap()
    }

    #[test]
    fn frf_finds_the_emulated_index_and_moves_land_on_target() {
        let p = Params::prototype();
        let mut vc = VirtualController::new(&p, &args()).unwrap();
        assert_eq!(vc.exchange("RON 1 1\nFRF 1\nERR?\n"), "0\n");
        assert!(run_until(&mut vc, 1.0, |s| s.controller.state() != State::Referencing));
        assert_eq!(vc.exchange("FRF? 1\nERR?\n"), "1=1\n0\n");
        // The index is where the plant's slider crossed −20 µm: the controller's zero now sits
        // there to within the distance covered in one control period at the search speed.
        let pos_mm = number(&vc.exchange("POS?\n"));
        let slider_um = vc.sil.plant.slider_position_m() * 1e6;
        let zero_um = slider_um - pos_mm * 1e3;
        assert!((zero_um - -20.0).abs() < 0.3, "zero at {zero_um} µm");
        assert_eq!(vc.exchange("SVO 1 1\nMOV 1 0.05\nERR?\n"), "0\n");
        assert!(run_until(&mut vc, 2.0, |s| s.controller.on_target()));
        assert_eq!(vc.exchange("ONT?\n"), "1=1\n");
        let pos_mm = number(&vc.exchange("POS?\n"));
        assert!((pos_mm - 0.05).abs() <= 50e-6, "{pos_mm}");
        let true_mm = (vc.sil.plant.slider_position_m() * 1e6 - zero_um) * 1e-3;
        assert!((true_mm - 0.05).abs() < 0.4e-3, "plant at {true_mm} mm");
    }

    #[test]
    fn stp_and_hlt_mid_move_brake_without_a_fault() {
        let p = Params::prototype();
        for stop in ["STP\n", "HLT 1\n", "\x18"] {
            let mut vc = VirtualController::new(&p, &args()).unwrap();
            assert_eq!(vc.exchange("RON 1 0\nSVO 1 1\nMOV 1 1\nERR?\n"), "0\n");
            vc.sil.run_until(0.1, |_| false);
            let moving_mm_s = vc.sil.plant.slider_velocity_m_s() * 1e3;
            assert!(moving_mm_s > 1.0, "{moving_mm_s} mm/s");
            assert_eq!(vc.exchange(stop), "");
            let stopped = vc.sil.run_until(0.5, |s| s.controller.on_target());
            assert!(stopped, "{stop:?}: {:?}", vc.sil.controller.state());
            assert_eq!(vc.exchange("ERR?\nXFT?\n\x05"), "10\n1=0 no fault\n0\n", "{stop:?}");
            let pos_mm = number(&vc.exchange("POS?\n"));
            assert!(pos_mm > 0.1 && pos_mm < 0.5, "{stop:?} stopped at {pos_mm} mm");
        }
    }

    #[test]
    fn servo_on_again_mid_move_changes_nothing() {
        let p = Params::prototype();
        let mut vc = VirtualController::new(&p, &args()).unwrap();
        assert_eq!(vc.exchange("RON 1 0\nSVO 1 1\nMOV 1 0.4\nERR?\n"), "0\n");
        vc.sil.run_until(0.1, |_| false);
        assert_eq!(vc.exchange("SVO 1 1\nERR?\n\x05"), "0\n1\n");
        assert!(vc.sil.run_until(1.0, |s| s.controller.on_target()));
        assert_eq!(vc.exchange("ERR?\n"), "0\n");
        assert!((number(&vc.exchange("POS?\n")) - 0.4).abs() <= 50e-6);
    }

    #[test]
    fn frf_turns_round_at_the_negative_limit_when_the_index_is_behind() {
        let p = Params::prototype();
        // Index 20 µm above the start, negative switch 30 µm below it.
        let a = ServeArgs { index_um: 20.0, limit_mm: 0.05, ..args() };
        let mut vc = VirtualController::new(&p, &a).unwrap();
        assert_eq!(vc.exchange("FRF\nERR?\n"), "0\n");
        let mut lowest = f64::MAX;
        let found = vc.sil.run_until(3.0, |s| {
            lowest = lowest.min(s.plant.slider_position_m());
            s.controller.state() != State::Referencing
        });
        assert!(found);
        assert_eq!(vc.exchange("FRF?\nERR?\n"), "1=1\n0\n");
        let slider_um = vc.sil.plant.slider_position_m() * 1e6;
        let pos_um = number(&vc.exchange("POS?\n")) * 1e3;
        assert!((slider_um - pos_um - 20.0).abs() < 0.3, "slider {slider_um} µm reads {pos_um} µm");
        // It went down to the switch at −30 µm first.
        assert!(lowest < -29e-6, "lowest {lowest}");
    }

    #[test]
    fn frf_without_an_index_references_on_the_negative_limit() {
        let p = Params::prototype();
        let a = ServeArgs { index_um: 10.0, limit_mm: 0.03, ..args() };
        let mut vc = VirtualController::new(&p, &a).unwrap();
        vc.sil.index_position_m = None; // a scale without index; switches at −20 and +40 µm
        let mut highest = f64::MIN;
        assert_eq!(vc.exchange("FRF\nERR?\n"), "0\n");
        assert!(vc.sil.run_until(3.0, |s| {
            highest = highest.max(s.plant.slider_position_m());
            s.controller.state() != State::Referencing
        }));
        assert_eq!(vc.exchange("FRF?\nERR?\n"), "1=1\n0\n");
        // It went all the way to the positive switch looking for an index, then back.
        assert!(highest >= 40e-6, "highest {highest}");
        let slider_um = vc.sil.plant.slider_position_m() * 1e6;
        let pos_um = number(&vc.exchange("POS?\n")) * 1e3;
        // Zero (parameter 0x1017) where the negative switch closed, at −20 µm.
        assert!((slider_um - pos_um - -20.0).abs() < 0.3, "slider {slider_um} µm reads {pos_um} µm");
    }

    #[test]
    fn frf_on_the_negative_limit_switch() {
        let p = Params::prototype();
        let a = ServeArgs { index_um: 5.0, limit_mm: 0.03, ..args() };
        let mut vc = VirtualController::new(&p, &a).unwrap();
        // Reference on the switch (the stage has no index, say) and call it −1 mm.
        assert_eq!(vc.exchange("SPA 1 0x1016 1 1 0x1017 -1\nERR?\nSVO 1 1\nFRF 1\nERR?\n"), "0\n0\n");
        assert!(vc.sil.run_until(3.0, |s| s.controller.state() != State::Referencing));
        // Servo was on: it holds where it found the switch.
        assert_eq!(vc.exchange("FRF?\nSVO?\n"), "1=1\n1=1\n");
        let pos_mm = number(&vc.exchange("POS?\n"));
        assert!((pos_mm - -1.0).abs() < 0.5e-3, "{pos_mm}");
        let slider_um = vc.sil.plant.slider_position_m() * 1e6;
        assert!(slider_um <= 5.0 - 30.0 + 0.5, "switch at −25 µm, slider at {slider_um} µm");
    }

    #[test]
    fn open_loop_stepping_moves_the_slider_and_stops() {
        let p = Params::prototype();
        let mut vc = VirtualController::new(&p, &args()).unwrap();
        let x0 = vc.sil.plant.slider_position_m();
        // 200 cycles at 1.5 kHz, 80 V, toward −x.
        assert_eq!(vc.exchange("XOS 1 -200 80 1500\nERR?\n\x05"), "0\n1\n");
        assert!(vc.sil.run_until(1.0, |s| s.controller.state() == State::Idle));
        let moved_um = (vc.sil.plant.slider_position_m() - x0) * 1e6;
        // 0.133 s at up to the no-load speed (~2 mm/s here): tens of µm, negative.
        assert!(moved_um < -20.0 && moved_um > -400.0, "moved {moved_um} µm");
        vc.sil.run_until(0.002, |_| false); // the amplitude slews out
        assert_eq!(vc.exchange("\x05XDA?\n"), "0\n1=0.000\n");
    }

    #[test]
    fn wpa_stores_the_boards_record_and_a_restart_loads_it() {
        let p = Params::prototype();
        let path = std::env::temp_dir().join(format!("host-sim-wpa-{}.bin", std::process::id()));
        let _ = std::fs::remove_file(&path);
        let a = ServeArgs { store: Some(path.clone()), ..args() };
        let mut vc = VirtualController::new(&p, &a).unwrap();
        // Only with the servo off and nothing moving (error 34 otherwise), as on the board where
        // writing the flash stalls the CPU.
        assert_eq!(vc.exchange("SVO 1 1\nWPA 100\nERR?\n"), "34\n");
        assert!(vc.board.stored.is_none() && !path.exists());
        assert_eq!(vc.exchange("SVO 1 0\nVEL 1 1.5\nSPA 1 0x15 20 1 0x1019 100\nWPA 100\nERR?\n"), "0\n");
        // The file is the record the board writes to its flash page, byte for byte.
        let record = std::fs::read(&path).unwrap();
        let mut expected = controller_config(&p);
        expected.velocity_max_nm_s = 1.5e6;
        expected.travel_max_nm = 20_000_000;
        expected.reference_timeout_s = 100.0;
        assert_eq!(record, storage::encode(&expected).to_vec());
        // A new virtual controller starts with them, as the board does from flash.
        let mut again = VirtualController::new(&p, &a).unwrap();
        assert_eq!(again.sil.controller.config(), &expected);
        assert_eq!(
            again.exchange("VEL?\nTMX?\nSPA? 1 0x1019\nERR?\n"),
            "1=1.5\n1=20.000000\n1 0x1019=100\n0\n"
        );
        // A file that is not a record is refused with the reason.
        std::fs::write(&path, "SPA 1 0xA 1.5\n").unwrap();
        let e = VirtualController::new(&p, &a).err().expect("a text file is not a record").to_string();
        assert!(e.contains("not a parameter record"), "{e}");
        let _ = std::fs::remove_file(&path);
    }

    #[test]
    fn wpa_without_a_file_keeps_the_record_in_memory() {
        let p = Params::prototype();
        let mut vc = VirtualController::new(&p, &args()).unwrap();
        assert_eq!(vc.exchange("SPA 1 0x1 55\nWPA\nERR?\n"), "0\n");
        let stored = vc.board.stored.clone().expect("stored");
        assert_eq!(stored, storage::encode(vc.sil.controller.config()).to_vec());
        assert_eq!(storage::decode(&stored, &controller_config(&p)).unwrap().kp_per_s, 55.0);
    }

    /// A link that delivers one chunk, collects what is written, then reports the client gone.
    struct OneChunk {
        chunk: Option<Vec<u8>>,
        written: Vec<u8>,
    }

    impl Link for OneChunk {
        fn poll_read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
            match self.chunk.take() {
                Some(c) => {
                    buf[..c.len()].copy_from_slice(&c);
                    Ok(c.len())
                }
                None => Err(std::io::Error::new(ErrorKind::UnexpectedEof, "done")),
            }
        }
        fn write_all_bytes(&mut self, bytes: &[u8]) -> std::io::Result<()> {
            self.written.extend_from_slice(bytes);
            Ok(())
        }
    }

    #[test]
    fn large_replies_to_commands_sent_together_are_complete() {
        let p = Params::prototype();
        let pos31 = format!("POS?{}\n", " 1".repeat(31));
        // HLP? (about 2 kB) after replies of every size from about 0.5 to 2.4 kB, all in one
        // read, as a client that does not wait for each reply sends them.
        for n in 0..=4 {
            for k in 0..=34 {
                let mut cmds = vec!["HPA?\n".to_string(), "SPA?\n".to_string()];
                cmds.extend(std::iter::repeat_n(pos31.clone(), n));
                cmds.extend(std::iter::repeat_n("POS?\n".to_string(), k));
                cmds.extend(["HLP?\n", "*IDN?\n", "ERR?\n"].map(String::from));
                let chunk = cmds.concat().into_bytes();
                assert!(chunk.len() <= 512, "one read: {}", chunk.len());
                // Each reply on its own, from a controller in the same state.
                let mut single = VirtualController::new(&p, &args()).unwrap();
                let expected: String = cmds.iter().map(|c| single.exchange(c)).collect();
                assert!(expected.len() > REPLY_CAPACITY, "{}", expected.len());
                let mut vc = VirtualController::new(&p, &args()).unwrap();
                let mut link = OneChunk { chunk: Some(chunk), written: Vec::new() };
                vc.serve_client(&mut link, None).unwrap();
                let got = String::from_utf8(link.written).unwrap();
                assert_eq!(got, expected, "{n} × POS? 1…1, {k} × POS?");
                // Complete by the GCS framing: both help lists end, SPA? lists every
                // parameter, and no error (3: reply too long) was latched.
                assert!(got.starts_with("#Possible parameters of this device: \n"), "{got}");
                assert_eq!(got.matches("end of help\n").count(), 2, "{got}");
                assert!(got.contains("\nHLP? Get List Of Available Commands \n"), "{got}");
                assert!(got.ends_with(", PD-SB1, 000001, 0.1.0\n0\n"), "{got}");
                let spa_lines = got.lines().filter(|l| l.starts_with("1 0x")).count();
                assert_eq!(spa_lines, PARAMS.len());
            }
        }
    }

    /// A link that delivers each input once the server has written `after` bytes, collects what
    /// is written, and reports the client gone once all is delivered and 20 polls found nothing
    /// new written.
    struct Scripted {
        inputs: std::collections::VecDeque<(usize, Vec<u8>)>,
        written: Vec<u8>,
        idle_polls: usize,
        seen: usize,
    }

    impl Link for Scripted {
        fn poll_read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
            if let Some((after, bytes)) = self.inputs.front() {
                if self.written.len() >= *after && bytes.len() <= buf.len() {
                    buf[..bytes.len()].copy_from_slice(bytes);
                    let n = bytes.len();
                    self.inputs.pop_front();
                    return Ok(n);
                }
                return Ok(0);
            }
            if self.written.len() == self.seen {
                self.idle_polls += 1;
            } else {
                (self.seen, self.idle_polls) = (self.written.len(), 0);
            }
            if self.idle_polls >= 20 {
                return Err(std::io::Error::new(ErrorKind::UnexpectedEof, "done"));
            }
            Ok(0)
        }
        fn write_all_bytes(&mut self, bytes: &[u8]) -> std::io::Result<()> {
            self.written.extend_from_slice(bytes);
            Ok(())
        }
    }

    #[test]
    fn a_stop_during_a_long_reply_stops_and_cuts_it_at_a_line() {
        let p = Params::prototype();
        let mut vc = VirtualController::new(&p, &args()).unwrap();
        let setup =
            "RON 1 0\nSVO 1 1\nDRC 1 1 1 2 1 2 3 1 3 4 1 1 5 1 2 6 1 3 7 1 1 8 1 2\nRTR 1\nDRT 0 4 0\n";
        assert_eq!(vc.exchange(&format!("{setup}MOV 1 5\nERR?\n")), "0\n");
        // The tables full, and a few periods more.
        for _ in 0..piezo_drive::recorder::DEPTH + 40 {
            vc.period();
        }
        assert_eq!(vc.sil.controller.state(), State::Moving);
        // #24 once 2 000 bytes of the DRR? reply (eight tables of 1 024 points) are out.
        let mut link = Scripted {
            inputs: [(0, b"DRR?\n".to_vec()), (2000, b"\x18ERR?\n".to_vec())].into(),
            written: Vec::new(),
            idle_polls: 0,
            seen: 0,
        };
        vc.serve_client(&mut link, None).unwrap();
        // Stopped: the target is the braking point, short of 5 mm.
        assert!(vc.sil.controller.target_nm() < 5_000_000, "{}", vc.sil.controller.target_nm());
        let got = String::from_utf8(link.written).unwrap();
        // The DRR? reply ends at the first LF without a space before it (PIPython's end of a
        // reply), at most one write part (512 bytes) and one line after the #24 came; then
        // ERR? → 10 (the #24 ran in its place).
        let end = got.as_bytes().windows(2).position(|w| w[0] != b' ' && w[1] == b'\n').unwrap() + 2;
        let (drr, rest) = got.split_at(end);
        assert_eq!(rest, "10\n", "{got}");
        assert!(drr.len() >= 2000 && drr.len() <= 2000 + 512 + 120, "{}", drr.len());
        let header_end = drr.find("# END_HEADER \n").unwrap() + "# END_HEADER \n".len();
        let ndata: usize =
            drr.lines().find_map(|l| l.strip_prefix("# NDATA = ")).unwrap().trim().parse().unwrap();
        let rows: Vec<&str> = drr[header_end..].lines().collect();
        // Fewer rows than announced, every one whole (eight numbers), the last ended by a bare LF.
        assert_eq!(ndata, piezo_drive::recorder::DEPTH);
        assert!(!rows.is_empty() && rows.len() < ndata, "{}", rows.len());
        for row in &rows {
            let values: Vec<f64> = row.split_whitespace().map(|v| v.parse().unwrap()).collect();
            assert_eq!(values.len(), 8, "{row:?}");
        }
        assert!(drr.ends_with("\n") && !drr.ends_with(" \n"));
    }

    #[test]
    fn a_client_that_leaves_mid_line_leaves_nothing_behind() {
        let p = Params::prototype();
        let port = {
            let l = TcpListener::bind("127.0.0.1:0").unwrap();
            l.local_addr().unwrap().port()
        };
        let a = ServeArgs { tcp: Some(format!("127.0.0.1:{port}")), duration_s: Some(4.0), ..args() };
        let server = std::thread::spawn(move || run(&p, &a));
        let connect = || {
            for _ in 0..200 {
                if let Ok(s) = TcpStream::connect(("127.0.0.1", port)) {
                    return s;
                }
                std::thread::sleep(Duration::from_millis(10));
            }
            panic!("server did not come up");
        };
        {
            let mut c = connect();
            c.write_all(b"MOV 1").unwrap();
            std::thread::sleep(Duration::from_millis(50));
        } // gone mid-line
        let mut c = connect();
        c.set_read_timeout(Some(Duration::from_secs(2))).unwrap();
        c.write_all(b"CSV?\nERR?\n").unwrap();
        let mut got = Vec::new();
        let mut buf = [0u8; 64];
        while got.len() < 6 {
            let n = c.read(&mut buf).unwrap();
            assert!(n > 0);
            got.extend_from_slice(&buf[..n]);
        }
        assert_eq!(got, b"2.0\n0\n");
        drop(c);
        server.join().unwrap().unwrap();
    }
}
