//! The thrust-model table the tick reads (`piezo_drive::controller::model_cache`), built on the
//! board in the background.
//!
//! Two sides, one per execution context (docs/firmware.md, *Who preempts whom*):
//! - [`table_link_task`], on the communication executor: every millisecond it asks the
//!   controller (under the tick lock, a few hundred instructions) whether it wants a new table,
//!   hands the request to the build, and installs a finished table: its parts copied beside the
//!   table in use, one tick lock each, then swapped in by an index change
//!   (`Controller::stage_model`; each lock measured on the M4 by `tools/pil/run`). The controller
//!   keeps the last complete table until then; a finished table that no longer answers the
//!   settings is refused and thrown away.
//! - [`table_build_task`], alone in thread mode, the lowest priority: it builds the requested
//!   table in one go, without yielding. Everything else (the tick, the UART, the preload ADC, the
//!   flash store, the monitor, this link) preempts it, so a build of seconds holds none of them
//!   off. A request that changes while a build runs makes the build stop at its next slice
//!   (`TableBuild::step`) and start again on the new one.
//!
//! The hand-over is [`BUILD`]: the request and a generation count in a critical-section cell
//! (a copy of a few hundred bytes), the result in a buffer that belongs to the build while
//! [`BUILD_STATE`] says `BUILDING` and to the link while it says `READY`.

use core::cell::{Cell, UnsafeCell};
use core::mem::MaybeUninit;
use core::sync::atomic::{AtomicU32, AtomicU8, Ordering};

use embassy_sync::blocking_mutex::CriticalSectionMutex;
use embassy_time::{Duration, Ticker};
use piezo_drive::controller::model_cache::{ModelRequest, ModelTable, Staged};
use piezo_drive::controller::table_build::TableBuild;

use super::control::CONTROLLER;

/// How often the link looks for a request or a finished table: a preload that drifts gets a new
/// request within about a millisecond, a finished table is installed within one.
const PERIOD: Duration = Duration::from_millis(1);

/// Nothing asked, or the last result taken.
const IDLE: u8 = 0;
/// A request waits in [`BUILD`] for the build task.
const ASKED: u8 = 1;
/// The build task works on it; the result buffer is the build's.
const BUILDING: u8 = 2;
/// A table is in the result buffer; it is the link's until it sets `IDLE`.
const READY: u8 = 3;

/// Where the build stands (one of the constants above).
static BUILD_STATE: AtomicU8 = AtomicU8::new(IDLE);
/// Bumped by the link for every new request: a build whose generation is older stops.
static WANTED: AtomicU32 = AtomicU32::new(0);
/// Instructions are not countable on the board; the build's wall time in microseconds is
/// (the last complete build), for `XTS?`-style diagnostics and the log.
pub static LAST_BUILD_US: AtomicU32 = AtomicU32::new(0);

/// The request handed to the build, with the generation it was posted under.
static BUILD: CriticalSectionMutex<Cell<Option<(u32, ModelRequest)>>> =
    CriticalSectionMutex::new(Cell::new(None));

/// The finished table: written by the build task while `BUILDING`, read by the link while
/// `READY`.
struct ResultBuffer(UnsafeCell<MaybeUninit<ModelTable>>);
// SAFETY: ownership passes through `BUILD_STATE` (Release on hand-over, Acquire on take-over).
unsafe impl Sync for ResultBuffer {}
static RESULT: ResultBuffer = ResultBuffer(UnsafeCell::new(MaybeUninit::uninit()));

/// For `XTS?`: whether a build runs, and the last complete one's time.
pub fn build_status() -> piezo_drive::gcs::TableBuildStatus {
    piezo_drive::gcs::TableBuildStatus {
        running: matches!(BUILD_STATE.load(Ordering::Relaxed), ASKED | BUILDING),
        last_build_us: LAST_BUILD_US.load(Ordering::Relaxed),
    }
}

/// The link, on the communication executor: requests, and installs what the build finished.
#[embassy_executor::task]
pub async fn table_link_task() -> ! {
    let mut ticker = Ticker::every(PERIOD);
    let mut posted: Option<ModelRequest> = None;
    loop {
        ticker.next().await;
        if BUILD_STATE.load(Ordering::Acquire) == READY {
            // SAFETY: READY hands the buffer to this task until it stores IDLE.
            let table = unsafe { (*RESULT.0.get()).assume_init_ref() };
            // A part per lock: the tick is held off for a few rows' copy at a time, never the
            // whole table; the last part swaps it in.
            let mut part = 0;
            let staged = loop {
                match CONTROLLER.lock(|c| c.as_mut().map(|c| c.stage_model(table, part))).flatten() {
                    Some(Staged::More) => part += 1,
                    other => break other,
                }
            };
            if staged == Some(Staged::Installed) {
                defmt::debug!(
                    "model table installed for {} N after {} us",
                    table.request().preload_n,
                    LAST_BUILD_US.load(Ordering::Relaxed)
                );
            }
            posted = None;
            BUILD_STATE.store(IDLE, Ordering::Release);
        }
        let wanted = CONTROLLER.lock(|c| c.as_ref().and_then(|c| c.model_request())).flatten();
        match wanted {
            Some(r) if !posted.is_some_and(|p| p.same_table_as(&r)) => {
                let generation = WANTED.load(Ordering::Relaxed).wrapping_add(1);
                WANTED.store(generation, Ordering::Release);
                BUILD.lock(|b| b.set(Some((generation, r))));
                posted = Some(r);
                // A build of an older request stops at its next slice (it sees WANTED move).
                if BUILD_STATE.load(Ordering::Acquire) == IDLE {
                    BUILD_STATE.store(ASKED, Ordering::Release);
                }
            }
            None if posted.is_some() => {
                // Nothing wanted any more (the table fits again): let a running build stop.
                WANTED.store(WANTED.load(Ordering::Relaxed).wrapping_add(1), Ordering::Release);
                posted = None;
            }
            _ => {}
        }
    }
}

/// The build, alone in thread mode: builds each posted request in one go.
#[embassy_executor::task]
pub async fn table_build_task() -> ! {
    let mut ticker = Ticker::every(PERIOD);
    loop {
        ticker.next().await;
        if BUILD_STATE.load(Ordering::Acquire) != ASKED {
            continue;
        }
        let Some((generation, request)) = BUILD.lock(|b| b.take()) else {
            BUILD_STATE.store(IDLE, Ordering::Release);
            continue;
        };
        BUILD_STATE.store(BUILDING, Ordering::Release);
        let started = embassy_time::Instant::now();
        let mut build = TableBuild::new(&request);
        let table = loop {
            if WANTED.load(Ordering::Acquire) != generation {
                break None;
            }
            if let Some(table) = build.step() {
                break Some(table);
            }
        };
        match table {
            Some(table) => {
                // SAFETY: BUILDING: the buffer is this task's.
                unsafe { (*RESULT.0.get()).write(table) };
                LAST_BUILD_US.store(started.elapsed().as_micros() as u32, Ordering::Relaxed);
                BUILD_STATE.store(READY, Ordering::Release);
            }
            None => {
                // Thrown away: a newer request waits (or none is wanted).
                let next = BUILD.lock(|b| {
                    let r = b.take();
                    b.set(r);
                    r.is_some()
                });
                BUILD_STATE.store(if next { ASKED } else { IDLE }, Ordering::Release);
            }
        }
    }
}
