//! Replays a client's transcript against the virtual controller and checks every reply the way
//! that client parses it: `tests/epics/motorpigcs2_c867.txt`, what EPICS motorPIGCS2 sends to
//! a C-863/C-867 class controller (the file says its format). `tests/epics/replay.py` reads the
//! same file over TCP against `host-sim serve`; here it runs on the controller core and the
//! simulated plant, stepped by plant time (deterministic), in `cargo test`.

use super::serve::VirtualController;
use piezo_drive::gcs::Reply;

/// How the client reads one reply.
#[derive(Debug, Clone, PartialEq)]
pub enum Rule {
    /// Sent only: nothing may come back.
    Nothing,
    /// The upper-cased reply contains this.
    Idn(String),
    /// The reply's lines, trailing spaces cut.
    Axes(Vec<String>),
    /// Any one-line reply.
    Text,
    /// `ERR?` read as an integer.
    Error(i64),
    /// The number after the first `=`: equal to, within a tolerance of, above.
    Equals(f64),
    Near(f64, f64),
    Above(f64),
    /// The number after the first `=` is a whole number above 0.
    PositiveInteger,
    /// `#4`: four hex digits from the third character on, masked, equal the value.
    Register {
        mask: u32,
        value: u32,
    },
    /// `#5`: the reply as hex, masked, equals the value.
    Motion {
        mask: u32,
        value: u32,
    },
    /// `#7`: the first byte is 0xB1.
    Ready,
}

/// One exchange of the transcript.
#[derive(Debug, Clone, PartialEq)]
pub struct Step {
    /// Line in the transcript (1-based), for messages.
    pub line: usize,
    pub command: String,
    /// Poll until the rule holds, failing after this many seconds.
    pub until_s: Option<f64>,
    pub rule: Rule,
}

fn number(word: Option<&str>, line: usize) -> Result<f64, String> {
    word.and_then(|w| w.parse().ok()).ok_or_else(|| format!("line {line}: a number expected"))
}

fn hex(word: Option<&str>, line: usize) -> Result<u32, String> {
    word.and_then(|w| u32::from_str_radix(w.trim_start_matches("0x"), 16).ok())
        .ok_or_else(|| format!("line {line}: a hex number expected"))
}

/// Reads a transcript: `<command> :: [until <s> ::] <rule>` lines; `#` followed by a space, and
/// blank lines, are comments (`#4` is a command).
pub fn parse(text: &str) -> Result<Vec<Step>, String> {
    let mut steps = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        let t = raw.trim();
        if t.is_empty() || t == "#" || t.starts_with("# ") {
            continue;
        }
        let parts: Vec<&str> = t.split("::").map(str::trim).collect();
        let (command, until_s, rule) = match parts.as_slice() {
            [c, r] => (*c, None, *r),
            [c, u, r] => {
                let mut w = u.split_whitespace();
                if w.next() != Some("until") {
                    return Err(format!("line {line}: `until <seconds>` expected"));
                }
                (*c, Some(number(w.next(), line)?), *r)
            }
            _ => return Err(format!("line {line}: `<command> :: <rule>` expected")),
        };
        let mut w = rule.split_whitespace();
        let rule = match w.next() {
            Some("-") => Rule::Nothing,
            Some("idn") => Rule::Idn(w.collect::<Vec<_>>().join(" ")),
            Some("axes") => Rule::Axes(w.map(String::from).collect()),
            Some("text") => Rule::Text,
            Some("err") => Rule::Error(number(w.next(), line)? as i64),
            Some("=") => Rule::Equals(number(w.next(), line)?),
            Some("~") => Rule::Near(number(w.next(), line)?, number(w.next(), line)?),
            Some(">") => Rule::Above(number(w.next(), line)?),
            Some("int>0") => Rule::PositiveInteger,
            Some("hex") => Rule::Register { mask: hex(w.next(), line)?, value: hex(w.next(), line)? },
            Some("hex5") => Rule::Motion { mask: hex(w.next(), line)?, value: hex(w.next(), line)? },
            Some("ready") => Rule::Ready,
            other => return Err(format!("line {line}: unknown rule {other:?}")),
        };
        steps.push(Step { line, command: command.to_string(), until_s, rule });
    }
    Ok(steps)
}

/// The bytes the client sends: `#4`, `#5`, `#7` as their single bytes, any other command with
/// its LF.
pub fn command_bytes(command: &str) -> Vec<u8> {
    match command {
        "#4" => vec![0x04],
        "#5" => vec![0x05],
        "#7" => vec![0x07],
        c => format!("{c}\n").into_bytes(),
    }
}

/// The client's atof of what follows the first `=`.
fn after_equals(text: &str) -> Result<f64, String> {
    let (_, v) = text.split_once('=').ok_or_else(|| format!("no '=' in {text:?}"))?;
    v.trim().parse().map_err(|_| format!("no number after '=' in {text:?}"))
}

