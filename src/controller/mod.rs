//! The positioning controller: one entry point, [`Controller::step`], called at a fixed rate with
//! raw sensor words; it returns the DAC words for the next period and the amplifier enable.
//!
//! Coarse motion: an online trapezoidal profile; the drive voltage comes from the inverse of the
//! fixed-point thrust model (feedforward: profile speed + position feedback, against a load
//! estimate integrated from the position error), at the drive frequency. Near the target the sine
//! ramps out and the stacks are held at static voltages (fine mode): the foot sticks to the slider
//! and moves it by a fraction of its stroke. Supervision puts the drive in a safe state on any
//! fault; only [`Controller::clear_fault`] leaves it.

use crate::fastmath::{clamp_sym_f32, fx_from_f32};
use crate::generator::QuadratureGenerator;
use crate::model::PerVolt;
use crate::profile::Profile;
use crate::sensors::{Encoder, PreloadCell};

mod config;
pub mod model_cache;
pub use config::{validate_settings, ControllerConfig, MAX_TRAVEL_NM};
use model_cache::{ModelRequest, ModelTable, PRELOAD_RESOLVE_N};

/// DAC samples produced per control period (DAC rate / loop rate).
pub const DAC_SAMPLES_PER_STEP: usize = 20;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum FaultCode {
    FollowingError = 1,
    Stall = 2,
    PreloadOutOfWindow = 3,
    PreloadSensor = 4,
    EncoderJump = 5,
    /// The board's control tick missed its deadline (latched by the board, see
    /// [`Controller::trip_external`]); the board has already dropped the amplifier enable.
    Overrun = 6,
    /// Fine mode commanded corrections the encoder never saw: the encoder signal is lost (or
    /// the foot slips without moving the slider).
    EncoderLoss = 7,
}

impl FaultCode {
    pub fn text(self) -> &'static str {
        match self {
            FaultCode::FollowingError => "following error above limit",
            FaultCode::Stall => "stall: slider does not follow the drive",
            FaultCode::PreloadOutOfWindow => "preload outside the usable window",
            FaultCode::PreloadSensor => "preload sensor reading invalid",
            FaultCode::EncoderJump => "encoder jump",
            FaultCode::Overrun => "control loop overrun: drive disabled",
            FaultCode::EncoderLoss => "encoder loss: fine corrections not seen by the encoder",
        }
    }
}

/// Why a command was refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum CommandError {
    Faulted(FaultCode),
    ServoOff,
    OutOfTravel,
    PreloadInvalid,
    PreloadOutOfWindow,
    InvalidValue,
    /// Servo on where the command needs it off (open-loop stepping).
    ServoOn,
    /// Referencing in progress.
    Busy,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum State {
    /// Servo off; outputs quiet.
    Idle,
    /// Following a profile.
    Moving,
    /// Closed loop at the target.
    Holding,
    /// Moving open loop toward a reference mark.
    Referencing,
    /// Open-loop stepping (servo off): a given number of drive cycles at a given amplitude and
    /// frequency.
    OpenLoop,
    Fault(FaultCode),
}

/// What referencing looks for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ReferenceSignal {
    /// The encoder index if the scale has one: searched toward −x first; at the negative limit
    /// switch the search turns round; reaching the positive one means there is no index, and
    /// the search goes back to reference on the negative limit switch.
    Index,
    /// The negative limit switch (stages without an index).
    NegativeLimit,
}

/// What the board gives each period.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Inputs {
    /// Timer count in quadrature mode (16 bit, wraps).
    pub encoder_raw: u16,
    /// Preload cell ADC word.
    pub preload_word: u16,
    /// Encoder index seen since the last period.
    pub index: bool,
    /// The raw encoder count latched at the index edge, when the board latches it (in the
    /// EXTI handler or by timer capture). Referencing on the index then places the reference
    /// at the edge itself rather than where the slider is at this period's read.
    pub index_raw: Option<u16>,
    /// Limit switches (active = the slider is at or beyond the end of travel on that side).
    pub negative_limit: bool,
    pub positive_limit: bool,
}

/// What the board applies during the next period.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Outputs {
    pub dac: [[u16; 2]; DAC_SAMPLES_PER_STEP],
    pub amp_enable: bool,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Mode {
    Coarse,
    /// Waiting for the sine to ramp out before static control starts.
    FineEntering,
    Fine,
}

/// The controller's copy of the model table (see [`model_cache`]) and what it asks for.
#[derive(Debug, Clone, Copy)]
struct ModelSlot {
    per_volt: PerVolt,
    /// Counts accepted configurations: a table built for an older one is refused.
    generation: u32,
    table: Option<ModelTable>,
}

/// Fine-mode encoder-loss check: a correction expected to move at least this many counts that
/// moves none counts as a miss; this many misses in a row trip [`FaultCode::EncoderLoss`].
const FINE_LOSS_MIN_COUNTS: i64 = 4;
const FINE_LOSS_MISSES: u32 = 3;

impl ModelSlot {
    fn new(cfg: &ControllerConfig, generation: u32) -> Self {
        ModelSlot {
            per_volt: cfg.motor.at_frequency(fx_from_f32(cfg.drive_freq_hz / 1000.0)),
            generation,
            table: None,
        }
    }
}

