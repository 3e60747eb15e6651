//! Processor-in-the-loop wire format: one fixed-size frame each way per control period between
//! `host-sim pil` (the plant) and `tools/pil` (this core on an emulated Cortex-M4F). Both sides
//! encode and decode with these functions, so they cannot disagree on the layout. Little-endian.

use crate::controller::{Controller, FaultCode, Inputs, Outputs, State, DAC_SAMPLES_PER_STEP};

/// Host → target: a command for this period (applied before the step) and the sensor inputs.
pub const TICK_BYTES: usize = 20;
/// Target → host: the outputs, the controller's state, the command's result, instruction counts.
pub const REPLY_BYTES: usize = 4 * DAC_SAMPLES_PER_STEP + 16;

/// What the host asks of the controller before this period's step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Command {
    None,
    Servo(bool),
    MoveTo(i64),
    ClearFault,
    /// Start referencing (GCS `FRF`).
    Reference,
    /// Open-loop stepping with the servo off (GCS `XOS`).
    OpenLoop {
        cycles: i32,
        amplitude_v: f32,
        frequency_hz: f32,
    },
    /// End of the run: the target exits.
    Exit,
}

impl Command {
    /// Gives the command to a controller, as both the target and the host build do before the
    /// period's step; true when the controller refuses it. `None` and `Exit` do nothing.
    pub fn apply(self, ctl: &mut Controller) -> bool {
        match self {
            Command::None | Command::Exit => false,
            Command::Servo(on) => ctl.set_servo(on).is_err(),
            Command::MoveTo(nm) => ctl.move_to(nm).is_err(),
            Command::ClearFault => {
                ctl.clear_fault();
                false
            }
            Command::Reference => ctl.start_referencing().is_err(),
            Command::OpenLoop { cycles, amplitude_v, frequency_hz } => {
                ctl.open_loop_step(cycles, amplitude_v, frequency_hz).is_err()
            }
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tick {
    pub command: Command,
    pub inputs: Inputs,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Reply {
    pub outputs: Outputs,
    /// [`state_code`] of the state after the step.
    pub state: u8,
    /// 0 = command accepted (or none), 1 = refused.
    pub command_refused: bool,
    /// Instructions of the whole tick (step + packing the DMA half-buffer) and of the step alone.
    pub tick_instructions: u32,
    pub step_instructions: u32,
    /// Instructions of the lower-rate work done after the step (the model table, when the
    /// controller asked for one; 0 otherwise): on the board a thread-mode task, not the tick.
    pub background_instructions: u32,
}

/// One byte per state: 0 idle, 1 moving, 2 holding, 3 referencing, 4 open loop, 0x80 + fault code.
pub fn state_code(s: State) -> u8 {
    match s.number() {
        Ok(n) => n,
        Err(code) => 0x80 | code as u8,
    }
}

/// The state a [`state_code`] stands for; `None` for a byte no state encodes to.
pub fn decode_state(code: u8) -> Option<State> {
    match code {
        0 => Some(State::Idle),
        1 => Some(State::Moving),
        2 => Some(State::Holding),
        3 => Some(State::Referencing),
        4 => Some(State::OpenLoop),
        c if c & 0x80 != 0 => FaultCode::ALL.into_iter().find(|f| *f as u8 == c & 0x7f).map(State::Fault),
        _ => None,
    }
}

/// Name of a [`state_code`] for reports.
pub fn state_name(code: u8) -> &'static str {
    match decode_state(code) {
        Some(State::Idle) => "idle",
        Some(State::Moving) => "moving",
        Some(State::Holding) => "holding",
        Some(State::Referencing) => "referencing",
        Some(State::OpenLoop) => "open_loop",
        Some(State::Fault(_)) => "fault",
        None => "unknown",
    }
}

fn put(buf: &mut [u8], at: usize, bytes: &[u8]) {
    if let Some(dst) = buf.get_mut(at..at + bytes.len()) {
        dst.copy_from_slice(bytes);
    }
}

fn get<const N: usize>(buf: &[u8], at: usize) -> [u8; N] {
    let mut out = [0u8; N];
    if let Some(src) = buf.get(at..at + N) {
        out.copy_from_slice(src);
    }
    out
}

pub fn encode_tick(t: &Tick) -> [u8; TICK_BYTES] {
    let mut b = [0u8; TICK_BYTES];
    let (cmd, arg, extra): (u8, i64, u32) = match t.command {
        Command::None => (0, 0, 0),
        Command::Servo(on) => (1, i64::from(on), 0),
        Command::MoveTo(nm) => (2, nm, 0),
        Command::ClearFault => (3, 0, 0),
        Command::Reference => (4, 0, 0),
        // Cycles in the low word, the amplitude's bits in the high word, the frequency's after.
        Command::OpenLoop { cycles, amplitude_v, frequency_hz } => {
            (5, i64::from(cycles as u32) | (i64::from(amplitude_v.to_bits()) << 32), frequency_hz.to_bits())
        }
        Command::Exit => (255, 0, 0),
    };
    let flags = u8::from(t.inputs.index)
        | (u8::from(t.inputs.negative_limit) << 1)
        | (u8::from(t.inputs.positive_limit) << 2)
        | (u8::from(t.inputs.index_raw.is_some()) << 3)
        | (u8::from(t.inputs.limits_wired) << 4);
    put(&mut b, 0, &[cmd, flags]);
    put(&mut b, 2, &t.inputs.encoder_raw.to_le_bytes());
    put(&mut b, 4, &t.inputs.preload_word.to_le_bytes());
    put(&mut b, 6, &t.inputs.index_raw.unwrap_or(0).to_le_bytes());
    put(&mut b, 8, &arg.to_le_bytes());
    put(&mut b, 16, &extra.to_le_bytes());
    b
}

/// `None` for an unknown command byte.
pub fn decode_tick(b: &[u8; TICK_BYTES]) -> Option<Tick> {
    let [cmd, flags] = get::<2>(b, 0);
    let arg = i64::from_le_bytes(get::<8>(b, 8));
    let extra = u32::from_le_bytes(get::<4>(b, 16));
    let command = match cmd {
        0 => Command::None,
        1 => Command::Servo(arg != 0),
        2 => Command::MoveTo(arg),
        3 => Command::ClearFault,
        4 => Command::Reference,
        5 => Command::OpenLoop {
            cycles: arg as u32 as i32,
            amplitude_v: f32::from_bits((arg >> 32) as u32),
            frequency_hz: f32::from_bits(extra),
        },
        255 => Command::Exit,
        _ => return None,
    };
    let inputs = Inputs {
        encoder_raw: u16::from_le_bytes(get::<2>(b, 2)),
        preload_word: u16::from_le_bytes(get::<2>(b, 4)),
        index: flags & 1 != 0,
        negative_limit: flags & 2 != 0,
        positive_limit: flags & 4 != 0,
        index_raw: (flags & 8 != 0).then(|| u16::from_le_bytes(get::<2>(b, 6))),
        limits_wired: flags & 16 != 0,
    };
    Some(Tick { command, inputs })
}

pub fn encode_reply(r: &Reply) -> [u8; REPLY_BYTES] {
    let mut b = [0u8; REPLY_BYTES];
    for (i, [a, c]) in r.outputs.dac.iter().enumerate() {
        put(&mut b, 4 * i, &a.to_le_bytes());
        put(&mut b, 4 * i + 2, &c.to_le_bytes());
    }
    let at = 4 * DAC_SAMPLES_PER_STEP;
    put(&mut b, at, &[u8::from(r.outputs.amp_enable), r.state, u8::from(r.command_refused), 0]);
    put(&mut b, at + 4, &r.tick_instructions.to_le_bytes());
    put(&mut b, at + 8, &r.step_instructions.to_le_bytes());
    put(&mut b, at + 12, &r.background_instructions.to_le_bytes());
    b
}

pub fn decode_reply(b: &[u8; REPLY_BYTES]) -> Reply {
    let mut dac = [[0u16; 2]; DAC_SAMPLES_PER_STEP];
    for (i, pair) in dac.iter_mut().enumerate() {
        *pair = [u16::from_le_bytes(get::<2>(b, 4 * i)), u16::from_le_bytes(get::<2>(b, 4 * i + 2))];
    }
    let at = 4 * DAC_SAMPLES_PER_STEP;
    let [enable, state, refused, _] = get::<4>(b, at);
    Reply {
        outputs: Outputs { dac, amp_enable: enable != 0 },
        state,
        command_refused: refused != 0,
        tick_instructions: u32::from_le_bytes(get::<4>(b, at + 4)),
        step_instructions: u32::from_le_bytes(get::<4>(b, at + 8)),
        background_instructions: u32::from_le_bytes(get::<4>(b, at + 12)),
    }
}

// ---------------------------------------------------------------- GCS commands (`--gcs-locks`)

/// First byte of a host → target frame that carries a GCS command instead of a tick: the
/// frame's bytes 2..4 give the length of the command bytes that follow it (as the UART would
/// deliver them: a line with its LF, or a single control byte). The target runs them through
/// [`crate::gcs::Gcs::execute_shared`] on its controller, counting each locked section, and
/// answers with a [`GcsReport`]. No step runs for such a frame.
pub const GCS_TAG: u8 = 6;
/// Most command bytes in one GCS frame (a too-long line fits).
pub const GCS_MAX_BYTES: usize = 512;
/// Most locked sections one command is reported with.
pub const GCS_SECTIONS: usize = 4;
/// Target → host answer to a GCS frame.
pub const GCS_REPORT_BYTES: usize = 20 + 4 * GCS_SECTIONS;

/// What the target did with a GCS frame's bytes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct GcsReport {
    /// Commands the bytes made (0 for bytes that complete none).
    pub commands: u8,
    /// Locked sections run, and the instructions of the first [`GCS_SECTIONS`] of them.
    pub sections: u8,
    pub section_instructions: [u32; GCS_SECTIONS],
    /// Instructions of the whole execution, locked and not.
    pub total_instructions: u32,
    /// The error latched after the command (not cleared).
    pub error: i32,
    /// Length and CRC-32 ([`crate::storage::crc32`]) of the reply bytes.
    pub reply_len: u32,
    pub reply_crc: u32,
}

impl GcsReport {
    /// The longest locked section.
    pub fn max_section(&self) -> u32 {
        self.section_instructions.iter().copied().max().unwrap_or(0)
    }
}

/// The frame that announces `len` command bytes.
pub fn encode_gcs_header(len: usize) -> [u8; TICK_BYTES] {
    let mut b = [0u8; TICK_BYTES];
    put(&mut b, 0, &[GCS_TAG, 0]);
    put(&mut b, 2, &(len.min(GCS_MAX_BYTES) as u16).to_le_bytes());
    b
}

/// The number of command bytes a GCS frame announces; `None` for any other frame.
pub fn decode_gcs_header(b: &[u8; TICK_BYTES]) -> Option<usize> {
    (b[0] == GCS_TAG).then(|| usize::from(u16::from_le_bytes(get::<2>(b, 2))).min(GCS_MAX_BYTES))
}

pub fn encode_gcs_report(r: &GcsReport) -> [u8; GCS_REPORT_BYTES] {
    let mut b = [0u8; GCS_REPORT_BYTES];
    put(&mut b, 0, &[r.commands, r.sections, 0, 0]);
    put(&mut b, 4, &r.total_instructions.to_le_bytes());
    put(&mut b, 8, &r.error.to_le_bytes());
    put(&mut b, 12, &r.reply_len.to_le_bytes());
    put(&mut b, 16, &r.reply_crc.to_le_bytes());
    for (i, s) in r.section_instructions.iter().enumerate() {
        put(&mut b, 20 + 4 * i, &s.to_le_bytes());
    }
    b
}

pub fn decode_gcs_report(b: &[u8; GCS_REPORT_BYTES]) -> GcsReport {
    let [commands, sections, _, _] = get::<4>(b, 0);
    let mut section_instructions = [0u32; GCS_SECTIONS];
    for (i, s) in section_instructions.iter_mut().enumerate() {
        *s = u32::from_le_bytes(get::<4>(b, 20 + 4 * i));
    }
    GcsReport {
        commands,
        sections,
        section_instructions,
        total_instructions: u32::from_le_bytes(get::<4>(b, 4)),
        error: i32::from_le_bytes(get::<4>(b, 8)),
        reply_len: u32::from_le_bytes(get::<4>(b, 12)),
        reply_crc: u32::from_le_bytes(get::<4>(b, 16)),
    }
}
