//! The board layer of the NUCLEO-G474RE firmware: one module per peripheral/task. It knows
//! nothing of control: it moves sensor words into [`piezo_drive::controller::Controller::step`]
//! and the step's DAC words and amplifier enable out to the chip.
//!
//! Pin map (NUCLEO-G474RE, Arduino header names in brackets):
//!
//! | signal | pin | peripheral |
//! |---|---|---|
//! | drive stack A (DAC variant) | PA4 [A2] | DAC1_OUT1 |
//! | drive stack B (DAC variant) | PA5 [D13, also LED LD2] | DAC1_OUT2 |
//! | drive stack A (PWM variant) | PA8 [D7] | TIM1_CH1 |
//! | drive stack B (PWM variant) | PA9 [D8] | TIM1_CH2 |
//! | amplifier enable (active high) | PA10 [D2] | GPIO |
//! | encoder A / B | PA6 [D12] / PA7 [D11] | TIM3_CH1 / TIM3_CH2 (quadrature) |
//! | encoder index (optional) | PB10 [D6] | EXTI10 |
//! | preload cell (amplified bridge) | PC0 [A5] | ADC1_IN6 |
//! | limit switches, negative / positive (optional) | PB5 [D4] / PC7 [D9] | GPIO, pull-up |
//! | UART to the host | PA2 / PA3 | LPUART1 TX / RX (ST-LINK virtual COM port) |

// On the host the bin is only a stub plus the unit tests of `ring`.
#![cfg_attr(not(target_os = "none"), allow(dead_code))]

pub mod ring;

#[cfg(all(target_os = "none", feature = "dac-drive", feature = "pwm-drive"))]
compile_error!("choose one drive: `dac-drive` (default) or `--no-default-features --features pwm-drive`");
#[cfg(all(target_os = "none", not(any(feature = "dac-drive", feature = "pwm-drive"))))]
compile_error!("no drive output selected: enable `dac-drive` or `pwm-drive`");

#[cfg(target_os = "none")]
pub mod control;
#[cfg(all(target_os = "none", feature = "dac-drive"))]
pub mod drive_dac;
#[cfg(target_os = "none")]
pub mod model;
#[cfg(target_os = "none")]
pub mod param_page;
#[cfg(all(target_os = "none", feature = "dac-drive"))]
pub use drive_dac as drive;
#[cfg(all(target_os = "none", feature = "pwm-drive", not(feature = "dac-drive")))]
pub mod drive_pwm;
#[cfg(all(target_os = "none", feature = "pwm-drive", not(feature = "dac-drive")))]
pub use drive_pwm as drive;
#[cfg(target_os = "none")]
pub mod drive_dma;
#[cfg(target_os = "none")]
pub mod encoder;
#[cfg(target_os = "none")]
pub mod monitor;
#[cfg(target_os = "none")]
pub mod params_flash;
#[cfg(target_os = "none")]
pub mod preload;
#[cfg(target_os = "none")]
pub mod safety;
#[cfg(target_os = "none")]
pub mod uart;

/// Core (and every timer kernel) clock: 24 MHz HSE → PLL M=6 N=85 R=2.
pub const CORE_HZ: u32 = 170_000_000;
/// DAC / PWM sample rate (the core's `DAC_RATE_HZ`).
pub const SAMPLE_HZ: u32 = piezo_drive::defaults::DAC_RATE_HZ;
/// Timer counts per drive sample and per control tick (both timers count at [`CORE_HZ`]).
pub const SAMPLE_COUNTS: u32 = CORE_HZ / SAMPLE_HZ;
pub const TICK_COUNTS: u32 = SAMPLE_COUNTS * ring::HALF as u32;
const _: () = assert!(CORE_HZ % SAMPLE_HZ == 0, "sample timer must divide the core clock exactly");
const _: () = assert!(SAMPLE_HZ / ring::HALF as u32 == piezo_drive::defaults::LOOP_HZ);
/// DAC word equal to the amplifier's output while its enable is low (0 V for the 0–100 V
/// amplifier at `full_scale_v` = 100 V): the drive starts there and every enable ramps up from
/// it ([`piezo_drive::safety::soft_start`]); the panic and fault paths write it too. Board-dependent: an amplifier that rests elsewhere
/// needs its own word here.
pub const AMP_REST_WORD: u16 = 0;
/// Soft-start ramp from [`AMP_REST_WORD`] to the controller's output: 20 ms (4 000 samples at
/// 200 kS/s), 50 V in 20 ms = 2.5 V/ms on the stacks.
pub const SOFT_START_SAMPLES: u32 = SAMPLE_HZ / 50;
/// Control ticks after the enable went low before the drive counts as parked (both buffer
/// halves hold the rest word).
pub const PARK_TICKS: u32 = 3;
