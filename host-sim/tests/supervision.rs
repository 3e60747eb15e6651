//! The supervision of every driving state against the plant (SIL, the prototype at 16 N):
//! referencing into a hard end stop with no limit switches, and a lost encoder channel whose
//! partner still toggles.

use host_sim::harness::moves::ready_board;
use host_sim::harness::sil::controller_config;
use host_sim::motor::params::Params;
use piezo_drive::controller::{FaultCode, State};

/// `FRF` with the index 1 mm on the +x side and a hard stop 100 µm on the −x side, no limit
/// switches: the search toward −x meets the stop. Before, the drive pushed 50 V into the stop
/// until the 200 s timeout; now `NoProgress` within 100 ms of meeting it (one window of the
/// progress watch, 20 ms at this drive, and the gain before it), the drive safe.
#[test]
fn referencing_into_a_hard_stop_goes_safe_within_100_ms() {
    let p = Params::prototype();
    let mut sil = ready_board(&p, controller_config(&p), 16.0).unwrap();
    sil.plant.end_stops_m = Some((-100e-6, 1.0));
    sil.index_position_m = Some(1e-3);
    sil.controller.start_referencing().unwrap();
    let mut met: Option<f64> = None;
    let ended = sil.run_until(3.0, |s| {
        if s.plant.at_end_stop() {
            met.get_or_insert(s.time_s());
        }
        s.controller.state() != State::Referencing
    });
    assert!(ended, "still referencing after 3 s");
    assert_eq!(sil.controller.state(), State::Fault(FaultCode::NoProgress));
    let after_s = sil.time_s() - met.expect("the stop was met");
    assert!(after_s <= 0.1, "fault {:.1} ms after meeting the stop", after_s * 1e3);
    let out = sil.period();
    assert!(!out.amp_enable);
}

/// One encoder channel lost 20 ms into a 300 µm move, the other still toggling: the count
/// flickers between two values. Before, every flick reset the coarse mode's encoder-loss watch
/// and the loss was never seen; now `EncoderLoss` within 5 ms.
#[test]
fn a_flickering_encoder_under_the_coarse_drive_is_encoder_loss_within_5_ms() {
    let p = Params::prototype();
    let mut sil = ready_board(&p, controller_config(&p), 16.0).unwrap();
    sil.controller.move_to(300_000).unwrap();
    sil.run_until(0.02, |_| false);
    assert_eq!(sil.controller.state(), State::Moving);
    sil.jittering_encoder_counts = Some(sil.plant.encoder_counts());
    let t0 = sil.time_s();
    let faulted = sil.run_until(0.05, |s| s.controller.fault().is_some());
    assert!(faulted, "no fault 50 ms after the channel was lost");
    assert_eq!(sil.controller.fault(), Some(FaultCode::EncoderLoss));
    let after_s = sil.time_s() - t0;
    assert!(after_s <= 0.005, "encoder loss {:.2} ms after the channel was lost", after_s * 1e3);
}
