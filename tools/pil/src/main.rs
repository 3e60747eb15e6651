//! The control core on an emulated Cortex-M4F (QEMU `mps2-an386`, `-icount shift=0`: one
//! instruction = 1 ns of virtual time, read through SysTick). Built from the same sources as the
//! firmware's core (the lib in Cargo.toml IS src/lib.rs), with the firmware's release settings.
//!
//! Two jobs, one program:
//! - **Processor in the loop**: when QEMU runs in a directory holding the FIFOs `pil-in` and
//!   `pil-out` (made by `host-sim pil`), each control period reads one tick frame (command and
//!   sensor inputs, `piezo_drive::pil_wire`), runs `Controller::step` and packs the 20 DAC sample
//!   pairs into a DMA half-buffer as the firmware's tick does, and writes back the outputs, the
//!   state and the instructions the tick took.
//! - **Hot-path counts** (no FIFOs, `tools/pil/run`): the old `m4-count` suite.
#![no_std]
#![no_main]

mod counts;

use core::panic::PanicInfo;
use core::sync::atomic::{compiler_fence, AtomicU32, Ordering};

use cortex_m::peripheral::syst::SystClkSource;
use cortex_m::peripheral::SYST;
use cortex_m_rt::{entry, exception};
use cortex_m_semihosting::{debug, hprintln, syscall};
use piezo_drive::controller::model_cache::ModelTable;
use piezo_drive::controller::{Controller, DAC_SAMPLES_PER_STEP};
use piezo_drive::defaults::controller_config;
use piezo_drive::gcs::{Board, Gcs, LoopStats, SharedController};
use piezo_drive::pil_wire::{
    self, Command, GcsReport, Reply, GCS_MAX_BYTES, GCS_SECTIONS, REPLY_BYTES, TICK_BYTES,
};
use piezo_drive::recorder::Recorder;

/// SysTick counts of `f`, down-counter with a 24-bit reload.
pub fn counts(f: impl FnOnce()) -> u32 {
    let start = SYST::get_current();
    f();
    let end = SYST::get_current();
    start.wrapping_sub(end) & 0x00FF_FFFF
}

/// Wraps of SysTick's 24-bit counter (its exception): a model-table build outlasts one wrap
/// (2^24 counts, 671 million instructions at 40 per count).
static SYSTICK_WRAPS: AtomicU32 = AtomicU32::new(0);

#[exception]
fn SysTick() {
    SYSTICK_WRAPS.fetch_add(1, Ordering::Relaxed);
}

/// SysTick's wraps and count, read consistently.
fn systick_now() -> (u32, u32) {
    loop {
        let wraps = SYSTICK_WRAPS.load(Ordering::Relaxed);
        let current = SYST::get_current();
        if SYSTICK_WRAPS.load(Ordering::Relaxed) == wraps {
            return (wraps, current);
        }
    }
}

/// SysTick counts of `f` however long it runs (the wraps counted by the exception).
pub fn long_counts(f: impl FnOnce()) -> u64 {
    let (w0, c0) = systick_now();
    f();
    let (w1, c1) = systick_now();
    let wrapped = u64::from(w1.wrapping_sub(w0)) << 24;
    (wrapped + u64::from(c0)).saturating_sub(u64::from(c1))
}

/// Instructions per SysTick count. `cortex_m::asm::delay(n)` (cortex-m 0.7.10) runs a
/// 2-instruction loop (`subs`, `bne`) n + 1 times; with `-icount shift=0` this comes out at 40
/// (1 ns per instruction, SysTick on the 25 MHz system clock).
pub fn calibrate() -> f32 {
    const CAL: u32 = 4_000_000;
    let cal = counts(|| cortex_m::asm::delay(CAL));
    2.0 * (CAL + 1) as f32 / cal.max(1) as f32
}

pub struct Stat {
    n: u32,
    total: u64,
    max: u32,
}
impl Stat {
    pub fn new() -> Self {
        Stat { n: 0, total: 0, max: 0 }
    }
    pub fn add(&mut self, c: u32) {
        self.n += 1;
        self.total += u64::from(c);
        self.max = self.max.max(c);
    }
    pub fn print(&self, name: &str, insn_per_count: f32) {
        let mean = self.total as f32 / self.n.max(1) as f32 * insn_per_count;
        let max = self.max as f32 * insn_per_count;
        hprintln!(
            "{}: {} calls, mean {} instructions, max {} (±{} per call)",
            name,
            self.n,
            mean as u32,
            max as u32,
            insn_per_count as u32
        );
    }
}

/// Semihosting file handle, or None.
fn open(name: &[u8], mode: usize) -> Option<usize> {
    // SYS_OPEN takes a NUL-terminated name and its length without the NUL.
    let fd = unsafe { syscall!(OPEN, name.as_ptr(), mode, name.len() - 1) } as isize;
    (fd >= 0).then_some(fd as usize)
}

