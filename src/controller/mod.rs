//! The positioning controller: one entry point, [`Controller::step`], called at a fixed rate with
//! raw sensor words; it returns the DAC words for the next period and the amplifier enable.
//!
//! Coarse motion: an online trapezoidal profile; the drive voltage comes from the inverse of the
//! fixed-point thrust model (feedforward: profile speed + position feedback, against a load
//! estimate integrated from the position error), at the drive frequency. Near the target the sine
//! ramps out and the stacks are held at static voltages (fine mode): the foot sticks to the slider
//! and moves it by a fraction of its stroke. Supervision puts the drive in a safe state on any
//! fault; only [`Controller::clear_fault`] leaves it.

use crate::generator::QuadratureGenerator;

// The parts own their state, each with its settings and its own tests: `feedback` (sensors),
// `motion` (the profile), `load_observer`, `plain_pi`, `fine` (`FineMode`), `mass`,
// `frequency_policy`, `supervisor`. The other modules are `Controller`'s jobs, which run the
// parts and write the generator: `supervision` (sense, supervise), `closed_loop`, `coarse`, `fine`,
// `referencing`, `open_loop`, `commands`, `frequency` and `model_cache` (the model table).
// `step` below is where to start.
mod closed_loop;
mod coarse;
mod commands;
mod config;
mod contact_build;
mod feedback;
mod fine;
mod frequency;
mod frequency_choice;
mod frequency_policy;
mod load_observer;
mod mass;
pub mod model_cache;
mod motion;
mod open_loop;
mod plain_pi;
mod referencing;
mod supervision;
mod supervisor;
pub mod table_build;
pub use crate::config::{ControllerConfig, ReferenceSignal, MAX_TRAVEL_NM};
pub use commands::ConfigChange;
pub use config::{validate_change, validate_settings};
use feedback::Feedback;
use fine::{FineMode, FineStep};
use frequency_policy::FrequencyPolicy;
use load_observer::LoadObserver;
use mass::MassEstimator;
use model_cache::ModelSlot;
use motion::Motion;
use open_loop::OpenLoopRun;
use plain_pi::PlainPi;
use referencing::ReferenceSearch;
use supervisor::Supervisor;

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
    /// Referencing or open-loop stepping drove without the encoder showing progress along the
    /// drive for a window (an end stop, a stalled slider or a lost encoder).
    NoProgress = 8,
}

impl FaultCode {
    /// Every fault, in code order: wire formats decode from it, tests walk it.
    pub const ALL: [FaultCode; 8] = [
        FaultCode::FollowingError,
        FaultCode::Stall,
        FaultCode::PreloadOutOfWindow,
        FaultCode::PreloadSensor,
        FaultCode::EncoderJump,
        FaultCode::Overrun,
        FaultCode::EncoderLoss,
        FaultCode::NoProgress,
    ];

    pub fn text(self) -> &'static str {
        match self {
            FaultCode::FollowingError => "following error above limit",
            FaultCode::Stall => "stall: slider does not follow the drive",
            FaultCode::PreloadOutOfWindow => "preload outside the usable window",
            FaultCode::PreloadSensor => "preload sensor reading invalid",
            FaultCode::EncoderJump => "encoder jump",
            FaultCode::Overrun => "control loop overrun: drive disabled",
            FaultCode::EncoderLoss => {
                "encoder loss: the drive moved the slider and the encoder saw none of it"
            }
            FaultCode::NoProgress => "no progress: the open-loop drive did not move the slider (end stop?)",
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

impl State {
    /// The number the wire formats give a state that is not a fault (0 idle, 1 moving,
    /// 2 holding, 3 referencing, 4 open loop), or the fault's code: each format (the PIL frame,
    /// the data recorder) marks faults its own way.
    pub fn number(self) -> Result<u8, FaultCode> {
        match self {
            State::Idle => Ok(0),
            State::Moving => Ok(1),
            State::Holding => Ok(2),
            State::Referencing => Ok(3),
            State::OpenLoop => Ok(4),
            State::Fault(code) => Err(code),
        }
    }
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
    /// The board reads limit switches (pins wired); the two above are then its debounced
    /// readings, false while the switches are disabled ([`ControllerConfig::limit_switches_enabled`]).
    pub limits_wired: bool,
}

/// The limit switches as the controller last saw them ([`Controller::limit_switches`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct LimitSwitches {
    /// The board has the switches wired (it reads their pins).
    pub wired: bool,
    /// The setting that has them read (`limit_switches_enabled`).
    pub enabled: bool,
    /// Their states after the board's debounce (active: at or beyond that end of travel).
    pub negative: bool,
    pub positive: bool,
}

/// What the board applies during the next period.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Outputs {
    pub dac: [[u16; 2]; DAC_SAMPLES_PER_STEP],
    pub amp_enable: bool,
}

/// How the closed loop drives while moving or holding.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Mode {
    Coarse,
    /// Waiting for the sine to ramp out before static control starts.
    FineEntering,
    /// Static offsets, with the step in progress.
    Fine(FineStep),
}