/// `Clone` lets a board answer read-only protocol queries from a copy taken in a short critical
/// section, instead of holding the control tick off while it formats the reply.
#[derive(Clone)]
pub struct Controller {
    cfg: ControllerConfig,
    model: ModelSlot,
    generator: QuadratureGenerator,
    encoder: Option<Encoder>,
    preload: PreloadCell,
    profile: Profile,
    state: State,
    mode: Mode,
    servo: bool,
    referenced: bool,
    dt_s: f32,
    thrust_bias_n: f32,
    /// Thrust-model branch: load correction integrated from position error (N).
    integral_n: f32,
    /// Plain-feedback branch: integral term (V, signed along +x).
    integral_v: f32,
    fine_offset_v: f32,
    speed_nm_s: f32,
    on_target_s: f32,
    stall_s: f32,
    drive_v: f32,
    max_following_error_nm: f32,
    accel_ref_nm_s2: f32,
    fine_cmd_v: f32,
    fine_rate_v_s: f32,
    fine_settle: u32,
    /// Encoder-loss check of the fine mode: counts the last correction should move (0 = none
    /// pending), the count when it was commanded, and corrections in a row the encoder missed.
    fine_expect_counts: i64,
    fine_start_counts: i64,
    fine_misses: u32,
    /// Load observer: thrust along +x the model says the motor gives, less M·a (N).
    observed_bias_n: f32,
    prev_speed_nm_s: f32,
    decel_nm_s2: f32,
    /// Referencing: search direction and time spent.
    reference_dir: i8,
    reference_s: f32,
    /// Index search fell back to the negative limit switch.
    reference_on_limit: bool,
    reference_failures: u32,
    faults: u32,
    /// Open-loop stepping: periods left, amplitude, frequency, direction.
    open_loop_periods: u32,
    open_loop_v: f32,
    open_loop_hz: f32,
    open_loop_dir: i8,
    /// Control periods since start (wraps): the speed-up limit (a model evaluation) is
    /// refreshed on odd periods only; the profile's acceleration changes little in 100 µs.
    tick: u32,
    /// The speed-up limit from the last odd period (nm/s²).
    speedup_nm_s2: core::cell::Cell<f32>,
}

/// Highest speed from which a stop at `accel` ends within `distance` (v = √(2·a·d)).
fn profile_speed(accel: f32, distance: f32) -> f32 {
    crate::fastmath::sqrt_f32(2.0 * accel * distance)
}

impl Controller {
    pub fn new(cfg: ControllerConfig) -> Result<Self, CommandError> {
        let samples = cfg.dac.sample_rate_hz / cfg.loop_hz.max(1);
        if samples as usize != DAC_SAMPLES_PER_STEP || cfg.loop_hz == 0 {
            return Err(CommandError::InvalidValue);
        }
        validate_settings(&cfg)?;
        let mut generator = QuadratureGenerator::new(cfg.dac);
        generator.set_frequency_hz(cfg.drive_freq_hz);
        Ok(Controller {
            generator,
            encoder: None,
            preload: PreloadCell::new(cfg.preload),
            profile: Profile::at_rest(0),
            state: State::Idle,
            mode: Mode::Coarse,
            servo: false,
            referenced: false,
            dt_s: 1.0 / cfg.loop_hz as f32,
            thrust_bias_n: cfg.expected_load_n,
            integral_n: 0.0,
            integral_v: 0.0,
            fine_offset_v: 0.0,
            speed_nm_s: 0.0,
            on_target_s: 0.0,
            stall_s: 0.0,
            drive_v: 0.0,
            max_following_error_nm: 0.0,
            accel_ref_nm_s2: 0.0,
            fine_cmd_v: 0.0,
            fine_rate_v_s: 0.0,
            fine_settle: 0,
            fine_expect_counts: 0,
            fine_start_counts: 0,
            fine_misses: 0,
            observed_bias_n: cfg.expected_load_n,
            model: ModelSlot::new(&cfg, 0),
            prev_speed_nm_s: 0.0,
            decel_nm_s2: 1.0,
            reference_dir: -1,
            reference_s: 0.0,
            reference_on_limit: false,
            reference_failures: 0,
            faults: 0,
            open_loop_periods: 0,
            open_loop_v: 0.0,
            open_loop_hz: 0.0,
            open_loop_dir: 1,
            tick: 0,
            speedup_nm_s2: core::cell::Cell::new(0.0),
            cfg,
        })
    }

    // ---- telemetry ----
    pub fn state(&self) -> State {
        self.state
    }
    pub fn config(&self) -> &ControllerConfig {
        &self.cfg
    }
    pub fn position_nm(&self) -> i64 {
        self.encoder.map_or(0, |e| e.position_nm())
    }
    pub fn target_nm(&self) -> i64 {
        self.profile.target_nm()
    }
    pub fn reference_nm(&self) -> i64 {
        self.profile.position_nm()
    }
    pub fn preload_n(&self) -> Option<f32> {
        self.preload.valid().then(|| self.preload.force_n())
    }
    pub fn servo(&self) -> bool {
        self.servo
    }
    pub fn referenced(&self) -> bool {
        self.referenced
    }
    pub fn drive_voltage_v(&self) -> f32 {
        self.generator.amplitude_v()
    }
    pub fn drive_frequency_hz(&self) -> f32 {
        self.generator.frequency_hz()
    }
    /// Common static offset of the fine mode (V).
    pub fn fine_offset_v(&self) -> f32 {
        self.fine_offset_v
    }
    pub fn fine_mode(&self) -> bool {
        self.mode != Mode::Coarse
    }
    pub fn speed_nm_s(&self) -> f32 {
        self.speed_nm_s
    }
    /// Largest |reference − position| since the last move command.
    pub fn max_following_error_nm(&self) -> f32 {
        self.max_following_error_nm
    }
    /// Referencing in progress (PI's "controller busy").
    pub fn referencing(&self) -> bool {
        self.state == State::Referencing
    }
    /// The active fault, if any.
    pub fn fault(&self) -> Option<FaultCode> {
        match self.state {
            State::Fault(code) => Some(code),
            _ => None,
        }
    }
    /// Faults since power-up (wraps): a change tells the protocol a fault happened.
    pub fn fault_count(&self) -> u32 {
        self.faults
    }
    /// Referencing searches that ended without finding the mark (wraps).
    pub fn reference_failure_count(&self) -> u32 {
        self.reference_failures
    }
    /// Motion in progress: a closed-loop move, referencing or open-loop stepping.
    pub fn in_motion(&self) -> bool {
        match self.state {
            State::Referencing | State::OpenLoop => true,
            State::Moving | State::Holding => !self.profile.done(),
            State::Idle | State::Fault(_) => false,
        }
    }

