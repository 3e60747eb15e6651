//! The model table built in slices ([`TableBuild`]): the same work as [`ModelTable::build`], cut
//! where it can wait, so that a cooperative context runs its other tasks between the slices. On
//! the board the build runs in the thread-mode executor beside the UART and the preload ADC
//! tasks; whole, it took 1.4–2.3 million instructions (8–13 ms at 170 MHz, more for a carriage
//! that rides the foot) in which neither ran: a rebuild while holding could outlast the tick's
//! 20 ms preload staleness limit and trip a false preload-sensor fault. A slice is one frequency
//! candidate, the preparation, one row of the thrust grid or one load of the speed table
//! (`tools/pil/run` prints the longest on the M4).

use super::contact_build;
use super::model_cache::{
    thrust_at_zero_speed, thrust_row, thrust_row_from_law, with_guide_friction, ModelRequest, ModelTable,
    LOAD_POINTS, PHASE_POINTS, RIDING_SHARE, VOLT_POINTS,
};
use crate::fastmath::fx_from_f32;
use crate::inertia::Orbits;
use crate::model::ThrustPoint;

impl ModelTable {
    /// The expensive part: the frequency chosen first when the request offers several
    /// ([`ModelRequest::chosen`]), then [`VOLT_POINTS`] model points, the thrust at every grid
    /// node and [`LOAD_POINTS`] speed roots or, for a carriage whose speed ripples, periodic orbits
    /// (a few hundred thousand instructions on the Cortex-M4; up to 2.25 million measured in PIL
    /// for the 1 kg default with the choice, 1.35 million without; more for a carriage that rides
    /// the foot, whose whole grid comes from orbits), for a lower-priority context. All at once:
    /// [`TableBuild`] is the same work in slices.
    pub fn build(request: &ModelRequest) -> Self {
        let mut build = TableBuild::new(request);
        loop {
            if let Some(table) = build.step() {
                return table;
            }
        }
    }
}

impl ModelTable {
    /// The table from another model of the carriage: `speed_at(volts, load_n)`, its mean speed
    /// (mm/s) at a drive against a load on the foot, None where it has none. The request's
    /// frequency is taken as it is (build one with [`ModelTable::build`] first to have it
    /// chosen). Every row of the grid goes through that model as a riding carriage's rows go
    /// through its periodic motion, the stall force is the top row's thrust at zero speed and
    /// the speed table comes from the model at full drive. For hosts: the contact model that
    /// host-sim feeds it costs the Cortex-M4 far more than a table build may (docs/simulator.md).
    pub fn from_speed_law(request: &ModelRequest, mut speed_at: impl FnMut(f32, f32) -> Option<f32>) -> Self {
        let mut thrust_n = [[0.0f32; PHASE_POINTS]; VOLT_POINTS];
        let mut largest = 0.0f32;
        for (j, slot) in thrust_n.iter_mut().enumerate() {
            *slot = thrust_row_from_law(request, j, &mut speed_at);
            largest = slot.iter().fold(largest, |a, &t| a.max(t.abs()));
        }
        let top_row = thrust_n.last().copied().unwrap_or([0.0; PHASE_POINTS]);
        let stall_n = thrust_at_zero_speed(&top_row).max(0.0);
        let top_v = request.max_drive_v.max(0.0);
        let speed_mm_s = core::array::from_fn(|k| {
            let load = stall_n * k as f32 / (LOAD_POINTS - 1) as f32;
            with_guide_friction(request, load, |foot_load| speed_at(top_v, foot_load).unwrap_or(0.0).max(0.0))
        });
        ModelTable::assemble(request, &thrust_n, largest, stall_n, speed_mm_s)
    }
}

/// What the next slice does.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Stage {
    /// Rank frequency candidate i.
    Candidate(usize),
    /// The full-drive point and whether the carriage rides the foot.
    Prepare,
    /// Row j of the thrust grid.
    Row(usize),
    /// Load k of the speed table.
    Speed(usize),
    Done,
}

/// The full-drive point of the chosen request, and its periodic motion.
#[derive(Debug, Clone, Copy)]
struct FullDrive {
    point: ThrustPoint,
    orbits: Orbits,
    /// The carriage's speed ripples within a period ...
    light: bool,
    /// ... so much that the whole grid comes from its periodic motion.
    riding: bool,
}

/// A [`ModelTable`] under construction; [`TableBuild::step`] runs one slice.
#[derive(Debug, Clone)]
pub struct TableBuild {
    stage: Stage,
    asked: ModelRequest,
    /// The fastest candidate so far and its request ([`ModelRequest::rank_candidate`]).
    best: (f32, ModelRequest),
    /// The request with its frequency chosen.
    request: ModelRequest,
    full: Option<FullDrive>,
    thrust_n: [[f32; PHASE_POINTS]; VOLT_POINTS],
    largest: f32,
    stall_n: f32,
    speed_mm_s: [f32; LOAD_POINTS],
    /// The last speed of the speed table: where the next root search starts.
    hint: f32,
    /// Rows of a contact build whose normal motion did not settle (bit j: row j).
    unsettled: u64,
}

impl TableBuild {
    pub fn new(request: &ModelRequest) -> Self {
        TableBuild {
            stage: if request.choice.len > 1 { Stage::Candidate(0) } else { Stage::Prepare },
            asked: *request,
            best: (0.0, *request),
            request: *request,
            full: None,
            thrust_n: [[0.0; PHASE_POINTS]; VOLT_POINTS],
            largest: 0.0,
            stall_n: 0.0,
            speed_mm_s: [0.0; LOAD_POINTS],
            hint: f32::NAN,
            unsettled: 0,
        }
    }

