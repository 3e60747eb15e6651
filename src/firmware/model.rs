//! The control core's lower-rate work, in thread mode: the thrust-model table the tick reads
//! (`piezo_drive::controller::model_cache`). Building it costs 1.4–2.3 million instructions,
//! far more than a 100 µs tick may spend, and its inputs (the preload, the settings) change
//! slowly; so this task asks the controller every millisecond whether it wants a new table,
//! builds it with the tick running (it preempts this task), and hands it over under the tick
//! lock (a copy of the table, ~2 KiB). The tick never waits for it: it keeps the table it has
//! until the new one is installed. The build runs in slices (`TableBuild`) and yields to the
//! executor between them, so the UART and preload tasks of the same executor wait at most one
//! slice, not the whole build (which outlasted the tick's 20 ms preload staleness limit).

use embassy_futures::yield_now;
use embassy_time::{Duration, Ticker};
use piezo_drive::controller::table_build::TableBuild;

use super::control::CONTROLLER;

/// How often the task looks for a request: a preload that drifts 0.02 N gets a new table within
/// about a millisecond plus the build.
const PERIOD: Duration = Duration::from_millis(1);

#[embassy_executor::task]
pub async fn model_task() -> ! {
    let mut ticker = Ticker::every(PERIOD);
    loop {
        ticker.next().await;
        let Some(Some(request)) = CONTROLLER.lock(|c| c.as_ref().and_then(|c| c.model_request())) else {
            continue;
        };
        let mut build = TableBuild::new(&request);
        let table = loop {
            if let Some(table) = build.step() {
                break table;
            }
            yield_now().await;
        };
        // Refused (false) when the settings changed meanwhile; the next request covers them.
        let installed = CONTROLLER.lock(|c| c.as_mut().map(|c| c.install_model(table)));
        if installed == Some(Some(true)) {
            defmt::debug!("model table installed for {} N", request.preload_n);
        }
    }
}