    /// Replaces the settings after checking them. What the hardware fixes (loop and DAC rates,
    /// DAC range, encoder resolution, motor table) cannot change at run time.
    pub fn set_config(&mut self, cfg: ControllerConfig) -> Result<(), CommandError> {
        let c = &self.cfg;
        if cfg.loop_hz != c.loop_hz
            || cfg.dac != c.dac
            || cfg.encoder_nm_per_count != c.encoder_nm_per_count
            || cfg.motor != c.motor
        {
            return Err(CommandError::InvalidValue);
        }
        validate_settings(&cfg)?;
        if cfg.preload != self.cfg.preload {
            // Re-primed by the next sample.
            self.preload = PreloadCell::new(cfg.preload);
        }
        self.cfg = cfg;
        self.model = ModelSlot::new(&self.cfg, self.model.generation.wrapping_add(1));
        Ok(())
    }

    /// As PI's ONT?: holding within the window for the settle time.
    pub fn on_target(&self) -> bool {
        self.state == State::Holding && self.on_target_s >= self.cfg.settle_time_s
    }

    /// Stall force (N) and no-load speed (mm/s) at full drive and the measured preload: from the
    /// model table when it fits the preload, else computed here (for queries, off the tick).
    pub fn thrust_limits(&self) -> Option<(f32, f32)> {
        let preload = self.preload_n()?;
        if let Some(t) = self.fitting_table(preload) {
            return Some((t.stall_n(), t.no_load_mm_s()));
        }
        let p = self.model.per_volt.point(fx_from_f32(preload), fx_from_f32(self.cfg.max_drive_v));
        Some((p.stall_force_n().to_num(), p.no_load_speed_mm_s().to_num()))
    }

    /// The installed table, if it was built for this preload (within [`PRELOAD_RESOLVE_N`]).
    fn fitting_table(&self, preload_n: f32) -> Option<&ModelTable> {
        self.model.table.as_ref().filter(|t| (preload_n - t.request().preload_n).abs() <= PRELOAD_RESOLVE_N)
    }

    /// The cached limits for the control path: (stall N, no-load mm/s), None before a table.
    fn cached_limits(&self) -> Option<(f32, f32)> {
        self.model.table.as_ref().map(|t| (t.stall_n(), t.no_load_mm_s()))
    }

    /// The model table the controller wants built, if the installed one does not fit the
    /// measured preload or the configuration (see [`model_cache`]); None without a valid preload.
    /// Cheap: a board calls it under its lock, builds the table outside, then installs it.
    pub fn model_request(&self) -> Option<ModelRequest> {
        let preload_n = self.preload_n()?;
        if self.fitting_table(preload_n).is_some() {
            return None;
        }
        Some(ModelRequest {
            per_volt: self.model.per_volt,
            preload_n,
            max_drive_v: self.cfg.max_drive_v,
            generation: self.model.generation,
        })
    }

    /// Takes a table built from [`Self::model_request`]; false (and the table dropped) when the
    /// configuration changed since the request.
    pub fn install_model(&mut self, table: ModelTable) -> bool {
        let r = table.request();
        let current = r.generation == self.model.generation
            && r.per_volt == self.model.per_volt
            && r.max_drive_v == self.cfg.max_drive_v;
        if current {
            self.model.table = Some(table);
        }
        current
    }

    /// The lower-rate work done at once: builds and installs the model table if one is wanted.
    /// For hosts that run the controller synchronously (simulator, tests); the board splits it
    /// into [`Self::model_request`], [`ModelTable::build`] outside its lock, [`Self::install_model`].
    pub fn background(&mut self) {
        if let Some(r) = self.model_request() {
            self.install_model(ModelTable::build(&r));
        }
    }

    fn check_preload(&self) -> Result<f32, CommandError> {
        let f = self.preload_n().ok_or(CommandError::PreloadInvalid)?;
        if f < self.cfg.preload_min_n || f > self.cfg.preload_max_n {
            return Err(CommandError::PreloadOutOfWindow);
        }
        Ok(f)
    }

    // ---- commands ----
    pub fn set_servo(&mut self, on: bool) -> Result<(), CommandError> {
        if let State::Fault(code) = self.state {
            return Err(CommandError::Faulted(code));
        }
        if on {
            self.check_preload()?;
        }
        self.servo = on;
        if on {
            self.fine_misses = 0;
            self.fine_expect_counts = 0;
            let here = self.position_nm();
            self.profile.reset(here);
            self.enter_hold();
        } else {
            self.state = State::Idle;
            self.generator.ramp_to_quiet();
        }
        Ok(())
    }

