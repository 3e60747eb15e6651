//! What the tests that talk to a running `host-sim serve` share.

use std::ffi::OsStr;
use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Stdio};

/// `host-sim serve --tcp` on a free port for `duration_s`, with `extra` arguments; returns the
/// child and the address it printed.
pub fn serve<I, S>(duration_s: u32, extra: I) -> (Child, String)
where
    I: IntoIterator<Item = S>,
    S: AsRef<OsStr>,
{
    let mut child = Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .args(["serve", "--tcp", "127.0.0.1:0", "--duration-s", &duration_s.to_string()])
        .args(extra)
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("serve starts");
    let mut line = String::new();
    BufReader::new(child.stdout.take().expect("stdout")).read_line(&mut line).expect("listening line");
    let addr = line.trim().rsplit(' ').next().expect("address").to_string();
    (child, addr)
}
