//! A small PI GCS 2.0 client: the host side of the wire protocol (README, "UART commands"), over
//! TCP (`host-sim serve --tcp`) or a serial port (a board's ST-LINK virtual COM port, or the pty
//! of `host-sim serve --pty`). Used by `host-sim characterize` and `host-sim calibrate` to drive a motor like any client.

use anyhow::{anyhow, bail, Context, Result};
use std::io::{ErrorKind, Read, Write};
use std::net::TcpStream;
use std::path::Path;
use std::time::{Duration, Instant};

/// Longest wait for a reply before the controller counts as gone.
const REPLY_TIMEOUT: Duration = Duration::from_secs(3);

/// A byte stream to one controller whose reads give up after a short wait (returning 0).
trait Port: Read + Write {}
impl<T: Read + Write> Port for T {}

pub struct GcsClient {
    port: Box<dyn Port>,
    /// What the link is, for error messages ("127.0.0.1:50000", "/dev/ttyACM0").
    name: String,
    /// Bytes received after the end of the last reply (never expected; kept, not dropped).
    pending: Vec<u8>,
}

impl GcsClient {
    /// The controller on `tcp` or else `serial` (the commands' `--tcp`/`--serial`).
    pub fn open(tcp: Option<&str>, serial: Option<&Path>, baud: u32) -> Result<Self> {
        match (tcp, serial) {
            (Some(addr), _) => GcsClient::connect_tcp(addr),
            (None, Some(dev)) => GcsClient::open_serial(dev, baud),
            (None, None) => bail!("give --tcp ADDR:PORT or --serial DEV"),
        }
    }

    pub fn connect_tcp(addr: &str) -> Result<Self> {
        let stream = TcpStream::connect(addr).with_context(|| format!("cannot connect to {addr}"))?;
        stream.set_read_timeout(Some(Duration::from_millis(50)))?;
        stream.set_nodelay(true)?;
        Ok(GcsClient { port: Box::new(stream), name: addr.to_string(), pending: Vec::new() })
    }

    /// Opens a serial device (raw mode, 8N1 at `baud`).
    #[cfg(unix)]
    pub fn open_serial(path: &Path, baud: u32) -> Result<Self> {
        let file = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .open(path)
            .with_context(|| format!("cannot open serial port {}", path.display()))?;
        serial::make_raw(&file, baud).with_context(|| format!("cannot configure {}", path.display()))?;
        Ok(GcsClient { port: Box::new(file), name: path.display().to_string(), pending: Vec::new() })
    }

    #[cfg(not(unix))]
    pub fn open_serial(path: &Path, _baud: u32) -> Result<Self> {
        bail!("serial ports are supported on Unix hosts only ({})", path.display())
    }

    /// Sends one command line (LF appended).
    pub fn send(&mut self, line: &str) -> Result<()> {
        let mut bytes = line.as_bytes().to_vec();
        bytes.push(b'\n');
        self.port
            .write_all(&bytes)
            .and_then(|_| self.port.flush())
            .with_context(|| format!("{}: write failed", self.name))
    }

    /// Sends a query and returns its whole reply (every line, LF-separated, without the final LF).
    /// A GCS reply ends with the first line that does not end in a space.
    pub fn query(&mut self, line: &str) -> Result<String> {
        self.send(line)?;
        self.read_reply(line)
    }

    /// A single-byte command (`#5` = 0x05, `#7` = 0x07, `#24` = 0x18) and its one-line reply.
    pub fn query_byte(&mut self, byte: u8) -> Result<String> {
        self.port
            .write_all(&[byte])
            .and_then(|_| self.port.flush())
            .with_context(|| format!("{}: write failed", self.name))?;
        self.read_reply(&format!("#{byte}"))
    }

    fn read_reply(&mut self, what: &str) -> Result<String> {
        let deadline = Instant::now() + REPLY_TIMEOUT;
        let mut buf = [0u8; 256];
        loop {
            // A complete reply: a line that does not end in " \n".
            let mut start = 0;
            while let Some(pos) = self.pending.iter().skip(start).position(|&b| b == b'\n') {
                let end = start + pos;
                if end == 0 || self.pending.get(end - 1) != Some(&b' ') {
                    let reply: Vec<u8> = self.pending.drain(..=end).collect();
                    let text = String::from_utf8_lossy(reply.get(..end).unwrap_or_default()).into_owned();
                    return Ok(text.replace(" \n", "\n"));
                }
                start = end + 1;
            }
            if Instant::now() >= deadline {
                bail!("{}: no reply to '{what}' within {} s", self.name, REPLY_TIMEOUT.as_secs());
            }
            match self.port.read(&mut buf) {
                Ok(0) => {}
                Ok(n) => self.pending.extend_from_slice(buf.get(..n).unwrap_or_default()),
                Err(e)
                    if matches!(
                        e.kind(),
                        ErrorKind::WouldBlock | ErrorKind::TimedOut | ErrorKind::Interrupted
                    ) => {}
                Err(e) => return Err(anyhow!(e).context(format!("{}: read failed", self.name))),
            }
        }
    }