/// What the controller is doing, with what only that needs: [`State`] without the data.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Activity {
    Idle,
    Moving,
    Holding,
    Referencing(ReferenceSearch),
    OpenLoop(OpenLoopRun),
    Fault(FaultCode),
}

impl Activity {
    fn state(&self) -> State {
        match *self {
            Activity::Idle => State::Idle,
            Activity::Moving => State::Moving,
            Activity::Holding => State::Holding,
            Activity::Referencing(_) => State::Referencing,
            Activity::OpenLoop(_) => State::OpenLoop,
            Activity::Fault(code) => State::Fault(code),
        }
    }
}

/// What the controller is doing, with that activity's own data; how the closed loop drives;
/// whether the servo is on and the axis referenced.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Status {
    activity: Activity,
    mode: Mode,
    servo: bool,
    referenced: bool,
}

/// The drive: the generator that makes the two sines (or the static offsets) and the voltage last
/// commanded (V peak-to-peak), the inverse model's next hint and what the supervisor and the load
/// observer call near full drive.
#[derive(Clone)]
struct Drive {
    generator: QuadratureGenerator,
    commanded_v: f32,
}

/// `Clone` lets a board answer read-only protocol queries from a copy taken in a short critical
/// section, instead of holding the control tick off while it formats the reply.
#[derive(Clone)]
pub struct Controller {
    cfg: ControllerConfig,
    /// The control period (s): one over the loop rate.
    dt_s: f32,
    /// The thrust model's table and what it asks for ([`model_cache`]).
    model: ModelSlot,
    /// What the controller is doing and how the closed loop drives, the servo and referencing
    /// flags.
    status: Status,
    /// The sine generator and the voltage last commanded of it.
    drive: Drive,
    // The parts, each with its own state (and settings, cut from `cfg` in `config.rs`):
    /// Encoder, speed and preload readings ([`feedback`]).
    feedback: Feedback,
    /// The profile, its acceleration and braking rate, the time on target ([`motion`]).
    motion: Motion,
    /// The load estimate the feedforward pushes against ([`load_observer`]).
    load: LoadObserver,
    /// The coarse mode's feedback without the model ([`plain_pi`]).
    pi: PlainPi,
    /// The static offset and the encoder-loss count of the fine mode ([`fine`]).
    fine: FineMode,
    /// The moving mass: told, measured or learned ([`mass`]).
    mass: MassEstimator,
    /// When the drive frequency may change ([`frequency_policy`]).
    frequency: FrequencyPolicy,
    /// Following error and stall judgement, and the counts the protocol watches ([`supervisor`]).
    supervisor: Supervisor,
    /// The limit switch inputs of the last period: wired, and their states.
    limits: (bool, bool, bool),
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
            drive: Drive { generator, commanded_v: 0.0 },
            feedback: Feedback::new(cfg.encoder_nm_per_count, cfg.preload),
            motion: Motion::new(),
            status: Status { activity: Activity::Idle, mode: Mode::Coarse, servo: false, referenced: false },
            dt_s: 1.0 / cfg.loop_hz as f32,
            load: LoadObserver::new(cfg.load_observer()),
            pi: PlainPi::new(cfg.plain_pi()),
            fine: FineMode::new(cfg.fine_mode()),
            frequency: FrequencyPolicy::new(cfg.profile_wait_lag_nm),
            model: ModelSlot::new(&cfg, 0),
            mass: MassEstimator::new(cfg.moving_mass_kg),
            supervisor: Supervisor::new(cfg.supervisor()),
            limits: (false, false, false),
            cfg,
        })
    }

    pub fn state(&self) -> State {
        self.status.activity.state()
    }

    pub fn config(&self) -> &ControllerConfig {
        &self.cfg
    }

    pub fn position_nm(&self) -> i64 {
        self.feedback.position_nm()
    }

    pub fn target_nm(&self) -> i64 {
        self.motion.profile().target_nm()
    }

    pub fn reference_nm(&self) -> i64 {
        self.motion.profile().position_nm()
    }

    pub fn preload_n(&self) -> Option<f32> {
        self.feedback.preload_n()
    }

    pub fn servo(&self) -> bool {
        self.status.servo
    }

    pub fn referenced(&self) -> bool {
        self.status.referenced
    }

    pub fn drive_voltage_v(&self) -> f32 {
        self.drive.generator.amplitude_v()
    }

    pub fn drive_frequency_hz(&self) -> f32 {
        self.drive.generator.frequency_hz()
    }

    /// Common static offset of the fine mode (V).
    pub fn fine_offset_v(&self) -> f32 {
        self.fine.offset_v()
    }

    pub fn fine_mode(&self) -> bool {
        !matches!(self.status.mode, Mode::Coarse)
    }

    pub fn speed_nm_s(&self) -> f32 {
        self.feedback.speed_nm_s()
    }

    /// The load estimate the feedforward pushes against (N along +x): the observer's, plus the
    /// integral's correction while moving.
    pub fn load_estimate_n(&self) -> f32 {
        self.load.estimate_n()
    }

    /// Largest |reference − position| since the last move command.
    pub fn max_following_error_nm(&self) -> f32 {
        self.supervisor.max_following_error_nm()
    }

    /// Referencing in progress (PI's "controller busy").
    pub fn referencing(&self) -> bool {
        self.state() == State::Referencing
    }

    /// The active fault, if any.
    pub fn fault(&self) -> Option<FaultCode> {
        match self.state() {
            State::Fault(code) => Some(code),
            _ => None,
        }
    }

    /// Faults since power-up (wraps): a change tells the protocol a fault happened.
    pub fn fault_count(&self) -> u32 {
        self.supervisor.faults()
    }

    /// Referencing searches that ended without finding the mark (wraps).
    pub fn reference_failure_count(&self) -> u32 {
        self.supervisor.reference_failures()
    }

    /// Closed-loop moves and open-loop runs that a limit switch stopped (wraps): a change tells
    /// the protocol one did.
    pub fn limit_stop_count(&self) -> u32 {
        self.supervisor.limit_stops()
    }

    /// The limit switches: whether the board has them wired, whether the settings have them read,
    /// and their debounced states as of the last period (what `LIM?` and the limit bits of the
    /// status answer from).
    pub fn limit_switches(&self) -> LimitSwitches {
        let (wired, negative, positive) = self.limits;
        LimitSwitches { wired, enabled: self.cfg.limit_switches_enabled, negative, positive }
    }

    /// Control-loop overruns the board reported (wraps), also those during a fault (which keep
    /// the first fault's code): a change tells the protocol one happened.
    pub fn overrun_count(&self) -> u32 {
        self.supervisor.overruns()
    }

    /// Motion in progress: a closed-loop move, referencing or open-loop stepping.
    pub fn in_motion(&self) -> bool {
        match self.state() {
            State::Referencing | State::OpenLoop => true,
            State::Moving | State::Holding => !self.motion.profile().done(),
            State::Idle | State::Fault(_) => false,
        }
    }

    /// As PI's ONT?: holding within the window for the settle time.
    pub fn on_target(&self) -> bool {
        self.state() == State::Holding
            && self.motion.on_target_ticks() >= self.cfg.ticks_for_s(self.cfg.settle_time_s)
    }

    /// The measured preload (N) if it is read and within the window: the one check, for
    /// servo on, moves, referencing, open-loop runs, the supervisor and the protocol's `SVO`
    /// after a fault.
    pub fn check_preload(&self) -> Result<f32, CommandError> {
        let f = self.preload_n().ok_or(CommandError::PreloadInvalid)?;
        if f < self.cfg.preload_min_n || f > self.cfg.preload_max_n {
            return Err(CommandError::PreloadOutOfWindow);
        }
        Ok(f)
    }

    fn enter_hold(&mut self) {
        self.status.activity = Activity::Holding;
        self.motion.restart_on_target();
    }

    /// The reference where the slider is, then holding there with the servo on, else quiet.
    fn hold_here_or_quiet(&mut self) {
        let here = self.position_nm();
        self.motion.profile_mut().reset(here);
        if self.status.servo {
            self.enter_hold();
        } else {
            self.status.activity = Activity::Idle;
            self.drive.generator.ramp_to_quiet();
        }
    }

    /// One control period.
    pub fn step(&mut self, inputs: &Inputs) -> Outputs {
        self.limits = (inputs.limits_wired, inputs.negative_limit, inputs.positive_limit);
        self.motion.tick();
        self.sense(inputs);
        self.supervise();
        // A limit switch in the direction of a closed-loop move stops it where it is.
        if self.state() == State::Moving {
            let v = self.motion.profile().velocity_nm_s();
            let toward = self.motion.profile().target_nm() - self.position_nm();
            if (inputs.negative_limit && (v < 0.0 || toward < 0))
                || (inputs.positive_limit && (v > 0.0 || toward > 0))
            {
                self.supervisor.note_limit_stop();
                self.stop();
            }
        }
        match self.state() {
            State::Moving | State::Holding => self.regulate(),
            State::Referencing => self.reference(inputs),
            State::OpenLoop => self.open_loop(inputs),
            State::Idle | State::Fault(_) => self.drive.generator.ramp_to_quiet(),
        }
        let mut out = Outputs { dac: [[0; 2]; DAC_SAMPLES_PER_STEP], amp_enable: false };
        if !matches!(self.state(), State::Fault(_)) {
            self.drive.generator.reset_slew();
        }
        if let State::Fault(_) = self.state() {
            // Safe within this very period: ramp every output to mid-range in these samples,
            // then the amplifier is disabled.
            self.drive.generator.quiet_within(DAC_SAMPLES_PER_STEP as u32);
            self.drive.generator.fill(&mut out.dac);
            out.amp_enable = false;
        } else {
            self.drive.generator.fill(&mut out.dac);
            out.amp_enable = true;
        }
        let quiet = self.drive_voltage_v() == 0.0;
        self.model.rest_preload.note(quiet, self.preload_n());
        out
    }
}
