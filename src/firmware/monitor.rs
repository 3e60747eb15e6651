//! The log's view of the running loop: every state change and fault of the controller goes to the
//! log (a fault also into the no-init record, `safety.rs`), an overrun trip with its figures, and
//! the loop statistics every 10 s. A task of the communication executor polling every 10 ms; it only reads.

use core::sync::atomic::Ordering;

use embassy_time::Timer;
use piezo_drive::controller::{FaultCode, State};
use piezo_drive::safety::fault_record::FaultKind;

use super::{control, safety};

/// Polls between two statistics lines (10 s).
const STATS_EVERY: u32 = 1000;

#[embassy_executor::task]
pub async fn monitor_task() -> ! {
    let mut last_state = None;
    let mut last_trips = 0;
    let mut polls: u32 = 0;
    loop {
        Timer::after_millis(10).await;
        // The communication executor is alive: the tick feeds the independent watchdog only
        // while this counts (`safety::COMMS_BEAT`).
        safety::COMMS_BEAT.fetch_add(1, Ordering::Relaxed);
        let state = control::CONTROLLER.lock(|c| c.as_ref().map(|c| c.state())).flatten();
        if state != last_state {
            if let Some(s) = state {
                log_state(s);
            }
            last_state = state;
        }
        let trips = control::OVERRUN_TRIPS.load(Ordering::Relaxed);
        if trips != last_trips {
            defmt::error!(
                "control loop overrun: amplifier disabled (trips {}, late ticks {}, worst start latency {} counts)",
                trips,
                control::loop_stats().overruns,
                control::LATENCY_MAX.load(Ordering::Relaxed)
            );
            last_trips = trips;
        }
        polls = polls.wrapping_add(1);
        if polls % STATS_EVERY == 0 {
            let s = control::loop_stats();
            defmt::info!(
                "ticks {} step cycles last {} max {} late ticks {} overrun trips {} worst latency {}",
                safety::ticks(),
                s.step_cycles_last,
                s.step_cycles_max,
                s.overruns,
                trips,
                control::LATENCY_MAX.load(Ordering::Relaxed)
            );
        }
    }
}

/// A new controller state in the log; a fault also in the no-init record (an overrun is
/// recorded by the tick itself, with its timing).
fn log_state(s: State) {
    defmt::info!("controller state: {}", state_name(s));
    if let State::Fault(code) = s {
        defmt::error!("controller fault {}: {}", code as u32, code.text());
        if code != FaultCode::Overrun {
            safety::record_fault(FaultKind::Controller, [code as u32, 0, 0, 0, 0, 0, 0, 0]);
        }
    }
}

fn state_name(s: State) -> &'static str {
    match s {
        State::Idle => "idle",
        State::Moving => "moving",
        State::Holding => "holding",
        State::Referencing => "referencing",
        State::OpenLoop => "open-loop stepping",
        State::Fault(_) => "fault",
    }
}
