//! The drive's DMA, shared by both output variants: DMA1 channel 1 copies 32-bit words from the
//! circular sample buffer into one peripheral register (DAC1 DHR12RD, or TIM1 DMAR), one word per
//! request, forever. No DMA interrupts: embassy owns their vectors; the control tick polls NDTR.

use embassy_stm32::pac;
use embassy_stm32::pac::bdma::vals::{Dir, Pl, Size};

/// DMA1 channel 1 (index 0) and its DMAMUX1 channel (index 0).
const DMA_CH: usize = 0;

/// Starts the channel: `transfers` words per lap from `memory` to `peripheral`, on DMAMUX request
/// `request` (taken from embassy's chip metadata by the caller).
pub fn start_circular(request: u8, peripheral: u32, memory: u32, transfers: u16) {
    let ch = pac::DMA1.ch(DMA_CH);
    ch.cr().write(|w| w.set_en(false));
    pac::DMAMUX1.ccr(DMA_CH).write(|w| w.set_dmareq_id(request));
    ch.par().write_value(peripheral);
    ch.mar().write_value(memory);
    ch.ndtr().write(|w| w.set_ndt(transfers));
    pac::DMA1.ifcr().write(|w| w.set_gif(DMA_CH, true));
    ch.cr().write(|w| {
        w.set_dir(Dir::FROM_MEMORY);
        w.set_circ(true);
        w.set_minc(true);
        w.set_psize(Size::BITS32);
        w.set_msize(Size::BITS32);
        w.set_pl(Pl::VERY_HIGH);
        w.set_en(true);
    });
}

/// Transfers left in the present lap (counts down from `transfers` to 1).
pub fn remaining() -> u16 {
    pac::DMA1.ch(DMA_CH).ndtr().read().ndt()
}

/// Stops the channel (the panic path and the safe state).
pub fn stop() {
    pac::DMA1.ch(DMA_CH).cr().modify(|w| w.set_en(false));
}