    pub fn move_to(&mut self, target_nm: i64) -> Result<(), CommandError> {
        if let State::Fault(code) = self.state {
            return Err(CommandError::Faulted(code));
        }
        if self.state == State::Referencing {
            return Err(CommandError::Busy);
        }
        if !self.servo {
            return Err(CommandError::ServoOff);
        }
        if target_nm < self.cfg.travel_min_nm || target_nm > self.cfg.travel_max_nm {
            return Err(CommandError::OutOfTravel);
        }
        self.check_preload()?;
        self.profile.set_target(target_nm);
        // The braking rate is fixed for the whole move: a braking curve that changed under the
        // profile's feet would arrive with speed left over.
        self.decel_nm_s2 = self.accel_limit_nm_s2();
        self.max_following_error_nm = 0.0;
        self.on_target_s = 0.0;
        self.state = State::Moving;
        if self.mode != Mode::Coarse
            && (target_nm - self.position_nm()).abs() as f32 > self.cfg.fine_window_nm
        {
            self.mode = Mode::Coarse;
        }
        Ok(())
    }

    pub fn move_relative(&mut self, delta_nm: i64) -> Result<(), CommandError> {
        self.move_to(self.profile.target_nm().saturating_add(delta_nm))
    }

    /// Smooth stop: decelerate along the profile and hold where it ends. Referencing and
    /// open-loop stepping stop at once.
    pub fn halt(&mut self) {
        match self.state {
            State::Moving => {
                let a = self.accel_limit_nm_s2();
                let p = self.profile.stopping_point_nm(a);
                self.profile.set_target(p);
            }
            State::Referencing | State::OpenLoop => self.stop(),
            _ => {}
        }
    }

    /// Stop as fast as the motor can (PI's STP): a closed-loop move brakes along the profile at
    /// the model's braking rate, whatever the deceleration limit says — the slider's inertia
    /// makes a stop on the spot impossible, and a reference that stopped dead would only build
    /// up following error. Referencing and open-loop stepping end at once: hold there (servo on)
    /// or go quiet (servo off).
    pub fn stop(&mut self) {
        if self.state == State::Moving {
            let a = self.model_brake_nm_s2();
            let p = self.profile.stopping_point_nm(a);
            self.profile.set_target(p);
            self.decel_nm_s2 = a;
            return;
        }
        if matches!(self.state, State::Holding | State::Referencing | State::OpenLoop) {
            let here = self.position_nm();
            self.profile.reset(here);
            self.open_loop_periods = 0;
            if self.servo {
                self.enter_hold();
            } else {
                self.state = State::Idle;
                self.generator.ramp_to_quiet();
            }
        }
    }

    /// Open-loop stepping with the servo off: `cycles` drive periods (the sign gives the
    /// direction) at `amplitude_v` peak-to-peak and `frequency_hz`, then quiet.
    pub fn open_loop_step(
        &mut self,
        cycles: i32,
        amplitude_v: f32,
        frequency_hz: f32,
    ) -> Result<(), CommandError> {
        if let State::Fault(code) = self.state {
            return Err(CommandError::Faulted(code));
        }
        if self.servo {
            return Err(CommandError::ServoOn);
        }
        if self.state == State::Referencing {
            return Err(CommandError::Busy);
        }
        let d = &self.cfg.dac;
        let amplitude_ok =
            amplitude_v.is_finite() && amplitude_v >= 0.0 && amplitude_v <= self.cfg.max_drive_v;
        let freq_ok =
            frequency_hz.is_finite() && frequency_hz >= d.min_freq_hz && frequency_hz <= d.max_freq_hz;
        if !amplitude_ok || !freq_ok || cycles == 0 {
            return Err(CommandError::InvalidValue);
        }
        self.check_preload()?;
        // Periods of the control loop that hold `cycles` drive periods, rounded to nearest.
        let periods =
            f64::from(cycles.unsigned_abs()) * f64::from(self.cfg.loop_hz) / f64::from(frequency_hz);
        self.open_loop_periods = (periods + 0.5).min(f64::from(u32::MAX)) as u32;
        self.open_loop_v = amplitude_v;
        self.open_loop_hz = frequency_hz;
        self.open_loop_dir = if cycles > 0 { 1 } else { -1 };
        self.mode = Mode::Coarse;
        self.state = State::OpenLoop;
        Ok(())
    }

    pub fn clear_fault(&mut self) {
        if matches!(self.state, State::Fault(_)) {
            self.state = State::Idle;
            self.servo = false;
            let here = self.position_nm();
            self.profile.reset(here);
        }
    }

    /// Declares the present position to be `position_nm` (referencing on a mark).
    pub fn set_reference_here(&mut self, position_nm: i64) {
        if let Some(e) = self.encoder.as_mut() {
            e.set_position_nm(position_nm);
        }
        let here = self.position_nm();
        self.profile.reset(here);
        self.referenced = true;
    }