    /// Sends a command that has no reply, then `ERR?`: a latched error fails with its number.
    pub fn command(&mut self, line: &str) -> Result<()> {
        self.send(line)?;
        match self.error()? {
            0 => Ok(()),
            e => bail!("{}: '{line}' was refused with GCS error {e}", self.name),
        }
    }

    /// `ERR?`: the latched error number (and clears it).
    pub fn error(&mut self) -> Result<i32> {
        let r = self.query("ERR?")?;
        r.trim().parse().map_err(|_| anyhow!("{}: ERR? answered '{r}'", self.name))
    }

    /// The value of a one-axis query such as `POS? 1` → `1=0.001234`.
    pub fn axis_value(&mut self, query: &str) -> Result<String> {
        let r = self.query(query)?;
        let value = r
            .trim()
            .strip_prefix("1=")
            .ok_or_else(|| anyhow!("{}: '{query}' answered '{r}', expected 1=<value>", self.name))?;
        Ok(value.to_string())
    }

    /// A parameter of axis 1 as a number: `SPA? 1 0x36` → `1 0x36=0.000050`.
    pub fn param_f64(&mut self, id: u32) -> Result<f64> {
        let query = format!("SPA? 1 0x{id:X}");
        let r = self.query(&query)?;
        r.trim().split_once('=').and_then(|(_, v)| v.trim().parse().ok()).ok_or_else(|| {
            anyhow!("{}: '{query}' answered '{}', expected 1 0x{id:X}=<number>", self.name, r.trim())
        })
    }

    /// A one-axis numeric query: `POS? 1` → mm.
    pub fn axis_f64(&mut self, query: &str) -> Result<f64> {
        let v = self.axis_value(query)?;
        // XTM? and similar carry several numbers; the first one is the answer here.
        let first = v.split_whitespace().next().unwrap_or_default();
        first.parse().map_err(|_| anyhow!("{}: '{query}' answered '{v}', not a number", self.name))
    }

    /// `#5`: motion status bit mask (bit 0: axis 1 moving, referencing or stepping).
    pub fn motion_status(&mut self) -> Result<u32> {
        let r = self.query_byte(0x05)?;
        u32::from_str_radix(r.trim().trim_start_matches("0x"), 16)
            .map_err(|_| anyhow!("{}: #5 answered '{r}'", self.name))
    }

    /// Polls `#5` until nothing moves; fails after `timeout`.
    pub fn wait_until_still(&mut self, timeout: Duration) -> Result<()> {
        let deadline = Instant::now() + timeout;
        loop {
            if self.motion_status()? & 1 == 0 {
                return Ok(());
            }
            if Instant::now() >= deadline {
                bail!("{}: the axis still moves after {:.1} s", self.name, timeout.as_secs_f64());
            }
            std::thread::sleep(Duration::from_millis(5));
        }
    }
}

#[cfg(unix)]
mod serial {
    use std::fs::File;
    use std::os::fd::AsRawFd;

    /// Raw mode, 8N1, no flow control, reads that return after at most 0.1 s.
    pub fn make_raw(file: &File, baud: u32) -> std::io::Result<()> {
        let speed = match baud {
            9600 => libc::B9600,
            19200 => libc::B19200,
            38400 => libc::B38400,
            57600 => libc::B57600,
            115200 => libc::B115200,
            230400 => libc::B230400,
            460800 => libc::B460800,
            921600 => libc::B921600,
            _ => {
                return Err(std::io::Error::new(
                    std::io::ErrorKind::InvalidInput,
                    format!("unsupported baud rate {baud}"),
                ))
            }
        };
        let fd = file.as_raw_fd();
        // SAFETY: termios calls on a descriptor we own; every result is checked.
        unsafe {
            let mut t: libc::termios = std::mem::zeroed();
            if libc::tcgetattr(fd, &mut t) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            libc::cfmakeraw(&mut t);
            t.c_cflag |= libc::CLOCAL | libc::CREAD;
            t.c_cflag &= !(libc::CRTSCTS | libc::CSTOPB | libc::PARENB);
            t.c_cc[libc::VMIN] = 0;
            t.c_cc[libc::VTIME] = 1;
            if libc::cfsetispeed(&mut t, speed) != 0 || libc::cfsetospeed(&mut t, speed) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            if libc::tcsetattr(fd, libc::TCSANOW, &t) != 0 {
                return Err(std::io::Error::last_os_error());
            }
        }
        Ok(())
    }
}
