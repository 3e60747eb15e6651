//! Drive output through DAC1: channel 1 on PA4, channel 2 on PA5 (PA5 also drives the Nucleo's
//! LED LD2 through a series resistor: the LED glows with stack B's voltage and loads the output
//! at the top of its range; the Nucleo-64 user manual names the solder bridge that disconnects
//! LD2, or use the PWM variant; see the README).
//!
//! Data path: TIM6 update (200 kHz, TRGO = update) triggers both DAC channels at once; each
//! trigger moves the dual holding register to the outputs and DAC channel 1's DMA request makes
//! DMA1 channel 1 (DMAMUX request 6, taken from embassy's chip metadata) load the next packed word into DHR12RD (channel 1 in bits
//! 0..12, channel 2 in bits 16..28). The DMA runs circular over 2 × 20 words, so both stacks
//! always change on the same trigger (phase-locked by construction) and the control tick
//! refills the half the DMA is not reading.
//!
//! embassy-stm32 0.4 configures the DAC (clock, pins, HFSEL, buffered mode, trigger selection),
//! but its DMA `write` feeds one channel's holding register only, with no half-buffer refill, and
//! it has no timer master-mode API: so the DMA channel, DMAMUX, DAC DMAEN and TIM6 MMS are
//! programmed here through the PAC (`unstable-pac`), for this one data path.

use core::cell::UnsafeCell;

use embassy_stm32::dac::{Dac, TriggerSel};
use embassy_stm32::mode::Blocking;
use embassy_stm32::pac;
use embassy_stm32::peripherals::{DAC1, DMA1_CH1, PA4, PA5, TIM6};
use embassy_stm32::timer::low_level::Timer;
use embassy_stm32::Peri;
use piezo_drive::controller::DAC_SAMPLES_PER_STEP;

use super::ring::{self, HALF, SAMPLES};
use super::{AMP_REST_WORD, SAMPLE_COUNTS};

/// The circular buffer the DMA reads. Written only by the control tick (one writer, in an
/// interrupt, in the half the DMA is not reading) and by `force_safe` in the panic handler with
/// the DMA stopped; read only by the DMA.
struct DmaBuffer(UnsafeCell<[u32; SAMPLES]>);
// SAFETY: see above; every CPU access is a volatile write through a raw pointer.
unsafe impl Sync for DmaBuffer {}
static BUFFER: DmaBuffer = DmaBuffer(UnsafeCell::new([0; SAMPLES]));

fn buffer_ptr() -> *mut u32 {
    BUFFER.0.get().cast::<u32>()
}

pub struct Drive {
    _dac: Dac<'static, DAC1, Blocking>,
    _tim6: Timer<'static, TIM6>,
    _dma: Peri<'static, DMA1_CH1>,
}

impl Drive {
    pub fn new(
        dac: Peri<'static, DAC1>,
        out1: Peri<'static, PA4>,
        out2: Peri<'static, PA5>,
        tim6: Peri<'static, TIM6>,
        dma: Peri<'static, DMA1_CH1>,
    ) -> Self {
        let safe = ring::pack_dac([AMP_REST_WORD; 2]);
        for i in 0..SAMPLES {
            // SAFETY: in bounds; the DMA is not running yet.
            unsafe { buffer_ptr().add(i).write_volatile(safe) };
        }

        let mut dac = Dac::new_blocking(dac, out1, out2);
        dac.ch1().set_trigger(TriggerSel::Tim6);
        dac.ch1().set_triggering(true);
        dac.ch2().set_trigger(TriggerSel::Tim6);
        dac.ch2().set_triggering(true);
        pac::DAC1.dhr12rd().write_value(pac::dac::regs::Dhr12rd(safe));
        dac.ch1().enable();
        dac.ch2().enable();
        pac::DAC1.cr().modify(|w| w.set_dmaen(0, true));

        // DMAMUX request of DAC1 channel 1 (6 on the G474), from embassy's chip metadata.
        let request = <DMA1_CH1 as embassy_stm32::dac::Dma<DAC1, embassy_stm32::dac::Ch1>>::request(&dma);
        super::drive_dma::start_circular(
            request,
            pac::DAC1.dhr12rd().as_ptr() as u32,
            buffer_ptr() as u32,
            SAMPLES as u16,
        );

        let tim6 = Timer::new(tim6);
        let r = tim6.regs_basic();
        r.cr1().modify(|w| w.set_cen(false));
        r.psc().write_value(0);
        r.arr().write(|w| w.set_arr((SAMPLE_COUNTS - 1) as u16));
        r.cr2().modify(|w| w.set_mms(pac::timer::vals::Mms::UPDATE));
        r.cnt().write(|w| w.set_cnt(0));

        Drive { _dac: dac, _tim6: tim6, _dma: dma }
    }

    /// Starts the sample timer; `with` starts the tick timer in the same critical section.
    pub fn start_with(&mut self, with: impl FnOnce()) {
        critical_section::with(|_| {
            pac::TIM6.cr1().modify(|w| w.set_cen(true));
            with();
        });
    }

    /// Half the DMA is reading now.
    pub fn dma_half(&self) -> usize {
        ring::dma_half(super::drive_dma::remaining(), SAMPLES as u16)
    }

    pub fn write_half(&mut self, half: usize, samples: &[[u16; 2]; DAC_SAMPLES_PER_STEP]) {
        let base = (half & 1) * HALF;
        for (i, s) in samples.iter().enumerate() {
            // SAFETY: base + i < SAMPLES; this half is not being read by the DMA.
            unsafe { buffer_ptr().add(base + i).write_volatile(ring::pack_dac(*s)) };
        }
    }
}

/// Panic/fault path, registers only (callable from the panic handler, before anything else):
/// stop the DMA, put the amplifier's rest word in the holding register; TIM6 keeps triggering, so it
/// reaches both outputs within one sample (5 µs). Harmless if the drive was never set up.
pub fn force_safe() {
    if !pac::RCC.ahb2enr().read().dac1en() {
        return; // DAC never set up: PA4/PA5 are still in their reset state.
    }
    pac::DAC1.cr().modify(|w| {
        w.set_dmaen(0, false);
        w.set_dmaen(1, false);
    });
    super::drive_dma::stop();
    pac::DAC1.dhr12rd().write_value(pac::dac::regs::Dhr12rd(ring::pack_dac([AMP_REST_WORD; 2])));
    pac::TIM6.cr1().modify(|w| w.set_cen(true));
}