    /// Moves open loop toward negative positions until the encoder index is seen, then sets the
    /// position there to zero.
    ///
    /// With [`ReferenceSignal::Index`] the search turns round at the negative limit switch and,
    /// finding no index up to the positive one, references on the negative switch after all;
    /// with [`ReferenceSignal::NegativeLimit`] the switch is the mark.
    /// The mark's position becomes `reference_position_nm`. Afterwards the controller holds there
    /// (servo on) or goes quiet (servo off). A search that runs out of time or switches fails:
    /// not referenced, [`Self::reference_failure_count`] counts it.
    pub fn start_referencing(&mut self) -> Result<(), CommandError> {
        if let State::Fault(code) = self.state {
            return Err(CommandError::Faulted(code));
        }
        self.check_preload()?;
        self.state = State::Referencing;
        self.mode = Mode::Coarse;
        self.referenced = false;
        self.reference_dir = -1;
        self.reference_s = 0.0;
        self.reference_on_limit = false;
        self.open_loop_periods = 0;
        Ok(())
    }

    fn enter_hold(&mut self) {
        self.state = State::Holding;
        self.on_target_s = 0.0;
    }

    /// A fault found outside the core (the board's loop timing): the same safe state as a fault
    /// of the core's own (servo off, outputs ramped to mid-range, amplifier disabled in the
    /// outputs from this period on), latched until [`Self::clear_fault`]. An active fault stays
    /// (the first cause is the one reported).
    pub fn trip_external(&mut self, code: FaultCode) {
        if !matches!(self.state, State::Fault(_)) {
            self.trip(code);
        }
    }

    fn trip(&mut self, code: FaultCode) {
        self.faults = self.faults.wrapping_add(1);
        self.state = State::Fault(code);
        self.servo = false;
        self.mode = Mode::Coarse;
        self.generator.ramp_to_quiet();
    }

    /// Highest profile speed: the model's speed at full drive against the estimated load in the
    /// direction of travel, with margin.
    fn speed_limit_nm_s(&self) -> f32 {
        let Some(t) = self.model.table.as_ref() else { return 0.0 };
        let dir = if self.profile.target_nm() >= self.profile.position_nm() { 1.0 } else { -1.0 };
        let load = (dir * self.thrust_bias_n).max(0.0);
        (t.speed_at_load_mm_s(load) * 1e6 * self.cfg.speed_fraction).min(self.cfg.velocity_max_nm_s)
    }

    /// Braking limit: the model's (below) within the user's deceleration limit.
    fn accel_limit_nm_s2(&self) -> f32 {
        self.model_brake_nm_s2().min(self.cfg.decel_max_nm_s2)
    }

    /// The model's braking: reverse drive at full voltage brakes with at least the stall force.
    fn model_brake_nm_s2(&self) -> f32 {
        let mass = self.cfg.motor.moving_mass_kg.to_num::<f32>().max(1e-3);
        let stall = self.cached_limits().map_or(0.0, |(f, _)| f);
        // Leave the load estimate's share of the thrust for the load.
        let usable = (stall - self.thrust_bias_n.abs()).max(0.3 * stall);
        usable / mass * 1e9 * self.cfg.accel_fraction
    }

    /// Speeding-up limit at the profile's present speed: the model's thrust at that speed and
    /// full drive, less the load estimate, over the moving mass. No acceleration the motor
    /// cannot deliver at the measured preload.
    fn speedup_limit_nm_s2(&self) -> f32 {
        let mass = self.cfg.motor.moving_mass_kg.to_num::<f32>().max(1e-3);
        let Some(t) = self.model.table.as_ref() else { return 0.0 };
        let v = self.profile.velocity_nm_s();
        let thrust = t.full_thrust_n(v.abs() * 1e-6);
        let load = v.signum() * self.thrust_bias_n;
        let stall = t.stall_n();
        let usable = (thrust - load.max(0.0)).max(0.05 * stall);
        (usable / mass * 1e9 * self.cfg.accel_fraction).min(self.cfg.accel_max_nm_s2)
    }

    /// One control period.
    pub fn step(&mut self, inputs: &Inputs) -> Outputs {
        self.tick = self.tick.wrapping_add(1);
        self.sense(inputs);
        self.supervise();
        // A limit switch in the direction of a closed-loop move stops it where it is.
        if self.state == State::Moving {
            let v = self.profile.velocity_nm_s();
            let toward = self.profile.target_nm() - self.position_nm();
            if (inputs.negative_limit && (v < 0.0 || toward < 0))
                || (inputs.positive_limit && (v > 0.0 || toward > 0))
            {
                self.stop();
            }
        }
        match self.state {
            State::Moving | State::Holding => self.regulate(),
            State::Referencing => self.reference(inputs),
            State::OpenLoop => self.open_loop(inputs),
            State::Idle | State::Fault(_) => self.generator.ramp_to_quiet(),
        }
        let mut out = Outputs { dac: [[0; 2]; DAC_SAMPLES_PER_STEP], amp_enable: false };
        if !matches!(self.state, State::Fault(_)) {
            self.generator.reset_slew();
        }
        if let State::Fault(_) = self.state {
            // Safe within this very period: ramp every output to mid-range in these samples,
            // then the amplifier is disabled.
            self.generator.quiet_within(DAC_SAMPLES_PER_STEP as u32);
            self.generator.fill(&mut out.dac);
            out.amp_enable = false;
        } else {
            self.generator.fill(&mut out.dac);
            out.amp_enable = true;
        }
        out
    }

    fn sense(&mut self, inputs: &Inputs) {
        self.preload.update(inputs.preload_word);
        self.prev_speed_nm_s = self.speed_nm_s;
        match self.encoder.as_mut() {
            None => {
                self.encoder = Some(Encoder::new(inputs.encoder_raw, self.cfg.encoder_nm_per_count));
                self.profile.reset(0);
            }
            Some(e) => {
                let delta = e.update(inputs.encoder_raw);
                let v = delta as f32 * e.nm_per_count() as f32 / self.dt_s;
                // 2 ms speed filter: the encoder quantum (50 nm per 100 µs) is 0.5 mm/s.
                self.speed_nm_s += 0.05 * (v - self.speed_nm_s);
            }
        }
    }

