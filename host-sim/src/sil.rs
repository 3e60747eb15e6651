//! Software in the loop: the firmware's control core against the plant, through exactly what the
//! board gives it — 12-bit DAC words through a zero-order hold and the amplifier, encoder counts
//! wrapped to 16 bits, preload ADC words — with a one-period output delay.

use crate::params::Params;
use crate::plant::{ExternalLoad, Plant};
use crate::steady::amplitudes;
use piezo_drive::controller::{Controller, ControllerConfig, Inputs, Outputs, DAC_SAMPLES_PER_STEP};
use piezo_drive::generator::DacConfig;
use piezo_drive::model::{MotorConstants, FREQ_POINTS};
use piezo_drive::sensors::PreloadCalibration;
use piezo_drive::Fx;
use rand::rngs::StdRng;
use rand::SeedableRng;

/// The motor table the firmware needs, from the physical parameters (eqs. 5, 7 and 1 per volt).
pub fn motor_constants(p: &Params) -> MotorConstants {
    let mut c = MotorConstants {
        freq_khz: [Fx::ZERO; FREQ_POINTS],
        kc_yc_n_per_v: [Fx::ZERO; FREQ_POINTS],
        foot_speed_mm_s_per_v: [Fx::ZERO; FREQ_POINTS],
        mu: Fx::from_num(p.friction.mu_dynamic),
        viscous_un_per_mm_s: Fx::from_num(p.friction.viscous_n_s_per_m * 1e3),
        // Common offset δ on both stacks moves the foot by λ·stroke·2δ (eq. 1).
        fine_nm_per_v: Fx::from_num(2.0 * p.stator.tangential_scale * p.stack.stroke_m_per_v * 1e9),
        moving_mass_kg: Fx::from_num(p.slider.mass_kg),
    };
    for i in 0..FREQ_POINTS {
        let f_hz = 400.0 + 100.0 * i as f64;
        // Amplitudes are linear in voltage: evaluate at 1 V peak-to-peak.
        let a = amplitudes(p, 1.0, f_hz);
        c.freq_khz[i] = Fx::from_num(f_hz / 1000.0);
        c.kc_yc_n_per_v[i] = Fx::from_num(p.contact.stiffness_n_per_m * a.yc_m);
        c.foot_speed_mm_s_per_v[i] = Fx::from_num(std::f64::consts::TAU * f_hz * a.xc_m * 1e3);
    }
    c
}

/// Controller settings for the simulated board (the firmware's defaults on the same motor).
pub fn controller_config(p: &Params) -> ControllerConfig {
    let motor = motor_constants(p);
    let drive_freq_hz = 2200.0f32;
    let max_drive_v = (p.amplifier.output_max_v - p.amplifier.output_min_v) as f32;
    let full_contact = motor
        .full_contact_preload_n(Fx::from_num(max_drive_v), Fx::from_num(drive_freq_hz / 1000.0))
        .to_num::<f32>();
    ControllerConfig {
        loop_hz: (p.amplifier.dac_rate_hz / DAC_SAMPLES_PER_STEP as f64).round() as u32,
        dac: DacConfig {
            full_scale_v: p.amplifier.output_max_v as f32,
            min_v: p.amplifier.output_min_v as f32,
            max_v: p.amplifier.output_max_v as f32,
            sample_rate_hz: p.amplifier.dac_rate_hz as u32,
            min_freq_hz: 500.0,
            max_freq_hz: 2200.0,
            slew_v_per_sample: 0.5,
        },
        motor,
        encoder_nm_per_count: (p.sensors.encoder_resolution_m * 1e9).round() as u32,
        preload: PreloadCalibration {
            zero_word: 0,
            newton_per_word: (p.sensors.force_cell_full_scale_n
                / f64::from((1u32 << p.sensors.force_cell_adc_bits) - 1)) as f32,
            min_valid_word: 0,
            max_valid_word: ((1u32 << p.sensors.force_cell_adc_bits) - 1) as u16,
            filter_alpha: 0.01,
        },
        preload_min_n: 3.0,
        preload_max_n: full_contact,
        drive_freq_hz,
        max_drive_v,
        speed_fraction: 0.92,
        accel_fraction: 0.8,
        kp_per_s: 40.0,
        ki_n_per_nm_s: 2e-4,
        feedforward: true,
        approach_speed_nm_s: 200_000.0,
        fine_window_nm: 300.0,
        fine_gain: 0.5,
        on_target_window_nm: 50,
        settle_time_s: 0.01,
        following_error_limit_nm: 50_000.0,
        stall_time_s: 0.05,
        encoder_jump_counts: 200,
        travel_min_nm: -50_000_000,
        travel_max_nm: 50_000_000,
    }
}