/// Checks `reply` (the bytes the board sent) against `rule`: the framing the client's link
/// reads (an LF at the end, read on while the text ends in a space; no CR), then the rule.
pub fn check(rule: &Rule, reply: &[u8]) -> Result<(), String> {
    if *rule == Rule::Nothing {
        return if reply.is_empty() {
            Ok(())
        } else {
            Err(format!("expected nothing, got {:?}", String::from_utf8_lossy(reply)))
        };
    }
    let shown = String::from_utf8_lossy(reply).into_owned();
    let Some(body) = reply.strip_suffix(b"\n") else {
        return Err(format!("reply not ended by LF: {shown:?}"));
    };
    if reply.contains(&b'\r') || body.ends_with(b" ") {
        return Err(format!("reply framing: {shown:?}"));
    }
    // Lines of a multi-line reply end in space + LF; none may end the reply early.
    let lines: Vec<&[u8]> = body.split(|&b| b == b'\n').collect();
    if lines.iter().rev().skip(1).any(|l| !l.ends_with(b" ")) {
        return Err(format!("a line inside the reply lacks its trailing space: {shown:?}"));
    }
    if *rule == Rule::Ready {
        return if body.first() == Some(&0xB1) { Ok(()) } else { Err(format!("not ready: {shown:?}")) };
    }
    let text = String::from_utf8_lossy(body).into_owned();
    let ok = match rule {
        Rule::Nothing | Rule::Ready => true,
        Rule::Idn(s) => text.to_uppercase().contains(&s.to_uppercase()),
        Rule::Axes(axes) => {
            let got: Vec<&str> = text.split('\n').map(|l| l.trim_end_matches(' ')).collect();
            got == axes.iter().map(String::as_str).collect::<Vec<_>>()
        }
        Rule::Text => lines.len() == 1 && !text.is_empty(),
        Rule::Error(n) => text.trim().parse::<i64>().ok() == Some(*n),
        Rule::Equals(v) => after_equals(&text)? == *v,
        Rule::Near(v, tol) => (after_equals(&text)? - v).abs() <= *tol,
        Rule::Above(v) => after_equals(&text)? > *v,
        Rule::PositiveInteger => {
            let x = after_equals(&text)?;
            x >= 1.0 && x.fract() == 0.0
        }
        Rule::Register { mask, value } => {
            let digits = text.get(2..6).ok_or_else(|| format!("too short for #4: {text:?}"))?;
            let r = u32::from_str_radix(digits, 16).map_err(|_| format!("not hex: {text:?}"))?;
            r & mask == *value
        }
        Rule::Motion { mask, value } => {
            let r = u32::from_str_radix(text.trim(), 16).map_err(|_| format!("not hex: {text:?}"))?;
            r & mask == *value
        }
    };
    if ok {
        Ok(())
    } else {
        Err(format!("{rule:?} does not hold for {shown:?}"))
    }
}

/// Plant time between two exchanges: what a 115 200 Bd link and a driver's turnaround take.
const EXCHANGE_S: f64 = 0.002;
/// Plant time between two polls of an `until` step.
const POLL_S: f64 = 0.01;

/// Replays `steps` on `vc`, the plant stepped by plant time between exchanges; the first step
/// whose reply breaks its rule is the error.
pub fn replay(vc: &mut VirtualController, steps: &[Step]) -> Result<(), String> {
    for s in steps {
        let mut waited = 0.0;
        loop {
            let mut out = Reply::new();
            vc.feed(&command_bytes(&s.command), &mut out);
            vc.sil.run_until(EXCHANGE_S, |_| false);
            match (check(&s.rule, &out), s.until_s) {
                (Ok(()), _) => break,
                (Err(_), Some(limit)) if waited < limit => {
                    vc.sil.run_until(POLL_S, |_| false);
                    waited += POLL_S + EXCHANGE_S;
                }
                (Err(e), _) => return Err(format!("line {} `{}`: {e}", s.line, s.command)),
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::motor::params::Params;
    use crate::virtual_controller::serve::ServeArgs;

    const TRANSCRIPT: &str = include_str!("../../../tests/epics/motorpigcs2_c867.txt");

    fn args() -> ServeArgs {
        crate::virtual_controller::serve::test_args()
    }

    #[test]
    fn the_epics_c867_path_runs_unmodified() {
        let steps = parse(TRANSCRIPT).unwrap();
        assert!(steps.len() > 60, "{} steps", steps.len());
        let mut vc = VirtualController::new(&Params::prototype(), &args()).unwrap();
        replay(&mut vc, &steps).unwrap();
    }

    #[test]
    fn without_the_setting_the_driver_finds_no_class() {
        // The honest identity names no PI model: the driver's class selection fails at once.
        let steps = parse(TRANSCRIPT).unwrap();
        let idn = steps.iter().position(|s| s.command == "*IDN?").unwrap();
        let mut vc = VirtualController::new(&Params::prototype(), &args()).unwrap();
        let err = replay(&mut vc, &steps[idn..=idn]).unwrap_err();
        assert!(err.contains("Idn"), "{err}");
    }

    #[test]
    fn the_rules_fail_where_the_driver_would() {
        // Each rule against a reply the driver could not use.
        let bad: &[(Rule, &[u8])] = &[
            (Rule::Nothing, b"0\n"),
            (Rule::Equals(1.0), b"1=1 \n"),
            (Rule::Equals(1.0), b"1\n"),
            (Rule::Equals(1.0), b"1=1\r\n"),
            (Rule::Error(0), b"0"),
            (Rule::Register { mask: 0x1000, value: 0x1000 }, b"1=0x1000\n"),
            (Rule::Register { mask: 0x1000, value: 0x1000 }, b"0x0FFF\n"),
            (Rule::Ready, b"\xB0\n"),
            (Rule::Axes(vec!["1".into()]), b"1 \n2\n"),
            (Rule::PositiveInteger, b"1 0xE=0.5\n"),
        ];
        for (rule, reply) in bad {
            assert!(check(rule, reply).is_err(), "{rule:?} {reply:?}");
        }
        let good: &[(Rule, &[u8])] = &[
            (Rule::Equals(1.0), b"1=1\n"),
            (Rule::Equals(20000.0), b"1 0xE=20000\n"),
            (Rule::Register { mask: 0xF000, value: 0x9000 }, b"0x9005\n"),
            (Rule::Axes(vec!["1".into(), "2".into()]), b"1 \n2\n"),
            (Rule::Ready, b"\xB1\n"),
        ];
        for (rule, reply) in good {
            assert_eq!(check(rule, reply), Ok(()), "{rule:?} {reply:?}");
        }
    }
}