/// Reads exactly `buf.len()` bytes; false at end of file.
fn read_exact(fd: usize, buf: &mut [u8]) -> bool {
    let mut done = 0;
    while done < buf.len() {
        let rest = &mut buf[done..];
        // SYS_READ returns the number of bytes NOT read.
        let left = unsafe { syscall!(READ, fd, rest.as_mut_ptr(), rest.len()) };
        let got = rest.len().saturating_sub(left);
        if got == 0 {
            return false;
        }
        done += got;
    }
    true
}

fn write_all(fd: usize, buf: &[u8]) -> bool {
    unsafe { syscall!(WRITE, fd, buf.as_ptr(), buf.len()) == 0 }
}

/// The data recorder, as the firmware's `RECORDER`: a point after each tick (outside the tick's
/// count here), configured and read by the GCS commands.
pub static RECORDER: Recorder = Recorder::new();

/// The protocol's view of this target, as the firmware's `FwBoard` (`src/firmware/uart.rs`).
/// `WPA` hands the settings over as the firmware's `params_flash::request_store` does: a copy
/// into a static under a critical section (the firmware's `Signal`), nothing more under the lock.
struct PilBoard;

static mut STORED: Option<piezo_drive::controller::ControllerConfig> = None;

impl Board for PilBoard {
    fn store_parameters(&mut self, cfg: &piezo_drive::controller::ControllerConfig) -> bool {
        cortex_m::interrupt::free(|_| {
            // SAFETY: single-threaded, inside a critical section.
            unsafe { *core::ptr::addr_of_mut!(STORED) = Some(*cfg) };
        });
        true
    }
    fn serial_number(&self) -> u32 {
        1
    }
    fn loop_stats(&self) -> LoopStats {
        LoopStats::default()
    }
    fn recorder(&self) -> Option<&Recorder> {
        Some(&RECORDER)
    }
}

/// The controller with every locked section counted: what runs inside `lock` is what runs with
/// the firmware's tick masked (`src/firmware/uart.rs` locks the same way).
struct Metered<'a> {
    ctl: &'a mut Controller,
    sections: u8,
    section_counts: [u32; GCS_SECTIONS],
}

impl SharedController for Metered<'_> {
    fn lock<R>(&mut self, f: impl FnOnce(&mut Controller) -> R) -> Option<R> {
        let mut r = None;
        let ctl = &mut *self.ctl;
        // As the firmware's `TickLock::lock`: compiler fences around the section; and the
        // section's result and the controller made observable before the count stops, so that
        // no copy into the result is left for after it.
        compiler_fence(Ordering::SeqCst);
        let c = counts(|| {
            r = Some(f(&mut *ctl));
            core::hint::black_box(&r);
            core::hint::black_box(&*ctl);
        });
        compiler_fence(Ordering::SeqCst);
        if let Some(slot) = self.section_counts.get_mut(usize::from(self.sections)) {
            *slot = c;
        }
        self.sections = self.sections.saturating_add(1);
        r
    }
}

/// A point for the recorder (kept out of `pil`'s loop, whose tick code stays as it was).
#[inline(never)]
fn record(ctl: &Controller) {
    RECORDER.sample(ctl);
}

static mut GCS_REPLY: piezo_drive::gcs::Reply = piezo_drive::gcs::Reply::new();
static mut GCS: Option<Gcs> = None;
static mut GCS_BYTES: [u8; GCS_MAX_BYTES] = [0; GCS_MAX_BYTES];

/// Reads a GCS frame's `len` command bytes, runs them and answers with the report; false when
/// the host has gone. Out of line, so that `pil`'s tick code is what it was without it.
#[inline(never)]
fn gcs_frame(fd_in: usize, fd_out: usize, len: usize, ctl: &mut Controller, k: f32) -> bool {
    // SAFETY: single-threaded; the only references to these statics.
    let (gcs, bytes) = unsafe {
        (
            (*core::ptr::addr_of_mut!(GCS)).get_or_insert_with(Gcs::new),
            &mut (&mut *core::ptr::addr_of_mut!(GCS_BYTES))[..len.min(GCS_MAX_BYTES)],
        )
    };
    if !read_exact(fd_in, bytes) {
        return false;
    }
    let report = run_gcs(gcs, ctl, bytes, k);
    write_all(fd_out, &pil_wire::encode_gcs_report(&report))
}

