//! Drive output through timer PWM (cargo feature `pwm-drive`): TIM1 channel 1 on PA8 and
//! channel 2 on PA9, edge-aligned at 200 kHz (ARR + 1 = 850 counts of 170 MHz, so 9.7 bits of
//! duty resolution), each into an external RC low-pass that makes the amplifier's input voltage.
//!
//! Data path: every TIM1 update raises a DMA request; with the DMA burst unit (DCR: base CCR1,
//! 2 transfers) DMA1 channel 1 (DMAMUX request 46, TIM1_UP) writes the next pair of compare values
//! through DMAR into CCR1 and CCR2. Compare preload is on, so both take effect together at the next
//! update: the two channels stay phase-locked. The circular buffer holds 2 × 20 pairs, one pair
//! per PWM period (200 kS/s, the DAC variant's rate), refilled by the same 10 kHz tick from the
//! core's 12-bit words scaled to the period (`ring::pwm_compare`). Registers the embassy 0.4
//! `SimplePwm` does not cover (DCR, UDE, the DMA channel, DMAMUX) are set through the PAC.

use core::cell::UnsafeCell;

use embassy_stm32::gpio::OutputType;
use embassy_stm32::pac;
use embassy_stm32::peripherals::{DMA1_CH1, PA8, PA9, TIM1};
use embassy_stm32::time::Hertz;
use embassy_stm32::timer::low_level::CountingMode;
use embassy_stm32::timer::simple_pwm::{PwmPin, SimplePwm};
use embassy_stm32::Peri;
use piezo_drive::controller::DAC_SAMPLES_PER_STEP;

use super::ring::{self, HALF, SAMPLES};
use super::{AMP_REST_WORD, SAMPLE_HZ};

/// Two compare values per sample.
const TRANSFERS: usize = 2 * SAMPLES;
/// CCR1's word offset in the timer's register block (0x34 / 4): the DMA burst's base.
const DBA_CCR1: u8 = 13;

struct DmaBuffer(UnsafeCell<[u32; TRANSFERS]>);
// SAFETY: written only by the control tick, in the half the DMA is not reading, and by
// `force_safe` with the DMA stopped; read by the DMA. All CPU writes are volatile.
unsafe impl Sync for DmaBuffer {}
static BUFFER: DmaBuffer = DmaBuffer(UnsafeCell::new([0; TRANSFERS]));

fn buffer_ptr() -> *mut u32 {
    BUFFER.0.get().cast::<u32>()
}

fn period() -> u32 {
    u32::from(pac::TIM1.arr().read().arr()) + 1
}

pub struct Drive {
    _pwm: SimplePwm<'static, TIM1>,
    _dma: Peri<'static, DMA1_CH1>,
    period: u32,
}

impl Drive {
    pub fn new(
        tim1: Peri<'static, TIM1>,
        out1: Peri<'static, PA8>,
        out2: Peri<'static, PA9>,
        dma: Peri<'static, DMA1_CH1>,
    ) -> Self {
        let mut pwm = SimplePwm::new(
            tim1,
            Some(PwmPin::new(out1, OutputType::PushPull)),
            Some(PwmPin::new(out2, OutputType::PushPull)),
            None,
            None,
            Hertz(SAMPLE_HZ),
            CountingMode::EdgeAlignedUp,
        );
        // Stopped until `start_with`, so it starts in step with the tick timer.
        pac::TIM1.cr1().modify(|w| w.set_cen(false));
        pac::TIM1.cnt().write(|w| w.set_cnt(0));
        let period = period();
        let safe = ring::pwm_compare(AMP_REST_WORD, period);
        for i in 0..TRANSFERS {
            // SAFETY: in bounds; the DMA is not running yet.
            unsafe { buffer_ptr().add(i).write_volatile(safe) };
        }
        pwm.ch1().set_duty_cycle(safe as u16);
        pwm.ch2().set_duty_cycle(safe as u16);
        pwm.ch1().enable();
        pwm.ch2().enable();

        // DMAMUX request of TIM1_UP (46 on the G474), from embassy's chip metadata.
        let request = <DMA1_CH1 as embassy_stm32::timer::UpDma<TIM1>>::request(&dma);
        super::drive_dma::start_circular(
            request,
            pac::TIM1.dmar().as_ptr() as u32,
            buffer_ptr() as u32,
            TRANSFERS as u16,
        );
        pac::TIM1.dcr().write(|w| {
            w.set_dba(DBA_CCR1);
            w.set_dbl(1);
        });
        pac::TIM1.dier().modify(|w| w.set_ude(true));

        Drive { _pwm: pwm, _dma: dma, period }
    }

    /// Starts the PWM timer; `with` starts the tick timer in the same critical section.
    pub fn start_with(&mut self, with: impl FnOnce()) {
        critical_section::with(|_| {
            pac::TIM1.cr1().modify(|w| w.set_cen(true));
            with();
        });
    }

    pub fn dma_half(&self) -> usize {
        ring::dma_half(super::drive_dma::remaining(), TRANSFERS as u16)
    }

    pub fn write_half(&mut self, half: usize, samples: &[[u16; 2]; DAC_SAMPLES_PER_STEP]) {
        let base = (half & 1) * HALF * 2;
        for (i, s) in samples.iter().enumerate() {
            let a = ring::pwm_compare(s[0], self.period);
            let b = ring::pwm_compare(s[1], self.period);
            // SAFETY: base + 2i + 1 < TRANSFERS; this half is not being read by the DMA.
            unsafe {
                buffer_ptr().add(base + 2 * i).write_volatile(a);
                buffer_ptr().add(base + 2 * i + 1).write_volatile(b);
            }
        }
    }
}

/// Panic/fault path, registers only: stop the DMA requests and the DMA, set both compare values
/// to the amplifier's rest level (the RC filters settle there). Harmless if TIM1 was never set up.
pub fn force_safe() {
    if !pac::RCC.apb2enr().read().tim1en() {
        return;
    }
    pac::TIM1.dier().modify(|w| w.set_ude(false));
    super::drive_dma::stop();
    let safe = ring::pwm_compare(AMP_REST_WORD, period());
    pac::TIM1.ccr(0).write(|w| w.set_ccr(safe as u16));
    pac::TIM1.ccr(1).write(|w| w.set_ccr(safe as u16));
}