/// Controller + plant, advanced one control period at a time.
pub struct Sil {
    pub plant: Plant,
    pub controller: Controller,
    rng: StdRng,
    /// Outputs computed last period, applied during this one.
    pending: Outputs,
    full_scale_v: f64,
    plant_steps_per_period: u32,
    dac_period_s: f64,
    /// Injected encoder disturbance (counts), for fault tests.
    pub encoder_offset_counts: i64,
}

impl Sil {
    pub fn new(p: &Params, cfg: ControllerConfig, preload_n: f64, seed: u64) -> anyhow::Result<Self> {
        let controller =
            Controller::new(cfg).map_err(|e| anyhow::anyhow!("controller configuration: {e:?}"))?;
        let plant = Plant::new(p, preload_n);
        let period_s = 1.0 / f64::from(cfg.loop_hz);
        let mid = ((p.amplifier_mid_v() / p.amplifier.output_max_v) * 4095.0).round() as u16;
        Ok(Sil {
            plant,
            controller,
            rng: StdRng::seed_from_u64(seed),
            pending: Outputs { dac: [[mid; 2]; DAC_SAMPLES_PER_STEP], amp_enable: false },
            full_scale_v: p.amplifier.output_max_v,
            plant_steps_per_period: (period_s / p.integrator.step_s).round() as u32,
            dac_period_s: 1.0 / p.amplifier.dac_rate_hz,
            encoder_offset_counts: 0,
        })
    }

    pub fn set_load(&mut self, load: ExternalLoad) {
        self.plant.load = load;
    }

    /// What the board reads now.
    pub fn inputs(&mut self) -> Inputs {
        let counts = self.plant.encoder_counts() + self.encoder_offset_counts;
        Inputs {
            encoder_raw: counts as u16, // the timer's 16-bit counter wraps
            preload_word: self.plant.force_cell_word(&mut self.rng).min(u32::from(u16::MAX)) as u16,
            index: false,
        }
    }

    /// One control period: the controller sees the sensors, its outputs take effect next period.
    pub fn period(&mut self) -> Outputs {
        let inputs = self.inputs();
        let out = self.controller.step(&inputs);
        let applied = std::mem::replace(&mut self.pending, out);
        self.apply(&applied);
        out
    }

    fn apply(&mut self, out: &Outputs) {
        self.plant.set_drive_off(!out.amp_enable);
        let start = self.plant.time_s();
        let scale = self.full_scale_v / 4095.0;
        let dac_period = self.dac_period_s;
        let samples = out.dac;
        let mut drive = move |t: f64| {
            let k = (((t - start) / dac_period).round().max(0.0) as usize).min(DAC_SAMPLES_PER_STEP - 1);
            let [a, b] = samples[k];
            [f64::from(a) * scale, f64::from(b) * scale]
        };
        for _ in 0..self.plant_steps_per_period {
            self.plant.step(&mut drive);
        }
    }

    pub fn time_s(&self) -> f64 {
        self.plant.time_s()
    }

    /// Runs until `done` says stop or `max_s` of plant time passed; returns whether `done` held.
    pub fn run_until(&mut self, max_s: f64, mut done: impl FnMut(&Sil) -> bool) -> bool {
        let end = self.time_s() + max_s;
        while self.time_s() < end {
            self.period();
            if done(self) {
                return true;
            }
        }
        false
    }
}