    fn supervise(&mut self) {
        if let State::Fault(_) = self.state {
            return;
        }
        let active =
            matches!(self.state, State::Moving | State::Holding | State::Referencing | State::OpenLoop);
        if let Some(e) = self.encoder {
            if e.last_delta().abs() > self.cfg.encoder_jump_counts {
                self.trip(FaultCode::EncoderJump);
                return;
            }
        }
        if !active {
            return;
        }
        match self.check_preload() {
            Err(CommandError::PreloadInvalid) => return self.trip(FaultCode::PreloadSensor),
            Err(_) => return self.trip(FaultCode::PreloadOutOfWindow),
            Ok(_) => {}
        }
        if matches!(self.state, State::Referencing | State::OpenLoop) {
            // Open-loop motion: no reference to follow, no stall judgement.
            return;
        }
        let err = (self.profile.position_nm() - self.position_nm()) as f32;
        self.max_following_error_nm = self.max_following_error_nm.max(err.abs());
        if err.abs() > self.cfg.following_error_limit_nm {
            return self.trip(FaultCode::FollowingError);
        }
        // Stall/slip: the foot is driven hard but the slider does not move the driven way
        // (commanded foot speed against encoder speed).
        let dir = f32::from(self.generator.direction());
        let driving = self.mode == Mode::Coarse && self.drive_v > 0.5 * self.cfg.max_drive_v;
        let foot_speed = self.cached_limits().map_or(0.0, |(_, v0)| v0 * 1e6);
        if driving && dir * self.speed_nm_s < 0.1 * foot_speed {
            // Sliding backwards under full drive is the clearest sign: count it five times faster.
            // (only at full drive: below it the controller may still be finding the load).
            let backwards =
                dir * self.speed_nm_s < -0.1 * foot_speed && self.drive_v >= 0.95 * self.cfg.max_drive_v;
            self.stall_s += if backwards { 5.0 * self.dt_s } else { self.dt_s };
            if self.stall_s >= self.cfg.stall_time_s {
                self.trip(FaultCode::Stall);
            }
        } else {
            self.stall_s = 0.0;
        }
    }

    fn regulate(&mut self) {
        let mut v_max = self.speed_limit_nm_s();
        // A reference running away from a slider that cannot follow (an unknown load, a preload
        // change) only builds following error: past some lag the profile waits for the slider.
        let lag =
            (self.profile.position_nm() - self.position_nm()) as f32 * self.profile.velocity_nm_s().signum();
        if lag > self.cfg.profile_wait_lag_nm {
            v_max = v_max.min((self.speed_nm_s * self.profile.velocity_nm_s().signum()).max(0.0));
        }
        let v_before = self.profile.velocity_nm_s();
        let (dt_s, decel) = (self.dt_s, self.decel_nm_s2);
        // The speed-up limit costs a model evaluation: only when the profile speeds up.
        let odd = self.tick & 1 == 1;
        let up = || {
            if odd || self.speedup_nm_s2.get() <= 0.0 {
                self.speedup_nm_s2.set(self.speedup_limit_nm_s2());
            }
            self.speedup_nm_s2.get()
        };
        let mut profile = self.profile;
        profile.step(dt_s, v_max, up, decel);
        self.profile = profile;
        self.accel_ref_nm_s2 = (self.profile.velocity_nm_s() - v_before) / self.dt_s;
        if self.state == State::Moving && self.profile.done() {
            self.enter_hold();
        }
        let pos = self.position_nm();
        let err = (self.profile.position_nm() - pos) as f32;
        let to_target = (self.profile.target_nm() - pos) as f32;

        // On-target bookkeeping.
        if self.state == State::Holding
            && (self.profile.target_nm() - pos).abs() <= self.cfg.on_target_window_nm
        {
            self.on_target_s += self.dt_s;
        } else {
            self.on_target_s = 0.0;
        }

        let fine_room_nm = self.fine_room_v() * self.cfg.motor.fine_nm_per_v.to_num::<f32>();
        match self.mode {
            Mode::Coarse => {
                let nm_per_v = self.cfg.motor.fine_nm_per_v.to_num::<f32>().max(1e-3);
                let fits = (self.fine_offset_v + to_target / nm_per_v).abs() < 0.9 * self.fine_room_v();
                if self.profile.done()
                    && fits
                    && to_target.abs() < self.cfg.fine_window_nm.min(0.8 * fine_room_nm)
                {
                    self.mode = Mode::FineEntering;
                    self.generator.set_amplitude_v(0.0);
                    self.drive_v = 0.0;
                    return;
                }
                self.coarse(err);
            }
            Mode::FineEntering => {
                self.generator.set_amplitude_v(0.0);
                if self.generator.amplitude_v() == 0.0 {
                    self.mode = Mode::Fine;
                    self.fine_cmd_v = self.fine_offset_v;
                    self.fine_rate_v_s = 0.0;
                    self.fine_settle = 0;
                    // Misses carry over: a frozen encoder sends the fine mode out of stroke and
                    // back through the coarse mode, again and again.
                    self.fine_expect_counts = 0;
                }
            }
            Mode::Fine => {
                if to_target.abs() > fine_room_nm.max(self.cfg.fine_window_nm) * 1.5 {
                    self.mode = Mode::Coarse;
                    return;
                }
                self.fine(err);
            }
        }
    }