    /// Runs the next slice; the table after the last one (and `None` after that).
    pub fn step(&mut self) -> Option<ModelTable> {
        match self.stage {
            Stage::Candidate(i) => {
                match self.asked.contact {
                    Some(c) => contact_build::rank_candidate(&self.asked, &c, i, &mut self.best),
                    None => self.asked.rank_candidate(i, &mut self.best),
                }
                if i + 1 < self.asked.choice.len {
                    self.stage = Stage::Candidate(i + 1);
                } else {
                    self.request = self.asked.with_choice_made(self.best);
                    self.stage = Stage::Prepare;
                }
                None
            }
            Stage::Prepare => {
                if self.request.contact.is_none() {
                    self.full = Some(self.full_drive());
                }
                self.stage = Stage::Row(0);
                None
            }
            Stage::Row(j) => {
                let row = match self.request.contact {
                    Some(c) => contact_build::contact_row(&self.request, &c, j).unwrap_or_else(|| {
                        self.unsettled |= 1u64 << j.min(63);
                        [0.0; PHASE_POINTS]
                    }),
                    None => thrust_row(&self.request, self.full.is_some_and(|f| f.riding), j),
                };
                self.largest = row.iter().fold(self.largest, |a, &t| a.max(t.abs()));
                if let Some(slot) = self.thrust_n.get_mut(j) {
                    *slot = row;
                }
                if j + 1 < VOLT_POINTS {
                    self.stage = Stage::Row(j + 1);
                } else {
                    contact_build::fill_unsettled_rows(&mut self.thrust_n, self.unsettled);
                    self.stall_n = self.stall_force_n();
                    self.stage = Stage::Speed(0);
                }
                None
            }
            Stage::Speed(_) if self.request.contact.is_some() => {
                // The contact table's speeds are its top row's (`contact_build::speed_table`).
                let top_row = self.thrust_n.last().copied().unwrap_or([0.0; PHASE_POINTS]);
                let top_v = self.request.max_drive_v.max(0.0);
                let foot_mm_s = self.request.per_volt.foot_speed_mm_s_per_v.to_num::<f32>() * top_v;
                self.speed_mm_s = contact_build::speed_table(&top_row, foot_mm_s);
                Some(self.finish())
            }
            Stage::Speed(k) => {
                let load = self.stall_n * k as f32 / (LOAD_POINTS - 1) as f32;
                let speed = self.speed_against(load);
                if let Some(slot) = self.speed_mm_s.get_mut(k) {
                    *slot = speed;
                }
                self.hint = speed;
                if k + 1 < LOAD_POINTS {
                    self.stage = Stage::Speed(k + 1);
                    None
                } else {
                    Some(self.finish())
                }
            }
            Stage::Done => None,
        }
    }

    /// The last slice: the table from what the slices made.
    fn finish(&mut self) -> ModelTable {
        self.stage = Stage::Done;
        ModelTable::assemble(&self.request, &self.thrust_n, self.largest, self.stall_n, self.speed_mm_s)
    }

    /// A light carriage: its full-drive speed from its periodic motion, and where that is far
    /// below the constant-speed model's, the whole grid from it too (see [`RIDING_SHARE`]).
    fn full_drive(&self) -> FullDrive {
        let r = &self.request;
        let point = r.per_volt.point(fx_from_f32(r.preload_n), fx_from_f32(r.max_drive_v.max(0.0)));
        let orbits = Orbits::new(&point, r.frequency_hz, r.moving_mass_kg);
        let light = orbits.inertia_matters();
        let constant_v0: f32 = point.no_load_speed_mm_s().to_num();
        let riding = light && orbits.mean_speed_mm_s(0.0).is_some_and(|v0| v0 < RIDING_SHARE * constant_v0);
        FullDrive { point, orbits, light, riding }
    }

    /// The stall force at full drive: the full-drive row's thrust at zero speed for a light
    /// carriage (the carriage's when the grid is the carriage's), eq. 19's net of the guide's
    /// Coulomb friction otherwise.
    fn stall_force_n(&self) -> f32 {
        if self.request.contact.is_some() {
            let top_row = self.thrust_n.last().copied().unwrap_or([0.0; PHASE_POINTS]);
            return thrust_at_zero_speed(&top_row).max(0.0);
        }
        match self.full {
            Some(f) if f.light => {
                let top_row = self.thrust_n.last().copied().unwrap_or([0.0; PHASE_POINTS]);
                thrust_at_zero_speed(&top_row).max(0.0)
            }
            Some(f) => (f.point.stall_force_n().to_num::<f32>() - self.request.rail_coulomb_n).max(0.0),
            None => 0.0,
        }
    }

    /// Forward speed at full drive against `load_n` (and the guide's friction): the periodic
    /// motion's for a light carriage, eq. 19's root (from the last load's speed) otherwise.
    fn speed_against(&self, load_n: f32) -> f32 {
        let Some(f) = self.full else { return 0.0 };
        let hint = self.hint;
        with_guide_friction(&self.request, load_n, |foot_load| {
            if f.light {
                f.orbits.mean_speed_mm_s(foot_load).unwrap_or(0.0).max(0.0)
            } else {
                f.point.speed_at_load_near(fx_from_f32(foot_load), hint).to_num()
            }
        })
    }
}