/// One GCS frame's bytes through the protocol, as the firmware's UART task runs them.
fn run_gcs(gcs: &mut Gcs, ctl: &mut Controller, bytes: &[u8], k: f32) -> GcsReport {
    // SAFETY: single-threaded; the only reference to GCS_REPLY.
    let reply = unsafe { &mut *core::ptr::addr_of_mut!(GCS_REPLY) };
    reply.clear();
    let mut board = PilBoard;
    let mut shared = Metered { ctl, sections: 0, section_counts: [0; GCS_SECTIONS] };
    let mut report = GcsReport::default();
    let mut total = 0u32;
    for &byte in bytes {
        let Some(pending) = gcs.push_byte(byte) else { continue };
        report.commands = report.commands.saturating_add(1);
        total += counts(|| gcs.execute_shared(&pending, &mut shared, &mut board, reply));
    }
    report.sections = shared.sections;
    for (r, c) in report.section_instructions.iter_mut().zip(shared.section_counts) {
        *r = (c as f32 * k) as u32;
    }
    report.total_instructions = (total as f32 * k) as u32;
    report.error = gcs.latched_error();
    report.reply_len = reply.len() as u32;
    report.reply_crc = piezo_drive::storage::crc32(reply);
    report
}

/// The DMA half-buffer the tick refills: DHR12RD words, channel 2 in the upper half.
static mut HALF: [u32; 2 * DAC_SAMPLES_PER_STEP] = [0; 2 * DAC_SAMPLES_PER_STEP];

fn pil(fd_in: usize, fd_out: usize, k: f32) {
    let Ok(mut ctl) = Controller::new(controller_config()) else {
        hprintln!("pil: the firmware's default configuration is refused");
        return;
    };
    let mut frame = [0u8; TICK_BYTES];
    let mut half = 0usize;
    while read_exact(fd_in, &mut frame) {
        if let Some(len) = pil_wire::decode_gcs_header(&frame) {
            if !gcs_frame(fd_in, fd_out, len, &mut ctl, k) {
                return;
            }
            continue;
        }
        let Some(tick) = pil_wire::decode_tick(&frame) else {
            hprintln!("pil: bad frame");
            return;
        };
        if tick.command == Command::Exit {
            return;
        }
        let refused = tick.command.apply(&mut ctl);
        let mut out = None;
        let mut step_counts = 0;
        let tick_counts = counts(|| {
            step_counts = counts(|| out = Some(ctl.step(core::hint::black_box(&tick.inputs))));
            if let Some(o) = &out {
                for (j, s) in o.dac.iter().enumerate() {
                    let w = u32::from(s[0].min(4095)) | (u32::from(s[1].min(4095)) << 16);
                    // SAFETY: in bounds, single-threaded.
                    unsafe { core::ptr::addr_of_mut!(HALF).cast::<u32>().add(half + j).write_volatile(w) };
                }
            }
        });
        half = DAC_SAMPLES_PER_STEP - half;
        // The board's thread-mode work (the model table), after the tick and counted apart.
        let background_counts = match ctl.model_request() {
            Some(request) => long_counts(|| {
                ctl.install_model(ModelTable::build(&request));
            })
            .max(1),
            None => 0,
        };
        // The firmware's tick records after the step; here outside the tick's count.
        record(&ctl);
        let Some(outputs) = out else { return };
        let reply = Reply {
            outputs,
            state: pil_wire::state_code(ctl.state()),
            command_refused: refused,
            tick_instructions: (tick_counts as f32 * k) as u32,
            step_instructions: (step_counts as f32 * k) as u32,
            background_instructions: if background_counts > 0 { (background_counts as f64 * f64::from(k)) as u32 } else { 0 },
        };
        let bytes: [u8; REPLY_BYTES] = pil_wire::encode_reply(&reply);
        if !write_all(fd_out, &bytes) {
            return;
        }
    }
}

#[entry]
fn main() -> ! {
    let mut cp = cortex_m::Peripherals::take().unwrap();
    cp.SYST.set_clock_source(SystClkSource::Core);
    cp.SYST.set_reload(0x00FF_FFFF);
    cp.SYST.clear_current();
    cp.SYST.enable_counter();
    cp.SYST.enable_interrupt();
    let k = calibrate();
    // Mode 1 = "rb", 5 = "wb" (binary). The host opens its ends in the same order.
    match open(b"pil-in\0", 1) {
        Some(fd_in) => match open(b"pil-out\0", 5) {
            Some(fd_out) => pil(fd_in, fd_out, k),
            None => hprintln!("pil: cannot open pil-out"),
        },
        None => counts::hot_paths(),
    }
    debug::exit(debug::EXIT_SUCCESS);
    loop {
        cortex_m::asm::wfi();
    }
}

#[panic_handler]
fn panic(info: &PanicInfo) -> ! {
    hprintln!("panic: {}", info);
    debug::exit(debug::EXIT_FAILURE);
    loop {
        cortex_m::asm::wfi();
    }
}