    /// Fine mode: the foot sticks to the slider and carries it by the static stroke. The offset
    /// moves along its own trapezoid (acceleration kept well below what static friction can
    /// give the moving mass); a new correction is measured only once the last one has been
    /// carried out and seen by the encoder (step and settle).
    fn fine(&mut self, err_nm: f32) {
        let nm_per_v = self.cfg.motor.fine_nm_per_v.to_num::<f32>().max(1e-3);
        let room = self.fine_room_v();
        let at_rest = self.fine_rate_v_s == 0.0 && (self.fine_cmd_v - self.fine_offset_v).abs() < 1e-3;
        let counts = self.encoder.map_or(0, |e| e.counts());
        if at_rest {
            self.fine_settle = self.fine_settle.saturating_add(1);
            if self.fine_settle >= 4 && self.fine_expect_counts != 0 {
                // The last correction has been carried out and settled: did the encoder see it?
                let moved = counts.saturating_sub(self.fine_start_counts);
                if self.fine_expect_counts.abs() >= FINE_LOSS_MIN_COUNTS && moved == 0 {
                    self.fine_misses = self.fine_misses.saturating_add(1);
                } else if moved != 0 {
                    self.fine_misses = 0;
                }
                self.fine_expect_counts = 0;
                if self.fine_misses >= FINE_LOSS_MISSES {
                    return self.trip(FaultCode::EncoderLoss);
                }
            }
            let nm_per_count = self.encoder.map_or(50, |e| e.nm_per_count());
            let half_count = 0.5 * nm_per_count as f32;
            if self.fine_settle >= 4 && err_nm.abs() > half_count {
                let wanted = self.fine_offset_v + err_nm / nm_per_v;
                if wanted.abs() > room {
                    // Out of static stroke: take the step with the sine, which recentres.
                    self.mode = Mode::Coarse;
                    return;
                }
                self.fine_cmd_v = wanted;
                self.fine_settle = 0;
                self.fine_expect_counts = (err_nm / nm_per_count.max(1) as f32) as i64;
                self.fine_start_counts = counts;
            }
        } else {
            self.fine_settle = 0;
        }
        // Trapezoid toward the commanded offset.
        let mass = self.cfg.motor.moving_mass_kg.to_num::<f32>().max(1e-3);
        let grip_n = self.preload.force_n().max(0.0) * self.cfg.motor.mu.to_num::<f32>();
        let accel_v_s2 = (0.25 * grip_n / mass / (nm_per_v * 1e-9)).max(1.0);
        let rate_max_v_s: f32 = 20_000.0;
        let d = self.fine_cmd_v - self.fine_offset_v;
        let dt = self.dt_s;
        let mut rate_des = d.signum() * rate_max_v_s.min(profile_speed(accel_v_s2, d.abs()));
        if d.abs() < 1e-4 {
            rate_des = 0.0;
        }
        self.fine_rate_v_s += clamp_sym_f32(rate_des - self.fine_rate_v_s, accel_v_s2 * dt);
        let next = self.fine_offset_v + self.fine_rate_v_s * dt;
        if (self.fine_cmd_v - next) * d <= 0.0 {
            self.fine_offset_v = self.fine_cmd_v;
            self.fine_rate_v_s = 0.0;
        } else {
            self.fine_offset_v = next;
        }
        self.generator.ramp_static_offsets_v([self.fine_offset_v; 2], DAC_SAMPLES_PER_STEP as u32);
    }

    /// Largest common static offset (V) that keeps both stacks in range.
    fn fine_room_v(&self) -> f32 {
        let d = &self.cfg.dac;
        (d.mid_v() - d.min_v).min(d.max_v - d.mid_v())
    }

    fn coarse(&mut self, err_nm: f32) {
        let v_ref = self.profile.velocity_nm_s();
        let mut v_cmd = v_ref + self.cfg.kp_per_s * err_nm;
        if self.profile.done() {
            // Final approach outside the fine range: below ~0.2 mm/s the model's crawl speeds are
            // not worth trusting, so approach at a speed the motor surely makes.
            v_cmd = err_nm.signum() * v_cmd.abs().max(self.cfg.approach_speed_nm_s);
        }
        let mut dir: i8 = if v_cmd >= 0.0 { 1 } else { -1 };
        let stall = self.cached_limits().map_or(0.0, |(stall, _)| stall);
        let volts = if self.cfg.feedforward {
            // Load observer (the thrust model run forwards): what the applied drive pushes at the
            // measured speed, less what accelerated the mass, is what the load took.
            let d = f32::from(self.generator.direction());
            // Observe only while the drive pushes the way the slider moves at a fair speed: the
            // model is least certain when braking and near standstill (stick).
            let backslide = self.state == State::Moving && d * self.speed_nm_s < -50_000.0;
            if (d * self.speed_nm_s > 200_000.0 || backslide) && self.drive_v > 0.2 * self.cfg.max_drive_v {
                let applied =
                    self.model.table.as_ref().map_or(0.0, |t| {
                        t.thrust_n(self.generator.amplitude_v(), d * self.speed_nm_s * 1e-6)
                    });
                let mass = self.cfg.motor.moving_mass_kg.to_num::<f32>();
                let accel = (self.speed_nm_s - self.prev_speed_nm_s) / self.dt_s * 1e-9;
                let sample = d * applied - mass * accel;
                // Sliding back under drive means the load is far above the estimate: learn faster.
                let gain = if backslide { 0.02 } else { 0.005 };
                self.observed_bias_n += gain * (sample - self.observed_bias_n);
            }
            // The integral on the position error corrects what the model gets wrong.
            self.integral_n =
                clamp_sym_f32(self.integral_n + self.cfg.ki_n_per_nm_s * err_nm * self.dt_s, stall);
            self.thrust_bias_n = clamp_sym_f32(self.observed_bias_n + self.integral_n, stall);
            // Inertia of the profile's acceleration is part of the load (F = M·a).
            let mass = self.cfg.motor.moving_mass_kg.to_num::<f32>();
            let load_along = f32::from(dir) * (self.thrust_bias_n + mass * self.accel_ref_nm_s2 * 1e-9);
            self.model
                .table
                .as_ref()
                .map_or(0.0, |t| t.voltage_for(v_cmd.abs() * 1e-6, load_along, self.drive_v))
        } else {
            // No model: PI from position error straight to signed volts. The integral stops
            // while the output is saturated the same way (anti-windup).
            let max_v = self.cfg.max_drive_v;
            let p_term = self.cfg.fb_kp_v_per_nm * err_nm;
            let unclamped = p_term + self.integral_v;
            let pushing_limit = unclamped.abs() >= max_v && unclamped * err_nm > 0.0;
            if !pushing_limit {
                self.integral_v =
                    clamp_sym_f32(self.integral_v + self.cfg.fb_ki_v_per_nm_s * err_nm * self.dt_s, max_v);
            }
            let signed = p_term + self.integral_v;
            dir = if signed >= 0.0 { 1 } else { -1 };
            signed.abs().min(max_v)
        };
        self.drive_v = volts;
        // While the sine runs the foot slides anyway: bring the static offset back to centre.
        let recentre = 10.0 * self.dt_s * self.fine_room_v();
        self.fine_offset_v -= clamp_sym_f32(self.fine_offset_v, recentre);
        self.fine_rate_v_s = 0.0;
        self.generator.ramp_static_offsets_v([self.fine_offset_v; 2], DAC_SAMPLES_PER_STEP as u32);
        self.generator.set_direction(dir);
        self.generator.set_frequency_hz(self.cfg.drive_freq_hz);
        self.generator.set_amplitude_v(volts);
    }

    fn reference(&mut self, inputs: &Inputs) {
        let here = self.position_nm();
        // No profile to follow while searching: keep the reference on the slider.
        self.profile.reset(here);
        let found = match self.cfg.reference_signal {
            ReferenceSignal::Index if self.reference_on_limit => inputs.negative_limit,
            ReferenceSignal::Index => inputs.index,
            ReferenceSignal::NegativeLimit => inputs.negative_limit,
        };
        if found {
            let mut at = self.cfg.reference_position_nm;
            if let (ReferenceSignal::Index, false, Some(raw), Some(e)) =
                (self.cfg.reference_signal, self.reference_on_limit, inputs.index_raw, self.encoder)
            {
                // Counts moved since the latched edge (well within ±2¹⁵ in one period).
                let since = i64::from(inputs.encoder_raw.wrapping_sub(raw) as i16);
                at = at.saturating_add(since.saturating_mul(e.nm_per_count()));
            }
            self.set_reference_here(at);
            self.end_open_loop_motion();
            return;
        }
        if self.cfg.reference_signal == ReferenceSignal::Index && !self.reference_on_limit {
            if inputs.negative_limit && self.reference_dir < 0 {
                self.reference_dir = 1;
            } else if inputs.positive_limit && self.reference_dir > 0 {
                // The whole travel without an index: the scale has none. Back to the negative
                // limit switch and reference on it.
                self.reference_on_limit = true;
                self.reference_dir = -1;
            }
        }
        self.reference_s += self.dt_s;
        if self.reference_s > self.cfg.reference_timeout_s {
            return self.reference_failed();
        }
        self.generator.set_direction(self.reference_dir);
        self.generator.set_frequency_hz(self.cfg.drive_freq_hz);
        self.generator.set_amplitude_v(self.cfg.reference_drive_v);
        self.drive_v = self.cfg.reference_drive_v;
    }

    fn reference_failed(&mut self) {
        self.reference_failures = self.reference_failures.wrapping_add(1);
        self.referenced = false;
        self.end_open_loop_motion();
    }

    /// End of referencing or open-loop stepping: hold here with the servo on, else go quiet.
    fn end_open_loop_motion(&mut self) {
        self.generator.set_amplitude_v(0.0);
        self.drive_v = 0.0;
        self.open_loop_periods = 0;
        let here = self.position_nm();
        self.profile.reset(here);
        if self.servo {
            self.enter_hold();
        } else {
            self.state = State::Idle;
            self.generator.ramp_to_quiet();
        }
    }

    fn open_loop(&mut self, inputs: &Inputs) {
        let here = self.position_nm();
        self.profile.reset(here);
        let blocked = (self.open_loop_dir < 0 && inputs.negative_limit)
            || (self.open_loop_dir > 0 && inputs.positive_limit);
        if self.open_loop_periods == 0 || blocked {
            return self.end_open_loop_motion();
        }
        self.open_loop_periods -= 1;
        self.generator.set_direction(self.open_loop_dir);
        self.generator.set_frequency_hz(self.open_loop_hz);
        self.generator.set_amplitude_v(self.open_loop_v);
        self.drive_v = self.open_loop_v;
    }
}
